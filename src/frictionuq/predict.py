"""Posterior predictive of the damper force for a new drive (issue 3, item 7).

Given a fit output folder (`frictionuq fit`, see frictionuq.infer.fit) and an applied force F:

* Parameter draws, each with the noise of one of its fit's tests: a fitted level's posterior,
  else the folder's force-dependence law (frictionuq.draws.choose_draws, which says how).
* Measurement noise. noise_phi was estimated at the decimated rate of each record (fit.json
  records[].rate_hz); reading the AR(1) noise as a sampled Ornstein-Uhlenbeck process, the
  correlation at the prediction's median step dt is phi ** (dt * rate_hz), the marginal sd
  unchanged. A fit with ARMA(1,1) noise (likelihood `arma`, MA coefficient noise_theta per
  test in fit.json) is read as AR(1) plus white noise (noisemodel.split_ar1_white): the AR(1)
  part is converted as above, the white part keeps its sd. A fit with the `chatter` noise effect
  (more noise in a window after each reversal) scales each draw's noise by its g(s) at the
  input's travel since the last reversal (noise.chatter_gain): the bands widen there.
* force_offset is a load-cell artefact, not damper force: it is never in the noise-free
  ("_model") bands, and in the noisy bands only with include_offset=True (default False: the
  noisy bands then describe what a zeroed load cell would read).
* Reversal dead band: eps = noise.default_eps(x) for a measured record (CSV input), 0 for the
  clean harmonic and for a CSV given as a clean generated drive (clean_input=True: a ground
  motion's displacement history, which the pipeline writes).
* Cycles: per-cycle peak force and dissipated energy (frictionuq.cycles: how a record's cycles
  are cut, and what the energy of an irregular record's cycle means).

Everything is SI (s, m, N, J); `applied` is given in the campaign's own unit at the edges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import atomic, params as P
from .environment import environment
from .errors import InputError, check_draws, check_seed
from .draws import LAW_SOURCE, Draws, choose_draws
from .extrapolation import warn_about
from .cycles import CYCLE_COLUMNS, cycle_bounds, cycle_table
from .fitdir import campaign_applied_unit, load_summary, not_converged
from .units import check_amplitude, check_drive, harmonic_speed_problem

QUANTILES = (2.5, 25.0, 50.0, 75.0, 97.5)
HARMONIC_CYCLES = 3
HARMONIC_SAMPLES_PER_CYCLE = 200
BAND_COLUMNS = ["time", "displacement",
                "force_median", "force_q2.5", "force_q25", "force_q75", "force_q97.5",
                "force_model_median", "force_model_q2.5", "force_model_q25", "force_model_q75",
                "force_model_q97.5"]
#: backlash parameters unused by the pure LuGre model (as in infer.space.Space)
_LUGRE_UNUSED = {"k2": 0.0, "d2": 0.0, "k3": 0.0, "d3": 0.0, "w": 1e-3}
FLOAT_FORMAT = "%.9g"
#: samples x draws per (S, N) array: a few such arrays live at once (about 240 MB each)
MAX_ELEMENTS = 30_000_000
_NOISE_CHUNK = 32


def kernel_matrix(params: dict[str, np.ndarray], model: str, effects) -> np.ndarray:
    """Named draws -> the kernel's parameter matrix (S, len(params.VECTOR_NAMES)): effects
    off unless listed, listed effects' unnamed parameters at their defaults (as infer.space)."""
    S = np.size(next(iter(params.values())))
    M = np.empty((S, len(P.VECTOR_NAMES)))
    M[:, len(P.BASE_NAMES):] = P.neutral_vector()
    for eff in effects:
        for n in P.EFFECTS[eff]:
            if n in P.INDEX:         # a noise effect's parameters are not the kernel's
                M[:, P.INDEX[n]] = P.PARAMS[n].default
    for n in P.BASE_NAMES:
        if n not in params:
            if model == "lugre" and n in _LUGRE_UNUSED:
                M[:, P.INDEX[n]] = _LUGRE_UNUSED[n]
                continue
            raise InputError(f"the parameter draws lack {n!r} ({P.PARAMS[n].description})")
    for n, v in params.items():
        if n in P.INDEX:
            M[:, P.INDEX[n]] = v
    return M


# ---------------------------------------------------------------- inputs

def harmonic_input(amplitude_m: float, frequency_hz: float, cycles: int = HARMONIC_CYCLES,
                   samples_per_cycle: int = HARMONIC_SAMPLES_PER_CYCLE) -> tuple[np.ndarray, np.ndarray]:
    """(t, x) of a clean sine x = A sin(2 pi f t): whole cycles from x = 0 moving up."""
    for name, v in (("amplitude (m)", amplitude_m), ("frequency (Hz)", frequency_hz)):
        if isinstance(v, bool) or not isinstance(v, (int, float, np.floating)) or not (
                math.isfinite(v) and v > 0):
            raise InputError(f"harmonic input: {name} must be a finite number > 0, got {v!r}")
    t = np.arange(cycles * samples_per_cycle + 1) / (samples_per_cycle * float(frequency_hz))
    return t, float(amplitude_m) * np.sin(2 * np.pi * float(frequency_hz) * t)


def read_input(path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(t, x, applied or None) from a CSV with columns time (s), displacement (m) and optionally
    applied (N or Pa); errors name the file and line."""
    from .simulate_io import read_drive
    cols = read_drive(path)
    return cols["time"], cols["displacement"], cols.get("applied")


# ---------------------------------------------------------------- bands and cycles

def simulate_draws(t, x, draws: Draws, eps: float, applied_signal=None,
                   reversal: str = "detection") -> np.ndarray:
    """Noise-free model force (S, N) of every draw (no offset); reversal: the fit's rule."""
    from .model import simulate_batch
    M = kernel_matrix(draws.params, draws.model, draws.effects)
    try:
        return simulate_batch(t, x, M, model=draws.model, eps=eps, applied=applied_signal,
                              reversal=reversal)
    except InputError:
        raise
    except ValueError as e:
        raise InputError(f"cannot simulate the parameter draws ({draws.source}): {e}") from None


def noise_gain(x, draws: Draws, eps: float) -> np.ndarray | None:
    """(S, N) sd multiplier of each draw's noise along x under the `chatter` noise effect
    (noise.chatter_gain at the travel since the last reversal), None without it."""
    if "chatter" not in draws.effects:
        return None
    from .noise import chatter_gain, since_reversal
    # a parameter the draws lack (b_ch in a fit made before it existed) takes its default
    q = [np.broadcast_to(np.asarray(draws.params.get(n, P.PARAMS[n].default), float), (draws.size,))
         for n in P.EFFECTS["chatter"]]
    return chatter_gain(since_reversal(np.asarray(x, float), float(eps)), *q)


def add_noise(F: np.ndarray, draws: Draws, dt: float, rng, include_offset: bool = False,
              gain: np.ndarray | None = None) -> np.ndarray:
    """F plus stationary AR(1) (+ white, for `arma` fits) measurement noise of each draw at step
    dt (module docstring), times `gain` (S, N; the `chatter` noise effect's noise_gain) if given."""
    from .infer.noisemodel import noise_paths, split_ar1_white
    phi_fit = np.clip(draws.phi, 0.0, 0.999)
    theta = np.zeros_like(phi_fit) if draws.theta is None else np.asarray(draws.theta, float)
    sd_ar, sd_white = split_ar1_white(draws.sigma, phi_fit, theta)
    phi = phi_fit ** (dt * draws.rate_hz)
    out = np.array(F, dtype=float)
    for i in range(0, F.shape[0], _NOISE_CHUNK):          # bounded temporary memory
        j = min(i + _NOISE_CHUNK, F.shape[0])
        e = noise_paths(sd_ar[i:j], phi[i:j], sd_white[i:j], F.shape[1], rng)
        out[i:j] += e if gain is None else gain[i:j] * e
    if include_offset:
        out += draws.offset[:, None]
    return out


def band_table(t, x, F_noisy: np.ndarray, F_model: np.ndarray) -> pd.DataFrame:
    qn = np.percentile(F_noisy, QUANTILES, axis=0)
    qm = np.percentile(F_model, QUANTILES, axis=0)
    cols = {"time": np.asarray(t, float), "displacement": np.asarray(x, float)}
    for pre, q in (("force", qn), ("force_model", qm)):
        cols[f"{pre}_median"] = q[2]
        for i, lab in ((0, "2.5"), (1, "25"), (3, "75"), (4, "97.5")):
            cols[f"{pre}_q{lab}"] = q[i]
    return pd.DataFrame(cols, columns=BAND_COLUMNS)


@dataclass
class Prediction:
    bands: pd.DataFrame
    cycles: pd.DataFrame
    draws: Draws
    eps: float
    F_model: np.ndarray
    fitted_range: dict | None = None     # fitted_range() of the input against the fits behind it
    applied_range: dict | None = None    # applied_range() of the applied force


def predict(fit_dir, applied_si: float, t, x, *, eps: float | str = 0.0, n_draws: int = 400,
            seed: int = 1, include_offset: bool = False, applied_signal=None,
            samples_per_cycle: int | None = None, summary: dict | None = None,
            drive_lowpass: float | str | None = "auto") -> Prediction:
    """Posterior predictive bands and per-cycle figures of the force for drive (t, x) (SI) at
    applied force `applied_si` (SI). samples_per_cycle: set for a generated harmonic.
    eps: the reversal dead band (m): 0 for a clean generated drive, "auto" for a measured record
    (noise.default_eps(x), as `predict --input` and `validate` use). drive_lowpass: the model runs
    on x low-passed like the fit's records (infer.drivefilter); "auto" (default) takes the
    fit's setting for this input (fit_drive_lowpass: a clean drive at eps 0 is not filtered),
    a number sets the multiple, None or "off" runs on x itself; the bands keep the given x.
    Warns (errors.ResultWarning) when the draws come from fits that did not converge or the
    input goes beyond extrapolation.BEYOND_FACTOR times the fitted amplitude or peak speed."""
    check_draws(n_draws)
    check_seed(seed, "predict")
    if isinstance(eps, str) and eps != "auto":
        raise InputError(f"predict: eps takes a number in m or 'auto', got {eps!r}")
    from .infer import drivefilter
    try:
        drive_lowpass = drivefilter.check_multiple(drive_lowpass, "predict: drive_lowpass")
    except ValueError as e:
        raise InputError(str(e)) from None
    summary = summary if summary is not None else load_summary(fit_dir)
    if eps == "auto":
        from .noise import default_eps
        eps = default_eps(np.asarray(x, float))
    if drive_lowpass == "auto":
        drive_lowpass = fit_drive_lowpass(summary, eps)
    if not (math.isfinite(applied_si) and applied_si >= 0):
        raise InputError(f"applied force must be a finite number >= 0, got {applied_si!r}")
    t, x = np.asarray(t, float), np.asarray(x, float)
    if int(n_draws) * t.size > MAX_ELEMENTS:
        raise InputError(f"{t.size} samples x {n_draws} draws is too large for memory (limit "
                         f"{MAX_ELEMENTS:.0e} values per array); use at most "
                         f"{max(MAX_ELEMENTS // t.size, 1)} draws, or a shorter or coarser input")
    if applied_signal is None and applied_si > 0:
        applied_signal = np.full(t.size, float(applied_si))    # applied_tracking: neutral
    rng = np.random.default_rng(seed)
    draws = choose_draws(fit_dir, applied_si, int(n_draws), rng, summary)
    from .infer.likelihood import lowpass_drive
    reversal = (summary.get("config") or {}).get("reversal", "detection")   # the fit's rule
    Fm = simulate_draws(t, lowpass_drive(t, x, drive_lowpass)[0], draws, eps, applied_signal,
                        reversal)
    Fn = add_noise(Fm, draws, float(np.median(np.diff(t))), rng, include_offset,
                   gain=noise_gain(x, draws, eps))
    bounds = cycle_bounds(x, eps, samples_per_cycle)
    rng_x, rng_a = warn_about(fit_dir, draws, summary, t, x, applied_si)
    return Prediction(band_table(t, x, Fn, Fm), cycle_table(t, x, Fm, bounds), draws, eps, Fm,
                      rng_x, rng_a)


def fit_drive_lowpass(summary: dict, eps: float) -> float | None:
    """The drive low-pass multiple an input with reversal dead band eps (m) is filtered at, by
    the fit's setting (FitConfig.drive_lowpass): None for a clean drive (eps = 0) and when the
    fit's is off; the fit's multiple when it is a number; for its "auto", 20 where the fit's
    records were filtered, i.e. decided by the fit's own eps when it was a number (eps = 0: not
    filtered) and by the input's eps when it was "auto" (drivefilter.resolve)."""
    from .infer import drivefilter
    cfg = summary.get("config") or {}
    if float(eps) == 0.0:
        return None
    fit_eps = cfg.get("eps", "auto")
    return drivefilter.resolve(cfg.get("drive_lowpass"), eps if fit_eps == "auto" else fit_eps)


# ---------------------------------------------------------------- files


def write_prediction(fit_dir, out_dir, *, input_csv=None, harmonic=None, applied: float,
                     applied_unit: str | None = None, n_draws: int = 400, seed: int = 1,
                     include_offset: bool = False, clean_input: bool = False,
                     source: dict | None = None) -> dict:
    """Predict and write out_dir/bands.csv, cycles.csv and prediction.json (the folder is
    replaced as a whole, atomically). `applied` is in `applied_unit`, by default the fitted
    campaign's applied unit; harmonic = (amplitude m, frequency Hz). clean_input: the CSV is a
    clean generated drive (a ground motion's displacement history), predicted like the harmonic
    with eps = 0 and unfiltered, not as a measured record; source: where such a drive came from
    (recorded in prediction.json's input). A drive of amplitude above units.AMPLITUDE_PLAUSIBLE_M is
    refused. Returns prediction.json."""
    from . import __version__, units as U
    from .campaign import sha256_file
    from .noise import default_eps
    fit_dir, out_dir = Path(fit_dir), Path(out_dir)
    if (input_csv is None) == (harmonic is None):
        raise InputError("give exactly one input: a displacement CSV or a harmonic (amplitude, frequency)")
    if clean_input and input_csv is None:
        raise InputError("clean_input (--clean-input) describes an input CSV; a harmonic is always clean")
    check_seed(seed, "predict")
    summary = load_summary(fit_dir)
    atomic.check_replaceable(fit_dir, out_dir, "prediction.json", "fit", "a prediction folder",
                             owned=("prediction.json", "bands.csv", "cycles.csv"))
    unit, unit_src = (applied_unit, "given") if applied_unit else campaign_applied_unit(fit_dir, summary)
    try:
        U.factor("applied", unit)
    except ValueError as e:
        raise InputError(f"applied unit: {e}") from None
    try:
        value = float(applied)
    except (TypeError, ValueError):
        raise InputError(f"applied force: {applied!r} is not a number (give it in {unit})") from None
    if not (math.isfinite(value) and value >= 0):
        raise InputError(f"applied force: must be a finite number >= 0 {unit}, got {applied!r}")
    a_si = float(U.to_si(value, "applied", unit))
    lowpass_mult = None
    if input_csv is not None:
        t, x, sig = read_input(input_csv)
        check_drive(t, x, str(input_csv))
        if clean_input:
            eps, rule = 0.0, "0: a clean generated drive (clean_input)"
        else:
            try:
                eps = default_eps(x)
            except ValueError as e:
                raise InputError(f"{input_csv}: {e}") from None
            rule = "noise.default_eps (8 x the displacement-noise sd)"
            lowpass_mult = fit_drive_lowpass(summary, eps)  # measured: filtered like the fit's
        spc = None
        inp = {"kind": "generated record" if clean_input else "record", "file": str(input_csv),
               "sha256": sha256_file(input_csv), "source": source,
               "samples": int(t.size), "duration_s": float(t[-1] - t[0]),
               "eps_m": eps, "eps_rule": rule,
               "drive_lowpass": lowpass_mult,
               "applied_signal": "from the file's `applied` column" if sig is not None else
               "constant at the applied force"}
    else:
        try:
            amp, freq = harmonic
        except (TypeError, ValueError):
            raise InputError(f"harmonic input: expected (amplitude m, frequency Hz), got {harmonic!r}") from None
        t, x = harmonic_input(amp, freq)
        check_amplitude(x, "harmonic input")
        if problem := harmonic_speed_problem(amp, freq):
            raise InputError(f"harmonic input: {problem}")
        sig, eps, spc = None, 0.0, HARMONIC_SAMPLES_PER_CYCLE
        inp = {"kind": "harmonic", "amplitude_m": float(amp), "frequency_hz": float(freq),
               "cycles": HARMONIC_CYCLES, "samples_per_cycle": HARMONIC_SAMPLES_PER_CYCLE,
               "start": "x = 0 moving up (clean sine)", "eps_m": 0.0, "drive_lowpass": None}
    pred = predict(fit_dir, a_si, t, x, eps=eps, n_draws=n_draws, seed=seed,
                   include_offset=include_offset, applied_signal=sig, samples_per_cycle=spc,
                   summary=summary, drive_lowpass=lowpass_mult)
    behind = pred.draws.resting_on(summary)
    from .infer.law import law_entry
    meta = {"package_version": __version__, "environment": environment(),
            "fit_dir": str(Path(fit_dir).resolve()), "campaign": summary.get("campaign"),
            "fitted_range": pred.fitted_range, "applied_range": pred.applied_range,
            "applied": {"si": a_si, "si_unit": U.si_unit_of_applied(unit), "value": value,
                        "unit": unit, "unit_source": unit_src},
            "draws_source": pred.draws.source, "fits": pred.draws.fits,
            "law": law_entry(fit_dir) if pred.draws.source == LAW_SOURCE else None,
            "not_converged_fits": not_converged(summary, behind),
            "model": pred.draws.model,
            "effects": list(pred.draws.effects), "n_draws": int(n_draws), "seed": int(seed),
            "input": inp, "include_offset": bool(include_offset),
            "offset": "force_offset (load-cell zero) excluded from force_model_*; "
                      + ("included in" if include_offset else "excluded from") + " force_*",
            "noise": "stationary AR(1) (+ white, from an arma fit's noise_theta) per draw: sigma_noise, noise_phi of one of the fit's tests "
                     + ("(same posterior draw)" if pred.draws.source != LAW_SOURCE else
                        "(a posterior draw of the fitted level nearest in log force, listed in fits)")
                     + "; phi converted to the input's step as phi ** (dt * rate_hz of the fit "
                       "record), marginal sd kept",
            "quantiles": "2.5/25/50/75/97.5 % over draws, pointwise in time",
            "cycles": "harmonic: whole periods; record: turning point to turning point in the same "
                      "direction; energy = trapezoid integral of F dx of the noise-free model over "
                      "the cycle (the dissipated energy for a closed loop; for an irregular record "
                      "the net work, including the change of stored backlash/bristle energy)",
            "units": {"time": "s", "displacement": "m", "force": "N", "peak_force": "N",
                      "energy": "J"},
            "files": {"bands.csv": BAND_COLUMNS, "cycles.csv": CYCLE_COLUMNS}}
    with atomic.output_dir(out_dir) as tmp:
        pred.bands.to_csv(tmp / "bands.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        pred.cycles.to_csv(tmp / "cycles.csv", index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
        atomic.write_json(tmp / "prediction.json", meta)
    return meta
