"""How much does simulating a decimated record on its decimated displacement cost the truth?

    .venv/bin/python benchmarks/decimation_bias.py [--levels 35 53 133] [--campaign data/brfd-twin]

For every harmonic test of the BRFD twin at the given applied forces (N), with the fit's default
decimation, it evaluates the published parameters (force_offset 0) three ways and prints the
simulated force's RMS difference from the reference, in units of the residual noise sd, and the
log-likelihood (AR(1), noise integrated out) relative to the reference:
  * `raw`     (the reference, infer.likelihood simulate_at="raw"): simulated on the raw 100 Hz
              record, then anti-alias filtered and decimated exactly like the measured force;
  * `kept`    (simulate_at="kept"): simulated on the decimated displacement;
  * `sampled` the raw-rate simulation sampled every q-th sample without filtering (separates the
              time-step effect from the filter's smoothing).
Not a test: figures only. The twin is generated at 100 Hz by the spec's discrete-time model, so
`raw` is what produced the data up to noise.
"""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from frictionuq.campaign import load_campaign
from frictionuq.infer import noisemodel
from frictionuq.infer.fit import FitConfig, plan, prepare
from frictionuq.published import published_params

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--levels", type=float, nargs="+", default=[35.0, 53.0, 133.0])
    ap.add_argument("--campaign", default=str(ROOT / "data/brfd-twin"))
    a = ap.parse_args(argv)
    camp = load_campaign(a.campaign)
    print(f"{'test':<16} {'q':>2} {'noise sd N':>10} {'scheme':<8} {'RMS dF / sd':>11} {'dlogL nats':>10}")
    for level in a.levels:
        ids = tuple(t.id for t in camp.tests if t.applied == level and t.kind == "harmonic")
        base = FitConfig(tests=ids)
        lps = {}
        for at in ("raw", "kept"):
            spec = plan(camp, "applied", replace(base, simulate_at=at))[0]
            _, _, space, lps[at] = prepare(spec)
        truth = dict(published_params("brfd", level), force_offset=0.0)
        th = space.to_theta(truth)[None]
        for j, rec in enumerate(lps["raw"].records):
            ref = lps["raw"].simulate(th, rec)[0]
            e_ref = rec.y - ref
            sd = float(np.std(e_ref))
            ll_ref = noisemodel.log_marginal(e_ref[None], **lps["raw"].noise)[0]
            rows = {"raw": ref, "kept": lps["kept"].simulate(th, lps["kept"].records[j])[0]}
            if rec.sim_drive is not None:
                full = replace(rec, q=1, sim_drive=None, drive=rec.sim_drive)
                rows["sampled"] = lps["raw"].simulate(th, full)[0][:: rec.q][: rec.n]
            for name, F in rows.items():
                rms = float(np.sqrt(np.mean((F - ref) ** 2))) / sd
                dll = noisemodel.log_marginal((rec.y - F)[None], **lps["raw"].noise)[0] - ll_ref
                print(f"{rec.id:<16} {rec.q:>2} {sd:>10.3f} {name:<8} {rms:>11.3f} {dll:>10.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
