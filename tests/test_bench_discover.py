"""benchmarks/bench_discover.py's configurations: the speed case (--full) runs what `frictionuq
discover CAMPAIGN --out DIR` runs, and the short campaigns what the CI's end-to-end cases run
(tests/discover_check.py). Until 2026-12-04 --full ran the short campaigns' 100 samples per cycle
and a 3,000-step cap, under which the refit mostly stopped unconverged: the speed figure was not the
user's."""
from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench_discover():
    sys.path.insert(0, str(ROOT / "benchmarks"))       # it imports bench_fit's SAMPLERS
    try:
        spec = importlib.util.spec_from_file_location("bench_discover",
                                                      ROOT / "benchmarks" / "bench_discover.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return mod


def _quiet(cfg):
    return replace(cfg, sampler=replace(cfg.sampler, progress=False)).to_json()


def test_the_speed_case_runs_the_clis_configuration():
    from frictionuq.cli.commands import discover_config
    from frictionuq.cli.options import build_parser
    bd = _bench_discover()
    cli = discover_config(build_parser().parse_args(["discover", "camp", "--out", "out"]))
    full = bd.bench_config(True, None, None, "raw", bd.SAMPLERS["chains"])
    assert full.to_json() == _quiet(cli)
    # the options still override it
    assert bd.bench_config(True, 100.0, 3000, "raw", {}).samples_per_cycle == 100.0
    assert bd.bench_config(True, 100.0, 3000, "raw", {}).sampler.max_steps == 3000


def test_the_short_campaigns_run_the_ci_cases_configuration():
    from frictionuq.infer.fit import FitConfig
    from frictionuq.infer.sampler import SamplerConfig
    bd = _bench_discover()
    short = bd.bench_config(False, None, None, "raw", bd.SAMPLERS["chains"])
    # tests/discover_check.py's configuration
    ci = FitConfig(samples_per_cycle=100, sampler=SamplerConfig(max_steps=3000, progress=False))
    assert short.to_json() == ci.to_json()
