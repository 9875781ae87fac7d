"""Workflow files: the shipped ones load and plan; unknown keys and bad values are refused with
the file, the key and the problem (exit code 2 in the CLI, one line, no traceback)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from frictionuq.errors import InputError
from frictionuq.pipeline import plan
from frictionuq.workflow import load_workflow

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "workflows").glob("*.toml"))

BASE = """
[workflow]
name = "t"
campaign = "{campaign}"

[fit]
tests = ["sine-2Hz-36lb-0.5in"]
"""


def _write(tmp_path, extra: str = "", base: str = BASE) -> Path:
    p = tmp_path / "wf.toml"
    p.write_text(base.format(campaign=ROOT / "data" / "brfd-arts-d2") + extra)
    return p


def test_the_shipped_workflows_load_and_plan():
    names = {p.stem for p in SHIPPED}
    assert {"quick", "brfd-arts", "brfd-twin", "mfd-twin"} <= names
    for p in SHIPPED:
        wf = load_workflow(p)
        assert wf.name == p.stem
        tasks = plan(wf)
        assert "ingest" in tasks and "fit/summary" in tasks and "report" in tasks
        assert any(t.stage == "fit" and t.heavy for t in tasks.values())
        assert wf.out.name == wf.name and wf.report_dir.name == wf.name


def test_defaults_are_filled_in(tmp_path):
    wf = load_workflow(_write(tmp_path))
    c = wf.config
    assert c["fit"]["by"] == "applied" and c["fit"]["likelihood"] == "ar1"
    assert c["compare"]["enabled"] is False and c["report"]["published"] == "none"
    assert wf.out == (tmp_path / ".." / "out" / "t").resolve()
    fc = wf.fit_config()
    assert fc.tests == ("sine-2Hz-36lb-0.5in",) and fc.sampler.progress is False


def test_the_stored_run_is_chosen_in_the_sampler_table(tmp_path):
    wf = load_workflow(_write(tmp_path, "\n[fit.sampler]\nstored_run = 'ensemble'\n"))
    assert wf.fit_config().sampler.stored_run == "ensemble"
    assert load_workflow(_write(tmp_path)).fit_config().sampler.stored_run == "chains"


@pytest.mark.parametrize("extra, where, problem", [
    ("\n[fitt]\nby = 'test'\n", "fitt", "unknown key"),
    ("\n[fit.sampler]\nmax_step = 10\n", "[fit.sampler].max_step", "unknown key"),
    ("\n[fit.sampler]\nmax_steps = -10\n", "[fit.sampler].max_steps", "must be > 0"),
    ("\n[fit.sampler]\nmax_steps = 2.5\n", "[fit.sampler].max_steps", "integer"),
    ("\n[fit.sampler]\nmax_steps = 100\nmin_steps = 500\n", "[fit.sampler].min_steps", "exceeds"),
    ("\n[fit.sampler]\nstored_run = 'chain'\n", "[fit.sampler].stored_run", "must be one of chains, ensemble"),
    ("\n[fit.sampler]\nstored_run = 3\n", "[fit.sampler].stored_run", "non-empty string"),
    ("\n[law]\nfamily = 'cubic'\n", "[law].family", "must be one of"),
    ("\n[report]\npublished = 'xyz'\n", "[report].published", "must be one of"),
    ("\n[predict]\nn_draws = 'many'\n", "[predict].n_draws", "integer"),
    ("\n[predict]\nn_draws = 1\n", "[predict].n_draws", "must be >= 2"),     # a band needs 2
    ("\n[[predict.harmonic]]\namplitude_m = 0.01\napplied = 36\n", "frequency_hz", "missing"),
    ("\n[[predict.harmonic]]\namplitude_m = 0.01\nfrequency_hz = 1\napplied = 36\nphase = 0\n",
     "phase", "unknown key"),
    ("\n[[predict.ground_motion]]\nrecord = 'northridge'\npeak_m = 0.01\napplied = 36\n",
     "record", "must be one of"),
    ("\n[[predict.ground_motion]]\nfile = 'nowhere.AT2'\npeak_m = 0.01\napplied = 36\n",
     "[[predict.ground_motion]][0].file", "is not a file"),
    ("\n[[predict.ground_motion]]\nrecord = 'kobe'\nfile = 'x.AT2'\npeak_m = 0.01\napplied = 36\n",
     "[[predict.ground_motion]][0]", "either record"),
    ("\n[[predict.ground_motion]]\npeak_m = 0.01\napplied = 36\n",
     "[[predict.ground_motion]][0]", "either record"),
    ("\n[[predict.ground_motion]]\nrecord = 'kobe'\ndt = 0.01\npeak_m = 0.01\napplied = 36\n",
     "[[predict.ground_motion]][0].dt", "applies to file only"),
    # a length in millimetres typed as metres: refused at load (until 2026-12-05 the fits ran
    # first and the predict task failed, naming a generated file)
    ("\n[[predict.harmonic]]\namplitude_m = 20\nfrequency_hz = 1\napplied = 36\n",
     "[[predict.harmonic]][0].amplitude_m", "20 m is above 1 m, which no damper test reaches"),
    ("\n[[predict.ground_motion]]\nrecord = 'kobe'\npeak_m = 20\napplied = 36\n",
     "[[predict.ground_motion]][0].peak_m", "20 m is above 1 m"),
    # a frequency in the wrong unit (0.1 mm at 1 MHz moves at 628 m/s): until 2026-12-06 predicted
    ("\n[[predict.harmonic]]\namplitude_m = 0.0001\nfrequency_hz = 1e6\napplied = 36\n",
     "[[predict.harmonic]][0].frequency_hz", "its peak speed 2 pi f A is 628.3 m/s (0.0001 m at "
     "1e+06 Hz), above 10 m/s, which no damper test reaches"),
    ("\n[compare]\nmodels = ['lugre']\n", "[compare].models", "two models"),
    ("\n[compare]\nenabled = 'yes'\n", "[compare].enabled", "true or false"),
    ("\n[discrepancy]\nenabled = 1\n", "[discrepancy].enabled", "true or false"),
    ("\n[discrepancy]\ncandidates = []\n", "discrepancy.candidates", "unknown key"),
    ("\n[discrepancy]\nmax_effects = 0\n", "[discrepancy].max_effects", "must be >= 1"),
    ("\n[discrepancy]\nmax_effects = 1.5\n", "[discrepancy].max_effects", "integer"),
    ("\n[discrepancy]\nextra_effects = [\"eccentricity\"]\n", "[discrepancy].extra_effects",
     "not one of chatter, speed_weakening, takeup_overshoot"),
    ("\n[discrepancy]\ncheck_seeds = [1]\n", "[discrepancy].check_seeds", "the workflow's own seed"),
    ("\n[discrepancy]\ncheck_seeds = [2, 2]\n", "[discrepancy].check_seeds", "twice"),
    ("\n[discrepancy]\ncheck_seeds = [-2]\n", "[discrepancy].check_seeds", "must be >= 0"),
    ("\n[discrepancy]\ncheck_seeds = [18446744073709551616]\n", "[discrepancy].check_seeds",
     "must be <= 9223372036854775807"),
    ("\n[discrepancy]\ncheck_seeds = 2\n", "[discrepancy].check_seeds", "list of integers"),
])
def test_bad_keys_and_values_name_file_key_and_problem(tmp_path, extra, where, problem):
    p = _write(tmp_path, extra)
    with pytest.raises(InputError) as e:
        load_workflow(p)
    msg = str(e.value)
    assert str(p) in msg and where in msg and problem in msg, msg


def test_a_folder_or_a_bom_is_named_for_what_it_is(tmp_path):
    """A folder given as the workflow said "workflow file not found", and a UTF-8 byte-order mark
    gave TOML's "Invalid statement (at line 1, column 1)" alone (until 2026-12-05)."""
    with pytest.raises(InputError, match="is a folder, not a file; give the workflow's .toml file"):
        load_workflow(tmp_path)
    with pytest.raises(InputError, match="workflow file not found"):
        load_workflow(tmp_path / "none.toml")
    p = _write(tmp_path, "")
    p.write_bytes(b"\xef\xbb\xbf" + p.read_bytes())
    with pytest.raises(InputError, match="not valid TOML .*byte-order mark .BOM.: save it as UTF-8 without BOM"):
        load_workflow(p)


def test_the_report_folder_is_checked_when_the_workflow_loads(tmp_path):
    """[workflow].report: a file, or a folder inside the campaign, is refused at load (until
    2026-12-05 every fit ran first and the report task then failed)."""
    (tmp_path / "repfile").write_text("x")
    for rep, problem in (("repfile", "is a file, not a folder"),
                         (str(ROOT / "data" / "brfd-arts-d2" / "r"), "lies inside the campaign")):
        p = _write(tmp_path, base=BASE.replace('[workflow]\n', f'[workflow]\nreport = "{rep}"\n', 1))
        with pytest.raises(InputError, match=r"\[workflow\]\.report.*" + problem):
            load_workflow(p)


def test_a_ground_motion_file_is_read_when_the_workflow_loads(tmp_path):
    """A user's accelerogram is checked at load time: a single-column file without dt, or one
    with text in it, is refused naming the workflow key and the file; a good one loads."""
    (tmp_path / "q.txt").write_text("0.01\n0.02\n" * 20)
    gm = "\n[[predict.ground_motion]]\nfile = 'q.txt'\npeak_m = 0.01\napplied = 36\n"
    with pytest.raises(InputError, match=r"\[\[predict.ground_motion\]\]\[0\].file: .*q.txt.*give dt"):
        load_workflow(_write(tmp_path, gm))
    wf = load_workflow(_write(tmp_path, gm.replace("applied", "dt = 0.005\napplied")))
    e = wf.config["predict"]["ground_motion"][0]
    assert e["file"] == str((tmp_path / "q.txt").resolve()) and e["dt"] == 0.005
    assert "predict:q-36" in plan(wf)
    (tmp_path / "my quake.txt").write_text("0.01\n0.02\n" * 20)      # a stem that is no name
    sp = load_workflow(_write(tmp_path, gm.replace("q.txt", "my quake.txt").replace(
        "applied", "dt = 0.005\napplied")))
    assert sp.config["predict"]["ground_motion"][0]["name"] == "my_quake-36"
    (tmp_path / "r.AT2").write_text("x")
    with pytest.raises(InputError, match=r"\]\[0\].dt: an .AT2 file states its own"):
        load_workflow(_write(tmp_path, gm.replace("q.txt", "r.AT2").replace("applied", "dt = 0.01\napplied")))
    (tmp_path / "q.txt").write_text("0.01\nabc\n" * 20)
    with pytest.raises(InputError, match=r"\.file: .*q.txt"):
        load_workflow(_write(tmp_path, gm.replace("applied", "dt = 0.005\napplied")))


def test_bad_fit_section_values(tmp_path):
    base = BASE.replace('tests = ["sine-2Hz-36lb-0.5in"]', "")
    for fit, where in [("model = 'coulomb'", "[fit].model"), ("likelihood = 'ar2'", "[fit].likelihood"),
                       ("simulate_at = 'fine'", "[fit].simulate_at"),
                       ("drive_lowpass = 0", "[fit].drive_lowpass"),
                       ("drive_lowpass = 'on'", "[fit].drive_lowpass: must be 'auto', 'off' or a number"),
                       ("effects = ['wobble']", "[fit].effects"), ("eps = -1.0", "[fit].eps"),
                       ("kinds = ['sine']", "[fit].kinds"), ("bogus = 1", "fit.bogus")]:
        p = _write(tmp_path, "", base.replace("[fit]", "[fit]\n" + fit))
        with pytest.raises(InputError, match=None) as e:
            load_workflow(p)
        assert where in str(e.value) and str(p) in str(e.value), str(e.value)
    p = _write(tmp_path, "\n[fit.priors]\nfc_sideways = 1.0\n")
    with pytest.raises(InputError, match="fc_sideways"):
        load_workflow(p)
    p = _write(tmp_path, "\n[fit.priors]\nnoise_phi = {dist = 'uniform', lower = 0, upper = 0.5}\n")
    with pytest.raises(InputError, match="noise_phi"):
        load_workflow(p)


def test_missing_required_and_unknown_tests(tmp_path):
    p = tmp_path / "wf.toml"
    p.write_text("[workflow]\nname = 't'\n")
    with pytest.raises(InputError, match=r"\[workflow\]\.campaign: missing"):
        load_workflow(p)
    p.write_text("[workflow]\nname = 't'\ncampaign = 'nowhere'\n")
    with pytest.raises(InputError, match="not a campaign folder"):
        load_workflow(p)
    p.write_text("[workflow\nname = 't'\n")
    with pytest.raises(InputError, match="not valid TOML"):
        load_workflow(p)
    with pytest.raises(InputError, match="not found"):
        load_workflow(tmp_path / "absent.toml")
    # a test id the campaign does not have: refused when the tasks are planned
    wf = load_workflow(_write(tmp_path, "\n[predict]\nvalidate = ['eq-northridge']\n"))
    with pytest.raises(InputError, match=r"\[predict\] validate.*eq-northridge"):
        plan(wf)


def test_cli_bad_workflow_is_one_line_exit_2(tmp_path):
    p = _write(tmp_path, "\n[law]\nfamily = 'cubic'\n")
    for cmd in (["run", str(p)], ["status", str(p)], ["run", str(p), "--dry-run"]):
        r = subprocess.run([sys.executable, "-m", "frictionuq.cli", *cmd], capture_output=True, text=True)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "[law].family" in lines[0] and "Traceback" not in r.stderr
    good = _write(tmp_path)
    r = subprocess.run([sys.executable, "-m", "frictionuq.cli", "run", str(good), "fitt"],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "unknown target 'fitt'" in r.stderr


def test_arma_likelihood_accepted_but_not_with_heldout_stages(tmp_path):
    base = BASE.replace("[fit]", "[fit]\nlikelihood = 'arma'")
    wf = load_workflow(_write(tmp_path, "", base))
    assert wf.fit_config().likelihood == "arma"
    assert wf.fit_config().simulate_at == "raw"            # the default
    kept = load_workflow(_write(tmp_path, "", base.replace("[fit]", "[fit]\nsimulate_at = 'kept'")))
    assert kept.fit_config().simulate_at == "kept"
    assert wf.fit_config().drive_lowpass == "auto"         # 20 where eps > 0 (drivefilter)
    assert wf.fit_config().reversal == "extreme"
    off = load_workflow(_write(tmp_path, "", base.replace("[fit]", "[fit]\ndrive_lowpass = 'off'")))
    assert off.fit_config().drive_lowpass is None
    lp = load_workflow(_write(tmp_path, "", base.replace("[fit]", "[fit]\ndrive_lowpass = 20")))
    assert lp.fit_config().drive_lowpass == 20
    assert lp.fit_config().record_options()["drive_lowpass"] == 20
    for sec in ("compare", "discrepancy"):
        p = _write(tmp_path, f"\n[{sec}]\nenabled = true\n", base)
        with pytest.raises(InputError) as e:
            load_workflow(p)
        assert str(p) in str(e.value) and "[fit].likelihood" in str(e.value) and sec in str(e.value)


def test_workflow_force_offset_key(tmp_path):
    """[fit] force_offset = "per_test" reaches the fit config; the default is "shared"; any other
    value is refused naming the key."""
    assert load_workflow(_write(tmp_path, "", BASE)).fit_config().force_offset == "shared"
    wf = load_workflow(_write(tmp_path, "", BASE.replace("[fit]", "[fit]\nforce_offset = 'per_test'")))
    assert wf.fit_config().force_offset == "per_test"
    with pytest.raises(InputError, match=r"\[fit\]\.force_offset"):
        load_workflow(_write(tmp_path, "", BASE.replace("[fit]", "[fit]\nforce_offset = 'each'")))


def test_workflow_refuses_per_test_offsets_with_what_they_cannot_serve(tmp_path):
    """[fit] force_offset = "per_test" with the arma likelihood, a noise effect in the model, or
    one screened by an enabled [discrepancy] stage: refused at load, naming the key."""
    base = BASE.replace("[fit]", "[fit]\nforce_offset = 'per_test'")
    with pytest.raises(InputError, match=r"\[fit\]\.force_offset.*'arma'"):
        load_workflow(_write(tmp_path, "", base.replace("[fit]", "[fit]\nlikelihood = 'arma'")))
    with pytest.raises(InputError, match=r"\[fit\]\.force_offset.*chatter"):
        load_workflow(_write(tmp_path, "\n[discrepancy]\nenabled = true\nextra_effects = ['chatter']\n", base))
    with pytest.raises(InputError, match=r"\[fit\]\.force_offset.*\[fit\]\.effects has chatter"):
        load_workflow(_write(tmp_path, "", base.replace("[fit]", "[fit]\neffects = ['chatter']")))
    assert load_workflow(_write(tmp_path, "\n[discrepancy]\nenabled = true\n", base)).fit_config().force_offset == "per_test"


def test_check_seeds_reach_discover(tmp_path, monkeypatch):
    """[discrepancy] check_seeds: read (default none) and handed to discover by the stage."""
    from frictionuq.discrepancy import discover as D
    from frictionuq.pipeline import tasks as T
    assert load_workflow(_write(tmp_path, "\n[discrepancy]\nenabled = true\n")
                         ).config["discrepancy"]["check_seeds"] == []
    wf = load_workflow(_write(tmp_path, "\n[discrepancy]\nenabled = true\ncheck_seeds = [2, 3]\n"))
    seen = {}

    def stub(*args, **kw):
        seen.update(kw)
        return {"named_effects": []}

    monkeypatch.setattr(D, "discover", stub)
    T._discrepancy(wf, plan(wf)["discrepancy"], lambda m: None)
    assert seen["check_seeds"] == (2, 3) and seen["seed"] == 1
