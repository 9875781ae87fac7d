"""The stopping rule's tau condition, one-sided (the rule since 2026-12-06) against two-sided (the
rule before), side by side in one run, on chains that have converged (issue 3, item 3).

    .venv/bin/python benchmarks/bench_tau_rule.py [--reps 40]

`--reps` sets of 16 independent stationary AR(1) chains (tau 11 steps, 14 parameters, 6,000
steps, seed 0), checked as the sampler checks (every 500 steps from 1,000, the first quarter
discarded, convergence.autocorr_time, its max over the parameters): the fraction of checks at
which each form of the tau condition fails, though nothing is unconverged. Under the two-check
rule each such failure costs a converging fit at least one 500-step chunk. For stored fits, both
forms side by side: benchmarks/replay_stop.py FIT_DIR/<fit id>.
"""
from __future__ import annotations

import argparse

import numpy as np

from frictionuq.infer.convergence import autocorr_time
from frictionuq.infer.sampler import SamplerConfig


def stationary(reps: int, rtol: float, seed: int = 0) -> tuple[int, int, int]:
    """(checks, two-sided failures, one-sided failures) over `reps` sets of stationary chains."""
    rng = np.random.default_rng(seed)
    tau, walkers, ndim, n_steps = 11.0, 16, 14, 6000
    phi = (tau - 1) / (tau + 1)               # an AR(1) process's integrated time is (1+phi)/(1-phi)
    checks = two = one = 0
    for _ in range(reps):
        x = np.empty((n_steps, walkers, ndim))
        x[0] = rng.standard_normal((walkers, ndim))
        e = rng.standard_normal((n_steps, walkers, ndim)) * np.sqrt(1 - phi ** 2)
        for t in range(1, n_steps):
            x[t] = phi * x[t - 1] + e[t]
        prev = None
        for n in range(1000, n_steps + 1, 500):
            t_max = float(np.max(autocorr_time(x[n // 4:n])))
            if prev is not None:
                change = (t_max - prev) / t_max
                checks += 1
                two += not abs(change) < rtol
                one += not change < rtol
            prev = t_max
    return checks, two, one


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=40)
    a = ap.parse_args(argv)
    rtol = SamplerConfig().tau_rtol
    n, two, one = stationary(a.reps, rtol)
    print(f"stationary AR(1) chains (16 x 14 parameters, tau 11, checks every 500 steps, seed 0): "
          f"{n} checks; the tau condition (rtol {rtol}) fails at {two / n:.3f} two-sided, "
          f"{one / n:.3f} one-sided (ratio {two / max(one, 1):.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
