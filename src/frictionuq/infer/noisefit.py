"""Fitting a noise effect (params.NOISE_EFFECTS: `chatter`), whose parameters scale the
measurement noise and leave the force alone, so that least squares cannot move them:

* scaled_residuals: a record's residuals divided by the effect's gain g (what least squares and
  the Gauss-Newton curvature of infer.optimize weigh, the gain held at one point);
* fit_noise: the noise parameters alone, model held, on residuals simulated once;
* noise_block_hessian: the curvature of the log-posterior over the noise parameters (for the
  Laplace evidence of the discrepancy screening and the sampler's initial ball).

Without a noise effect every function here is a no-op or returns the plain residuals."""
from __future__ import annotations

import numpy as np

from .. import params as P
from . import noisemodel
from .likelihood import LogPosterior


def scaled_residuals(logpost: LogPosterior, theta: np.ndarray, j: int, gain_at=None) -> np.ndarray:
    """Record j's residuals (W, N) at the points theta (W, D), divided by the noise gain of a
    noise effect (chatter) at `gain_at` (one point; default: each row's own) when the fit has one."""
    theta = np.atleast_2d(theta)
    e = logpost.residuals(theta, logpost.records[j])
    g = logpost.noise_gain(theta if gain_at is None else np.atleast_2d(gain_at), j)
    return e if g is None else e / g


def noise_indices(space) -> list[int]:
    """Sampling coordinates of the noise effects' parameters (params.NOISE_EFFECTS)."""
    return [i for i, n in enumerate(space.names) if P.PARAMS[n].kind == "noise_effect"]


def noise_objective(logpost: LogPosterior, theta: np.ndarray, idx: list[int]):
    """lp(U): the log-posterior (up to a constant) at theta with its noise-effect coordinates
    idx replaced by the rows of U (W, len(idx)); the residuals are simulated once, here (the
    noise parameters do not change the force)."""
    sp = logpost.space
    E = [logpost.residuals(theta[None, :], rec)[0] for rec in logpost.records]

    def lp(U):
        T = np.repeat(theta[None, :], U.shape[0], axis=0)
        T[:, idx] = U
        out = sp.log_prior(T)
        ok = np.isfinite(out)
        for j, rec in enumerate(logpost.records):
            g = logpost.noise_gain(T[ok], j)
            e = noisemodel.prefilter(E[j][None, :] / g, rec.noise_theta)
            out[ok] += (noisemodel.log_marginal_stats(noisemodel.suff_stats(e), rec.n, **logpost.noise)
                        - np.log(g).sum(axis=1))
        return out
    return lp


def fit_noise(logpost: LogPosterior, theta: np.ndarray, grid: int = 6) -> np.ndarray:
    """theta with its noise-effect parameters (chatter) at the maximum of the log-posterior
    over them alone, the model parameters held (theta itself without a noise effect). A grid
    of grid^k points over the prior box plus the current point, then Nelder-Mead from the
    best (noise_objective). Needed because least squares cannot move a parameter that only
    scales the noise."""
    from scipy.optimize import minimize
    idx = noise_indices(logpost.space)
    theta = np.asarray(theta, float)
    if not idx:
        return theta
    sp = logpost.space
    lp = noise_objective(logpost, theta, idx)
    lo, hi = sp.lo[idx], sp.hi[idx]
    axes = [np.linspace(a + 0.02 * (b - a), b - 0.02 * (b - a), grid) for a, b in zip(lo, hi)]
    G = np.vstack([np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(idx)), theta[idx]])
    vals = np.concatenate([lp(G[i:i + 64]) for i in range(0, len(G), 64)])
    u0 = G[int(np.argmax(vals))]
    r = minimize(lambda u: -lp(np.clip(u, lo, hi)[None, :])[0], u0, method="Nelder-Mead",
                 options={"xatol": 1e-6, "fatol": 1e-4, "maxiter": 600})
    best = np.clip(r.x, lo, hi) if -r.fun >= vals.max() else u0
    out = theta.copy()
    out[idx] = best
    m = 1e-9 * (sp.hi - sp.lo)
    return np.clip(out, sp.lo + m, sp.hi - m)


def noise_block_hessian(logpost: LogPosterior, theta: np.ndarray, idx: list[int]) -> np.ndarray:
    """-Hessian of the log-posterior over the noise-effect coordinates idx at theta (central
    differences of noise_objective, one batch; the force does not depend on them, so the
    surface is smooth and the residuals are simulated once)."""
    sp = logpost.space
    k = len(idx)
    h = 1e-3 * (sp.hi[idx] - sp.lo[idx])
    theta = theta.copy()       # a point at a bound (a_ch = 0): the stencil moved inside the box
    theta[idx] = np.clip(theta[idx], sp.lo[idx] + 1.01 * h, sp.hi[idx] - 1.01 * h)
    pts = []
    for a in range(k):
        for b in range(a, k):
            for sa, sb in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                p = theta[idx].copy()
                p[a] += sa * h[a]
                p[b] += sb * h[b]
                pts.append(p)
    v = noise_objective(logpost, theta, idx)(np.array(pts))
    H = np.zeros((k, k))
    m = 0
    for a in range(k):
        for b in range(a, k):
            pp, pm, mp, mm = v[m:m + 4]
            m += 4
            H[a, b] = H[b, a] = -(pp - pm - mp + mm) / (4 * h[a] * h[b])
    return H
