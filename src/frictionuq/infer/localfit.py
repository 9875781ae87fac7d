"""Local fits around a point: least squares from a start (raw, or on the AR(1)-whitened
residuals), the per-record whitening, the noise parameters and the model fitted in turn, each
record's ARMA(1,1) shape at a point, and the Gauss-Newton covariance there.

The pieces the MAP search (optimize.py) refines its starts with, and that the quick fits
(quickfit.py), the sampler's initial ball (sampler.py) and the discrepancy workflow's fits use
directly. Everything works in the sampled coordinates of the log-posterior's Space, inside the
prior box (clip_in keeps a point a hair inside it).
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from . import noisemodel
from .likelihood import LogPosterior
from .noisefit import fit_noise, noise_block_hessian, noise_indices, scaled_residuals


def clip_in(space, th):
    m = 1e-9 * (space.hi - space.lo)
    return np.clip(th, space.lo + m, space.hi - m)



def whitening(logpost: LogPosterior, theta: np.ndarray) -> list[tuple[float, float]]:
    """Per record (lag-1 correlation phi, innovation sd) of the residuals at theta (scaled by a
    noise effect's gain there)."""
    out = []
    for j, rec in enumerate(logpost.records):
        e = scaled_residuals(logpost, theta, j)[0]
        phi = float(np.clip(np.corrcoef(e[1:], e[:-1])[0, 1], 0.0, 0.995)) if e.size > 3 else 0.0
        s = float(np.std(e[1:] - phi * e[:-1])) or 1.0
        out.append((phi if np.isfinite(phi) else 0.0, s if np.isfinite(s) else 1.0))
    return out



def least_squares_fit(logpost: LogPosterior, theta0: np.ndarray, max_nfev: int = 200, white=None):
    """Least squares over all sampled parameters (model and offset) from theta0; with `white`
    (per record (phi, innovation sd), from `whitening`) on the AR(1)-whitened residuals, each
    record scaled by its own noise: iterated, this maximises the likelihood with per-record
    AR(1) noise (the raw least squares lets the records with the largest misfit dominate).
    With a noise effect (chatter) the residuals are divided by its gain at theta0, held fixed:
    least squares cannot fit a noise parameter (fit_noise does), only weigh by it."""
    sp = logpost.space
    gains = [logpost.noise_gain(np.atleast_2d(theta0), j) for j in range(len(logpost.records))]

    def resid_batch(th):
        th = np.atleast_2d(th)
        parts = []
        for j, rec in enumerate(logpost.records):
            e = logpost.residuals(th, rec)
            if gains[j] is not None:
                e = e / gains[j]
            if white is not None:     # AR(1)-whitened and scaled by the innovation sd
                phi, s = white[j]
                e = np.concatenate([e[:, :1] * np.sqrt(1 - phi**2), e[:, 1:] - phi * e[:, :-1]],
                                   axis=1) / s
            parts.append(e)
        r = np.concatenate(parts, axis=1)
        return np.where(np.isfinite(r), r, 1e12)

    lo, hi = sp.lo, sp.hi
    h = 1e-6 * (hi - lo)
    last = {}    # least_squares asks for the Jacobian at the point it has just evaluated

    def fun(p):
        r = resid_batch(p)[0]
        last.update(p=p.copy(), r=r)
        return r

    def jac(p):
        step = np.where(p + h <= hi, h, -h)
        pts = np.repeat(p[None, :], p.size, axis=0) + np.diag(step)
        r0 = last["r"] if "p" in last and np.array_equal(last["p"], p) else fun(p)
        return ((resid_batch(pts) - r0) / step[:, None]).T

    p0 = clip_in(sp, theta0)
    r = least_squares(fun, p0, jac=jac, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev,
                      xtol=1e-10, ftol=1e-10)
    return clip_in(sp, r.x), r


def set_noise_shape(logpost: LogPosterior, theta: np.ndarray) -> list[float]:
    """Set each record's ARMA(1,1) MA coefficient (FitRecord.noise_theta) to its estimate from
    the residuals at theta (noisemodel.estimate_theta); returns them."""
    kw = {k: v for k, v in logpost.noise.items() if k != "kind"}
    out = []
    for rec in logpost.records:
        e = logpost.residuals(theta[None, :], rec)[0]
        rec.noise_theta = noisemodel.estimate_theta(e, **kw)
        out.append(rec.noise_theta)
    return out


def alternate_noise(logpost: LogPosterior, theta: np.ndarray, lp: float | None = None,
                    rounds: int = 2) -> tuple[np.ndarray, float]:
    """(theta, log-posterior) after fit_noise and whitened least squares weighted by the new
    gain, in turn, `rounds` times; a step is kept only if it raises the log-posterior."""
    best = np.asarray(theta, float)
    best_lp = float(logpost.log_prob(best[None, :])[0]) if lp is None else lp
    for _ in range(rounds):
        for step in ("noise", "model"):
            if step == "noise":
                th = fit_noise(logpost, best)
            else:
                th, _ = least_squares_fit(logpost, best, max_nfev=40, white=whitening(logpost, best))
            v = float(logpost.log_prob(th[None, :])[0])
            if v > best_lp:
                best, best_lp = th, v
    return best, best_lp


def gauss_newton_cov(logpost: LogPosterior, theta: np.ndarray, ignore_jumps: bool = False) -> np.ndarray:
    """Approximate posterior covariance at theta: Gauss-Newton with each record weighted by its
    residual variance, inflated by (1 + phi)/(1 - phi) for its lag-1 correlation phi, plus the
    prior box as a weak regulariser. With a noise effect (chatter) the residuals are divided by
    its gain at theta, and its parameters' block is the finite-difference curvature of the
    log-posterior over them (noisefit.noise_block_hessian), their cross terms with the model
    parameters left at 0 (least squares has no curvature along a parameter that only scales the
    noise).

    The Jacobian is a one-sided difference, a step of 1e-6 of each parameter's box (down where up
    leaves the box). With `ignore_jumps` each parameter is stepped both ways (where both stay in
    the box) and the side with the smaller weighted slope is kept: the residuals of a sampled
    record jump where a threshold (d3, d2) crosses a sample, and a difference across a jump is
    jump / step, not a slope (a point a hair below a 180-nat drop in d3 had a Laplace evidence 13
    nats from that of a point 3e-7 of the box away, whose step crossed it: docs/log-discrepancy.md,
    2026-11-28). For a smooth residual the two sides agree to the step's order, and it costs D
    more simulations per record."""
    sp = logpost.space
    D = sp.ndim
    w = 1e-6 * (sp.hi - sp.lo)
    up = theta + w <= sp.hi
    steps = [np.where(up, w, -w)]
    if ignore_jumps:
        steps.append(np.where(up & (theta - w >= sp.lo), -w, steps[0]))
    pts = np.repeat(theta[None, :], 1 + D * len(steps), axis=0)
    for s, h in enumerate(steps):
        pts[1 + s * D:1 + (s + 1) * D] += np.diag(h)
    H = np.diag(1.0 / (0.25 * (sp.hi - sp.lo)) ** 2)
    idx = noise_indices(sp)
    if idx:
        Hn = noise_block_hessian(logpost, theta, idx)
        if np.all(np.isfinite(Hn)):
            H[np.ix_(idx, idx)] += Hn
    jacs, scales = [], []                   # per record: J per side ((D, N) each), its variance
    for j, rec in enumerate(logpost.records):
        R = scaled_residuals(logpost, pts, j, gain_at=theta)
        e = R[0]
        var = float(np.mean(e**2)) or 1e-300
        phi = float(np.clip(np.corrcoef(e[1:], e[:-1])[0, 1], 0.0, 0.99)) if e.size > 3 else 0.0
        jacs.append([(R[1 + s * D:1 + (s + 1) * D] - e) / h[:, None] for s, h in enumerate(steps)])
        scales.append(var * (1 + phi) / (1 - phi))
    if ignore_jumps:                        # per parameter, the side of the smaller slope
        slope = [sum(np.nansum(J[s] ** 2, axis=1) / v for J, v in zip(jacs, scales))
                 for s in range(2)]
        down = slope[1] < slope[0]
        jacs = [[np.where(down[:, None], J[1], J[0])] for J in jacs]
    for J, v in zip(jacs, scales):
        H += J[0] @ J[0].T / v
    H = np.where(np.isfinite(H), H, 0.0)
    try:
        cov = np.linalg.inv(H)
        np.linalg.cholesky(cov)
        return cov
    except np.linalg.LinAlgError:
        return np.diag(1.0 / np.clip(np.diag(H), 1e-300, None))
