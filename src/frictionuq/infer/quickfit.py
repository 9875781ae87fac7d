"""A fixed-budget posterior sample for small problems (statistical tests, quick looks).

`quick_sample` runs the same pieces as the full sampler (frictionuq.infer.sampler.sample) but
with a fixed, small budget and no convergence loop, no multi-start MAP search and no storage:

1. start: the best of `n_prior` prior draws, then trust-region least squares from it
   (localfit.least_squares_fit), with `arma` noise each record's MA coefficient there
   (localfit.set_noise_shape), the Gauss-Newton covariance there (localfit.gauss_newton_cov)
   and the walkers' initial ball around it (walkers.initial_ball);
2. emcee with the sampler's moves (differential evolution + snooker) in the unbounded
   coordinates (likelihood.UnboundedPosterior: logit of the prior box, Jacobian included) for
   `steps` steps, all returned (the caller discards its burn-in and thins).

Meant for posteriors of a few parameters on records of a few hundred samples, where an
autocorrelation time is ~10-30 steps and a few hundred steps mix; it gives no convergence
guarantee of its own. Deterministic for a given seed.
"""
from __future__ import annotations

from dataclasses import dataclass

import emcee
import numpy as np

from .burnin import moves_for
from .likelihood import LogPosterior, UnboundedPosterior
from .localfit import gauss_newton_cov, least_squares_fit, set_noise_shape
from .sampler import SamplerConfig
from .walkers import initial_ball


@dataclass
class QuickSample:
    chain: np.ndarray        # (steps, walkers, ndim), box (sampling) coordinates
    log_prob: np.ndarray     # (steps, walkers), log-posterior in the unbounded coordinates
    theta_start: np.ndarray  # least-squares optimum the walkers started around
    acceptance: float


def quick_sample(logpost: LogPosterior, seed, steps: int, nwalkers: int = 32,
                 n_prior: int = 256, max_nfev: int = 100) -> QuickSample:
    """`steps` emcee steps of `nwalkers` walkers; see the module docstring. `seed`: an int or a
    sequence of ints (numpy SeedSequence entropy)."""
    sp = logpost.space
    if nwalkers <= 2 * sp.ndim:
        raise ValueError(f"differential evolution needs more than 2 x ndim = {2 * sp.ndim} walkers")
    rng = np.random.default_rng(seed)
    draws = sp.sample_prior(n_prior, rng)
    th0 = draws[int(np.argmax(logpost.log_prob(draws)))]
    th_ls, _ = least_squares_fit(logpost, th0, max_nfev=max_nfev)
    if sp.likelihood == "arma":         # each record's MA coefficient at the optimum, as in a fit
        set_noise_shape(logpost, th_ls)
    cov = gauss_newton_cov(logpost, th_ls)
    start = sp.to_u(initial_ball(th_ls, cov, nwalkers, rng, sp))
    sampler = emcee.EnsembleSampler(nwalkers, sp.ndim, UnboundedPosterior(logpost), vectorize=True,
                                    moves=moves_for(SamplerConfig()))
    # emcee copies NumPy's global state at construction: seed its own state explicitly
    sampler.random_state = np.random.RandomState(rng.integers(0, 2**32, size=4, dtype=np.uint64)
                                                 .astype(np.uint32)).get_state()
    sampler.run_mcmc(start, steps, progress=False, skip_initial_state_check=True)
    u = sampler.get_chain()
    return QuickSample(chain=sp.from_u(u), log_prob=sampler.get_log_prob(), theta_start=th_ls,
                       acceptance=float(np.mean(sampler.acceptance_fraction)))
