"""How far apart do a candidate's MAP searches end on one level? The discrepancy screening's
answer rests on each candidate's maximum a posteriori point on all tests of the level
(discrepancy.candidate.candidate_map). This runs that search for each chosen effect and seed, and
after it more differential-evolution searches from their own Sobol populations (unseeded, on the
"kept" copies, as find_map's later runs), each refined by the screening's whitened least squares,
and prints each end's log-posterior gain over the baseline's MAP (nats) and its force RMSE (N):

    .venv/bin/python benchmarks/bench_search_spread.py data/brfd-arts-d1 \\
        --test sine-0.5Hz-20lb --test sine-1Hz-20lb \\
        --effect takeup_overshoot --effect eccentricity --seeds 1 2 --extra 3

The spread of the ends is how much of a real level's answer is the search's (docs/log-discrepancy.md,
2026-12-04). Figures only, not a test. Side by side, give each run one numba thread
(NUMBA_NUM_THREADS=1)."""
from __future__ import annotations

import argparse
import time

import numpy as np

from frictionuq import params as P
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits as F
from frictionuq.discrepancy.candidate import candidate_map
from frictionuq.errors import InputError
from frictionuq.infer.fit import FitConfig, plan
from frictionuq.infer.optimize import coarsened, find_map, global_start


def spread(tests, cfg: FitConfig, effect: str, seed: int, extra: int, base: dict) -> dict:
    """The candidate's search (the screening's, seeded as in round 1) and `extra` unseeded
    differential-evolution searches, each refined: their gains over base's MAP and RMSEs."""
    lp, scales = F.logpost_for(tests, (effect,), cfg)
    t0 = time.perf_counter()
    th, lp_c = candidate_map(lp, base, np.random.default_rng([seed, 17, 1]), scales)
    ends = [("screening's search", lp_c - base["log_prob"], F.rmse(lp, th),
             time.perf_counter() - t0)]
    ranked = coarsened(lp, simulate="kept")
    rng = np.random.default_rng([seed, 23, 1])
    for k in range(extra):
        t0 = time.perf_counter()
        th_g, gens = global_start(ranked, None, rng)
        th_r = F.white_fit(lp, th_g, rounds=3)
        ends.append((f"extra search {k + 1} ({gens} gen.)", F.log_prob(lp, th_r) - base["log_prob"],
                     F.rmse(lp, th_r), time.perf_counter() - t0))
    return {"effect": effect, "seed": seed, "ends": ends}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("campaign")
    ap.add_argument("--test", action="append", required=True, help="a test of the level (repeat)")
    ap.add_argument("--effect", action="append", required=True, help="a candidate effect (repeat)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--extra", type=int, default=3, help="unseeded searches after the screening's")
    ap.add_argument("--samples-per-cycle", type=float, default=None,
                    help="the fits' decimation (default: FitConfig's, as `frictionuq discover`)")
    a = ap.parse_args(argv)
    unknown = [e for e in a.effect if e not in P.EFFECTS]
    if unknown:
        ap.error(f"--effect {unknown[0]!r}: not an effect; known: {', '.join(P.EFFECTS)}")
    rate = {"samples_per_cycle": a.samples_per_cycle} if a.samples_per_cycle else {}
    cfg = FitConfig(tests=tuple(a.test), **rate)
    try:
        specs = plan(load_campaign(a.campaign), "applied", cfg)
    except InputError as e:
        ap.error(str(e))
    if len(specs) != 1:
        ap.error(f"the tests {a.test} span {len(specs)} applied forces; give one level's tests")
    tests = specs[0].tests
    print(f"level {specs[0].id}: {', '.join(t.id for t in tests)}")
    for seed in a.seeds:
        lp, scales = F.logpost_for(tests, (), cfg)
        t0 = time.perf_counter()
        th, lpmap, info = find_map(lp, scales, np.random.default_rng([seed, 17, 0]),
                                   n_random=1, n_prior=1)
        base = {"space": lp.space, "all": th, "log_prob": lpmap,
                "global_points": info.get("global_points", [])}
        print(f"seed {seed}: baseline MAP {lpmap:.1f} nats, RMSE {F.rmse(lp, th):.4g} N "
              f"({time.perf_counter() - t0:.0f} s)", flush=True)
        for e in a.effect:
            r = spread(tests, cfg, e, seed, a.extra, base)
            gains = [g for _, g, _, _ in r["ends"]]
            print(f"  {e}: best {max(gains):+.1f} nats, spread {max(gains) - min(gains):.1f} nats")
            for what, g, rmse, secs in r["ends"]:
                print(f"    {what:28s} {g:+9.1f} nats  RMSE {rmse:8.4g} N  {secs:5.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
