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
