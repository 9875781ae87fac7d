"""Storing the sampler's steps: the cost per step of the HDF5 backend (infer.storage), side by
side: emcee's own HDFBackend.save_step on the file kept open (what the fits did until
2026-12-05), the cached writer the fits use now (OpenHDFBackend's _StepWriter), and no storage
(emcee in memory, the floor). A trivial log-probability, so the step is all bookkeeping; the
shape of a fit's stored run (16 chains, --ndim parameters, one blob column per record and
statistic). Also checks that the two files hold the same chain, log-probabilities, blobs,
acceptance counts and random state, read by emcee's own backend.

    .venv/bin/python benchmarks/bench_storage.py [--steps 3000] [--walkers 16] [--ndim 16] [--blobs 13]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import emcee
import numpy as np

from frictionuq.infer.storage import OpenHDFBackend, open_backend


class _EmceeSaveStep(OpenHDFBackend):
    """The file kept open, each step written by emcee's HDFBackend.save_step."""

    def save_step(self, state, accepted):
        emcee.backends.HDFBackend.save_step(self, state, accepted)


def run(kind: str, path: Path, steps: int, nw: int, ndim: int, nblob: int):
    def log_prob(x):
        r = np.zeros((x.shape[0], 1 + nblob))
        r[:, 0] = -0.5 * np.sum(x**2, axis=1)
        r[:, 1:] = x[:, :1]
        return r

    be = None
    if kind != "memory":
        be, _ = open_backend(path, nw, ndim, resume=False)
        if kind == "emcee":
            be.__class__ = _EmceeSaveStep
        be.keep_open()
    s = emcee.EnsembleSampler(nw, ndim, log_prob, vectorize=True, backend=be,
                              moves=emcee.moves.GaussianMove(0.1))
    s.random_state = np.random.RandomState(1).get_state()
    p0 = np.random.default_rng(0).standard_normal((nw, ndim))
    t0 = time.perf_counter()
    s.run_mcmc(p0, steps, skip_initial_state_check=True)
    dt = time.perf_counter() - t0
    if be is not None:
        be.close()
    return dt / steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--walkers", type=int, default=16)
    ap.add_argument("--ndim", type=int, default=16)
    ap.add_argument("--blobs", type=int, default=13)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        t = {k: run(k, d / f"{k}.h5", a.steps, a.walkers, a.ndim, a.blobs)
             for k in ("memory", "emcee", "cached")}
        print(f"{a.steps} steps, {a.walkers} walkers, {a.ndim} parameters, {a.blobs} blob columns")
        print(f"{'storage':<36}{'ms per step':>12}{'over memory (ms)':>18}")
        for k, label in (("memory", "none (emcee in memory)"),
                         ("emcee", "emcee's save_step, file kept open"),
                         ("cached", "cached writer (the fits' now)")):
            print(f"{label:<36}{t[k] * 1e3:12.3f}{(t[k] - t['memory']) * 1e3:18.3f}")
        print(f"storage cost, emcee's / cached: "
              f"{(t['emcee'] - t['memory']) / (t['cached'] - t['memory']):.2f}")
        a_, b_ = (emcee.backends.HDFBackend(str(d / f"{k}.h5"), read_only=True)
                  for k in ("emcee", "cached"))
        same = (np.array_equal(a_.get_chain(), b_.get_chain())
                and np.array_equal(a_.get_log_prob(), b_.get_log_prob())
                and np.array_equal(a_.get_blobs(), b_.get_blobs())
                and np.array_equal(a_.accepted, b_.accepted)
                and a_.iteration == b_.iteration
                and all(np.array_equal(np.asarray(x), np.asarray(y))
                        for x, y in zip(a_.random_state, b_.random_state)))
        print(f"the two files read back the same by emcee's HDFBackend: {same}")


if __name__ == "__main__":
    main()
