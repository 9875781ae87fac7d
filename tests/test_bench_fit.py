"""benchmarks/bench_fit.py's own code that runs before any fit: the output folder of each
configuration. From a9b5461 until this test came, the folder was built as Path + str, a TypeError
on every run before its first fit."""
from __future__ import annotations

import importlib.util
from itertools import product
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench_fit():
    spec = importlib.util.spec_from_file_location("bench_fit", ROOT / "benchmarks" / "bench_fit.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_every_configuration_gets_its_own_folder(tmp_path):
    bf = _bench_fit()
    names = set()
    for combo in product(["twin", "arts-d1"], ["raw", "kept"], ["chains", "ensemble"], [1, 2],
                         ["shared", "per_test"], [1, 3], [None, 150.0], [1, 2], [False, True]):
        name = bf.run_name(*combo)
        folder = tmp_path / name
        assert folder.parent == tmp_path and "/" not in name
        names.add(name)
    assert len(names) == 2 ** 9
    assert bf.run_name("arts-d1", "raw", "chains", 1, "shared", 1, 150.0).endswith("-spc150")


def test_the_target_is_met_only_when_every_fit_converged_in_time():
    bf = _bench_fit()
    row = ("applied-267N", 30.0, 1000, 500.0, 1.005, True, 1500, 10.0)
    fast_unconverged = {"wall": 34.0, "target": 120.0, "rows": [row[:5] + (False,) + row[6:]]}
    assert bf.target_verdict(fast_unconverged) == "NOT met (0 of 1 fits converged)"
    assert bf.target_verdict({"wall": 34.0, "target": 120.0, "rows": [row]}) == "met"
    assert bf.target_verdict({"wall": 130.0, "target": 120.0, "rows": [row]}) == "NOT met"
