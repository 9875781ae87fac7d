"""Mechanical advantage and friction coefficient per fitted applied force (issue 3, item 7).

For every fit at one applied force F (summary.json fits[i]["applied"] > 0), per direction:

    C_fwd = fc_fwd / F,   C_bwd = fc_bwd / F          (posterior draws -> mean, 2.5 %, 97.5 %)

(BRFD paper, Eq. 10 with F_damping = the direction's kinetic friction force, spec section 6).
C is dimensionless for an applied force (N/N) and N/Pa for an applied pressure (the MFD).

Where the campaign has [geometry] (drum_radius r, damping_radius r_b, wrap_deg phi) and the
applied quantity is a force, the friction coefficient follows from Eq. 10,
C = (exp(mu phi) - 1) r / r_b, inverted in closed form per draw:

    mu = ln(1 + C r_b / r) / phi                        (phi in radians)

Beside them: the design values (campaign geometry mu_design, C_design; C_design from mu_design
by Eq. 10 when only mu_design is given) and the papers' values (BRFD Table 3 test values; MFD
Table 4 slopes of the kinetic friction force per pressure). Note: BRFD Table 3 prints mu_fwd =
0.42 and mu_bwd = 0.41 for C = 145 and 126, while Eq. 10 with the Table 1 geometry gives 0.392
and 0.380 for those C (its design pair, C 142 / mu 0.39, is consistent); the table is reported as
printed.

With a force-dependence law in the folder (frictionuq.infer.law), rows at the geometric
midpoints between consecutive fitted forces are added (source "force-dependence law").
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd

from . import atomic, published
from . import units as U
from .environment import environment
from .draws import LAW_SOURCE
from .errors import InputError
from .fitdir import campaign_applied_unit, campaign_of, load_posterior, load_summary, not_converged

COLUMNS = ["fit", "source", "applied", "applied_unit", "applied_display", "direction",
           "fc_mean", "C_mean", "C_q2.5", "C_q97.5", "C_unit", "mu_mean", "mu_q2.5", "mu_q97.5",
           "C_design", "mu_design", "C_paper", "mu_paper", "paper", "at_bounds"]
UNITS = {"applied": "N or Pa (applied_unit)", "fc_mean": "N", "C": "C_unit (N/N or N/Pa)",
         "mu": "1", "at_bounds": "1 (fraction of the draws)"}
#: a row whose draws sit at the prior box this often has an interval set by the box, not the data
AT_BOUNDS_FLAG = 0.025
LAW_DRAWS = 400
LAW_SEED = 1


def mu_from_C(C, drum_radius: float, damping_radius: float, wrap_deg: float):
    """Friction coefficient from the mechanical advantage by BRFD Eq. 10 (inverse)."""
    phi = math.radians(wrap_deg)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.log1p(np.asarray(C, float) * damping_radius / drum_radius) / phi


def C_from_mu(mu, drum_radius: float, damping_radius: float, wrap_deg: float):
    """Mechanical advantage from the friction coefficient by BRFD Eq. 10."""
    return np.expm1(np.asarray(mu, float) * math.radians(wrap_deg)) * drum_radius / damping_radius


def _device(camp) -> str | None:
    text = f"{getattr(camp, 'device', '')} {getattr(camp, 'name', '')}".upper()
    if "BRFD" in text:
        return "brfd"
    if "MFD" in text:
        return "mfd"
    return None


def _paper(device: str | None, direction: str, pressure: bool) -> tuple[float, float, str]:
    if device == "brfd" and not pressure:
        return (published.BRFD_TABLE3[f"C_{direction}"], published.BRFD_TABLE3[f"mu_{direction}"],
                "BRFD Table 3 (test value)")
    if device == "mfd" and pressure:
        return published.mfd_mechanical_advantage(direction), float("nan"), \
            "MFD Table 4 (fc slope per pressure)"
    return float("nan"), float("nan"), ""


def _rows(fit_id, source, applied, fc: dict, unit: str, geo, device) -> list[dict]:
    from . import units as U
    pressure = U.si_unit_of_applied(unit) == "Pa"
    ok_geo = geo is not None and not pressure and all(
        k in geo for k in ("drum_radius", "damping_radius", "wrap_deg"))
    mu_d = geo.get("mu_design", float("nan")) if geo else float("nan")
    C_d = geo.get("C_design", float("nan")) if geo else float("nan")
    if ok_geo and not np.isfinite(C_d) and np.isfinite(mu_d):
        C_d = float(C_from_mu(mu_d, geo["drum_radius"], geo["damping_radius"], geo["wrap_deg"]))
    out = []
    for direction in ("fwd", "bwd"):
        f = np.asarray(fc[direction], float)
        C = f / applied
        # draws pinned at the prior box (the law's draws are clipped to it): the share of draws
        # equal to the smallest or the largest value (continuous draws tie there only by chance;
        # a fixed parameter's draws are all equal and have no interval to flag)
        at_bounds = float(np.mean(f == f.min()) + np.mean(f == f.max())) \
            if f.size > 1 and f.max() > f.min() else 0.0
        row = {"fit": fit_id, "source": source, "applied": applied, "applied_unit": "Pa" if pressure else "N",
               "applied_display": f"{U.from_si(applied, 'applied', unit):g} {unit}",
               "direction": direction, "fc_mean": float(np.mean(fc[direction])),
               "C_mean": float(np.mean(C)), "C_q2.5": float(np.percentile(C, 2.5)),
               "C_q97.5": float(np.percentile(C, 97.5)), "C_unit": "N/Pa" if pressure else "N/N",
               "mu_mean": float("nan"), "mu_q2.5": float("nan"), "mu_q97.5": float("nan"),
               "C_design": C_d if not pressure else float("nan"),
               "mu_design": mu_d if not pressure else float("nan"), "at_bounds": at_bounds}
        if ok_geo:
            mu = mu_from_C(C, geo["drum_radius"], geo["damping_radius"], geo["wrap_deg"])
            row.update({"mu_mean": float(np.mean(mu)), "mu_q2.5": float(np.percentile(mu, 2.5)),
                        "mu_q97.5": float(np.percentile(mu, 97.5))})
        row["C_paper"], row["mu_paper"], row["paper"] = _paper(device, direction, pressure)
        out.append(row)
    return out


def _fc(post, direction: str) -> np.ndarray:
    name = f"fc_{direction}"
    if name in post.params:
        return post.params[name]
    if name in post.fixed:
        return np.array([post.fixed[name]])
    raise InputError(f"fit {post.id}: no {name} among its free or fixed parameters")


def zero_force_fits(summary: dict) -> list[str]:
    """Fits at zero applied force: no row (C = fc / applied is undefined there), said so in
    advantage.json and by the command line."""
    return [f["id"] for f in summary["fits"]
            if f.get("applied") is not None and not float(f["applied"]) > 0]


def advantage(fit_dir, law: bool = True) -> pd.DataFrame:
    """One row per fitted applied force (> 0) and direction (module docstring); with law=True
    and a force-dependence law in the folder, also rows at interpolated forces."""
    summary = load_summary(fit_dir)
    camp = campaign_of(summary)
    geo = camp.geometry if camp is not None else None
    device = _device(camp) if camp is not None else None
    unit, _ = campaign_applied_unit(fit_dir, summary)
    rows = []
    for f in summary["fits"]:
        a = f.get("applied")
        if a is None or not float(a) > 0:
            continue
        post = load_posterior(fit_dir, f["id"])
        fc = {d: _fc(post, d) for d in ("fwd", "bwd")}
        rows += _rows(f["id"], "posterior", float(a), fc, unit, geo, device)
    if not rows:
        raise InputError(f"{fit_dir}: no fit at a single applied force > 0 (mechanical advantage "
                         "needs fits --by applied or --by test at positive applied forces)")
    if law:
        rows += _law_rows(fit_dir, summary, unit, geo, device)
    df = pd.DataFrame(rows, columns=COLUMNS)
    return df.sort_values(["applied", "source", "direction"], kind="stable",
                          ascending=[True, False, False]).reset_index(drop=True)


def _law_rows(fit_dir, summary, unit, geo, device) -> list[dict]:
    """Rows at the geometric midpoints of consecutive fitted forces, from the law (none when
    the folder has no law)."""
    try:
        from .infer.lawdraws import draws_at
    except ImportError:
        return []
    levels = sorted({float(f["applied"]) for f in summary["fits"]
                     if f.get("applied") is not None and float(f["applied"]) > 0})
    rows = []
    rng = np.random.default_rng(LAW_SEED)
    for lo, hi in zip(levels[:-1], levels[1:]):
        a = math.sqrt(lo * hi)
        try:
            d, _, _ = draws_at(fit_dir, a, LAW_DRAWS, rng)
        except InputError:
            return []
        if "fc_fwd" in d and "fc_bwd" in d:
            rows += _rows("law", LAW_SOURCE, a, {"fwd": d["fc_fwd"], "bwd": d["fc_bwd"]},
                          unit, geo, device)
    return rows


def format_table(df: pd.DataFrame) -> str:
    """A plain-text table with units, for the terminal."""
    head = (f"{'fit':<22} {'applied':>12} {'dir':>3} {'fc mean (N)':>12} {'C mean':>9} "
            f"{'C 95 % interval':>21} {'C unit':>6} {'mu mean':>8} {'mu 95 % interval':>17} "
            f"{'C design':>8} {'mu design':>9} {'C paper':>9} {'mu paper':>8}")
    lines = [head, "-" * len(head)]

    def g(v, fmt):
        return format(v, fmt) if np.isfinite(v) else "-"
    for d in df.to_dict(orient="records"):
        lines.append(
            f"{str(d['fit'])[:22]:<22} {d['applied_display']:>12} {d['direction']:>3} "
            f"{g(d['fc_mean'], '.4g'):>12} {g(d['C_mean'], '.4g'):>9} "
            f"{'[' + g(d['C_q2.5'], '.4g') + ', ' + g(d['C_q97.5'], '.4g') + ']':>21} {d['C_unit']:>6} "
            f"{g(d['mu_mean'], '.3f'):>8} "
            f"{'[' + g(d['mu_q2.5'], '.3f') + ', ' + g(d['mu_q97.5'], '.3f') + ']':>17} "
            f"{g(d['C_design'], '.4g'):>8} {g(d['mu_design'], '.3f'):>9} "
            f"{g(d['C_paper'], '.4g'):>9} {g(d['mu_paper'], '.3f'):>8}"
            + (" *" if d["at_bounds"] > AT_BOUNDS_FLAG else ""))
    if any(d["at_bounds"] > AT_BOUNDS_FLAG for d in df.to_dict(orient="records")):
        lines.append(f"* more than {AT_BOUNDS_FLAG:.1%} of the draws sit at the prior box's bounds: "
                     "the interval is set by the prior, not the data (on a law row: few or "
                     "scattered levels; on a posterior row: a fit the data do not pin down)")
    lines.append("C = fc / applied (BRFD Eq. 10, fc of the direction); mu = ln(1 + C r_b / r) / phi; "
                 "intervals: 2.5-97.5 % of the posterior (law rows: of the law's draws)")
    pressure = df[df["applied_unit"] == "Pa"]
    if len(pressure):
        unit = str(pressure["applied_display"].iloc[0]).split()[-1]
        per = U.factor("applied", unit) if unit in U.UNITS["applied"] else 1.0
        lines.append(f"a pressure-applied device: C is friction force per pressure, N/Pa (times "
                     f"{per:.6g} for N/{unit}); mu and the design values are not computed: Eq. 10 "
                     "relates a band brake's tension to its friction, and a drum brake's mu would "
                     "need its piston area and lining geometry, which the campaign format does "
                     "not carry")
    return "\n".join(lines)


def fits_behind(df: pd.DataFrame, summary: dict) -> list[str]:
    """The fits the table's rows are drawn from: the posterior rows' own, and every fit when a
    row comes from the force-dependence law (fitted on all levels)."""
    if (df["source"] != "posterior").any():
        return [f["id"] for f in summary["fits"]]
    return list(dict.fromkeys(df.loc[df["source"] == "posterior", "fit"]))


def write_advantage(fit_dir, out_dir=None) -> pd.DataFrame:
    """advantage() written as out_dir/advantage.csv and advantage.json (out_dir defaults to the
    fit folder), each atomically. Returns the table."""
    from . import __version__
    from .infer.fit import jsonable
    df = advantage(fit_dir)
    out = Path(out_dir) if out_dir is not None else Path(fit_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    if any((out / f).is_file() for f in ("campaign.toml", "manifest.json")):
        raise InputError(f"--out {out}: a campaign folder; write the table beside the fits "
                         "(the default) or to a folder of its own")
    summary = load_summary(fit_dir)
    camp = campaign_of(summary)
    from .infer.law import law_entry
    doc = {"package_version": __version__, "environment": environment(),
           "fit_dir": str(Path(fit_dir).resolve()), "campaign": summary.get("campaign"),
           # the law rows' draws come from this seed; the fits' own seed and config as fitted
           "seed": LAW_SEED, "fit_config": summary.get("config"),
           "law": law_entry(fit_dir) if (df["source"] == LAW_SOURCE).any() else None,
           "no_row": [{"fit": i, "reason": "zero applied force: C = fc / applied is undefined"}
                      for i in zero_force_fits(summary)],
           "not_converged_fits": not_converged(summary, fits_behind(df, summary)),
           "device": getattr(camp, "device", None), "geometry": getattr(camp, "geometry", None),
           "formula": "C = fc_dir / applied; mu = ln(1 + C damping_radius / drum_radius) / "
                      "radians(wrap_deg) (BRFD Eq. 10 inverted)",
           "intervals": "2.5 and 97.5 % of the posterior draws (law rows: of the law's draws at "
                        "the geometric midpoint of consecutive fitted forces)",
           "units": UNITS, "columns": COLUMNS,
           "rows": [{k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                     for k, v in r.items()} for r in df.to_dict(orient="records")]}
    atomic.writable_parent(out / "advantage.csv")      # the folder, or one line why not
    atomic.write_text(out / "advantage.csv", df.to_csv(index=False, float_format="%.6g", lineterminator="\n"))
    atomic.write_json(out / "advantage.json", jsonable(doc))
    return df
