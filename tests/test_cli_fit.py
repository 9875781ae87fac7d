"""`frictionuq fit`: bad requests are refused before any sampling, with one line and exit 2.
(The sampling itself is covered by tests/test_infer_fit.py.)"""
from dataclasses import replace
from pathlib import Path

import pytest

from frictionuq.cli import main

TWIN = str(Path(__file__).resolve().parents[1] / "data" / "brfd-twin")


@pytest.mark.parametrize("extra,fragment", [
    (["--effect", "hump"], "unknown effect 'hump'"),
    (["--test", "no-such-test"], "no test 'no-such-test'; its tests: h-35N-0.05Hz, "),
    (["--test", "h-35N-0.05Hz", "--test", "h-35N-0.5hz"], "no test 'h-35N-0.5hz'; its tests: "),
    (["--temperatures", "3", "--stored-run", "ensemble"], "temperatures > 1 needs stored_run"),
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


def test_fit_refuses_an_out_folder_that_is_not_a_fit_folder_of_this_campaign(tmp_path, capsys):
    """--out holding other files (a prediction's, one's own notes) or another campaign's fits is
    refused before any work: a later `predict --out` there replaced the folder, fits and all
    (a new user's trial, 2026-12-05). A fit folder of this campaign, or one whose fit was
    interrupted before its first stored step, is accepted."""
    from frictionuq.infer.fit import _check_fit_folder
    from frictionuq.errors import InputError
    out = tmp_path / "out"
    (out / "applied-35N").mkdir(parents=True)
    _check_fit_folder(out, "brfd-twin")                    # an interrupted fit: kept
    (out / "applied-35N" / "chain.h5").write_bytes(b"")
    (out / "summary.json").write_text('{"campaign": "brfd-twin", "fits": []}')
    _check_fit_folder(out, "brfd-twin")
    with pytest.raises(InputError, match="holds fits of campaign 'brfd-twin', not 'other'"):
        _check_fit_folder(out, "other")
    (out / "prediction.json").write_text("{}")
    code = main(["fit", TWIN, "--out", str(out), "--test", "h-35N-0.05Hz"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "holds prediction.json, not a fit folder's; choose an empty or new folder" in err
    assert sorted(p.name for p in out.iterdir()) == ["applied-35N", "prediction.json", "summary.json"]


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


@pytest.mark.parametrize("text, want", [
    ("k2=1e5", ("k2", 1e5)),
    ("b_ch=uniform:0:1", ("b_ch", {"dist": "uniform", "lower": 0.0, "upper": 1.0})),
    (" v_s = loguniform:1e-4:0.01", ("v_s", {"dist": "loguniform", "lower": 1e-4, "upper": 0.01})),
    ("force_offset=normal:0:5", ("force_offset", {"dist": "normal", "mu": 0.0, "sd": 5.0})),
    ("fc_fwd=normal:300:30:100:900",
     ("fc_fwd", {"dist": "normal", "mu": 300.0, "sd": 30.0, "lower": 100.0, "upper": 900.0})),
])
def test_prior_option_syntax(text, want):
    from frictionuq.infer.priors import parse_prior_option
    assert parse_prior_option(text) == want


@pytest.mark.parametrize("extra, fragment", [
    (["--prior", "k2"], "--prior 'k2': no NAME="),
    (["--prior", "zz=1"], "unknown parameter 'zz'; the spec's names are fc_fwd, "),
    (["--prior", "k2=beta:1:2"], "unknown dist 'beta'"),
    (["--prior", "k2=uniform:1"], "uniform takes 2 numbers, got 1"),
    (["--prior", "k2=uniform:a:2"], "not a number"),
    (["--prior", "b_ch=0.5", "--prior", "b_ch=uniform:0:1"], "b_ch is given twice"),
    (["--prior", "k2=uniform:5:1"], "prior of 'k2': need 0 <= lower < upper"),
    (["--prior", "p2=-1"], "p2"),                      # an effect's: checked without the effect too
    (["--prior", "fs_fwd=normal:100:10"], "relative to fc_fwd"),
    (["--prior", "noise_phi=uniform:0:0.5"], "noise_phi is integrated out"),
])
@pytest.mark.parametrize("command", ["fit", "discover", "compare"])
def test_bad_prior_options_are_refused_before_any_file(tmp_path, capsys, command, extra, fragment):
    """One line, exit 2, and no output folder (every fit's priors are checked before the first
    fit, and before a fit's folder is made)."""
    out = tmp_path / "out"
    code = main([command, TWIN, "--out", str(out), "--test", "h-35N-0.05Hz", "--test",
                 "h-35N-0.5Hz", "--test", "h-53N-0.05Hz", "--test", "h-53N-0.5Hz"] + extra)
    err = capsys.readouterr().err.splitlines()
    assert code == 2, err
    assert len([ln for ln in err if ln.startswith("frictionuq: error:")]) == 1, err
    assert fragment in err[-1] and "Traceback" not in "\n".join(err), err
    assert not out.exists()


def _configs_seen(monkeypatch, target: str, argv: list[str]) -> list:
    """The FitConfigs the command line hands the library function `target` (stubbed: it stops
    the command at its call)."""
    import importlib
    seen = []

    class Stop(Exception):
        pass

    def stub(*args, **kw):
        for a in list(args) + list(kw.values()):
            seen.extend([a] if hasattr(a, "priors") else
                        [c for c in a.values() if hasattr(c, "priors")] if isinstance(a, dict) else [])
        raise Stop
    mod, name = target.rsplit(".", 1)
    monkeypatch.setattr(importlib.import_module(mod), name, stub)
    with pytest.raises(Stop):
        main(argv)
    return seen


@pytest.mark.parametrize("command, target", [
    ("fit", "frictionuq.infer.fit.fit_campaign"),
    ("discover", "frictionuq.discrepancy.discover.discover"),
    ("compare", "frictionuq.infer.compare.compare_campaign"),
])
def test_prior_options_reach_the_fit_config_and_its_space(tmp_path, monkeypatch, command, target):
    """--prior reaches FitConfig.priors of fit and discover (the library call is stubbed), and
    that config's space fixes k2, samples b_ch only with chatter and bounds sigma2 as given."""
    from frictionuq.campaign import load_campaign
    from frictionuq.infer.fit import build_space, plan
    from frictionuq.infer.priors import record_scales

    seen = _configs_seen(monkeypatch, target, [
        command, TWIN, "--out", str(tmp_path / "o"), "--prior", "k2=2e5", "--prior",
        "b_ch=uniform:0:1", "--prior", "sigma2=loguniform:10:1000"])
    cfg = seen[0]
    assert len(seen) == (2 if command == "compare" else 1)     # compare: three_stage and lugre
    assert all(c.priors == cfg.priors for c in seen) and cfg.priors == {"k2": 2e5, "b_ch": {"dist": "uniform", "lower": 0.0, "upper": 1.0},
                          "sigma2": {"dist": "loguniform", "lower": 10.0, "upper": 1000.0}}
    camp = load_campaign(TWIN)
    for effects in ((), ("chatter",)):
        spec = plan(camp, "applied", replace(cfg, effects=effects))[0]
        sp = build_space(spec, record_scales([t.record for t in spec.tests]))
        assert sp.fixed == {"k2": 2e5} and "k2" not in sp.names
        assert ("b_ch" in sp.names) == bool(effects)
        assert (sp.priors["sigma2"].lower, sp.priors["sigma2"].upper) == (10.0, 1000.0)
    lugre = plan(camp, "applied", replace(cfg, model="lugre"))[0]
    sp = build_space(lugre, record_scales([t.record for t in lugre.tests]))
    assert "k2" not in sp.fixed and "k2" not in sp.names    # no backlash, no k2 override


def test_a_relative_default_needs_both_bounds_to_be_overridden():
    """fs_fwd's default bounds are of fs_fwd/fc_fwd: an override giving both bounds is in N (the
    ratio dropped); one that keeps a default bound is refused (it would have read 0.9-1.35 N)."""
    from frictionuq.errors import InputError
    from frictionuq.infer.priors import Prior, apply_overrides
    base = {"fs_fwd": Prior("fs_fwd", "loguniform", 0.9, 1.35, ratio_of="fc_fwd")}
    pri, _ = apply_overrides(base, {"fs_fwd": {"dist": "uniform", "lower": 100.0, "upper": 400.0}})
    assert pri["fs_fwd"] == Prior("fs_fwd", "uniform", 100.0, 400.0)
    for partial in ({"dist": "normal", "mu": 200.0, "sd": 20.0}, {"upper": 400.0}):
        with pytest.raises(InputError, match="relative to fc_fwd"):
            apply_overrides(base, {"fs_fwd": partial})


@pytest.mark.slow
def test_ctrl_c_while_sampling_is_one_line_and_the_rerun_resumes(tmp_path):
    """SIGINT once the stored run is under way (its first progress line): exit 130, the CLI's one
    line, no traceback and none of emcee's parameter dump (before: about 90 lines); the same
    command again resumes from the stored steps."""
    import signal
    import subprocess
    import sys
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "frictionuq.cli", "fit", TWIN, "--out", str(out), "--test",
           "h-35N-0.5Hz", "--max-steps", "100000"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        if ": step " in line:           # the stored run has stored steps
            proc.send_signal(signal.SIGINT)
            break
    rest = proc.stderr.read()
    code = proc.wait(timeout=120)
    assert code == 130, rest
    assert "Traceback" not in rest and "emcee" not in rest, rest
    assert rest.strip().splitlines()[-1] == ("frictionuq: interrupted; finished outputs are kept, "
                                             "and the same command resumes a fit from its stored steps"), rest
    assert len(rest.strip().splitlines()) <= 3, rest
    again = subprocess.run(cmd[:-1] + ["10"], capture_output=True, text=True, timeout=300)
    assert "resuming from stored step" in again.stderr, again.stderr


def test_fit_says_which_posteriors_press_against_a_prior_bound(tmp_path, monkeypatch, capsys):
    """A posterior the prior cuts off (a new user's sigma0 on its data-derived lower bound, with
    an interval that looked confident) is named on the command line, not only in the report."""
    import importlib
    summary = {"campaign": "c", "fits": [
        {"id": "applied-500psi", "converged": False, "rmse": 17.0,
         "identifiability": {"at_prior_bound": {"sigma0": "lower"}}},
        {"id": "applied-1000psi", "converged": True, "rmse": 18.0,
         "identifiability": {"at_prior_bound": {}}}]}
    monkeypatch.setattr(importlib.import_module("frictionuq.infer.fit"), "fit_campaign",
                        lambda *a, **k: summary)
    assert main(["fit", TWIN, "--out", str(tmp_path / "out")]) == 1
    out = capsys.readouterr().out
    assert "note: applied-500psi: posterior pressed against a prior bound: sigma0 (lower)" in out
    assert "note: applied-1000psi" not in out


@pytest.mark.parametrize("command, target", [
    ("fit", "frictionuq.infer.fit.fit_campaign"),
    ("discover", "frictionuq.discrepancy.discover.discover"),
    ("compare", "frictionuq.infer.compare.compare_campaign"),
])
def test_force_offset_option_reaches_the_fit_config(tmp_path, monkeypatch, command, target):
    """--force-offset per_test reaches every FitConfig of fit, discover and compare (the library
    call stubbed); the default is one shared zero; a per-test config's space samples no
    force_offset and keeps its box instead."""
    from frictionuq.campaign import load_campaign
    from frictionuq.infer.fit import build_space, plan
    from frictionuq.infer.priors import record_scales
    for flag, want in (([], "shared"), (["--force-offset", "per_test"], "per_test")):
        seen = _configs_seen(monkeypatch, target, [command, TWIN, "--out", str(tmp_path / "o")] + flag)
        assert seen and all(c.force_offset == want for c in seen), seen
    spec = plan(load_campaign(TWIN), "applied", seen[0])[0]
    space = build_space(spec, record_scales([t.record for t in spec.tests]))
    assert "force_offset" not in space.names and space.offset_box[0] < 0 < space.offset_box[1]


def test_temperatures_option_reaches_the_sampler_config(tmp_path, monkeypatch):
    """--temperatures L reaches the FitConfig's sampler of fit (the library call stubbed); the
    default is no tempering."""
    for flag, want in (([], 1), (["--temperatures", "4"], 4)):
        seen = _configs_seen(monkeypatch, "frictionuq.infer.fit.fit_campaign",
                             ["fit", TWIN, "--out", str(tmp_path / "o")] + flag)
        assert seen and all(c.sampler.temperatures == want for c in seen), seen


@pytest.mark.parametrize("command, target", [
    ("fit", "frictionuq.infer.fit.fit_campaign"),
    ("discover", "frictionuq.discrepancy.discover.discover"),
    ("compare", "frictionuq.infer.compare.compare_campaign"),
])
def test_mode_search_option_reaches_the_sampler_config(tmp_path, monkeypatch, command, target):
    """--mode-search and --no-mode-search reach the sampler config of fit, discover and compare
    (the library call stubbed); the default is the config's own (None: search wherever the
    independence move runs)."""
    for flag, want in (([], None), (["--mode-search"], True), (["--no-mode-search"], False)):
        seen = _configs_seen(monkeypatch, target, [command, TWIN, "--out", str(tmp_path / "o")] + flag)
        assert seen and all(c.sampler.mode_search is want for c in seen), seen


def test_records_that_cannot_be_fitted_are_named(tmp_path, capsys):
    """A record too short for the displacement-noise estimate, and one whose force does not
    follow the motion (no sliding plateaus), are named in the one-line error (the test id and
    the fit), by `table` and `fit` (they were not until 2026-12-05)."""
    import numpy as np
    (tmp_path / "c" / "tests").mkdir(parents=True)
    for name, n in (("short", 12), ("z", 500)):
        t = np.arange(n) * 0.01
        x = 0.01 * np.sin(2 * np.pi * 0.5 * t)
        f = -1000.0 * np.sign(np.cos(2 * np.pi * 0.5 * t))     # against the motion's direction
        np.savetxt(tmp_path / "c" / "tests" / f"{name}.csv", np.column_stack([t, x, f]),
                   delimiter=",", header="time,displacement,force", comments="")
    (tmp_path / "c" / "campaign.toml").write_text(
        'name = "m"\n[units]\ntime = "s"\ndisplacement = "m"\nforce = "N"\napplied = "N"\n'
        '[[tests]]\nid = "short"\nfile = "tests/short.csv"\napplied = 10\n'
        '[[tests]]\nid = "z"\nfile = "tests/z.csv"\napplied = 20\n')
    for argv, fragment in (
            (["table", str(tmp_path / "c")], "test short: need at least 14 samples"),
            (["fit", str(tmp_path / "c"), "--out", str(tmp_path / "o"), "--test", "z"],
             "fit applied-20N: cannot derive priors: the records show no forward and backward "
             "sliding plateaus")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and fragment in err, err
    assert "none in test(s) z" in err and not (tmp_path / "o" / "summary.json").exists()


def test_fit_notes_priors_of_parameters_its_model_does_not_have(tmp_path, monkeypatch, capsys):
    """--prior k2=... with --model lugre (no backlash), or b_ch without chatter, is not applied
    (build_space), and fit says so instead of ignoring it silently (a new user's trial)."""
    from frictionuq.infer.fit import FitConfig, unused_parameters
    assert unused_parameters(FitConfig(model="lugre"), ["k2", "fc_fwd", "b_ch"]) == ["k2", "b_ch"]
    assert unused_parameters(FitConfig(effects=("chatter",)), ["k2", "b_ch"]) == []
    _configs_seen(monkeypatch, "frictionuq.infer.fit.fit_campaign",
                  ["fit", TWIN, "--out", str(tmp_path / "o"), "--model", "lugre", "--prior", "k2=2e5",
                   "--prior", "fc_fwd=uniform:1:1e5"])
    assert ("note: --prior k2: not a parameter of the lugre model: ignored"
            in capsys.readouterr().err)


def test_discover_says_when_its_refit_did_not_converge(tmp_path, monkeypatch, capsys):
    """A refit stopped at its step cap unconverged: the command says so and exits 1 (as fit and
    compare do), and the page warns above the intervals (before: they were printed and shown as
    any other, exit 0)."""
    import importlib
    import json
    out = tmp_path / "out"
    doc = {"package_version": "0.1.0", "campaign": "c", "seed": 1, "config": {},
           "named_effect": "reversal_hump", "named_effects": ["reversal_hump"], "reason": "test",
           "rounds": [], "candidates": [], "rmse_before": 30.0, "rmse_after": 20.0,
           "noise_scale": 20.0, "decision_rule": "rule", "seconds": 1.0,
           "seconds_by_stage": {"screening": 1.0, "refit": 0.0, "diagnostics": 0.0},
           "refit": [{"id": "applied-1200psi", "converged": False, "rmse": 20.0,
                      "effects": ["reversal_hump"]}],
           "effect_parameters": {"a_hump": {"mean": 0.45, "sd": 0.01, "q2.5": 0.44, "q97.5": 0.46,
                                            "unit": "1"}}}

    def fake(campaign, out_dir, cfg, **kw):
        Path(out_dir).mkdir()
        (Path(out_dir) / "discrepancy.json").write_text(json.dumps(doc))
        return doc
    monkeypatch.setattr(importlib.import_module("frictionuq.discrepancy.discover"), "discover", fake)
    assert main(["discover", TWIN, "--out", str(out)]) == 1
    printed = capsys.readouterr().out
    assert "not converged (R-hat > 1.01 or ESS < 400 for some parameter): the refit of " \
           "applied-1200psi" in printed
    page = (out / "report.html").read_text()
    assert "The refit did NOT converge (applied-1200psi" in page
