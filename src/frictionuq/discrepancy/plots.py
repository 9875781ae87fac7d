"""The residual-diagnostics figure (matplotlib, Agg): one panel per view with the binned excess
friction d*(data - model) (N) +- 2 standard errors (from the block-permutation null), the views
that are significant after the Holm correction framed and titled in red, and a panel with the
position-locked spectrum (power relative to its null mean against wavelength) and its critical
level, and one with the high-frequency bursts (chatter.py: rms of the residual's unrepeated
high-frequency part against the travel since the reversal, beside the null's 95 % per bin).
Feature axes are in display units (mm, mm/s, s, kJ); forces in N.
"""
from __future__ import annotations

import io
import math

import numpy as np

from ..environment import png_metadata

#: feature -> (display factor from SI, axis label)
AXES = {
    "displacement": (1e3, "displacement x (mm)"),
    "velocity": (1e3, "velocity v (mm/s)"),
    "time": (1.0, "time t (s)"),
    "cycle": (1.0, "cycle number (-)"),
    "since_reversal": (1e3, "travel since last reversal s (mm)"),
    "energy": (1e-3, "energy dissipated E (kJ)"),
    "applied": (1.0, "measured applied force (N)"),
}
SIGNIFICANT = "#c0392b"


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot


def _arr(values):
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def _mark(ax, significant: bool):
    if significant:
        for spine in ax.spines.values():
            spine.set_edgecolor(SIGNIFICANT)
            spine.set_linewidth(2.0)


def _view_panel(ax, view: dict):
    factor, label = AXES.get(view["feature"], (1.0, f"{view['feature']} ({view['unit']})"))
    b = view["bins"]
    c, m, se = _arr(b["centre"]) * factor, _arr(b["mean"]), _arr(b["se"])
    colour = SIGNIFICANT if view["significant"] else "C0"
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.errorbar(c, m, yerr=2 * se, fmt="o-", ms=3, lw=1.2, capsize=2, color=colour,
                label="excess friction d*(data - model), bin mean +- 2 se")
    ax.plot(c, _arr(b["mean_fwd"]), ":", color="C2", lw=1, label="data - model, forward (d=+1)")
    ax.plot(c, _arr(b["mean_bwd"]), ":", color="C1", lw=1, label="data - model, backward (d=-1)")
    verdict = "SIGNIFICANT" if view["significant"] else "not significant"
    T = "T_trend" if view.get("test", "binned") != "binned" else "T"
    ax.set_title(f"{view['feature']}: {T} = {view['statistic']:.3g}, p_adj = {view['p_adjusted']:.3g} "
                 f"({verdict})", fontsize=9, color=SIGNIFICANT if view["significant"] else "black")
    ax.set_xlabel(label)
    ax.set_ylabel("residual (N)")
    _mark(ax, view["significant"])


def _spectrum_panel(ax, spec: dict | None):
    if spec is None:
        ax.text(0.5, 0.5, "no position-locked spectrum\n(displacement range too small)",
                ha="center", va="center", transform=ax.transAxes)
        ax.set_xlabel("wavelength (mm)")
        ax.set_ylabel("power / null mean power (-)")
        return
    lam = 1e3 / _arr(spec["wavenumber_per_m"])
    colour = SIGNIFICANT if spec["significant"] else "C0"
    ax.semilogx(lam, _arr(spec["power_ratio"]), color=colour, lw=1, label="periodogram of d*r over x\n(both directions) / null mean")
    ax.axhline(spec["critical_ratio"], color="0.4", ls="--", lw=1, label="null critical level (alpha / m)")
    ax.plot([spec["wavelength_m"] * 1e3], [spec["peak_ratio"]], "v", color=SIGNIFICANT, ms=7,
            label=f"peak at {spec['wavelength_m'] * 1e3:.3g} mm")
    verdict = "SIGNIFICANT" if spec["significant"] else "not significant"
    ax.set_title(f"position-locked spectrum: p_adj = {spec['p_adjusted']:.3g} ({verdict})", fontsize=9,
                 color=SIGNIFICANT if spec["significant"] else "black")
    ax.set_xlabel("wavelength in displacement (mm)")
    ax.set_ylabel("power / null mean power (-)")
    ax.legend(fontsize=7, loc="upper right")
    _mark(ax, spec["significant"])


def _chatter_panel(ax, ch: dict):
    b = ch["bins"]
    c = _arr(b["centre"]) * 1e3
    colour = SIGNIFICANT if ch["significant"] else "C0"
    ax.plot(c, _arr(b["rms"]), "o-", ms=3, lw=1.2, color=colour, label="high-frequency residual rms, bin")
    ax.plot(c, _arr(b["rms_fwd"]), ":", color="C2", lw=1)
    ax.plot(c, _arr(b["rms_bwd"]), ":", color="C1", lw=1)
    ax.plot(c, _arr(b["null_rms_q95"]), "--", color="0.4", lw=1, label="null 95 % (per bin)")
    verdict = "SIGNIFICANT" if ch["significant"] else "not significant"
    ax.set_title(f"bursts > {ch['highpass_hz']:.3g} Hz (chatter): p_adj = {ch['p_adjusted']:.3g} "
                 f"({verdict})", fontsize=9, color=SIGNIFICANT if ch["significant"] else "black")
    ax.set_xlabel("travel since last reversal s (mm)")
    ax.set_ylabel("rms of the unrepeated residual (N)")
    ax.legend(fontsize=7, loc="upper right")
    _mark(ax, ch["significant"])


def build_figure(diag: dict, title: str | None = None):
    """The matplotlib Figure of `diag` (a `diagnose` result): len(views) + 1 axes, + 1 for the
    high-frequency bursts when the record has them (`chatter`)."""
    pyplot = _plt()
    views = list(diag["views"].values())
    ch = diag.get("chatter")
    n_panels = len(views) + 1 + (ch is not None)
    ncols = min(3, n_panels)
    nrows = math.ceil(n_panels / ncols)
    fig, axes = pyplot.subplots(nrows, ncols, figsize=(4.2 * ncols, 3.3 * nrows + 0.8), squeeze=False)
    flat = list(axes.ravel())
    for ax, view in zip(flat, views):
        _view_panel(ax, view)
    _spectrum_panel(flat[len(views)], diag.get("spectrum"))
    if ch is not None:
        _chatter_panel(flat[len(views) + 1], ch)
    for ax in flat[n_panels:]:
        fig.delaxes(ax)
    if views:
        handles, labels = flat[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=3, fontsize=8, frameon=False)
    null = diag["null"]
    fig.suptitle(title or (f"Residual diagnostics: family-wise alpha = {diag['alpha']:g} ({diag['correction']}, "
                           f"m = {diag['family_size']}), {null['method']}, L = {null['block_length_samples']:.0f} "
                           f"samples, {diag['n_perm']} permutations; red = significant"), fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.95))
    return fig


def residual_figure(diag: dict, path=None, title: str | None = None, dpi: int = 90) -> bytes:
    """The figure of `diag` as PNG bytes, also written to `path` when given."""
    pyplot = _plt()
    fig = build_figure(diag, title)
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, metadata=png_metadata())
    finally:
        pyplot.close(fig)
    data = buf.getvalue()
    if path is not None:
        with open(path, "wb") as fh:
            fh.write(data)
    return data


def centred_rmse(r) -> float:
    """RMSE of a residual with its mean removed (the load-cell offset is not a misfit), N."""
    r = np.asarray(r, float)
    return float(np.sqrt(np.mean((r - r.mean()) ** 2)))


def loop_figure(t, x, y, models: dict, title: str, dpi: int = 90) -> bytes:
    """Force-displacement loops of the data (grey points) and of each model in `models`
    ({label: force (N)}, e.g. the baseline and the model with the named effect) beside their
    residuals against time, as PNG bytes. x in m (shown in mm), forces in N (shown in kN)."""
    pyplot = _plt()
    fig, (ax1, ax2) = pyplot.subplots(1, 2, figsize=(11.0, 4.0))
    try:
        ax1.plot(np.asarray(x) * 1e3, np.asarray(y) / 1e3, ".", ms=1.5, color="0.6", label="measured")
        for i, (label, F) in enumerate(models.items()):
            ax1.plot(np.asarray(x) * 1e3, np.asarray(F) / 1e3, "-", lw=1.0, color=f"C{i}", label=label)
            r = np.asarray(y) - np.asarray(F)
            ax2.plot(t, r, "-", lw=0.7, color=f"C{i}", alpha=0.8,
                     label=f"{label}: RMSE {centred_rmse(r):.4g} N")
        ax1.set_xlabel("displacement x (mm)")
        ax1.set_ylabel("force F (kN)")
        ax1.set_title("force-displacement loops", fontsize=9)
        ax1.legend(fontsize=7, loc="upper left")
        ax2.axhline(0.0, color="0.4", lw=0.8)
        ax2.set_xlabel("time t (s)")
        ax2.set_ylabel("data - model (N)")
        ax2.set_title("residuals against time", fontsize=9)
        ax2.legend(fontsize=7, loc="upper right")
        fig.suptitle(title, fontsize=10)
        fig.tight_layout(rect=(0, 0, 1, 0.94))
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, metadata=png_metadata())
    finally:
        pyplot.close(fig)
    return buf.getvalue()
