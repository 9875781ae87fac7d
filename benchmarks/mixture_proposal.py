"""Experiment (not the package's sampler): a fit whose stored run proposes from a two-component
mixture, the burn-in's independence proposal and a second one fitted to another fit's states in
a region of one parameter (docs/log-calibration.md, 2026-12-06, evening: dataset 2's second d3
mode, where the default proposal lets chains stick).

    .venv/bin/python benchmarks/mixture_proposal.py --from FIT/applied-36lb --param d3
        --above 6.1e-3 --out DIR [--weight 0.1] [--max-steps 6000] [--case arts-d2] [--seed 1]

--from: a fit folder (chain.h5, fit.json) whose cold chains visited the region, e.g. a run with
`--temperatures 4`; the second component is `Proposal.fit` of its stored states (from step 200)
with PARAM above the value (SI). The new fit is bench_fit.py's case (default arts-d2, the ten
36 lb sines) at the CLI's defaults but the step cap. The mixture's density is the exact one of
the two normalised t's (proposal.MixtureMove, the move of `--mode-search`); the stored run's
other move (the random walk) is unchanged. The second component comes from an earlier run: an
oracle, against which the package's own search (SamplerConfig.mode_search) can be compared.
"""
from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

import frictionuq.infer.sampler as sampler_module
from bench_fit import CASES
from chain_modes import cold_states
from frictionuq.infer.fit import FitConfig, fit_campaign
from frictionuq.infer.proposal import Proposal
from frictionuq.infer.sampler import SamplerConfig


def second_component(fit: Path, param: str, above: float) -> tuple[Proposal, int]:
    j, edge, chain, _, _, _ = cold_states(fit, param, above, start=200)
    x = chain.reshape(-1, chain.shape[2])
    pool = x[x[:, j] > edge]
    return Proposal.fit(pool), len(pool)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from", dest="source", required=True)
    ap.add_argument("--param", required=True)
    ap.add_argument("--above", type=float, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--weight", type=float, default=0.1)
    ap.add_argument("--max-steps", type=int, default=6000)
    ap.add_argument("--case", choices=sorted(CASES), default="arts-d2")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args(argv)
    p2, n_pool = second_component(Path(a.source), a.param, a.above)
    print(f"second component: Proposal.fit of {n_pool} states with {a.param} > {a.above:g}, "
          f"weight {a.weight:g}", flush=True)
    default_moves = sampler_module.moves_for

    def moves_for(cfg, proposal=None, stored=False):
        if stored and proposal is not None:        # the package's mixture move (infer.modes)
            proposal = replace(proposal, modes=(p2,), mode_weight=a.weight)
        return default_moves(cfg, proposal, stored)
    sampler_module.moves_for = moves_for         # the stored run's moves only (sampler.run)
    path, sel, _ = CASES[a.case]
    cfg = FitConfig(tests=sel.get("tests"), sampler=SamplerConfig(max_steps=a.max_steps), seed=a.seed)
    t0 = time.perf_counter()
    s = fit_campaign(path, Path(a.out), by="applied", config=cfg,
                     log=lambda m: print(f"[{time.perf_counter() - t0:6.0f} s] {m}", flush=True))
    for f in s["fits"]:
        print(f"{f['id']}: converged {f['converged']}, {f['sampler_steps']} stored steps, tau "
              f"{f['tau_max']:.1f}, {f['model_evaluations']} evaluations, {f['seconds']:.0f} s")


if __name__ == "__main__":
    main()
