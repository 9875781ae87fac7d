"""Fast unit tests of the pipeline's pieces: cache entries, target closure, progress display."""
from __future__ import annotations

import io
from pathlib import Path

import pytest

from frictionuq.errors import InputError
from frictionuq.pipeline import cache, plan
from frictionuq.pipeline.plan import Task, closure
from frictionuq.pipeline.runner import _Display, _last_line
from frictionuq.workflow import load_workflow

ROOT = Path(__file__).resolve().parents[1]


def test_cache_entry_lifecycle(tmp_path):
    t = Task("fit:a", "fit", [], {}, ["fit/a", "extra.json"], key="k1")
    assert cache.state(tmp_path, t) == (False, "never run (no cache entry)")
    (tmp_path / "fit" / "a").mkdir(parents=True)
    (tmp_path / "fit" / "a" / "posterior.nc").write_bytes(b"abc")
    (tmp_path / "fit" / "a" / ".task-key").write_text("k1")          # hidden: not an output
    (tmp_path / "extra.json").write_text("{}")
    m = cache.record(tmp_path, t, 1.5)
    assert set(m["outputs"]) == {"fit/a/posterior.nc", "extra.json"}
    assert cache.state(tmp_path, t) == (True, "up to date")
    t2 = Task("fit:a", "fit", [], {}, t.outputs, key="k2")
    assert "changed" in cache.state(tmp_path, t2)[1]
    (tmp_path / "fit" / "a" / "posterior.nc").write_bytes(b"abd")
    ok, why = cache.state(tmp_path, t)
    assert not ok and "posterior.nc changed since it was written" in why
    (tmp_path / "fit" / "a" / "posterior.nc").unlink()
    assert "missing" in cache.state(tmp_path, t)[1]
    cache.forget(tmp_path, "fit:a")
    assert cache.read(tmp_path, "fit:a") is None


def test_targets_and_their_closure():
    wf = load_workflow(ROOT / "workflows" / "quick.toml")
    tasks = plan(wf)
    assert closure(tasks, ["ingest"]) == ["ingest"]
    fit = closure(tasks, ["fit"])
    assert fit[0] == "ingest" and "fit/summary" in fit and not any(n.startswith("predict") for n in fit)
    pred = closure(tasks, ["predict:validation"])
    assert pred == ["ingest", "fit:applied-0lb", "fit:applied-36lb", "fit/summary", "predict:validation"]
    assert closure(tasks, ["all"]) == list(tasks)
    assert closure(tasks, []) == list(tasks)
    with pytest.raises(InputError, match="unknown target 'fits'"):
        closure(tasks, ["fits"])
    with pytest.raises(InputError, match="disabled in the workflow file"):
        closure(tasks, ["discrepancy"])
    # keys: deterministic, and distinct per task
    again = plan(load_workflow(ROOT / "workflows" / "quick.toml"))
    assert [t.key for t in tasks.values()] == [t.key for t in again.values()]
    assert len({t.key for t in tasks.values()}) == len(tasks)


class _Tty(io.StringIO):
    def isatty(self):
        return True

    def fileno(self):
        raise OSError("no real terminal")


def test_display_live_on_a_terminal_plain_otherwise(tmp_path):
    plain = io.StringIO()
    d = _Display(tmp_path / "a.log", plain)
    d.status("fit:x: step 500")
    d.line("done fit:x")
    d.close()
    assert "\r" not in plain.getvalue() and "done fit:x" in plain.getvalue()
    assert "step 500" not in plain.getvalue()              # no live line when not a terminal
    tty = _Tty()
    d = _Display(tmp_path / "b.log", tty)
    d.status("fit:x: step 500")
    d.line("done fit:x")
    d.close()
    out = tty.getvalue()
    assert "\r\033[K" in out and "step 500" in out and "done fit:x" in out
    assert "done fit:x" in (tmp_path / "b.log").read_text()
    assert "step 500" not in (tmp_path / "b.log").read_text()   # the log keeps lines only


def test_last_line_of_a_task_log(tmp_path):
    p = tmp_path / "t.log"
    p.write_text("[    1.0 s] start\n[   12.5 s] fit a: step 500: max tau 30\n")
    assert _last_line(p) == "fit a: step 500: max tau 30"
    assert _last_line(tmp_path / "absent.log") == ""


def test_a_task_logs_notes_are_found_for_the_console():
    from frictionuq.pipeline.runner import NOTE
    log = ("[    0.0 s] start predict:far\n[   12.5 s] prediction far: draws from the law\n"
           "[   12.6 s] note: applied 2000 N lies above the fitted levels (133, 267 N)\n"
           "[   12.7 s] done predict:far in 12.7 s\n")
    assert NOTE.findall(log) == ["note: applied 2000 N lies above the fitted levels (133, 267 N)"]


def test_a_dependency_recomputed_in_another_run_makes_its_dependents_stale(tmp_path):
    up = Task("fit:a", "fit", [], {}, ["a.txt"], key="ka")
    down = Task("report", "report", ["fit:a"], {}, ["r.txt"], key="kr")
    (tmp_path / "a.txt").write_text("posterior 1")
    cache.record(tmp_path, up, 1.0)
    (tmp_path / "r.txt").write_text("report of posterior 1")
    cache.record(tmp_path, down, 1.0)
    assert cache.state(tmp_path, down) == (True, "up to date")
    (tmp_path / "a.txt").write_text("posterior 2")         # e.g. `run fit --force` alone
    cache.record(tmp_path, up, 1.0)
    ok, why = cache.state(tmp_path, down)
    assert not ok and "dependency fit:a was recomputed since" in why
    # a dependency recomputed to the same bytes leaves it up to date (content, not time)
    cache.record(tmp_path, down, 1.0)
    cache.record(tmp_path, up, 2.0)
    assert cache.state(tmp_path, down)[0]
    # tasks that name their inputs' content in their key (key_deps=[]) do not follow the dep
    fit = Task("fit:b", "fit", ["fit:a"], {}, ["r.txt"], key="kb", key_deps=[])
    cache.record(tmp_path, fit, 1.0)
    (tmp_path / "a.txt").write_text("posterior 3")
    cache.record(tmp_path, up, 1.0)
    assert cache.state(tmp_path, fit)[0]


def test_status_names_an_interrupted_task(tmp_path):
    """A fit whose own folder holds the task key of an unfinished run (and no cache entry):
    status says it resumes, not "never run"; another key is "never run" as before."""
    from frictionuq.pipeline.runner import plan_status
    wf = load_workflow(ROOT / "workflows" / "quick.toml")
    wf.out = tmp_path / "run"
    task = plan(wf)["fit:applied-36lb"]
    d = wf.out / "fit" / "applied-36lb"
    d.mkdir(parents=True)
    (d / cache.KEY_FILE).write_text(task.key)
    why = {n: w for n, _, w in plan_status(wf, ["fit:applied-36lb"])}
    assert why["fit:applied-36lb"] == "interrupted: the next run resumes it from its stored state"
    (d / cache.KEY_FILE).write_text("another key")
    why = {n: w for n, _, w in plan_status(wf, ["fit:applied-36lb"])}
    assert why["fit:applied-36lb"] == "never run (no cache entry)"


def _keys(folder: Path, edit_wf=lambda s: s, edit_camp=lambda s: s) -> dict[str, str]:
    """Task keys of quick.toml run on a copy of its campaign's campaign.toml (records linked),
    with the discrepancy stage on its own tests, after the two edits."""
    camp = folder / "c"
    if not camp.exists():
        camp.mkdir(parents=True)
        (camp / "records").symlink_to(ROOT / "data" / "brfd-arts-d2" / "records")
    src = (ROOT / "data" / "brfd-arts-d2" / "campaign.toml").read_text()
    (camp / "campaign.toml").write_text(edit_camp(src))
    text = (ROOT / "workflows" / "quick.toml").read_text()
    text = text.replace('campaign = "../data/brfd-arts-d2"',
                        'campaign = "c"\noutput = "out"\nreport = "rep"')
    text += '\n[discrepancy]\nenabled = true\ntests = ["sine-1Hz-36lb-1in"]\n'
    (folder / "wf.toml").write_text(edit_wf(text))
    return {n: t.key for n, t in plan(load_workflow(folder / "wf.toml")).items()}


def test_keys_change_for_exactly_the_tasks_that_read_the_change(tmp_path):
    """A task's key holds what it reads: its own fit settings (not the whole [fit] section), its
    tests, and the campaign's units, columns and (the summary's mechanical advantage) geometry."""
    base = _keys(tmp_path)
    assert base == _keys(tmp_path)

    def changed(**edits):
        new = _keys(tmp_path, **edits)
        assert set(new) == set(base)
        return {n for n in base if new[n] != base[n]}

    preds = {"predict:validation", "predict:harmonic-25mm-1Hz-36lb", "predict:kobe-10mm-36lb"}
    # a test added at 36 lb: the 36 lb fit and what reads it; not the 0 lb fit, nor the
    # comparison and discrepancy, which have tests of their own
    assert changed(edit_wf=lambda s: s.replace('"sine-2Hz-0lb-1in"]\nsamples',
                                               '"sine-2Hz-0lb-1in", "sine-0.25Hz-36lb-1in"]\nsamples')
                   ) == {"fit:applied-36lb", "fit/summary", "report"} | preds
    # the fits' sampler: the fits (and the discrepancy's screening config); the comparison has
    # its own [compare.sampler]
    assert changed(edit_wf=lambda s: s.replace("max_steps = 1000", "max_steps = 1200")) == {
        "fit:applied-36lb", "fit:applied-0lb", "fit/summary", "discrepancy", "report"} | preds
    # a prior of the 3-stage model: not the pure-LuGre comparison, which does not use it
    got = changed(edit_wf=lambda s: s.replace("[law]", '[fit.priors]\nw = 0.0002\n\n[law]'))
    assert "compare:applied-36lb:three_stage" in got and "compare:applied-36lb:lugre" not in got
    # the records' force unit: everything that reads a record
    assert changed(edit_camp=lambda s: s.replace('force = "kip"', 'force = "kN"')) == set(base)
    # the geometry: the mechanical advantage (fit/summary) and after it; no fit
    got = changed(edit_camp=lambda s: s.replace("C_design = 142", "C_design = 150"))
    assert got == {"ingest", "fit/summary", "report"} | preds, got


def test_a_bad_scheduler_address_or_record_file_is_one_line_of_input_error(tmp_path):
    """--scheduler that names no Dask scheduler, and a campaign entry whose record file is gone
    (which `status` and `--dry-run` meet before any record is read), are InputErrors (one line,
    exit 2 at the command line), not tracebacks."""
    from frictionuq.pipeline.runner import _Pool
    with pytest.raises(InputError, match="--scheduler nonsense: cannot connect to a Dask scheduler"):
        _Pool(2, "nonsense")
    # and the failed client leaves dask's configuration as it was (it became the process's
    # scheduler, and the next files' xarray/ArviZ calls on this xdist worker tried 'nonsense')
    import dask
    from distributed.client import _get_global_client
    assert dask.config.get("scheduler", None) is None and _get_global_client() is None
    _keys(tmp_path)
    toml = tmp_path / "c" / "campaign.toml"
    toml.write_text(toml.read_text().replace("records/1Hz36lbtension1amplitude.json.gz",
                                             "records/gone.json.gz"))
    with pytest.raises(InputError, match=r"campaign.toml, tests\[\d+\], key file: .*gone.json.gz: "
                                         "file not found"):
        plan(load_workflow(tmp_path / "wf.toml"))
