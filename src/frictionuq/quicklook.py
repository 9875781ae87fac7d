"""`frictionuq table`: a per-test table of a campaign, optionally beside a simulation with a
paper's published parameters (the foundation's main job, before calibration exists).

For each test: nominal applied level, kind, frequency, samples, sampling rate, displacement and
force ranges, the displacement-noise estimate and the reversal dead-band eps it gives, the
number of reversals seen with that eps; with --published, the RMSE and normalised RMSE of the
published model at the published level nearest to the test's applied level (force offset
removed: the mean residual is reported separately, since load cells of real records are not
zeroed). NRMSE is RMSE over the measured force's peak to peak, as `validate` and the report
define it. A test whose applied level lies beyond extrapolation.BEYOND_FACTOR times the published
levels (BRFD: from the nearest published level; MFD: outside the tested pressures) is flagged.
"""
from __future__ import annotations

import numpy as np
import pandas as pd

from . import units as U
from .extrapolation import BEYOND_FACTOR
from .campaign import load_campaign
from .errors import InputError
from .model import simulate
from .noise import count_reversals, default_eps, displacement_noise_sd
from .wording import count


def _eps(arg, x, where: str) -> float:
    if arg in (None, "auto"):
        return default_eps(x, where=where)
    try:
        e = float(arg)
    except (TypeError, ValueError):
        raise InputError(f"--eps: {arg!r} is neither a number (m) nor 'auto'") from None
    if not (np.isfinite(e) and e >= 0):
        raise InputError(f"--eps: must be a finite number >= 0 (m), got {arg!r}")
    return e


def campaign_frame(path, published: str = "none", eps="auto") -> tuple[pd.DataFrame, object]:
    """The table as a DataFrame (column names carry units) and the campaign."""
    from .published import published_params, BRFD_APPLIED_N, MFD_PRESSURES_PSI
    camp = load_campaign(path)
    pub = (published or "none").lower()
    if pub not in ("none", "brfd", "mfd"):
        raise InputError(f"--published: unknown parameter set {published!r}; use brfd, mfd or none")
    if pub != "none" and (camp.applied_si_unit == "Pa") != (pub == "mfd"):
        raise InputError(f"--published {pub}: the campaign's applied unit {camp.units['applied']!r} "
                         f"does not fit that device (BRFD: a force, MFD: a pressure)")
    unit = camp.units["applied"]
    rows, far = [], []
    for te in camp.tests:
        r = te.record
        e = _eps(eps, r.x, f"test {te.id}")
        row = {"test": te.id, f"applied ({unit})": U.from_si(te.applied, "applied", unit),
               "kind": te.kind, "freq (Hz)": te.frequency_hz if te.frequency_hz else np.nan,
               "samples": r.n, "rate (Hz)": r.rate_hz,
               "x range (mm)": f"{r.x.min() * 1e3:.1f}..{r.x.max() * 1e3:.1f}",
               "F range (kN)": f"{r.force.min() / 1e3:.2f}..{r.force.max() / 1e3:.2f}",
               "x noise (um)": displacement_noise_sd(r.x) * 1e6, "eps (um)": e * 1e6,
               "reversals": count_reversals(r.x, e)}
        if pub != "none":
            if pub == "brfd":
                level = min(BRFD_APPLIED_N, key=lambda a: abs(a - te.applied))
                p = published_params("brfd", level)
                row["published at (N)"] = level
                if not level / BEYOND_FACTOR <= te.applied <= level * BEYOND_FACTOR:
                    far.append(f"{te.id}: applied {te.applied:.4g} N, the nearest published level "
                               f"is {level:g} N")
            else:
                p = published_params("mfd", te.applied)
                psi = U.from_si(te.applied, "applied", "psi")
                row["published at (psi)"] = psi
                lo, hi = min(MFD_PRESSURES_PSI), max(MFD_PRESSURES_PSI)
                if not lo / BEYOND_FACTOR <= psi <= hi * BEYOND_FACTOR:
                    far.append(f"{te.id}: applied {psi:.4g} psi, the paper's law is from "
                               f"{lo:g}-{hi:g} psi")
            F = simulate(r.t, r.x, p, eps=e)
            res = r.force - F
            off = float(np.mean(res))
            rmse = float(np.sqrt(np.mean((res - off) ** 2)))
            row["mean resid (kN)"] = off / 1e3
            row["RMSE (kN)"] = rmse / 1e3
            ptp = float(np.ptp(r.force))
            row["NRMSE (% of p-p)"] = 100 * rmse / ptp if ptp > 0 else np.nan
        rows.append(row)
    df = pd.DataFrame(rows)
    df.attrs["far_from_published"] = far
    return df, camp


def campaign_table(path, published: str = "none", eps="auto") -> str:
    """The table as text, with a header line naming the campaign and units."""
    df, camp = campaign_frame(path, published, eps)
    from . import __version__
    head = (f"frictionuq {__version__} | campaign {camp.name!r}: {count(len(camp.tests), 'test')}, device {camp.device or '?'}; "
            f"source units {', '.join(f'{k} {v}' for k, v in camp.units.items())}; values below "
            "in the units of each column header")
    note = ""
    if published and published != "none":
        note = ("\nRMSE/NRMSE: published model at the nearest published level, after removing the mean "
                "residual (force offset); NRMSE = RMSE / peak-to-peak of the measured force. The "
                "published parameters are the paper's own prototype tests; calibrating them to these "
                "records is the next stage (Bayesian calibration).")
        for f in df.attrs["far_from_published"]:
            note += (f"\nflags: {f}: more than a factor {BEYOND_FACTOR:g} from the published levels, "
                     "the published model is extrapolated")
    from .quality import quality
    flags = [f"flags: {te.id}: {'; '.join(q['flags'])}" for te in camp.tests
             if (q := quality(te))["flags"]]
    if flags:
        note += "\n" + "\n".join(flags)
    with pd.option_context("display.width", 250, "display.max_columns", 40, "display.max_rows", 500):
        return head + "\n" + df.to_string(index=False, na_rep="-", float_format=lambda v: f"{v:.4g}") + note
