"""The stopping rule's tau condition, one-sided (the rule since 2026-12-06) against two-sided (the
rule before), side by side in one run (issue 3, item 3).

    .venv/bin/python benchmarks/bench_tau_rule.py [FIT_DIR/<fit id> ...] [--reps 40]

1. Stationary chains: `--reps` sets of 16 independent AR(1) chains (tau 11 steps, 14 parameters,
   6,000 steps, seeded), checked as the sampler checks (every 500 steps from 1,000, the first
   quarter discarded, emcee's integrated time, its max over the parameters): the fraction of
   checks at which each form of the tau condition fails, though nothing is unconverged. Every
   such failure costs a converging fit at least one 500-step chunk under the two-check rule.
2. Stored fits (each argument a fit folder: fit.json and chain.h5, e.g. one run with
   min_steps = max_steps): the full rule replayed under each form (convergence.check on the
   summary's values, as benchmarks/replay_stop.py), printing each check and the step each form
   stops at with the fit's confirm_checks. No model evaluations.
"""
from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import emcee
import numpy as np

from frictionuq.infer.convergence import check
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.infer.space import Space


def tau_ok(tau: float, prev: float | None, rtol: float, two_sided: bool) -> bool:
    if prev is None:
        return False
    change = (tau - prev) / tau
    return (abs(change) if two_sided else change) < rtol


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
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                t_max = float(np.max(emcee.autocorr.integrated_time(x[n // 4:n], quiet=True, tol=0)))
            if prev is not None:
                checks += 1
                two += not tau_ok(t_max, prev, rtol, True)
                one += not tau_ok(t_max, prev, rtol, False)
            prev = t_max
    return checks, two, one


def replay_both(fdir: Path) -> None:
    rec = json.loads((fdir / "fit.json").read_text())
    stored = {k: v for k, v in rec["config"]["sampler"].items()
              if k in SamplerConfig.__dataclass_fields__}
    cfg = SamplerConfig(**{**stored, "min_steps": SamplerConfig().min_steps, "progress": False})
    chain = emcee.backends.HDFBackend(str(fdir / "chain.h5"), read_only=True).get_chain()
    space = Space.from_json(rec["space"])
    prev, runs, stops, lines = None, {True: 0, False: 0}, {True: None, False: None}, []
    for n in range(cfg.chunk, chain.shape[0] + 1, cfg.chunk):
        if n < cfg.min_steps:
            continue
        burn = int(n * cfg.discard_fraction)
        c = check(chain[burn:n], cfg, space)
        rest = (n - burn > cfg.tau_factor * c["tau_max"] and c["r_hat_max"] <= cfg.r_hat_max
                and c["ess_min"] >= cfg.ess_min)
        met = {}
        for two_sided in (True, False):
            met[two_sided] = rest and tau_ok(c["tau_max"], prev, cfg.tau_rtol, two_sided)
            runs[two_sided] = runs[two_sided] + 1 if met[two_sided] else 0
            if stops[two_sided] is None and runs[two_sided] >= cfg.confirm_checks:
                stops[two_sided] = n
        prev = c["tau_max"]
        lines.append(f"  step {n:6d}: max tau {c['tau_max']:6.1f}, R-hat max {c['r_hat_max']:.4f}, "
                     f"ESS min {c['ess_min']:6.0f}; rule two-sided {'held' if met[True] else '-':4s} "
                     f"one-sided {'held' if met[False] else '-'}")
    print(f"== {fdir} ({chain.shape[0]} stored steps, {chain.shape[1]} chains; confirm_checks "
          f"{cfg.confirm_checks}): stops at two-sided {stops[True] or 'none'}, one-sided "
          f"{stops[False] or 'none'}")
    print("\n".join(lines))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fits", nargs="*", type=Path, help="fit folders (fit.json, chain.h5)")
    ap.add_argument("--reps", type=int, default=40)
    a = ap.parse_args(argv)
    rtol = SamplerConfig().tau_rtol
    n, two, one = stationary(a.reps, rtol)
    print(f"stationary AR(1) chains (16 x 14 parameters, tau 11, checks every 500 steps, seed 0): "
          f"{n} checks; the tau condition (rtol {rtol}) fails at {two / n:.3f} two-sided, "
          f"{one / n:.3f} one-sided (ratio {two / max(one, 1):.2f})")
    for f in a.fits:
        replay_both(f)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
