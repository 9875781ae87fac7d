"""frictionuq.tomlcheck: every refusal is one InputError line naming the file and the key."""
from __future__ import annotations

from pathlib import Path

import pytest

from frictionuq.errors import InputError
from frictionuq.tomlcheck import Checker

C = Checker(Path("w.toml"))


@pytest.mark.parametrize("call, message", [
    (lambda: C.table({"fit": 3}, "fit"), "w.toml: [fit]: must be a table, got int"),
    (lambda: C.unknown({"bye": 1}, {"by"}, "fit"), "w.toml: fit.bye: unknown key 'bye' (did you mean 'by'?); known: by"),
    (lambda: C.str_({}, "name", "workflow", required=True), "w.toml: workflow.name: missing (required)"),
    (lambda: C.str_({"by": "x"}, "by", "fit", choices=("applied", "test")),
     "w.toml: fit.by: must be one of applied, test, got 'x'"),
    (lambda: C.bool_({"enabled": 1}, "enabled", "law", True), "w.toml: law.enabled: must be true or false, got 1"),
    (lambda: C.num({"seed": True}, "seed", "workflow", integer=True), "w.toml: workflow.seed: must be an integer, got True"),
    (lambda: C.num({"x": float("nan")}, "x", "p"), "w.toml: p.x: must be a number, got nan"),
    (lambda: C.num({"x": 0}, "x", "p", positive=True), "w.toml: p.x: must be > 0, got 0"),
    (lambda: C.num({"x": 1}, "x", "p", minimum=2), "w.toml: p.x: must be >= 2, got 1"),
    (lambda: C.strings({"k": ["a", "a"]}, "k", "fit"), "w.toml: fit.k: lists an entry twice"),
    (lambda: C.strings({"k": ["a"]}, "k", "fit", choices=("b",)), "w.toml: fit.k: 'a' is not one of b"),
])
def test_refusals_name_the_file_and_key(call, message):
    with pytest.raises(InputError) as e:
        call()
    assert str(e.value) == message


def test_defaults_and_good_values_pass_through():
    assert C.str_({}, "title", "report", default="t") == "t"
    assert C.num({"n": 3}, "n", "predict", integer=True, positive=True) == 3
    assert C.num({}, "n", "predict", default=400) == 400
    assert C.strings({}, "tests", "fit") == []
    assert C.bool_({"enabled": False}, "enabled", "law", True) is False
