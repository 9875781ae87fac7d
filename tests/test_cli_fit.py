"""`frictionuq fit`: bad requests are refused before any sampling, with one line and exit 2.
(The sampling itself is covered by tests/test_infer_fit.py.)"""
from pathlib import Path

import pytest

from frictionuq.cli import main

TWIN = str(Path(__file__).resolve().parents[1] / "data" / "brfd-twin")


@pytest.mark.parametrize("extra,fragment", [
    (["--effect", "hump"], "unknown effect 'hump'"),
    (["--test", "no-such-test"], "no test matches"),
    (["--jobs", "0"], "jobs must be an integer >= 1, got 0"),
    (["--effect", "applied_tracking", "--test", "h-267N-0.5Hz", "--model", "lugre", "--effect", "stage2_nonlinear"],
     "stage2_nonlinear"),
])
def test_fit_refuses(tmp_path, capsys, extra, fragment):
    out = tmp_path / "out"
    code = main(["fit", TWIN, "--out", str(out)] + extra)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and fragment in err, err
    assert not (out / "summary.json").exists()
