"""Numeric options every command shares: a negative seed, one beyond 64 bits, a step cap, a
process count or an effect count below 1, or fewer than 2 draws is refused by the parser, before
any work, with one line naming the option, exit 2, and nothing written (until 2026-12-05 the step
cap's, processes' and draws' lines named the library's field, "sampler: max_steps"). (Until
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
    (["fit", TWIN, "--max-steps", "0"], "argument --max-steps: takes an integer >= 1, got '0'"),
    (["fit", TWIN, "--max-steps", "-3"], "argument --max-steps: takes an integer >= 1, got '-3'"),
    (["fit", TWIN, "--jobs", "0"], "argument --jobs/-j: takes an integer >= 1, got '0'"),
    (["fit", TWIN, "--temperatures", "0"], "argument --temperatures: takes an integer >= 1, got '0'"),
    (["compare", TWIN, "--seed", "-2"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-2'"),
    (["compare", TWIN, "--max-steps", "0"], "argument --max-steps: takes an integer >= 1, got '0'"),
    (["discover", TWIN, "--seed", "-2"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-2'"),
    (["discover", TWIN, "--max-steps", "0"], "argument --max-steps: takes an integer >= 1, got '0'"),
    (["discover", TWIN, "--max-effects", "0"], "argument --max-effects: takes an integer >= 1, got '0'"),
    (["run", "WF", "-j", "0"], "argument -j/--jobs: takes an integer >= 1, got '0'"),
    (["predict", "FIT", "--harmonic", "0.01,1", "--applied", "36", "--seed", "-1"],
     "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
    (["validate", "FIT", TWIN, "--test", "x", "--seed", "-1"],
     "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
    (["validate", "FIT", TWIN, "--test", "x", "--draws", "1"],
     "argument --draws: takes an integer >= 2, got '1'"),
    (["predict", "FIT", "--harmonic", "0.01,1", "--applied", "36", "--draws", "x"],
     "argument --draws: takes an integer >= 2, got 'x'"),
    (["law", "FIT", "--seed", "-1"], "argument --seed: takes an integer from 0 to 9223372036854775807, got '-1'"),
])
def test_bad_numbers_are_refused_before_any_work(tmp_path, capsys, argv, fragment):
    out = tmp_path / "out"
    argv = [str(tmp_path / "fit") if a == "FIT" else a for a in argv]
    if argv[0] not in ("law", "run"):
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


@pytest.mark.parametrize("argv, fragment", [
    (["discover", TWIN, "--out", ""], "--out is empty; give the output folder's path"),
    (["discover", TWIN, "--out", "o", "--drive-lowpass", "-3"],
     "argument --drive-lowpass: takes 'auto', 'off' or a multiple > 0 (e.g. 20), got '-3'"),
    (["discover", TWIN, "--out", "o", "--extra-effect", "thermal_fade"],
     "extra effect 'thermal_fade' is in the spec's library, which is screened already"),
    (["fit", TWIN, "--out", "o", "--prior", "b_ch=uniform:1:0"],
     "need 0 <= lower < upper <= 1 (dimensionless), got [1, 0]"),
])
def test_discover_trial_messages(tmp_path, monkeypatch, capsys, argv, fragment):
    """Messages a new user's trial of discover found unclear (2026-12-05)."""
    monkeypatch.chdir(tmp_path)
    try:
        code = main(argv)
    except SystemExit as e:         # the parser's own refusal (an option's type)
        code = e.code
    assert code == 2
    err = capsys.readouterr().err
    assert fragment in err and "Traceback" not in err, err
    assert not (tmp_path / "o").exists()


def test_discover_notes_options_that_do_nothing(capsys):
    from frictionuq.cli.commands import _discover_notes, discover_config
    from frictionuq.cli.options import build_parser
    a = build_parser().parse_args(["discover", "c", "--out", "o", "--prior", "b_ch=uniform:0:1",
                                   "--no-refit", "--max-steps", "100", "--prior", "kappa=0.2"])
    assert _discover_notes(a, discover_config(a)) == [
        "--prior b_ch: its effect chatter is not screened (--extra-effect chatter screens it); "
        "the prior does nothing",
        "--max-steps: a setting of the refit's sampler, and --no-refit runs no refit: ignored"]
    a = build_parser().parse_args(["discover", "c", "--out", "o", "--prior", "b_ch=0.5",
                                   "--extra-effect", "chatter"])
    assert _discover_notes(a, discover_config(a)) == []
