"""The in-sample evidence hidden-effect campaigns carry, without running discover (issue 5, item
4): per campaign, the baseline's MAP as the screening finds it and the truth fit's gain over it
(discrepancy.truthfit: the baseline plus the hidden effect fitted from the generating values),
beside the decision rule's threshold for the effect (rule.min_gain). A draw whose truth fit stays
under the threshold leaves too little in the records for discover to name it at the rule's
false-alarm rate, whatever its search; the truth fit is a lower bound (a search can end higher),
so a draw over the threshold is one that a search can name. Not a test: figures only.

    .venv/bin/python benchmarks/bench_evidence.py [--effects stage2_nonlinear] [--devices brfd mfd]
        [--seeds 11 12 ...] [--rows ROWS.jsonl]

About 15-30 s per short campaign on one thread (the baseline's multi-start search is most of it).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from frictionuq import atomic
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits as F, rule
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.discrepancy.truthfit import truth_fit_gain
from frictionuq.infer.fit import FitConfig
from frictionuq.infer.optimize import find_map

from bench_discover import SHORT_SAMPLES_PER_CYCLE, refuse_bad_rows   # the CI cases' decimation


def evidence_row(campaign_dir: Path, device: str, effect: str, seed: int) -> dict:
    """One campaign's row: the hidden parameters, the baseline's MAP log-posterior (find_map with
    the screening's generator, rng [1, 17, 0], discover's seed 1) and the truth fit's gain."""
    t0 = time.perf_counter()
    ans = hidden_campaign(campaign_dir, device, effect, seed=seed, short=True)
    tests = list(load_campaign(campaign_dir).tests)
    cfg = FitConfig(samples_per_cycle=SHORT_SAMPLES_PER_CYCLE)
    lp0, scales = F.logpost_for(tests, (), cfg)
    th_b, lp_b, _ = find_map(lp0, scales, np.random.default_rng([1, 17, 0]), n_random=1, n_prior=1)
    o = truth_fit_gain(tests, cfg, ans, F.values(lp0.space, th_b), lp_b)
    return {"device": device, "effect": effect, "seed": seed, "parameters": ans["parameters"],
            "truth_fit_gain": o["gain"], "truth_fit_map": {n: o["map"][n] for n in ans["parameters"]},
            "min_gain": rule.min_gain(effect), "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--effects", nargs="+", default=["stage2_nonlinear"])
    ap.add_argument("--devices", nargs="+", default=["brfd", "mfd"])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11])
    ap.add_argument("--rows", type=Path, default=None, metavar="PATH",
                    help="also write the rows to PATH as JSON lines (rewritten after each campaign)")
    a = ap.parse_args(argv)
    refuse_bad_rows(ap, a.rows)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for dev in a.devices:
            for eff in a.effects:
                for seed in a.seeds:
                    r = evidence_row(Path(tmp) / f"{dev}-{eff}-{seed}", dev, eff, seed)
                    rows.append(r)
                    if a.rows is not None:
                        atomic.write_text(a.rows, "".join(json.dumps(x) + "\n" for x in rows))
                    par = ", ".join(f"{k} {v:.4g}" for k, v in r["parameters"].items())
                    print(f"{dev:<4} {eff} seed {seed:>3} ({par}): truth fit {r['truth_fit_gain']:+8.1f} "
                          f"nats over the baseline's MAP (needs {r['min_gain']:.3g}) "
                          f"{r['seconds']:5.1f} s", flush=True)
    for dev in a.devices:
        for eff in a.effects:
            g = [r["truth_fit_gain"] for r in rows if r["device"] == dev and r["effect"] == eff]
            over = sum(x >= rule.min_gain(eff) for x in g)
            print(f"{dev} {eff}: truth fit over the threshold in {over}/{len(g)} campaigns "
                  f"(min {min(g):+.1f}, median {float(np.median(g)):+.1f} nats)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
