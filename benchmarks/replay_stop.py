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
        print(f"== {fdir} ({chain.shape[0]} stored steps, {chain.shape[1]} chains)")
        for r in rows:
            print(f"  step {r['steps']:6d}: max tau {r['tau_max']:6.1f} steps, R-hat max "
                  f"{r['r_hat_max']:.4f}, ESS min {r['ess_min']:6.0f}, rule "
                  f"{'held' if r['rule_met'] else '-'}")
        for k in args.confirm:
            stop = next((i for i, r in enumerate(rows) if r["in_a_row"] >= k), None)
            if stop is None:
                print(f"  confirm_checks {k}: no stop within {chain.shape[0]} steps")
                continue
            after = [r["rule_met"] for r in rows[stop + 1:]]
            print(f"  confirm_checks {k}: stops at step {rows[stop]['steps']}; the rule held at "
                  f"{sum(after)} of the {len(after)} later checks")


if __name__ == "__main__":
    main()
