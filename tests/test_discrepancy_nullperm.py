"""The permutation null of the residual diagnostics evaluated a chunk of permuted copies at a
time (frictionuq.discrepancy.nullperm): every batched piece gives each row exactly what it gives
that row alone, and diagnose's output does not depend on the chunk size, to the last bit."""
from __future__ import annotations

import json

import numpy as np
import pytest

import frictionuq
from frictionuq.discrepancy import chatter as C, diagnose, features, nullperm as NP
from frictionuq.noise import ar1_from_normals
from frictionuq.published import published_params


@pytest.fixture(scope="module")
def record():
    """A 0.5 Hz sine of slowly varying amplitude at 100 Hz (2,000 samples), the BRFD at 267 N,
    AR(1) noise plus a position-locked ripple in the residual."""
    t = np.arange(2000) / 100.0
    x = 0.0254 * np.sin(np.pi * t) * (1 + 0.3 * np.sin(0.1 * np.pi * t))
    force = frictionuq.simulate(t, x, published_params("brfd", 267.0))
    r = ar1_from_normals(np.random.default_rng(1).standard_normal(t.size), 0.8, 300.0)
    return t, x, force, r + 80.0 * np.sin(2 * np.pi * x / 0.004)


def test_row_pieces_equal_the_single_row_ones(record):
    t, x, _, r = record
    rng = np.random.default_rng(0)
    rows = np.stack([r[NP.block_permutation(r.size, 40.0, rng)] for _ in range(5)])
    idx = rng.integers(0, 33, r.size)
    B = NP.row_bincount(idx, rows, 33)
    for i, row in enumerate(rows):
        assert np.array_equal(B[i], np.bincount(idx, weights=row, minlength=33))
    n_c, n_d = np.bincount(idx, minlength=33).astype(float)[:32], np.array([900.0, 1100.0])
    T = NP.stat(B[:, :32], n_c, n_d, 7.0)
    assert all(T[i] == NP.stat(B[i, :32], n_c, n_d, 7.0) for i in range(5))
    acc = np.full(33, 0.1)
    want = acc.copy()
    for row in B:
        want = want + row
    assert np.array_equal(NP.accumulate(acc, B), want)
    up = (np.gradient(x) > 0).astype(np.int64)
    spec = NP.Spectrum(x, up, 256, 8)
    assert spec.ok
    P = spec.power(rows)
    assert all(np.array_equal(P[i], spec.power(rows[i][None, :])[0]) for i in range(5))
    lock = C.lock_cells(up, np.abs(x))
    H = C.power(rows, *lock)
    assert all(np.array_equal(H[i], C.power(rows[i], *lock)) for i in range(5))


def test_chunks_draw_the_sequential_permutations():
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    got = np.concatenate([p for _, p in NP.permutation_chunks(300, 12.5, rng_a, 23, chunk_samples=7 * 300)])
    want = np.stack([NP.block_permutation(300, 12.5, rng_b) for _ in range(23)])
    assert np.array_equal(got, want)
    starts = [s for s, _ in NP.permutation_chunks(300, 12.5, np.random.default_rng(5), 23, chunk_samples=7 * 300)]
    assert starts == [0, 7, 14, 21]


def test_diagnose_does_not_depend_on_the_chunk_size(record, monkeypatch):
    """One row per chunk (the copy-at-a-time loop), 7 rows, and all 999 at once (the default's
    chunk on a record this short): the same document, every view, the spectrum and the bursts
    included."""
    t, x, force, r = record
    ft = features(t, x, force)
    kw = dict(spread=150.0 + 20.0 * np.abs(np.cos(t)), features=ft, seed=3)
    docs, sizes = [], []
    chunks = NP.permutation_chunks

    def spy(*a, **k):
        for start, perms in chunks(*a, **k):
            sizes[-1].append(perms.shape[0])
            yield start, perms

    monkeypatch.setattr("frictionuq.discrepancy.diagnostics.permutation_chunks", spy)
    for rows in (1, 7, 999):
        monkeypatch.setattr(NP, "CHUNK_SAMPLES", rows * r.size)
        sizes.append([])
        d = diagnose(t, x, r, **kw)
        docs.append(json.dumps(d, sort_keys=True))
    assert [max(s) for s in sizes] == [1, 7, 999] and all(sum(s) == 999 for s in sizes)
    assert d["chatter"] is not None and d["spectrum"] is not None
    assert {"time", "cycle", "energy"} <= set(d["views"])           # the trend statistics too
    assert "spectrum" in d["significant"]                            # the ripple is found
    assert docs[0] == docs[1] == docs[2]
