"""Where the walkers stand: the start ball around the MAP and the burn-in's re-initialisation
from a round's pooled states (the sampler controller, sampler.py, explains why)."""
from __future__ import annotations

import numpy as np


def initial_ball(theta_map, cov, nwalkers, rng, space) -> np.ndarray:
    """Walkers around the MAP (box coordinates): N(MAP, Sigma/4), kept 0.1 % of the box width
    away from its walls (a MAP on a wall would put every walker at u = -inf)."""
    width = space.hi - space.lo
    sd = np.sqrt(np.clip(np.diag(cov), (1e-8 * width) ** 2, (0.1 * width) ** 2))
    dsd = np.sqrt(np.abs(np.diag(cov)))
    corr = cov / np.outer(dsd, dsd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    try:
        L = np.linalg.cholesky(corr + 1e-9 * np.eye(len(sd)))
    except np.linalg.LinAlgError:
        L = np.eye(len(sd))
    margin = 1e-3 * width
    centre = np.clip(theta_map, space.lo + margin, space.hi - margin)
    z = rng.standard_normal((nwalkers, len(sd))) @ L.T
    p = centre + 0.5 * z * sd   # half the approximate posterior sd: inside the typical set
    return np.clip(p, space.lo + 0.5 * margin, space.hi - 0.5 * margin)


def pooled_states(chain: np.ndarray, log_prob: np.ndarray):
    """States of the second half of a burn-in chain (steps, walkers, ndim) with finite log
    posterior, pooled over the walkers that are not stuck (mean log-posterior more than
    max(10, 3 sqrt(D/2)) below the median walker's). Returns (states, number of stuck walkers)."""
    n = chain.shape[0]
    half, lp = chain[n // 2:], log_prob[n // 2:]
    mean_lp = np.mean(lp, axis=0)
    tol = max(10.0, 3.0 * np.sqrt(chain.shape[2] / 2.0))
    good = np.flatnonzero(mean_lp >= np.median(mean_lp) - tol)
    pool = half[:, good].reshape(-1, chain.shape[2])
    pool_lp = lp[:, good].ravel()
    return pool[np.isfinite(pool_lp)], int(chain.shape[1] - good.size)


def reinitialise(chain: np.ndarray, log_prob: np.ndarray, nwalkers: int, rng) -> tuple[np.ndarray, int]:
    """New walker positions drawn (without replacement) from `pooled_states`. Returns
    (positions, number of stuck walkers)."""
    pool, stuck = pooled_states(chain, log_prob)
    # a rejected proposal repeats a state: draw distinct states only (two identical walkers
    # make the snooker move divide by zero)
    pool = np.unique(pool, axis=0)
    if pool.shape[0] >= nwalkers:
        return pool[rng.choice(pool.shape[0], size=nwalkers, replace=False)], stuck
    p = pool[rng.choice(pool.shape[0], size=nwalkers, replace=True)]
    sd = np.std(pool, axis=0) if pool.shape[0] > 1 else np.ones(chain.shape[2])
    p = p + 1e-3 * np.where(sd > 0, sd, 1e-6) * rng.standard_normal(p.shape)
    return p, stuck
