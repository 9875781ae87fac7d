"""The stored run's convergence statistics (the sampler controller's stopping rule, sampler.py):
the integrated autocorrelation time, the thinning of the stored draws, and R-hat and ESS on the
draws a fit reports, the stopping rule at one check, and its replay on a stored chain. `cfg` is
the run's sampler.SamplerConfig."""
from __future__ import annotations

import warnings

import emcee
import numpy as np

from .. import azadapter


def autocorr_time(chain: np.ndarray) -> np.ndarray:
    """Integrated autocorrelation time per parameter (steps); a parameter whose walkers did not
    move at all gets the chain length (i.e. not converged), never NaN."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tau = emcee.autocorr.integrated_time(chain, quiet=True, tol=0)
    return np.where(np.isfinite(tau), tau, float(chain.shape[0]))


def thinning(cfg, tau: np.ndarray) -> int:
    """The stored draws' thinning: cfg.thin_output, or about a quarter of the largest tau."""
    return int(cfg.thin_output or max(1, int(np.max(tau) / 4)))


def check(chain: np.ndarray, cfg, space=None) -> dict:
    """Convergence statistics of a kept chain (steps, walkers, ndim; the sampler's unbounded
    coordinates): tau on the whole kept chain, R-hat and ESS on the draws the fit will report,
    i.e. thinned as sampler._result thins them (emcee's get_chain(thin=...) picks the steps
    thin - 1, 2 thin - 1, ...) and, given the `space`, as parameter values (SI, ratio parameters
    multiplied out), so that the stopping rule is the summary's rule (outputs.summary_entry).
    Before 2026-12-01 it ran on the unthinned chain in u: a synthetic 267 N fit stopped at R-hat
    1.0098 there and reported 1.0105 for sigma0, "not converged"."""
    tau = autocorr_time(chain)
    thin = thinning(cfg, tau)
    kept = chain[thin - 1::thin]
    if space is not None:
        kept = space.to_values(space.from_u(kept))
    diag = azadapter.diagnostics(np.transpose(kept, (1, 0, 2)))
    return {"tau": tau, "tau_max": float(np.max(tau)), "r_hat_max": float(np.max(diag["r_hat"])),
            "ess_min": float(min(np.min(diag["ess_bulk"]), np.min(diag["ess_tail"]))),
            "r_hat": diag["r_hat"]}


def rule_met(c: dict, prev_tau: float | None, kept: int, cfg) -> bool:
    """The stopping rule at one check (sampler module docstring): `c` from check() on the `kept`
    steps, `prev_tau` the previous check's max tau (None at the first check: never met).

    Tau must not have *grown* by `cfg.tau_rtol` or more since the previous check; a fall is no
    warning. What the tau condition guards against is a chain still finding slower directions,
    whose tau estimate rises as it does (the dataset-2 fit of 2026-12-05: 14.8 -> 20.7 steps at
    the check after its premature stop, 94.5 at 12,000). A falling estimate is the estimator's
    noise or a transient leaving the window, and the kept chain is then longer than ever in
    units of tau. Until 2026-12-06 the condition was two-sided, and on converged chains the
    estimator's noise alone failed it: on 16 stationary AR(1) chains (tau 11, 14 parameters,
    the sampler's windows) 12.5 % of checks against 6.5 % one-sided; the refit of item 6's
    campaign held the rule at 2,500 steps, failed it at 3,000 on tau 11.7 -> 10.9 (R-hat
    1.005, ESS 2,845) and stopped at 4,000 instead of 3,000 (docs/log-calibration.md)."""
    tau_ok = prev_tau is not None and kept > cfg.tau_factor * c["tau_max"] and \
        (c["tau_max"] - prev_tau) / c["tau_max"] < cfg.tau_rtol
    return bool(tau_ok and c["r_hat_max"] <= cfg.r_hat_max and c["ess_min"] >= cfg.ess_min)


def replay(chain: np.ndarray, cfg, space=None, from_step: int = 0) -> list[dict]:
    """The stopping rule's checks replayed on a stored run's chain (steps, walkers, ndim; the
    sampler's coordinates, e.g. a fit's chain.h5): one row per check (every cfg.chunk steps from
    cfg.min_steps, as the sampler makes them) with max tau, R-hat, ESS, whether the rule held
    and how many checks in a row it has held. Shows where a longer run would have stopped under
    each `confirm_checks` (benchmarks/replay_stop.py). `from_step`: only the checks at or after
    it (the first of them has no previous tau, so the rule cannot hold there)."""
    rows, prev, passes = [], None, 0
    for n in range(cfg.chunk, chain.shape[0] + 1, cfg.chunk):
        if n < max(cfg.min_steps, from_step):
            continue
        burn = int(n * cfg.discard_fraction)
        c = check(chain[burn:n], cfg, space)
        met = rule_met(c, prev, n - burn, cfg)
        prev = c["tau_max"]
        passes = passes + 1 if met else 0
        rows.append({"steps": n, "tau_max": c["tau_max"], "r_hat_max": c["r_hat_max"],
                     "ess_min": c["ess_min"], "rule_met": met, "in_a_row": passes})
    return rows
