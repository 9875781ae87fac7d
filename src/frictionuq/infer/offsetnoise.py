"""Log-likelihood of a held-out record whose load-cell offset is unknown: the offset c is
integrated out in closed form together with the noise's sigma (and on the noise model's phi
grid), under a uniform prior on a box; the derivation is in frictionuq.infer.compare's docstring,
which uses it for leave-one-test-out ELPD."""
from __future__ import annotations

import math

import numpy as np
from scipy.special import betaln, gammaln, hyp2f1, log_ndtr, logsumexp, stdtr

from . import noisemodel


def log_cdf_t(t, nu: float) -> np.ndarray:
    """log of the Student-t CDF with nu degrees of freedom, accurate far in the lower tail
    (where scipy's stdtr underflows): there via the incomplete-beta identity
    I_x(a, b) = x^a (1-x)^b F(a+b, 1; a+1; x) / (a B(a, b)) (DLMF 8.17.8), x = nu/(nu+t^2),
    a = nu/2, b = 1/2; the normal tail (log_ndtr) where that hypergeometric series fails
    (nu above about 1e5, where t and normal tails agree to a fraction of a nat)."""
    t = np.asarray(t, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.log(stdtr(nu, t))
        tail = (t < 0) & ~(out > -690.0)
        if np.any(tail):
            tt = t[tail]
            x = nu / (nu + tt**2)
            a = 0.5 * nu
            v = (math.log(0.5) + a * np.log(x) + 0.5 * np.log1p(-x) - math.log(a) - betaln(a, 0.5)
                 + np.log(hyp2f1(a + 0.5, 1.0, a + 1.0, x)))
            out[tail] = np.where(np.isfinite(v), v, log_ndtr(tt))
    return out


def log_interval(lo, hi, logcdf) -> np.ndarray:
    """log(F(hi) - F(lo)) for a distribution symmetric about 0, lo < hi elementwise, accurate when
    both ends lie in the same tail."""
    lo, hi = np.broadcast_arrays(np.asarray(lo, float), np.asarray(hi, float))
    flip = lo > 0                                  # F(hi) - F(lo) = F(-lo) - F(-hi)
    a = np.where(flip, -hi, lo)
    b = np.where(flip, -lo, hi)
    la, lb = logcdf(a), logcdf(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        out = lb + np.log1p(-np.exp(la - lb))
    return np.where(np.isfinite(lb), out, -np.inf)


#: standardised distance of the offset's conditional optimum from both ends of its box beyond
#: which the box holds all of its conditional mass but a tail below exp(-46) (Student-t with 20
#: degrees of freedom; exp(-145) with 100, about exp(-800) with the records' thousands): the
#: term is then 0 within that, and its t CDFs, the costliest part of a per-test-offset
#: likelihood, are skipped
_INSIDE_T = 40.0


def _box_term(t_lo, t_hi, logcdf) -> np.ndarray:
    """log P(t_lo < T < t_hi), elementwise; exactly 0 where both ends lie beyond _INSIDE_T."""
    out = np.zeros(np.broadcast(t_lo, t_hi).shape)
    t_lo, t_hi = np.broadcast_arrays(t_lo, t_hi)
    near = (t_lo > -_INSIDE_T) | (t_hi < _INSIDE_T)
    if np.any(near):
        out[near] = log_interval(t_lo[near], t_hi[near], logcdf)
    return out


#: phi grid points more than this many nats below a row's best (before the box term) add less
#: than exp(-50) of its integral: their box terms are not computed unless the box cuts the best
#: points by more than _BOX_CUT nats (an offset at or beyond the box), when all are
_FAR_BELOW, _BOX_CUT = 50.0, 10.0


def _box_terms(lp, t_lo, t_hi, logcdf) -> np.ndarray:
    """(W, P) the box factors log P(t_lo < T < t_hi) over the phi grid, computed where they can
    change the row's integral (_FAR_BELOW, _INSIDE_T): 0 elsewhere, to double precision of
    the logsumexp. Without the skips a per-test-offset likelihood spent 90 % of its time in the
    t CDFs (32 walkers, three 1,500-sample records: 32.6 against 3.1 ms per call)."""
    top = np.max(lp, axis=1, keepdims=True)
    use = lp > top - _FAR_BELOW
    out = np.zeros(lp.shape)
    out[use] = _box_term(t_lo[use], t_hi[use], logcdf)
    cut = np.max(np.where(use, lp + out, -np.inf), axis=1) < top[:, 0] - _BOX_CUT
    if np.any(cut):                        # the box matters at the top: every point counts
        rows = np.flatnonzero(cut)
        out[rows] = _box_term(t_lo[rows], t_hi[rows], logcdf)
    return out


def log_marginal_offset(e: np.ndarray, kind: str, sigma_bounds: tuple[float, float],
                        sigma_fixed: float | None = None, phi_fixed: float | None = None,
                        offset_box: tuple[float, float] = (-np.inf, np.inf),
                        offset_width: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """log p(y | F) of residuals e = y - F (no offset subtracted; (W, N)) with a constant offset c
    integrated out under a uniform prior on offset_box (density 1 / its width; for an unbounded
    box pass offset_width, the density being 1/offset_width), and the noise parameters
    integrated out as in noisemodel.log_marginal: see the module docstring. Returns
    (log marginal (W,), c_hat (W,): the conditional optimum of c at the most probable phi)."""
    e = np.atleast_2d(np.asarray(e, dtype=float))
    W, N = e.shape
    if N < 3:
        raise ValueError("a held-out record needs at least 3 samples")
    lo, hi = map(float, offset_box)
    if not lo < hi:
        raise ValueError(f"offset box needs lower < upper, got {offset_box}")
    width = offset_width if offset_width is not None else hi - lo
    if not (np.isfinite(width) and width > 0):
        raise ValueError("an unbounded offset box needs a finite offset_width > 0")
    mean = e.mean(axis=1, keepdims=True)
    ec = e - mean                      # work about the mean (less cancellation); c shifts with it
    if kind == "iid":
        phi_fixed = 0.0
    if phi_fixed is not None:
        phis, logw = np.array([float(phi_fixed)]), np.array([0.0])
    else:
        phis, logw = noisemodel.PHI_GRID, noisemodel._LOG_W
    S0, S1, S2, e0sq = noisemodel.suff_stats(ec)
    ph = phis[None, :]
    Q0 = S0[:, None] - 2 * ph * S1[:, None] + ph**2 * (S2 - e0sq)[:, None]
    e0 = ec[:, 0][:, None]
    T1 = (ec[:, 1:].sum(axis=1))[:, None]
    T0 = (ec[:, :-1].sum(axis=1))[:, None]
    A = (1 - ph**2) + (N - 1) * (1 - ph) ** 2                       # (1, P)
    B = (1 - ph**2) * e0 + (1 - ph) * (T1 - ph * T0)                 # (W, P)
    c_opt = mean + B / A                                              # (W, P), about the data
    Qmin = np.maximum(Q0 - B**2 / A, 1e-300)
    half = 0.5 * np.log1p(-ph**2) - 0.5 * np.log(A) - math.log(width)
    if sigma_fixed is None:
        a, b = sigma_bounds
        M = N - 1
        lp = (-0.5 * M * math.log(math.pi) + gammaln(0.5 * M) - math.log(2 * math.log(b / a))
              + half - 0.5 * M * np.log(Qmin))
        k = np.sqrt(A * M / Qmin)                   # Student-t in c with N - 1 dof

        def logcdf(t):
            return log_cdf_t(t, M)
    else:
        s2 = sigma_fixed**2 * (1 - ph**2)
        lp = -0.5 * (N - 1) * np.log(2 * math.pi * s2) + half - Qmin / (2 * s2)
        k = np.sqrt(A / s2) * np.ones_like(c_opt)   # Gaussian in c
        logcdf = log_ndtr
    lp = lp + logw[None, :]
    if np.isfinite(lo) or np.isfinite(hi):
        lp = lp + _box_terms(lp, (lo - c_opt) * k, (hi - c_opt) * k, logcdf)
    best = np.argmax(lp, axis=1)
    return logsumexp(lp, axis=1), c_opt[np.arange(W), best]
