"""The stored run's convergence statistics (the sampler controller's stopping rule, sampler.py):
the integrated autocorrelation time, the thinning of the stored draws, and R-hat and ESS on the
draws a fit reports. `cfg` is the run's sampler.SamplerConfig."""
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
