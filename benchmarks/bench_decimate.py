"""Decimating a batch of simulated forces: scipy.signal.resample_poly (infer.decimate.decimate,
the definition) against the banded matrix (infer.decimate.Decimator) used by the log-posterior.
Prints the time per call of each, their ratio and the largest difference, side by side, for
record lengths and decimation factors met in the shipped campaigns.

    .venv/bin/python benchmarks/bench_decimate.py [--walkers 36]
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from frictionuq.infer.decimate import decimate, decimator


def per_call(f, min_seconds: float = 0.5) -> float:
    f()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < min_seconds:
        f()
        n += 1
    return (time.perf_counter() - t0) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--walkers", type=int, default=36)
    a = ap.parse_args()
    rng = np.random.default_rng(1)
    print(f"{'samples':>8}{'q':>4}{'build (s)':>11}{'resample_poly (ms)':>20}{'banded (ms)':>13}"
          f"{'speed-up':>10}{'max |diff| (rel.)':>19}")
    for n, q in [(5001, 2), (5001, 10), (20480, 5), (61440, 5), (61440, 20)]:
        F = rng.standard_normal((a.walkers, n)).cumsum(axis=1)
        t0 = time.perf_counter()
        D = decimator(n, q)
        build = time.perf_counter() - t0
        ref, got = decimate(F, q), D(F)
        diff = float(np.max(np.abs(ref - got)) / np.max(np.abs(ref)))
        t_ref = per_call(lambda: decimate(F, q))
        t_new = per_call(lambda: D(F))
        print(f"{n:8d}{q:4d}{build:11.2f}{t_ref * 1e3:20.2f}{t_new * 1e3:13.2f}"
              f"{t_ref / t_new:9.1f}x{diff:19.1e}")


if __name__ == "__main__":
    main()
