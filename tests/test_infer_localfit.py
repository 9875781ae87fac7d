"""infer/localfit.py: least squares from a start."""
from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
from scipy.optimize import least_squares

from frictionuq.infer.localfit import clip_in, least_squares_fit


class _Toy:
    """A log-posterior's least-squares face: two records, residuals y - a exp(-b t) + c (rows of
    theta), counting the residual rows it evaluates."""

    def __init__(self):
        self.space = NS(lo=np.array([0.1, 0.01, -1.0]), hi=np.array([10.0, 5.0, 1.0]))
        rng = np.random.default_rng(3)
        self.records = []
        for n in (40, 70):
            t = np.linspace(0.0, 4.0, n)
            y = 2.5 * np.exp(-0.7 * t) - 0.2 + 0.01 * rng.standard_normal(n)
            self.records.append(NS(t=t, y=y))
        self.rows = 0

    def noise_gain(self, theta, j):
        return None

    def residuals(self, th, rec):
        th = np.atleast_2d(th)
        self.rows += th.shape[0]
        return rec.y[None, :] - th[:, :1] * np.exp(-th[:, 1:2] * rec.t[None, :]) + th[:, 2:3]


def _reference(toy, theta0):
    """least_squares_fit as it was before 2026-12-03: the Jacobian at D + 1 points, the first of
    them the point least_squares had just evaluated."""
    lo, hi = toy.space.lo, toy.space.hi
    h = 1e-6 * (hi - lo)

    def resid_batch(th):
        r = np.concatenate([toy.residuals(th, rec) for rec in toy.records], axis=1)
        return np.where(np.isfinite(r), r, 1e12)

    def jac(p):
        step = np.where(p + h <= hi, h, -h)
        pts = np.repeat(p[None, :], p.size + 1, axis=0)
        pts[1:] += np.diag(step)
        R = resid_batch(pts)
        return ((R[1:] - R[0]) / step[:, None]).T

    r = least_squares(lambda p: resid_batch(p)[0], clip_in(toy.space, theta0), jac=jac,
                      bounds=(lo, hi), x_scale="jac", max_nfev=200, xtol=1e-10, ftol=1e-10)
    return clip_in(toy.space, r.x), r


def test_the_jacobian_reuses_the_point_just_evaluated_with_the_same_result():
    """The fit reuses the residual least_squares has just computed at the Jacobian's base point:
    the same steps and answer to the last bit as the D + 1-point Jacobian, one row fewer each."""
    theta0 = np.array([1.0, 2.0, 0.5])
    ref_toy, toy = _Toy(), _Toy()
    th_ref, r_ref = _reference(ref_toy, theta0)
    th, r = least_squares_fit(toy, theta0)
    assert np.array_equal(th, th_ref)
    assert r.nfev == r_ref.nfev and r.njev == r_ref.njev and r.njev > 2
    assert np.allclose(th, [2.5, 0.7, 0.2], atol=0.05)          # it did fit
    # one base point per Jacobian saved (a row per record)
    assert toy.rows == ref_toy.rows - r.njev * len(toy.records)
