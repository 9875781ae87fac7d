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
the two normalised t's; the stored run's other move (the random walk) is unchanged. The second
component comes from an earlier run, so this tests the remedy, it is not one the package could
run on its own.
"""
from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import emcee
import numpy as np
from scipy.special import gammaln

import frictionuq.infer.sampler as sampler_module
from bench_fit import CASES
from chain_modes import cold_states
from frictionuq.infer.fit import FitConfig, fit_campaign
from frictionuq.infer.proposal import IndependenceMove, Proposal
from frictionuq.infer.sampler import SamplerConfig


def log_norm(move: IndependenceMove) -> float:
    """The constant that IndependenceMove._logq leaves out: the t's normalisation."""
    d = move.p.mean.size
    return (gammaln(0.5 * (move.df + d)) - gammaln(0.5 * move.df) - 0.5 * d * math.log(move.df * math.pi)
            - float(np.sum(np.log(np.diag(move.L)))))


class MixtureMove(emcee.moves.MHMove):
    """Independence Metropolis-Hastings from (1 - w) q1 + w q2, both fixed."""

    def __init__(self, p1: Proposal, p2: Proposal, w: float):
        self.m = [IndependenceMove(p1), IndependenceMove(p2)]
        self.lw = [math.log1p(-w) + log_norm(self.m[0]), math.log(w) + log_norm(self.m[1])]
        self.w = w
        super().__init__(self._propose, ndim=p1.mean.size)

    def logq(self, x):
        return np.logaddexp(self.lw[0] + self.m[0]._logq(x), self.lw[1] + self.m[1]._logq(x))

    def _propose(self, x0, random):
        pick = random.random(x0.shape[0]) < self.w
        x = np.where(pick[:, None], self.m[1]._propose(x0, random)[0], self.m[0]._propose(x0, random)[0])
        return x, self.logq(x0) - self.logq(x)


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
        moves = default_moves(cfg, proposal, stored)
        if stored and proposal is not None:
            moves = [(MixtureMove(proposal, p2, a.weight), w) if isinstance(m, IndependenceMove)
                     else (m, w) for m, w in moves]
        return moves
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
