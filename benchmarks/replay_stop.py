"""The stopping rule replayed on stored chains (issue 3, item 3): where a fit run past its stop
would have stopped under each number of confirming checks.

    .venv/bin/python benchmarks/replay_stop.py FIT_DIR/<fit id> [...] [--confirm 1 2 3]
        [--min-steps N]

Each argument is one fit's folder (fit.json and chain.h5, e.g. a fit run with min_steps =
max_steps so that it never stopped early). The checks are the sampler's own
(frictionuq.infer.convergence.replay, on the parameter values the summary reports), every
`chunk` steps of the fit's sampler configuration, from --min-steps (default the sampler's
default, 1,000; the fit's own min_steps is that of the long run). It prints every check (max tau, R-hat max,
ESS min, rule held) and, per `confirm_checks`, the first step the run would have stopped at and
whether the rule still held at the checks after it (a stop the longer chain does not confirm is
premature). No model evaluations: seconds per fit.

Beside each check it also gives the verdict of the two-sided tau condition used until
2026-12-06 (a fall of max tau by `tau_rtol` failed a check too; convergence.rule_met), and the
step that rule would have stopped at: the current rule and the old one side by side.
"""
from __future__ import annotations

import argparse
import json
from pathlib import Path

import emcee

from frictionuq.infer.convergence import replay
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.infer.space import Space


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("fits", nargs="+", help="fit folders (fit.json, chain.h5)")
    ap.add_argument("--confirm", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--min-steps", type=int, default=SamplerConfig().min_steps)
    args = ap.parse_args(argv)
    for fdir in map(Path, args.fits):
        rec = json.loads((fdir / "fit.json").read_text())
        stored = {k: v for k, v in rec["config"]["sampler"].items()
                  if k in SamplerConfig.__dataclass_fields__}
        cfg = SamplerConfig(**{**stored, "min_steps": args.min_steps, "progress": False})
        chain = emcee.backends.HDFBackend(str(fdir / "chain.h5"), read_only=True).get_chain()
        rows = replay(chain, cfg, Space.from_json(rec["space"]))
        old = two_sided(rows, cfg)
        print(f"== {fdir} ({chain.shape[0]} stored steps, {chain.shape[1]} chains)")
        for r, o in zip(rows, old):
            print(f"  step {r['steps']:6d}: max tau {r['tau_max']:6.1f} steps, R-hat max "
                  f"{r['r_hat_max']:.4f}, ESS min {r['ess_min']:6.0f}, rule "
                  f"{'held' if r['rule_met'] else '-':4s} (two-sided: {'held' if o else '-'})")
        for k in args.confirm:
            stop = next((i for i, r in enumerate(rows) if r["in_a_row"] >= k), None)
            if stop is None:
                print(f"  confirm_checks {k}: no stop within {chain.shape[0]} steps")
                continue
            after = [r["rule_met"] for r in rows[stop + 1:]]
            print(f"  confirm_checks {k}: stops at step {rows[stop]['steps']}; the rule held at "
                  f"{sum(after)} of the {len(after)} later checks")
        k = cfg.confirm_checks
        stop_old = next((r["steps"] for i, r in enumerate(rows)
                         if i + 1 >= k and all(old[i + 1 - k:i + 1])), None)
        print(f"  confirm_checks {k}, two-sided tau condition (before 2026-12-06): "
              + (f"stops at step {stop_old}" if stop_old else f"no stop within {chain.shape[0]} steps"))


def two_sided(rows: list[dict], cfg) -> list[bool]:
    """The old rule's verdict at each replayed check: the current one (a tau grown by tau_rtol
    fails) and max tau not fallen by tau_rtol since the check before."""
    return [r["rule_met"] and (p["tau_max"] - r["tau_max"]) / r["tau_max"] < cfg.tau_rtol
            for p, r in zip([rows[0]] + rows[:-1], rows)]


if __name__ == "__main__":
    main()
