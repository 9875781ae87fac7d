"""Figures across applied forces: force-dependent parameters against the applied force (with the
force-dependence law and the papers' values) and the mechanical advantage (PNG bytes)."""
from __future__ import annotations

import numpy as np

from .. import params as P
from .. import units
from .figures import WIDTH, plt, png


def display(name: str) -> tuple[float, str, bool]:
    """(factor from SI, unit label, log axis) of a force-dependent parameter, in the parameter
    tables' display units (kN, kN/mm); sigma0 on a log axis."""
    unit, fac = units.display(P.PARAMS[name].unit)
    return fac, unit, name == "sigma0"


def across_figure(names: list[str], levels: list[dict], law: dict | None, published: dict | None,
                  applied_unit: str, title: str) -> bytes:
    """One panel per parameter: per-level posterior median and 95 % interval (open markers: fit
    not converged), the law's median, 95 % band of its mean and 95 % band with the between-level
    scatter (law: {name: (grid, med, lo, hi, lo_s, hi_s)}), published values ({name: (a, v)})."""
    pyplot = plt()
    n = len(names)
    ncols = 3
    nrows = max(1, -(-(n + 1) // ncols))
    fig, axes = pyplot.subplots(nrows, ncols, figsize=(WIDTH, 3.0 * nrows), squeeze=False)
    flat = axes.ravel()
    for ax, name in zip(flat, names):
        fac, unit, logy = display(name)
        for conv, mk, lab in ((True, "o", "posterior median, 95 % interval"),
                              (False, "o", "posterior (fit NOT converged)")):
            pts = [L for L in levels if name in L["stats"] and L["converged"] == conv]
            if not pts:
                continue
            a = np.array([L["applied"] for L in pts])
            med, lo, hi = (np.array([L["stats"][name][k] for L in pts]) * fac for k in range(3))
            ax.errorbar(a, med, yerr=[med - lo, hi - med], fmt=mk, color="C0", capsize=3, ms=5,
                        mfc="C0" if conv else "white", label=lab)
        if law and name in law:
            g, med, lo, hi, lo_s, hi_s = law[name]
            ax.fill_between(g, lo_s * fac, hi_s * fac, color="C1", alpha=0.12, lw=0,
                            label="law: 95 % incl. between-level scatter")
            ax.fill_between(g, lo * fac, hi * fac, color="C1", alpha=0.3, lw=0, label="law: 95 % band")
            ax.plot(g, med * fac, color="C1", lw=1.2, label="law: median")
        if published and name in published:
            a, v = published[name]
            ax.plot(a, np.asarray(v) * fac, "x", color="C3", ms=7, mew=1.6, label=published["_label"])
        if logy:
            ax.set_yscale("log")
        ax.set_xlabel(f"applied force ({applied_unit})")
        ax.set_ylabel(f"{name} ({unit})")
        ax.set_title(name, fontsize=9)
        ax.grid(alpha=0.3)
    seen = {}
    for ax in flat[:n]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    for ax in flat[n:]:
        ax.set_axis_off()
    flat[n].legend(list(seen.values()), list(seen.keys()), loc="center", fontsize=8,
                   frameon=False, title="legend")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return png(fig)


def advantage_figure(rows: list[dict], applied_unit: str, title: str) -> bytes:
    """Mechanical advantage C (and friction coefficient mu where available) against the applied
    force: posterior mean with 95 % interval per direction, the design value and the paper's.
    rows: advantage.csv records with an extra key `x` (applied force in applied_unit)."""
    pyplot = plt()
    has_mu = any(np.isfinite(r.get("mu_mean", np.nan)) for r in rows)
    qty = [("C", "mechanical advantage C")] + ([("mu", "friction coefficient mu")] if has_mu else [])
    fig, axes = pyplot.subplots(1, len(qty), figsize=(WIDTH, 3.6), squeeze=False)
    xs = np.array([r["x"] for r in rows], float)
    span = float(np.ptp(xs)) or max(abs(float(np.max(xs))), 1.0)
    jitter = 0.01 * span            # fwd/bwd side by side
    for ax, (q, label) in zip(axes.ravel(), qty):
        unit = rows[0].get("C_unit", "N/N") if q == "C" else "1"
        for k, d in enumerate(("fwd", "bwd")):
            for src, mk in (("posterior", "o"), ("force-dependence law", "s")):
                pts = [r for r in rows if r["direction"] == d and r["source"] == src
                       and np.isfinite(r.get(f"{q}_mean", np.nan))]
                if not pts:
                    continue
                x = np.array([r["x"] for r in pts]) + (1 if d == "bwd" else -1) * jitter
                m = np.array([r[f"{q}_mean"] for r in pts])
                lo = np.array([r[f"{q}_q2.5"] for r in pts])
                hi = np.array([r[f"{q}_q97.5"] for r in pts])
                ax.errorbar(x, m, yerr=[m - lo, hi - m], fmt=mk, color=f"C{k}", capsize=3,
                            label=f"{d}: {'posterior' if src == 'posterior' else 'law'} mean, 95 %")
            paper = [r.get(f"{q}_paper") for r in rows if r["direction"] == d]
            paper = [v for v in paper if v is not None and np.isfinite(v)]
            if paper:
                ax.axhline(paper[0], color=f"C{k}", ls="--", lw=1, label=f"{d}: paper")
        design = [r.get(f"{q}_design") for r in rows]
        design = [v for v in design if v is not None and np.isfinite(v)]
        if design:
            ax.axhline(design[0], color="k", ls=":", lw=1.2, label="design value")
        if np.ptp(xs) == 0:         # one level: a readable range around it
            ax.set_xlim(xs[0] - 0.5 * span, xs[0] + 0.5 * span)
        ax.set_xlabel(f"applied force ({applied_unit})")
        ax.set_ylabel(f"{label} ({unit})")
        ax.set_title(label, fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return png(fig)
