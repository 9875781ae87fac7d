"""What a prediction rests on (predict.py): the input's amplitude and peak speed and the applied
force beside those of the fits its draws come from, and the warnings when they go beyond them
or the fits did not converge. The bands then extrapolate the model (or the force-dependence
law), which prediction.json (`fitted_range`, `applied_range`) and the command line say."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .fitdir import not_converged
from .noise import amplitude


#: an input whose amplitude or peak speed exceeds the fitted records' by more than this factor is
#: flagged (prediction.json "fitted_range", and a note on the command line): the model's
#: parameters, v_s and sigma2 above all, are then extrapolated beyond what the data showed
BEYOND_FACTOR = 1.5


def fitted_range(fit_dir, fit_ids, t, x) -> dict:
    """The input's amplitude (largest |x - median x|, m: half the stroke of a centred sine) and
    peak speed (m/s) beside the largest of
    the records of the fits its draws come from (fit.json's scales), and which of them go
    beyond BEYOND_FACTOR times those."""
    from .fitdir import read_json
    amp, vmax = 0.0, 0.0
    for fid in fit_ids:
        sc = read_json(Path(fit_dir) / fid / "fit.json", f"record of fit {fid}").get("scales") or {}
        amp, vmax = max(amp, float(sc.get("amp", 0.0))), max(vmax, float(sc.get("v_max", 0.0)))
    x = np.asarray(x, float)
    amp_in = amplitude(x)
    speed = float(np.max(np.abs(np.gradient(x, np.asarray(t, float))))) if x.size > 1 else 0.0
    beyond = [name for name, v, ref in (("amplitude", amp_in, amp), ("peak speed", speed, vmax))
              if ref > 0 and v > BEYOND_FACTOR * ref]
    return {"amplitude_m": amp_in, "fitted_amplitude_m": amp, "peak_speed_m_s": speed,
            "fitted_peak_speed_m_s": vmax, "beyond": beyond, "factor": BEYOND_FACTOR}


def applied_range(summary: dict, applied_si: float) -> dict:
    """The applied force beside the fitted levels' (SI): `beyond` when it lies above
    BEYOND_FACTOR times the highest or below the lowest positive one divided by it, where the
    force-dependence law extrapolates (a pressure typed in the wrong unit lands there too)."""
    from .fitdir import fitted_levels
    levels = fitted_levels(summary)
    lo = min((a for a in levels if a > 0), default=None)
    hi = max(levels, default=None)
    above = bool(levels) and applied_si > BEYOND_FACTOR * hi
    below = lo is not None and 0 < applied_si < lo / BEYOND_FACTOR
    return {"applied_si": float(applied_si), "fitted_levels_si": levels, "beyond": above or below,
            "side": "above" if above else "below" if below else None, "factor": BEYOND_FACTOR}


def warn_about(fit_dir, draws, summary, t, x, applied_si) -> tuple[dict, dict]:
    """ResultWarning for what the bands rest on (the CLI says the same in its notes); returns
    the input's fitted_range and the applied force's applied_range."""
    import warnings
    from .errors import ResultWarning
    behind = draws.resting_on(summary)
    bad = not_converged(summary, behind)
    if bad:
        warnings.warn(f"the bands are drawn from fit(s) not converged ({', '.join(bad)}): "
                      "indicative only", ResultWarning, stacklevel=3)
    rng = fitted_range(fit_dir, behind, t, x)
    if rng["beyond"]:
        warnings.warn(f"the input goes beyond {BEYOND_FACTOR} times the fitted records' "
                      f"{' and '.join(rng['beyond'])}: the bands extrapolate the model",
                      ResultWarning, stacklevel=3)
    ar = applied_range(summary, applied_si)
    if ar["beyond"]:
        warnings.warn(f"the applied force {applied_si:g} (SI: N or Pa) lies {ar['side']} the "
                      f"fitted levels ({', '.join(f'{v:g}' for v in ar['fitted_levels_si'])}) by "
                      f"more than a factor {BEYOND_FACTOR}: the force-dependence law "
                      "extrapolates", ResultWarning, stacklevel=3)
    return rng, ar


def notes(meta: dict) -> list[str]:
    """The sentences a prediction's record (prediction.json) calls for about where it
    extrapolates: the input beyond the fitted records' amplitude or speed, the applied force beyond
    the fitted levels. The same words on the command line (`predict`), in a workflow's task log
    and console, and in the report."""
    from .units import from_si
    out = []
    r = meta.get("fitted_range") or {}
    if r.get("beyond"):
        # amplitude_m was stroke_m before 2026-12-05 (the same figure): older records still read
        a, fa = (r.get("amplitude_m", r.get("stroke_m")), r.get("fitted_amplitude_m", r.get("fitted_stroke_m")))
        out.append(f"the input goes beyond the fitted records ({', '.join(r['beyond'])}): amplitude "
                   f"(largest |x - median x|) {a:.4g} m against {fa:.4g} m, peak speed "
                   f"{r['peak_speed_m_s']:.4g} m/s against {r['fitted_peak_speed_m_s']:.4g} m/s; "
                   "the bands extrapolate the model there")
    ar, ap = meta.get("applied_range") or {}, meta.get("applied") or {}
    if ar.get("beyond"):
        u = ap["unit"]
        lv = ", ".join(f"{from_si(v, 'applied', u):g}" for v in ar["fitted_levels_si"])
        out.append(f"applied {ap['value']:g} {u} lies {ar['side']} the fitted levels ({lv} {u}) "
                   f"by more than a factor {ar['factor']:g}: the force-dependence law "
                   f"extrapolates there (is {u} the unit you meant?)")
    return out
