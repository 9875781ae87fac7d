"""Where the walkers stand: the start ball around the MAP and the burn-in's re-initialisation
from a round's pooled states (the sampler controller, sampler.py, explains why)."""
from __future__ import annotations

import numpy as np


#: steps of the profiled start's probes, in (clipped) Gauss-Newton standard deviations
PROFILE_STEPS = 2.0 ** np.arange(-3, 7)
#: a side of the profile reaches as far as the log-posterior stays within this of the MAP's
PROFILE_DROP = 2.0


def ball_sd(cov, space) -> np.ndarray:
    """The Gauss-Newton standard deviations, kept between 1e-8 and 0.1 of the box width."""
    width = space.hi - space.lo
    return np.sqrt(np.clip(np.diag(cov), (1e-8 * width) ** 2, (0.1 * width) ** 2))


def profile_sides(log_prob, theta_map, lp_map, cov, space) -> np.ndarray:
    """(ndim, 2) half-widths of the start ball below and above the MAP, in ball_sd units, from
    one-dimensional profiles: each parameter alone is moved from the MAP by PROFILE_STEPS
    (1/8 to 64 sds) each way, one batch of log_prob (box coordinates; a point outside the box
    counts as -inf); a side reaches the largest step up to which every step is within
    PROFILE_DROP nats of the MAP's `lp_map` (find_map's, not evaluated again; a Gaussian's drop
    at 2 sd), and the half-width is half of it.
    Why: the Gauss-Newton covariance is a local curvature; where the log-posterior has a kink at
    the MAP it can be far off on one side. BRFD twin 267 N: d3 is 40 times wider than its
    Gauss-Newton sd below the MAP (-0.18 nats at 64 sds) and falls by 94 nats within one sd above
    it, and the burn-in's ensemble took seven rounds to spread along it."""
    sd = ball_sd(cov, space)
    D, K = sd.size, PROFILE_STEPS.size
    off = np.array([-1.0, 1.0])[:, None] * PROFILE_STEPS[None, :]
    pts = np.broadcast_to(np.asarray(theta_map, float), (D, 2, K, D)).copy()
    for i in range(D):
        pts[i, :, :, i] += off * sd[i]
    flat = pts.reshape(-1, D)
    inside = np.all((flat > space.lo) & (flat < space.hi), axis=1)
    lp = np.full(flat.shape[0], -np.inf)
    if inside.any():
        lp[inside] = log_prob(flat[inside])
    ok = (lp_map - lp.reshape(D, 2, K)) <= PROFILE_DROP          # NaN or -inf: not within
    n_ok = np.argmin(np.concatenate([ok, np.zeros((D, 2, 1), bool)], axis=2), axis=2)
    return PROFILE_STEPS[np.maximum(n_ok - 1, 0)] / 2.0


def initial_ball(theta_map, cov, nwalkers, rng, space, sides=None) -> np.ndarray:
    """Walkers around the MAP (box coordinates): N(MAP, Sigma/4) (the Gauss-Newton correlation,
    half its sds), or with `sides` (profile_sides) each parameter's half-width below and above
    the MAP from its profile; kept 0.1 % of the box width away from its walls (a MAP on a wall
    would put every walker at u = -inf)."""
    width = space.hi - space.lo
    sd = ball_sd(cov, space)
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
    # half the approximate posterior sd: inside the typical set
    half = 0.5 if sides is None else np.where(z < 0, sides[:, 0], sides[:, 1])
    p = centre + half * z * sd
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
