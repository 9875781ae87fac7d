"""The permutation null of the residual diagnostics (diagnostics.py says what it tests and why):
the random-cut block permutations, and the statistics evaluated on many permuted copies at once.

diagnose() evaluates every view's statistic on the observed residual and on N_PERM (999)
block-permuted copies of it. One copy at a time that was about 20 small numpy calls per copy (a
0.3-0.5 s diagnose on a 2,000-sample record, most of it Python overhead). Here the copies come in
chunks, one row each, and every statistic is computed for the whole chunk: `row_bincount`
(one np.bincount over the chunk, each row offset into its own range of bins) gives each row the
sums np.bincount gives it alone, added in the same order, so the results are those of the
copy-at-a-time loop to the last bit (tests/test_discrepancy_nullperm.py compares the two).
Where a batched product would round differently from the single one (a matrix product against
a matrix-vector product), the rows are still done one by one.

The permutations are drawn one after the other from the same generator, as before: the same
seed gives the same permutations whatever the chunk size.
"""
from __future__ import annotations

import numpy as np

#: the most samples (rows x record length) held per chunk: 2e6 doubles = 16 MB per array
CHUNK_SAMPLES = 2_000_000


def autocorrelation_length(r) -> float:
    """2 x the first lag (samples) at which the sample autocorrelation of r drops below 1/e."""
    r = np.asarray(r, dtype=float) - np.mean(r)
    n = r.size
    spec = np.fft.rfft(r, 2 * n)
    acf = np.fft.irfft(spec * spec.conj(), 2 * n)[:n]
    if acf[0] <= 0:
        return 1.0
    below = np.flatnonzero(acf / acf[0] < 1.0 / np.e)
    return 2.0 * float(below[0] if below.size else n)


def block_permutation(n: int, block: float, rng) -> np.ndarray:
    """Index array: 0..n-1 cut at round(n/block) - 1 random points, the blocks randomly reordered."""
    if block <= 1:
        return rng.permutation(n)
    k = max(1, int(round(n / block)))
    if k == 1:
        return np.arange(n)
    cuts = np.sort(rng.choice(np.arange(1, n), k - 1, replace=False))
    starts = np.concatenate(([0], cuts))
    lengths = np.diff(np.concatenate((starts, [n])))
    order = rng.permutation(k)
    out_start = np.concatenate(([0], np.cumsum(lengths[order])[:-1]))
    return np.arange(n) + np.repeat(starts[order] - out_start, lengths[order])


def permutation_chunks(n: int, block: float, rng, n_perm: int, chunk_samples: int | None = None):
    """(first index, (m, n) index rows) for n_perm block permutations of n samples, drawn one
    after the other from rng, m rows at a time (m * n <= chunk_samples, default CHUNK_SAMPLES;
    at least one row)."""
    m = max(1, min(n_perm, (chunk_samples or CHUNK_SAMPLES) // max(n, 1)))
    for start in range(0, n_perm, m):
        rows = min(m, n_perm - start)
        yield start, np.stack([block_permutation(n, block, rng) for _ in range(rows)])


def row_bincount(idx: np.ndarray, weights: np.ndarray, size: int) -> np.ndarray:
    """(m, size): np.bincount(idx, weights=row, minlength=size) of each row of weights (m, n),
    in one call (row i's bins offset by i * size); each row's sums are added in its own order."""
    m = weights.shape[0]
    flat = (np.arange(m, dtype=np.int64)[:, None] * size + idx[None, :]).ravel()
    return np.bincount(flat, weights=weights.ravel(), minlength=m * size).reshape(m, size)


def stat(S, n_c, n_d, ss):
    """Partial correlation ratio from cell sums S (..., 2B) (cell 2b+1: d=+1, 2b: d=-1)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        cells = np.where(n_c > 0, S * S / n_c, 0.0).sum(-1)
        Sd = np.stack([S[..., 0::2].sum(-1), S[..., 1::2].sum(-1)], -1)
        dirs = np.where(n_d > 0, Sd * Sd / n_d, 0.0).sum(-1)
    return (cells - dirs) / ss


def accumulate(acc: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """acc + rows[0] + rows[1] + ..., added in that order (as a loop over the rows would)."""
    return np.cumsum(np.concatenate([acc[None], rows]), axis=0)[-1]


def trend_stat(basis: np.ndarray, rows: np.ndarray, ss: float) -> np.ndarray:
    """(m,): the fraction of each row's variance explained by the orthonormal trend basis
    (n, k). Row by row: a matrix-vector product each, as for a single residual."""
    return np.array([float(np.sum((basis.T @ row) ** 2)) / ss for row in rows])


def trend_basis(f: np.ndarray, up: np.ndarray, degree: int) -> np.ndarray:
    """Orthonormal columns (n, 2 degree): polynomials of degree 1..degree in the standardised
    feature, separately per direction, orthogonal to the two direction means."""
    z = (f - f.mean()) / (f.std() or 1.0)
    P = np.stack([z**k for k in range(1, degree + 1)], 1)
    cols = [P * (up == 1)[:, None], P * (up == 0)[:, None]]
    X = np.concatenate([np.stack([(up == 1), (up == 0)], 1).astype(float)] + cols, 1)
    Q, R = np.linalg.qr(X)
    keep = np.abs(np.diag(R)) > 1e-10 * np.abs(np.diag(R)).max()
    keep[:2] = False                  # the direction means: not structure (as in T)
    return Q[:, keep]


class Spectrum:
    """Grid, band and detrending of the position-locked spectrum; one profile per direction."""

    def __init__(self, x, up, n_grid, pad):
        lo, hi = float(x.min()), float(x.max())
        self.range, self.n_grid = hi - lo, n_grid
        self.step = self.range / n_grid if hi > lo else 1.0
        self.idx = np.minimum(((x - lo) / self.step).astype(np.int64), n_grid - 1) + n_grid * up
        self.counts = np.bincount(self.idx, minlength=2 * n_grid).astype(float).reshape(2, n_grid)
        self.dirs = [i for i in (0, 1) if (self.counts[i] > 0).sum() >= 16]
        self.centres = lo + (np.arange(n_grid) + 0.5) * self.step
        self.nfft = pad * n_grid
        k = np.fft.rfftfreq(self.nfft, self.step)
        self.band = (k >= 2.0 / max(self.range, 1e-300)) & (k <= 1.0 / (4.0 * self.step))
        self.k = k[self.band]
        A = np.stack([np.ones(n_grid), self.centres - self.centres.mean()], 1)
        self.detrend = np.eye(n_grid) - A @ np.linalg.pinv(A)
        self.window = np.hanning(n_grid)
        self.ok = self.range > 0 and bool(self.dirs) and self.band.sum() >= 4

    def power(self, dr: np.ndarray) -> np.ndarray:
        """(m, band) summed periodograms of the rows of dr (m, n)."""
        sums = row_bincount(self.idx, dr, 2 * self.n_grid).reshape(dr.shape[0], 2, self.n_grid)
        out = 0.0
        for i in self.dirs:
            f = self.counts[i] > 0
            means = sums[:, i, f] / self.counts[i, f]
            prof = np.stack([self.detrend @ np.interp(self.centres, self.centres[f], row) for row in means])
            out = out + np.abs(np.fft.rfft(self.window * prof, self.nfft, axis=-1))[:, self.band] ** 2
        return out
