"""Decimation: anti-alias filter a record and keep every q-th sample.

`decimate(a, q)` is the definition (scipy.signal.resample_poly, a zero-phase Kaiser-windowed
FIR, after removing the line through the end points so that the filter's zero padding does not
create edge transients). It is linear in `a`, so for one record length n it is a fixed matrix:
banded (each kept sample is a weighted sum of the 20 q + 1 raw samples around it) plus two
columns (the end points, through the line). `Decimator(n, q)` holds that matrix and applies it
to a batch of simulated forces (one row per walker) with a numba kernel, rows in parallel.

Why: with the model simulated at the raw rate (infer.likelihood), every log-posterior
evaluation decimates each walker's simulated force: in one 36-walker evaluation of a three-test
MFD level (3 x 5,000 raw samples, q = 10, 2, 1; 2 cores) resample_poly took 9 of 31 ms. The
banded product gives the same numbers (to 1e-15 relative, checked on every build) 2-3.6 times
faster (benchmarks/bench_decimate.py prints both side by side); that evaluation now takes 22 ms.

The matrix is read off resample_poly itself, by impulses spaced so far apart that their
responses do not overlap: no copy of scipy's filter design, whatever its version does.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numba import njit, prange
from scipy.signal import resample_poly


def decimate(a: np.ndarray, q: int) -> np.ndarray:
    """Anti-alias filter and keep every q-th sample along the last axis (1-D record, or one row
    per walker). Linear in `a`, so decimating y - F equals decimating y minus decimating F."""
    if q == 1:
        return a.copy()
    n = a.shape[-1]
    ramp = np.arange(n) / (n - 1)
    trend = a[..., :1] + (a[..., -1:] - a[..., :1]) * ramp
    out = resample_poly(a - trend, 1, q, axis=-1)
    return out + trend[..., ::q][..., : out.shape[-1]]


@njit(parallel=True, cache=True, fastmath={"reassoc", "contract"})
def _apply(a, W, start, c0, c1, out):
    m, n = a.shape
    n_out, width = W.shape
    for r in prange(m):
        a0 = a[r, 0]
        a1 = a[r, n - 1]
        for j in range(n_out):
            s = start[j]
            acc = a0 * c0[j] + a1 * c1[j]
            for k in range(width):
                acc += W[j, k] * a[r, s + k]
            out[r, j] = acc


def _reach(q: int, n: int) -> int:
    """How many kept samples on each side of it one raw impulse reaches (plus a margin of 2):
    read off an impulse in the middle of a zero row long enough that the response is not cut."""
    m = max(n, 64 * q)
    while True:
        mid = np.zeros(m)
        mid[m // 2] = 1.0
        nz = np.flatnonzero(resample_poly(mid, 1, q))
        if nz.size and nz[0] > 0 and nz[-1] < (m - 1) // q:
            return int(np.ceil(np.max(np.abs(nz - (m // 2) / q)))) + 2
        m *= 2


class Decimator:
    """decimate(., q) for rows of length n as a banded matrix (see the module docstring)."""

    def __init__(self, n: int, q: int):
        if q < 2 or n < 2:
            raise ValueError(f"Decimator needs q >= 2 and n >= 2, got q={q}, n={n}")
        self.n, self.q = int(n), int(q)
        self.n_out = resample_poly(np.zeros(n), 1, q).size
        reach = _reach(q, n)                 # kept samples on each side an impulse reaches
        spacing = q * (2 * reach + 3)        # impulses this far apart: responses do not overlap
        rows, cols, vals = [], [], []
        for r0 in range(0, spacing, 64):
            offs = np.arange(r0, min(r0 + 64, spacing))
            P = np.zeros((offs.size, n))
            for k, o in enumerate(offs):
                P[k, o::spacing] = 1.0
            R = resample_poly(P, 1, q, axis=-1)
            for k, o in enumerate(offs):
                for i in range(o, n, spacing):
                    j0, j1 = max(i // q - reach - 1, 0), min(i // q + reach + 2, self.n_out)
                    seg = R[k, j0:j1]
                    j = np.flatnonzero(seg)
                    rows.append(j + j0)
                    cols.append(np.full(j.size, i))
                    vals.append(seg[j])
        rows, cols, vals = map(np.concatenate, (rows, cols, vals))
        lo = np.full(self.n_out, n, dtype=np.int64)
        hi = np.full(self.n_out, -1, dtype=np.int64)
        np.minimum.at(lo, rows, cols)
        np.maximum.at(hi, rows, cols)
        lo = np.where(hi < 0, 0, lo)
        width = int(max(np.max(hi - lo + 1), 1))
        self.start = np.clip(lo, 0, n - width).astype(np.int64)
        self.W = np.zeros((self.n_out, width))
        self.W[rows, cols - self.start[rows]] = vals
        # the line through the end points: decimate(a) = D a + a[0] c0 + a[-1] c1
        ramp = np.arange(n) / (n - 1)
        self.c0 = (1.0 - ramp)[::q][: self.n_out] - resample_poly(1.0 - ramp, 1, q)
        self.c1 = ramp[::q][: self.n_out] - resample_poly(ramp, 1, q)
        self._self_check()

    def __call__(self, a: np.ndarray) -> np.ndarray:
        a = np.ascontiguousarray(np.atleast_2d(a), dtype=float)
        if a.shape[1] != self.n:
            raise ValueError(f"Decimator for rows of {self.n} samples got {a.shape[1]}")
        out = np.empty((a.shape[0], self.n_out))
        _apply(a, self.W, self.start, self.c0, self.c1, out)
        return out

    def _self_check(self) -> None:
        """The matrix reproduces decimate() on a random row (to rounding), or this raises."""
        a = np.random.default_rng(0).standard_normal(self.n).cumsum()
        ref = decimate(a, self.q)
        got = self(a)[0]
        tol = 1e-9 * (np.max(np.abs(ref)) + 1.0)
        if ref.shape != got.shape or not np.allclose(got, ref, rtol=0, atol=tol):
            raise RuntimeError(f"Decimator(n={self.n}, q={self.q}) does not reproduce "
                               "scipy.signal.resample_poly; report this with your scipy version")


@lru_cache(maxsize=64)
def decimator(n: int, q: int) -> Decimator:
    """The Decimator of rows of n samples by q (built once per (n, q))."""
    return Decimator(n, q)
