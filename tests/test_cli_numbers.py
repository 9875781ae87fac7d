"""Numeric options every command shares: a negative seed, one beyond 64 bits or a step cap
below 1 is refused before any work, with one line naming the option, exit 2, and nothing written. (Until
2026-11-27 `--max-steps 0` fell back silently to the default cap of 100,000 steps, and a
negative seed failed inside numpy, after the fit had started, with "expected non-negative
integer"; a seed of 2**64 or more passed until 2026-12-05 and failed when the chain's HDF5
file stored it.)"""
from pathlib import Path

import pytest

from frictionuq.cli import main
from frictionuq.errors import InputError
from frictionuq.infer.sampler import SamplerConfig

TWIN = str(Path(__file__).resolve().parents[1] / "data" / "brfd-twin")


@pytest.mark.parametrize("argv,fragment", [
    (["fit", TWIN, "--seed", "-1"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
    (["fit", TWIN, "--seed", str(2**64)], "argument --seed: takes an integer from 0 to 9223372036854775807, got '18446744073709551616'"),
    (["discover", TWIN, "--check-seed", "-4"], "argument --check-seed: takes an integer from 0"),
    (["fit", TWIN, "--max-steps", "0"], "sampler: max_steps must be an integer >= 1, got 0"),
    (["fit", TWIN, "--max-steps", "-3"], "max_steps must be an integer >= 1, got -3"),
    (["compare", TWIN, "--seed", "-2"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-2'"),
    (["compare", TWIN, "--max-steps", "0"], "max_steps must be an integer >= 1, got 0"),
    (["discover", TWIN, "--seed", "-2"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-2'"),
    (["discover", TWIN, "--max-steps", "0"], "max_steps must be an integer >= 1, got 0"),
    (["predict", "FIT", "--harmonic", "0.01,1", "--applied", "36", "--seed", "-1"],
     "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
    (["validate", "FIT", TWIN, "--test", "x", "--seed", "-1"],
     "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
    (["validate", "FIT", TWIN, "--test", "x", "--draws", "1"],
     "validate: number of draws must be an integer >= 2, got 1"),
    (["law", "FIT", "--seed", "-1"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
])
def test_bad_numbers_are_refused_before_any_work(tmp_path, capsys, argv, fragment):
    out = tmp_path / "out"
    argv = [str(tmp_path / "fit") if a == "FIT" else a for a in argv]
    if argv[0] not in ("law",):
        argv += ["--out", str(out)]
    try:
        code = main(argv)
    except SystemExit as e:         # the parser's own refusal (an option's type, e.g. --seed)
        code = e.code
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and fragment in err, err
    assert not out.exists()


@pytest.mark.parametrize("field,value", [("max_steps", 0), ("chunk", -1), ("min_steps", 1.5),
                                         ("nwalkers", 0), ("n_global_starts", -1),
                                         ("r_hat_max", float("nan")), ("tau_factor", 0.0),
                                         ("discard_fraction", 1.0), ("max_steps", True)])
def test_sampler_config_refuses_unusable_settings(field, value):
    with pytest.raises(InputError, match=f"sampler: {field} must be"):
        SamplerConfig(**{field: value})


def test_sampler_config_accepts_the_defaults_and_the_optional_nones():
    SamplerConfig()
    SamplerConfig(nwalkers=40, de_gamma=None, thin_output=None, progress=False, n_random_starts=0)
