"""Validation on held-out measured tests: predict a test the fit never saw and score the bands.

For each held-out test of a campaign: the posterior predictive bands at its applied force (the
fitted level's posterior, or the force-dependence law when the level was not fitted), driven by
its measured displacement, with the fitted load-cell offset and measurement noise included (the
measured force carries both), and scored against the measured force:

* coverage95 / coverage50: fraction of measured samples inside the 95 % / 50 % band (a calibrated
  predictive band covers about 95 % / 50 %; far less means overconfident);
* rmse: RMSE of the band's median against the measured force (N);
* nrmse: rmse / peak-to-peak measured force (dimensionless; stated beside the rmse);
* rmse_model_offset_free: RMSE after removing the mean residual (the offset), as the `table`
  command reports for the published model;
* bias_N: the mean residual, measured minus median (N).
`calibration_notes` says in words when the scores show a miscalibrated band: a 95 % band under
90 %, or a 50 % band outside 30-70 % (a 95 % band can cover well while the median is biased: the
50 % band then shows it).
Writes out_dir/validation.json (+ the bands of every test as <test>.bands.csv and a figure
<test>.png of measured force inside the bands).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from . import atomic
from .environment import environment, png_metadata
from .errors import InputError, check_draws, check_seed
from .units import from_si


def score(y: np.ndarray, bands) -> dict:
    """Coverage and errors of a bands table (predict.band_table) against measured force y (N)."""
    y = np.asarray(y, float)
    inside95 = (y >= bands["force_q2.5"].to_numpy()) & (y <= bands["force_q97.5"].to_numpy())
    inside50 = (y >= bands["force_q25"].to_numpy()) & (y <= bands["force_q75"].to_numpy())
    r = y - bands["force_median"].to_numpy()
    rmse = float(np.sqrt(np.mean(r**2)))
    ptp = float(np.ptp(y))
    return {"coverage95": float(np.mean(inside95)), "coverage50": float(np.mean(inside50)),
            "rmse_N": rmse, "nrmse": rmse / ptp if ptp > 0 else float("nan"),
            "rmse_offset_free_N": float(np.std(r)), "bias_N": float(np.mean(r)),
            "peak_to_peak_N": ptp, "samples": int(y.size)}


COVERAGE95_LOW = 0.90          # a 95 % band covering less than this: overconfident
COVERAGE50_RANGE = (0.30, 0.70)  # a 50 % band covering outside this: biased, too narrow or too wide


def calibration_notes(s: dict) -> list[str]:
    """One sentence per sign of miscalibration in a test's scores (score's dict, or one entry of
    validate()'s "tests"), none if the bands look calibrated. Given validate()'s whole result,
    the sentences of every test, each starting with the test's id."""
    if isinstance(s, dict) and isinstance(s.get("tests"), list):
        return [f"{t.get('test', '?')}: {line}" for t in s["tests"] for line in calibration_notes(t)]
    if not (isinstance(s, dict) and "coverage95" in s and "coverage50" in s):
        raise ValueError("calibration_notes: expected one test's scores (a dict with coverage95 "
                         "and coverage50, e.g. validate(...)['tests'][0]) or validate()'s result, "
                         f"got {type(s).__name__}" + (f" with keys {sorted(s)[:6]}" if isinstance(s, dict) else ""))
    out = []
    c95, c50 = s.get("coverage95"), s.get("coverage50")
    bias = s.get("bias_N")
    why = (f"; the median is off by {bias:+.4g} N on average (measured minus median)"
           if bias is not None and np.isfinite(bias) else "")
    if c95 is not None and c95 < COVERAGE95_LOW:
        out.append(f"the 95 % band covers {c95:.1%} of the samples, under {COVERAGE95_LOW:.0%}: "
                   f"overconfident{why}")
    if c50 is not None and c50 < COVERAGE50_RANGE[0]:
        out.append(f"the 50 % band covers {c50:.1%} of the samples (calibrated: about 50 %): the "
                   f"prediction is biased or too narrow{why}, so the 95 % band's coverage "
                   f"({c95:.1%}) overstates its calibration")
    elif c50 is not None and c50 > COVERAGE50_RANGE[1]:
        out.append(f"the 50 % band covers {c50:.1%} of the samples (calibrated: about 50 %): the "
                   "bands are wider than the errors (conservative)")
    return out


def _figure(path, t, y, bands, title):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(10, 3.2))
    ax.fill_between(t, bands["force_q2.5"], bands["force_q97.5"], color="C0", alpha=0.25,
                    lw=0, label="95 % band (with noise)")
    ax.fill_between(t, bands["force_q25"], bands["force_q75"], color="C0", alpha=0.45, lw=0,
                    label="50 % band")
    ax.plot(t, y, color="k", lw=0.5, label="measured")
    ax.plot(t, bands["force_median"], color="C3", lw=0.7, label="median")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("force (N)")
    ax.set_title(title, fontsize=9)
    ax.legend(fontsize=7, ncol=4, loc="upper right")
    fig.tight_layout()
    with atomic.replacing(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png", metadata=png_metadata())
    plt.close(fig)


def validate(fit_dir, campaign_path, test_ids, out_dir, *, n_draws: int = 400, seed: int = 1,
             figures: bool = True, log=None) -> dict:
    """Predict each held-out test (ids: a list, or one id as a string) of a campaign from a fit
    folder and score it."""
    from . import __version__
    from .campaign import load_campaign
    from .fitdir import load_summary, not_converged
    from .noise import default_eps
    from .predict import fit_drive_lowpass, predict
    log = log or (lambda m: None)
    test_ids = [test_ids] if isinstance(test_ids, str) else list(test_ids or ())
    if not test_ids:
        raise InputError("validate: no test given; name the held-out tests (--test ID)")
    check_seed(seed, "validate")
    check_draws(n_draws, "validate")
    camp = load_campaign(campaign_path)
    summary = load_summary(fit_dir)
    fitted_tests = {t for f in summary["fits"] for t in f.get("tests", [])}
    by_id = {t.id: t for t in camp.tests}
    unknown = [i for i in test_ids if i not in by_id]
    if unknown:
        raise InputError(f"{campaign_path}: no test {unknown[0]!r}; tests: {', '.join(by_id)}")
    twice = sorted({i for i in test_ids if list(test_ids).count(i) > 1})
    if twice:
        raise InputError(f"--test {twice[0]}: given twice (each held-out test is scored once)")
    out = Path(out_dir)
    # the folder is written whole (a bad test later in the list leaves nothing half-written)
    atomic.check_replaceable(fit_dir, out, "validation.json", "fit", "a validation folder",
                             owned=("validation.json", "*.bands.csv", "*.png"))
    results, behind = [], []
    with atomic.output_dir(out) as tmp:
        unit = camp.units.get("applied", "N")
        for tid in test_ids:
            te = by_id[tid]
            r = te.record
            log(f"{tid}: predicting {r.n} samples")      # progress; the scores are in the result
            eps = default_eps(r.x, where=f"test {tid}")
            lowpass_mult = fit_drive_lowpass(summary, eps)   # filtered like the fit's records
            p = predict(fit_dir, te.applied, r.t, r.x, eps=eps, n_draws=n_draws, seed=seed,
                        include_offset=True, summary=summary, drive_lowpass=lowpass_mult)
            s = score(r.force, p.bands)
            s.update(test=tid, applied_si=te.applied, kind=te.kind, eps_m=eps,
                     drive_lowpass=lowpass_mult,
                     held_out=tid not in fitted_tests, draws_source=p.draws.source,
                     # where the prediction extrapolates (extrapolation.notes reads these)
                     applied={"value": float(from_si(te.applied, "applied", unit)), "unit": unit},
                     fitted_range=p.fitted_range, applied_range=p.applied_range)
            results.append(s)
            behind += p.draws.resting_on(summary)
            atomic.write_text(tmp / f"{tid}.bands.csv", p.bands.to_csv(index=False))
            if figures:
                _figure(tmp / f"{tid}.png", r.t, r.force, p.bands,
                        f"{camp.name} / {tid}: coverage95 {s['coverage95']:.2f}, NRMSE {s['nrmse']:.3f} "
                        f"({p.draws.source})")
        doc = {"package_version": __version__, "environment": environment(),
               "fit_dir": str(Path(fit_dir).resolve()), "campaign": camp.name,
               "campaign_path": str(Path(campaign_path).resolve()), "seed": seed, "n_draws": n_draws,
               "not_converged_fits": not_converged(summary, behind),
               "units": f"force N, applied_si {camp.applied_si_unit}, eps m; coverage fractions of samples; nrmse = rmse / "
                        "peak-to-peak measured force",
               "tests": results}
        atomic.write_json(tmp / "validation.json", doc)
    return doc
