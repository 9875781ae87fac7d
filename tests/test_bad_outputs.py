"""Output paths that cannot be written, outputs that must not be replaced, and corrupt or
ambiguous inputs, across the commands: one line `frictionuq: error: ...`, exit 2, no traceback,
nothing half-written and nothing of the user's removed. (Cases found by probing the CLI on
2026-12-01; each failed on the code before.)"""
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from frictionuq.cli import main
from frictionuq.infer.fit import FitConfig, fit_campaign
from frictionuq.infer.sampler import SamplerConfig

ROOT = Path(__file__).resolve().parents[1]
TWIN = ROOT / "data" / "brfd-twin"
TINY = dict(nwalkers=32, run_walkers=8, chunk=50, min_steps=50, max_steps=50, burn_rounds=1, burn_max_rounds=1,
            burn_steps=20, n_random_starts=1, n_prior_starts=1, n_global_starts=0, progress=False)


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A two-test copy of the BRFD twin, a one-test fit of it (tiny, not converged), an input
    record and a parameter file."""
    import json
    import shutil

    from frictionuq import published
    root = tmp_path_factory.mktemp("bad")
    camp = root / "camp"
    (camp / "tests").mkdir(parents=True)
    toml = (TWIN / "campaign.toml").read_text()
    head, *blocks = toml.split("[[tests]]")
    keep = [b for b in blocks if 'id = "h-35N-0.05Hz"' in b or 'id = "h-35N-0.5Hz"' in b]
    (camp / "campaign.toml").write_text(head + "".join("[[tests]]" + b for b in keep))
    for tid in ("h-35N-0.05Hz", "h-35N-0.5Hz"):
        shutil.copy(TWIN / "tests" / f"{tid}.csv", camp / "tests" / f"{tid}.csv")
    fit_campaign(camp, root / "fit", config=FitConfig(tests=("h-35N-0.5Hz",), likelihood="iid",
                                                      sampler=SamplerConfig(**TINY), n_predictive=4))
    t = np.arange(500) / 100.0
    np.savetxt(root / "X.csv", np.column_stack([t, 0.01 * np.sin(t)]), delimiter=",",
               header="time,displacement", comments="")
    (root / "P.json").write_text(json.dumps(published.brfd_params(133.0)))
    (root / "afile").write_text("mine\n")
    return root


def _one_line(capsys, code, fragment):
    """Exit 2 and one error line, the last on stderr (progress lines may come before it)."""
    err = capsys.readouterr().err
    assert code == 2, err
    errors = [ln for ln in err.splitlines() if ln.startswith("frictionuq: error:")]
    assert len(errors) == 1 and err.splitlines()[-1] == errors[0] and fragment in errors[0], err
    assert "Traceback" not in err, err
    return errors[0]


@pytest.mark.parametrize("argv", [
    ["ingest", "{camp}", "--out", "{out}"],
    ["twin", "mfd", "--out", "{out}"],
    ["simulate", "--params", "{root}/P.json", "--input", "{root}/X.csv", "--out", "{out}"],
    ["predict", "{root}/fit", "--harmonic", "0.02,0.5", "--applied", "35", "--out", "{out}"],
    ["validate", "{root}/fit", "{camp}", "--test", "h-35N-0.05Hz", "--out", "{out}"],
    ["advantage", "{root}/fit", "--out", "{out}"],
    ["fit", "{camp}", "--out", "{out}", "--max-steps", "5"],
    # compare checked its --out only after every fit had run (a new user's trial, 2026-12-05)
    ["compare", "{camp}", "--out", "{out}", "--max-steps", "5"],
])
def test_an_output_under_a_file_is_one_line(work, capsys, argv):
    """--out below an existing file (e.g. /dev/null/x): before, an OSError's traceback or a
    message naming a temporary sibling."""
    out = work / "afile" / "x"
    args = [a.format(camp=work / "camp", root=work, out=out) for a in argv]
    _one_line(capsys, main(args), f"{work / 'afile'} is a file, not a folder")
    assert (work / "afile").read_text() == "mine\n"


def test_twin_and_validate_do_not_replace_a_folder_of_the_users(work, tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.txt").write_text("mine")
    _one_line(capsys, main(["twin", "brfd", "--out", str(mine)]), "is not a twin campaign")
    _one_line(capsys, main(["validate", str(work / "fit"), str(work / "camp"), "--test",
                            "h-35N-0.05Hz", "--out", str(mine)]), "is not a validation folder")
    _one_line(capsys, main(["twin", "brfd", "--out", str(work / "afile")]), "exists and is not a folder")
    assert [p.name for p in mine.iterdir()] == ["thesis.txt"]
    assert (work / "afile").read_text() == "mine\n"
    # an earlier twin is replaced, but not once the user has added a file to it (it was lost)
    twin = tmp_path / "twin"
    assert main(["twin", "mfd", "--out", str(twin)]) == 0
    assert main(["twin", "mfd", "--out", str(twin), "--seed", "3"]) == 0
    (twin / "tests" / "extra.csv").write_text("mine")
    _one_line(capsys, main(["twin", "mfd", "--out", str(twin)]), "is not a twin campaign")
    assert (twin / "tests" / "extra.csv").read_text() == "mine"


def test_validate_writes_nothing_when_a_later_test_fails(work, tmp_path, capsys):
    """The second held-out test sits at an applied force the fit cannot predict (no law): no
    folder is left, and an earlier validation folder is kept whole."""
    camp = tmp_path / "camp50"
    import shutil
    shutil.copytree(work / "camp", camp)
    toml = (camp / "campaign.toml").read_text()
    i = toml.index('id = "h-35N-0.5Hz"')
    j = toml.index("applied", i)
    k = toml.index("\n", j)
    (camp / "campaign.toml").write_text(toml[:j] + "applied = 50.0" + toml[k:])
    both = ["--test", "h-35N-0.05Hz", "--test", "h-35N-0.5Hz"]
    out = tmp_path / "val"
    _one_line(capsys, main(["validate", str(work / "fit"), str(camp), *both, "--out", str(out)]),
              "no fitted level at applied force 50 N")
    assert not out.exists()
    assert main(["validate", str(work / "fit"), str(camp), "--test", "h-35N-0.05Hz", "--out", str(out)]) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    capsys.readouterr()
    _one_line(capsys, main(["validate", str(work / "fit"), str(camp), *both, "--out", str(out)]),
              "no fitted level")
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_simulate_refuses_a_folder_as_out_and_names_the_faulty_input(work, tmp_path, capsys):
    odir = tmp_path / "odir"
    odir.mkdir()
    base = ["simulate", "--params", str(work / "P.json"), "--input", str(work / "X.csv")]
    _one_line(capsys, main(base + ["--out", str(odir)]), "it is a folder")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["odir"]        # no odir.json sidecar
    t = np.arange(500) / 100.0
    bad = tmp_path / "neg.csv"
    np.savetxt(bad, np.column_stack([t, 0.01 * np.sin(t), -5 + 0 * t]), delimiter=",",
               header="time,displacement,applied", comments="")
    err = _one_line(capsys, main(["simulate", "--params", str(work / "P.json"), "--input", str(bad),
                                  "--out", str(tmp_path / "s.csv")]), "applied-force signal")
    assert f"{bad}:" in err and "P.json" not in err
    _one_line(capsys, main(base + ["--out", str(tmp_path / "s.csv"), "--eps", "-1"]),
              "--eps -1.0: the reversal dead-band")
    # a 5 m dead band, or a drive in millimetres given as metres (until 2026-12-05 simulated)
    _one_line(capsys, main(base + ["--out", str(tmp_path / "s.csv"), "--eps", "5"]),
              "--eps 5.0: 5 m is above 1 m, which no damper test reaches")
    mm = tmp_path / "mm.csv"
    np.savetxt(mm, np.column_stack([t, 20.0 * np.sin(t)]), delimiter=",", header="time,displacement",
               comments="")
    _one_line(capsys, main(["simulate", "--params", str(work / "P.json"), "--input", str(mm),
                            "--out", str(tmp_path / "s.csv")]), f"{mm}: the drive's amplitude is 26.31 m, above 1 m")
    # a drive at 1 MHz (until 2026-12-06 simulated): its fastest step named
    fast = tmp_path / "fast.csv"
    tf = np.arange(601) / 2e8
    np.savetxt(fast, np.column_stack([tf, 1e-4 * np.sin(2e6 * np.pi * tf)]), delimiter=",",
               header="time,displacement", comments="")
    _one_line(capsys, main(["simulate", "--params", str(work / "P.json"), "--input", str(fast),
                            "--out", str(tmp_path / "s.csv")]),
              f"{fast}: the drive moves at 628.2 m/s between t = ")
    # an existing FIFO (or device) as --out: until 2026-12-05 replaced by a regular file
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    _one_line(capsys, main(base + ["--out", str(fifo)]), "it exists and is not a regular file")
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    _one_line(capsys, main(["simulate", "--params", str(odir), "--input", str(work / "X.csv"),
                            "--out", str(tmp_path / "s.csv")]), "is a folder, not a file")
    assert not (tmp_path / "s.csv").exists()


@pytest.mark.parametrize("corrupt, fragment", [
    (("applied-35N/posterior.nc", "garbage"), "posterior.nc: cannot read the posterior"),
    (("summary.json", "[]"), "summary.json: expected a JSON object"),
    (("summary.json", "{bad"), "summary.json: not valid JSON"),
    (("applied-35N/fit.json", "{bad"), "fit.json: not valid JSON"),
])
def test_law_on_a_corrupt_fit_folder_names_the_file(work, tmp_path, capsys, corrupt, fragment):
    import shutil
    fit = tmp_path / "fit"
    shutil.copytree(work / "fit", fit)
    (fit / corrupt[0]).write_text(corrupt[1])
    _one_line(capsys, main(["law", str(fit)]), fragment)


def test_csv_lines_count_blank_lines_and_a_repeated_column_is_refused(work, tmp_path, capsys):
    import shutil
    camp = tmp_path / "camp"
    shutil.copytree(work / "camp", camp)
    f = camp / "tests" / "h-35N-0.05Hz.csv"
    lines = f.read_text().splitlines()
    bad = lines[:3] + ["", ""] + lines[3:]
    cells = bad[10].split(",")
    cells[1] = "abc"                                   # file line 11, displacement
    bad[10] = ",".join(cells)
    f.write_text("\n".join(bad) + "\n\n")
    _one_line(capsys, main(["ingest", str(camp), "--out", str(tmp_path / "o")]),
              "h-35N-0.05Hz.csv, line 11, column 'displacement'")
    rows = [lines[0] + ",force"] + [r + ",1" for r in lines[1:]]
    f.write_text("\n".join(rows) + "\n")
    _one_line(capsys, main(["ingest", str(camp), "--out", str(tmp_path / "o")]),
              "the header repeats column 'force'")
    f.write_text("\n".join(lines[:1] + [""] + lines[1:]) + "\n")      # blank lines alone: fine
    assert main(["ingest", str(camp), "--out", str(tmp_path / "o")]) == 0


@pytest.mark.parametrize("argv, fragment", [
    (["simulate", "--params", "p", "--input", "x", "--out", "o", "--eps", "1mm"],
     "frictionuq simulate: argument --eps: invalid float value: '1mm'"),
    (["fit"], "frictionuq fit: the following arguments are required"),
    (["nosuch"], "invalid choice: 'nosuch'"),
])
def test_usage_errors_are_one_line(capsys, argv, fragment):
    """argparse's own errors: one line (before, the usage lines came first)."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and err.startswith("frictionuq: error:"), err
    assert fragment in err, err


def test_clean_removes_only_a_run_folder(tmp_path, capsys):
    """A workflow whose output names the user's own folder: refused when it holds the workflow
    file or the campaign; a folder holding anything a run does not write is not removed."""
    import shutil
    camp = tmp_path / "camp"
    shutil.copytree(TWIN, camp)
    for output, fragment in ((".", "holds the campaign or this workflow file"),
                             ("..", "holds the campaign or this workflow file")):
        wf = tmp_path / "wf.toml"
        wf.write_text(f'[workflow]\nname = "x"\ncampaign = "camp"\noutput = "{output}"\n')
        _one_line(capsys, main(["clean", str(wf)]), fragment)
    mine = tmp_path / "mine"
    (mine / "fit").mkdir(parents=True)
    (mine / "thesis.txt").write_text("mine")
    wf.write_text('[workflow]\nname = "x"\ncampaign = "camp"\noutput = "mine"\n')
    _one_line(capsys, main(["clean", str(wf)]), "holds what no run wrote (thesis.txt)")
    assert (mine / "thesis.txt").read_text() == "mine" and (mine / "fit").is_dir()
    assert (camp / "campaign.toml").is_file() and wf.is_file()
    (mine / "thesis.txt").unlink()                     # a run folder's own entries only: removed
    assert main(["clean", str(wf)]) == 0 and not mine.exists()


def test_run_on_a_bad_campaign_is_one_line_before_any_task(work, tmp_path, capsys):
    """A record the ingest task would refuse: `run` says so in one line (file and line), exit 2,
    and no run folder is made (before, the task failed: exit 1 and a report of several lines)."""
    import shutil
    camp = tmp_path / "camp"
    shutil.copytree(work / "camp", camp)
    f = camp / "tests" / "h-35N-0.5Hz.csv"
    lines = f.read_text().splitlines()
    lines[6] = lines[6].split(",", 1)[0] + ",x,1,1"
    f.write_text("\n".join(lines) + "\n")
    wf = tmp_path / "wf.toml"
    wf.write_text('[workflow]\nname = "x"\ncampaign = "camp"\noutput = "run"\n')
    _one_line(capsys, main(["run", str(wf)]), "h-35N-0.5Hz.csv, line 7, column 'displacement'")
    assert not (tmp_path / "run").exists()


def test_a_negative_harmonic_amplitude_reaches_its_own_check(work, tmp_path, capsys):
    """`--harmonic -0.02,0.5` is the option's value, not an unknown option: the amplitude check
    answers (before: argparse's "expected one argument")."""
    for value in ("-0.02,0.5", "-.02,0.5"):
        _one_line(capsys, main(["predict", str(work / "fit"), "--harmonic", value, "--applied", "35",
                                "--out", str(tmp_path / "p")]), "amplitude (m) must be a finite number > 0")
    assert not (tmp_path / "p").exists()


def test_fit_into_its_campaign_and_a_test_validated_twice_are_refused(work, capsys):
    camp = work / "camp"
    before = sorted(p.name for p in camp.iterdir())
    _one_line(capsys, main(["fit", str(camp), "--out", str(camp), "--max-steps", "5"]),
              "must differ from the campaign folder")
    assert sorted(p.name for p in camp.iterdir()) == before
    _one_line(capsys, main(["validate", str(work / "fit"), str(camp), "--test", "h-35N-0.05Hz",
                            "--test", "h-35N-0.05Hz", "--out", str(work / "v2")]),
              "--test h-35N-0.05Hz: given twice")
    assert not (work / "v2").exists()


def test_a_folder_that_cannot_be_moved_aside_keeps_the_old_output_and_leaves_no_copy(tmp_path,
                                                                                    monkeypatch):
    """atomic.output_dir: when the existing output cannot be renamed (an immutable folder, as
    root with chattr +i), one line of InputError, the previous output in place, and no hidden
    temporary copy of the new one left beside it (both were left before 2026-12-05)."""
    import os
    from frictionuq import atomic
    from frictionuq.errors import InputError
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.json").write_text("old")
    real = os.replace

    def stuck(src, dst):
        if Path(src) == out.absolute():
            raise PermissionError(1, "Operation not permitted", str(src))
        return real(src, dst)

    monkeypatch.setattr(os, "replace", stuck)
    with pytest.raises(InputError, match=r"cannot write .*out: Operation not permitted"):
        with atomic.output_dir(out) as tmp:
            (tmp / "new.json").write_text("new")
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert [p.name for p in out.iterdir()] == ["old.json"]


def test_compare_refuses_a_file_or_the_campaign_as_out_before_any_fit(work, capsys):
    from frictionuq.infer import compare as C
    calls = []
    real = C.compare_level
    C.compare_level = lambda *a, **k: calls.append(1) or real(*a, **k)
    try:
        _one_line(capsys, main(["compare", str(work / "camp"), "--out", str(work / "afile"),
                                "--max-steps", "5"]), "exists and is not a folder")
        _one_line(capsys, main(["compare", str(work / "camp"), "--out", str(work / "camp"),
                                "--max-steps", "5"]), "must differ from the campaign folder")
    finally:
        C.compare_level = real
    assert calls == [] and (work / "afile").read_text() == "mine\n"


def test_a_failed_output_folder_removes_the_parents_it_made(tmp_path):
    """output_dir makes the missing parents of its folder; a run that fails (or is interrupted)
    removes those it made, innermost first, as long as they are empty, and leaves the rest."""
    import pytest
    from frictionuq import atomic
    (tmp_path / "kept").mkdir()
    target = tmp_path / "kept" / "new1" / "new2" / "out"
    with pytest.raises(KeyboardInterrupt):
        with atomic.output_dir(target) as tmp:
            (tmp / "half.json").write_text("{")
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept"]
    assert list((tmp_path / "kept").iterdir()) == []
