"""discrepancy/gap.py: the gap before and after (discover's last stage). Made in worker
processes it must be the serial stage: the same diagnostics, p-values and figures, in order."""
from __future__ import annotations

import json

import pytest

from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits
from frictionuq.discrepancy.gap import combined, level_gap
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.infer.fit import FitConfig, plan
from frictionuq.workers import Workers


@pytest.mark.slow
def test_the_gap_made_in_two_processes_is_the_serial_one(tmp_path):
    hidden_campaign(tmp_path / "c", "brfd", "thermal_fade", seed=11, short=True)
    cfg = FitConfig(samples_per_cycle=100, seed=1)
    tests = plan(load_campaign(tmp_path / "c"), "applied", cfg)[0].tests
    # two points, not fits: the stage only reads the models' forces at them
    maps = {}
    for eff in ((), ("thermal_fade",)):
        lp, _ = fits.logpost_for(tests, eff, cfg)
        maps[eff] = fits.values(lp.space, 0.5 * (lp.space.lo + lp.space.hi))
    docs, files = {}, {}
    for jobs in (1, 2):
        out = tmp_path / f"out{jobs}"
        out.mkdir()
        with Workers(jobs) as w:
            docs[jobs] = level_gap(tests, cfg, maps[()], ["thermal_fade"], maps[("thermal_fade",)],
                                   1, out, lambda m: None, w)
        files[jobs] = {f.name: f.read_bytes() for f in sorted(out.iterdir())}
    # every test under both models, in the serial order, with its residual and loops figures
    ids = [t.id for t in tests]
    assert [(g["model"], g["test"]) for g in docs[1]] == \
        [(m, t) for m in ("baseline", "with thermal_fade") for t in ids]
    assert len(files[1]) == 3 * len(ids) and all(len(b) > 10_000 for b in files[1].values())
    assert json.dumps(docs[2], sort_keys=True, default=str) == \
        json.dumps(docs[1], sort_keys=True, default=str)
    assert files[2] == files[1]
    # each test its own permutation seed (combine.py needs independent p-values)
    seeds = [g["diagnostics"]["seed"] for g in docs[1] if g["model"] == "baseline"]
    assert len(set(seeds)) == len(ids)
    assert [c["model"] for c in (combined("L", docs[1], lambda m: None))] == \
        ["baseline", "with thermal_fade"]
