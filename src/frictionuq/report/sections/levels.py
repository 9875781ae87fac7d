"""Sections "across" (force-dependent parameters against the applied force, with the
force-dependence law and the papers' values) and "advantage" (mechanical advantage)."""
from __future__ import annotations

import numpy as np

from ... import published as PUB
from ... import units as U
from ...errors import InputError
from ...infer.law import FORCE_DEPENDENT, LAW_FILE, load_law
from ...infer.lawdraws import law_values
from .. import blocks as B
from ..figures_levels import advantage_figure, across_figure, display
from ..tables import DASH, interval, num, scaled, table
from ...wording import count

LAW_GRID = 120
LAW_SEED = 1
PAPER_LABEL = {"brfd": "BRFD paper, Table 2", "mfd": "MFD paper, Tables 1-4 (linear in pressure)"}


# ---------------------------------------------------------------- across applied forces

def level_stats(ctx) -> list[dict]:
    """Per fit at one applied force: median, 2.5 % and 97.5 % of each force-dependent parameter
    (a fixed parameter: its value three times)."""
    out = []
    for f in ctx.fits():
        if f.get("applied") is None:
            continue
        try:
            post = ctx.posterior(f["id"])["posterior"]
        except InputError:          # reported in the fits section
            continue
        fixed = (ctx.fit_record(f["id"]).get("space") or {}).get("fixed") or {}
        stats = {}
        for n in FORCE_DEPENDENT:
            if n in post.data_vars:
                v = np.asarray(post[n].values, float).ravel()
                stats[n] = tuple(np.percentile(v, [50, 2.5, 97.5]))
            elif n in fixed:
                stats[n] = (float(fixed[n]),) * 3
        out.append({"id": f["id"], "applied_si": float(f["applied"]),
                    "applied": ctx.applied_value(f["applied"]),
                    "converged": bool(f.get("converged")), "stats": stats})
    return sorted(out, key=lambda L: L["applied_si"])


def law_curves(ctx, law: dict, levels: list[dict]) -> dict:
    """{name: (grid in the campaign unit, median, 2.5 %, 97.5 %, same with scatter)} (SI values)."""
    top = max(L["applied_si"] for L in levels)
    grid = np.linspace(0.0, 1.1 * top, LAW_GRID + 1)[1:]
    rng = np.random.default_rng(LAW_SEED)
    out = {}
    for n in FORCE_DEPENDENT:
        if n not in law.get("laws", {}):
            continue
        v = law_values(law, n, grid, False, rng)
        vs = law_values(law, n, grid, True, rng)
        q = np.percentile(v, [50, 2.5, 97.5], axis=0)
        qs = np.percentile(vs, [2.5, 97.5], axis=0)
        out[n] = (np.array([ctx.applied_value(a) for a in grid]), q[0], q[1], q[2], qs[0], qs[1])
    return out


def published_points(ctx) -> tuple[dict | None, str | None]:
    """({name: (applied in the campaign unit, values SI), "_label": ...}, or None and why)."""
    dev = ctx.published()
    if dev == "none":
        return None, None
    si = U.si_unit_of_applied(ctx.applied_unit())
    want = "N" if dev == "brfd" else "Pa"
    if si != want:
        return None, (f"The {dev.upper()} paper's values are given per applied "
                      f"{'force' if want == 'N' else 'pressure'}, this campaign's applied unit is "
                      f"{ctx.applied_unit()}: not compared.")
    levels = PUB.BRFD_APPLIED_N if dev == "brfd" else tuple(p * U.PSI for p in PUB.MFD_PRESSURES_PSI)
    pts = {"_label": PAPER_LABEL[dev]}
    for n in FORCE_DEPENDENT:
        vals = [PUB.published_params(dev, a).get(n) for a in levels]
        if all(v is not None for v in vals):
            pts[n] = (np.array([ctx.applied_value(a) for a in levels]), np.array(vals, float))
    return pts, None


def across(ctx) -> list[dict]:
    if ctx.summary() is None:
        return [B.note("This run has no fits (fit/summary.json missing): nothing to show across "
                       "applied forces.")]
    levels = level_stats(ctx)
    if not levels:
        return [B.note("No fit at a single applied force (fits grouped otherwise): nothing to "
                       "show across applied forces.")]
    unit = ctx.applied_unit()
    names = [n for n in FORCE_DEPENDENT if any(n in L["stats"] for L in levels)]
    out = []
    positive = [L for L in levels if L["applied_si"] > 0]
    law, curves = None, None
    if (ctx.fit_dir / LAW_FILE).is_file():
        try:
            law = load_law(ctx.fit_dir)
        except (InputError, ValueError) as e:
            out.append(B.warn(f"fit/{LAW_FILE} could not be read: {e}"))
    if law is not None:
        curves = law_curves(ctx, law, levels)
        out.append(B.para(f"Force-dependence law (fit/{LAW_FILE}): family {law.get('family', '?')} "
                          f"for the force-dependent parameters, fitted on "
                          f"{count(len(law.get('levels', [])), 'level')}."))
    elif len(positive) < 2:
        out.append(B.note(f"Only {len(positive)} fitted applied force above zero: a force-dependence "
                          "law needs fits at 2 or more applied forces > 0, so only the per-level "
                          "posteriors are shown."))
    else:
        out.append(B.note(f"No force-dependence law in this run (fit/{LAW_FILE} absent): only the "
                          "per-level posteriors are shown."))
    pub, why = published_points(ctx)
    if why:
        out.append(B.note(why))
    elif pub is None:
        out.append(B.note("No published parameter set to compare with (workflow [report] "
                          "published = none)."))
    if names:
        png = across_figure(names, levels, curves, pub, unit,
                            "force-dependent parameters against the applied force")
        out.append(B.figure(png, "force-dependent parameters against the applied force",
                            "Posterior median and 95 % interval per fitted applied force"
                            + ("; the law's median and bands" if curves else "")
                            + (f"; {pub['_label']} (crosses)" if pub else "") + "."))
    rows = []
    for n in names:
        fac, u, _ = display(n)
        row = [n, u]
        for L in levels:
            s = L["stats"].get(n)
            row.append(DASH if s is None else f"{num(s[0] * fac)} {interval(s[1], s[2], factor=fac)}")
        rows.append(row)
    cols = ["parameter", "unit"] + [f"{L['applied']:g} {unit} ({L['id']}"
                                    + ("" if L["converged"] else ", NOT converged") + ")" for L in levels]
    out.append(B.html(table(cols, rows, caption="posterior median [2.5 %, 97.5 %] per applied force")))
    return out


# ---------------------------------------------------------------- mechanical advantage

def advantage(ctx) -> list[dict]:
    import pandas as pd
    path = ctx.run_dir / "advantage" / "advantage.csv"
    if not path.is_file():
        return [B.note("The mechanical advantage was not computed in this workflow "
                       "(advantage/advantage.csv absent).")]
    df = pd.read_csv(path)
    if df.empty:
        return [B.note("advantage/advantage.csv has no rows (no fit at an applied force > 0).")]
    unit = ctx.applied_unit()
    rows = df.to_dict(orient="records")
    for r in rows:
        r["x"] = ctx.applied_value(r["applied"])
    trows = []
    for r in rows:
        trows.append([f"{r['x']:g}", r["source"], r["direction"], scaled(r["fc_mean"], 1e-3),
                      num(r["C_mean"]), interval(r["C_q2.5"], r["C_q97.5"]), r["C_unit"],
                      num(r["mu_mean"], 3), interval(r["mu_q2.5"], r["mu_q97.5"], 3),
                      num(r["C_design"]), num(r["mu_design"], 3), num(r["C_paper"]),
                      num(r["mu_paper"], 3), r["paper"] if isinstance(r["paper"], str) else DASH])
    cols = [f"applied force ({unit})", "source", "direction", "fc mean (kN)", "C mean", "C 95 % interval",
            "C unit", "mu mean (1)", "mu 95 % interval", "C design", "mu design", "C paper",
            "mu paper", "paper"]
    out = [B.para("C = fc / applied force per direction (BRFD paper Eq. 10 with the kinetic friction "
                  "force of the direction); mu = ln(1 + C r_b / r) / phi from the campaign's geometry. "
                  "Intervals: 2.5-97.5 % of the posterior draws (law rows: of the law's draws).")]
    out.append(B.html(table(cols, rows=trows, caption="mechanical advantage and friction coefficient")))
    from ...advantage import AT_BOUNDS_FLAG
    pinned = sorted({f"{r['x']:g} {unit}" for r in rows
                     if float(r.get("at_bounds", 0.0) or 0.0) > AT_BOUNDS_FLAG})
    if pinned:
        out.append(B.note(f"At {', '.join(pinned)} more than {AT_BOUNDS_FLAG:.1%} of the draws sit "
                          "at the prior box's bounds: those intervals are set by the prior, not by "
                          "the data (a force-dependence law from few or scattered levels)."))
    out.append(B.figure(advantage_figure(rows, unit, "mechanical advantage against the applied force"),
                        "mechanical advantage against the applied force",
                        "Mean and 95 % interval per direction, with the design value and the "
                        "paper's values where available."))
    bad = [f["id"] for f in ctx.fits() if not f.get("converged") and f["id"] in set(df["fit"].astype(str))]
    if bad:
        out.append(B.warn(f"Computed from fits that did NOT converge ({', '.join(bad)}): not reliable."))
    return out
