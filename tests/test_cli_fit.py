"""`frictionuq fit`: bad requests are refused before any sampling, with one line and exit 2.
(The sampling itself is covered by tests/test_infer_fit.py.)"""
from pathlib import Path

import pytest

from frictionuq.cli import main

TWIN = str(Path(__file__).resolve().parents[1] / "data" / "brfd-twin")


@pytest.mark.parametrize("extra,fragment", [
    (["--effect", "hump"], "unknown effect 'hump'"),
    (["--test", "no-such-test"], "no test 'no-such-test'; its tests: h-35N-0.05Hz, "),
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


@pytest.mark.parametrize("command, target", [
    ("fit", "frictionuq.infer.fit.fit_campaign"),
    ("compare", "frictionuq.infer.compare.compare_campaign"),
    ("discover", "frictionuq.discrepancy.discover.discover"),
])
def test_stored_run_option_reaches_the_sampler_config(tmp_path, monkeypatch, command, target):
    """--stored-run ensemble (or chains, the default) and --max-steps reach the SamplerConfig of
    the fit, compare and discover commands; the library call is replaced by a stub that records
    the configuration and stops."""
    import importlib

    class Stop(Exception):
        pass

    seen = []

    def stub(*args, **kw):
        cfgs = [a for a in list(args) + list(kw.values()) if hasattr(a, "sampler")]
        cfgs += [c for a in list(args) + list(kw.values()) if isinstance(a, dict)
                 for c in a.values() if hasattr(c, "sampler")]
        seen.extend(c.sampler for c in cfgs)
        raise Stop
    mod, name = target.rsplit(".", 1)
    monkeypatch.setattr(importlib.import_module(mod), name, stub)
    for extra, want in (([], "chains"), (["--stored-run", "ensemble"], "ensemble")):
        seen.clear()
        with pytest.raises(Stop):
            main([command, TWIN, "--out", str(tmp_path / "out"), "--max-steps", "7"] + extra)
        assert seen and all(s.stored_run == want and s.max_steps == 7 for s in seen), seen
