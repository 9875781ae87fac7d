"""Make-like execution of a workflow's tasks: up-to-date checks, parallel fits, failures kept
apart, progress and logs.

* A task runs when it is not up to date (cache.state) or with force; a task whose dependency
  failed is skipped. The others go on: a failed fit loses nothing else, the run reports which
  tasks failed and why and ends with exit code 1, and the next run retries only those.
* Sampling tasks (fits, comparisons) go to `jobs` spawned local processes (spawn, not fork:
  numba's OpenMP layer and fork do not mix), or to a Dask distributed cluster with
  `scheduler=ADDRESS` (its workers must see the run folder, e.g. a shared file system). Each
  worker gets cores // jobs numba threads. Light tasks run in this process.
* Progress: on a terminal a live status line (stage, tasks done, each running task's latest log
  line, e.g. its sampler step); otherwise plain log lines. Every run appends to
  RUN/logs/run-<time>.log, with each task's own log (RUN/logs/tasks/<task>.log) copied in.
* Ctrl-C stops the workers; finished tasks keep their cache entries, an interrupted fit resumes
  from its HDF5 chain on the next run.
"""
from __future__ import annotations

import os
import re
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..environment import timestamp
from ..errors import InputError
from ..interrupts import interrupts
from . import cache
from .plan import closure, plan
from .tasks import execute, interrupted, task_log_path


@dataclass
class RunResult:
    ran: list[str] = field(default_factory=list)
    cached: list[str] = field(default_factory=list)
    failed: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    seconds: float = 0.0
    log_file: Path | None = None

    @property
    def ok(self) -> bool:
        return not self.failed and not self.skipped


def plan_status(wf, targets=("all",), force: bool = False) -> list[tuple[str, bool, str]]:
    """[(task, runs?, why)] for the targets, in dependency order."""
    tasks = plan(wf)
    rows, runs = [], set()
    for n in closure(tasks, targets):
        t = tasks[n]
        ok, why = cache.state(wf.out, t)
        if not ok and why.startswith("never run") and interrupted(wf.out, t):
            why = "interrupted: the next run resumes it from its stored state"
        upstream = [d for d in (t.deps if t.key_deps is None else t.key_deps) if d in runs]
        if ok and upstream:         # make-like: what a rerun task feeds is rerun too
            ok, why = False, f"dependency {upstream[0]} reruns"
        if force or not ok:
            runs.add(n)
        rows.append((n, n in runs, "forced (--force)" if force and ok else why))
    return rows


class _Display:
    """Live status line on a terminal, plain lines otherwise; everything also to the run log."""

    def __init__(self, log_path: Path, stream=None):
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.t0 = time.perf_counter()
        log_path.parent.mkdir(parents=True, exist_ok=True)
        self.file = open(log_path, "a", buffering=1)
        self.live = False

    def line(self, msg: str) -> None:
        stamp = f"[{time.perf_counter() - self.t0:7.1f} s]"
        self.file.write(f"{time.strftime('%H:%M:%S')} {msg}\n")
        if self.live:
            self.stream.write("\r\033[K")
            self.live = False
        self.stream.write(f"{stamp} {msg}\n")
        self.stream.flush()

    def status(self, text: str) -> None:
        if not self.tty:
            return
        try:
            width = max(40, os.get_terminal_size(self.stream.fileno()).columns - 1)
        except (OSError, ValueError, AttributeError):
            width = 100
        self.stream.write("\r\033[K" + text[:width])
        self.stream.flush()
        self.live = True

    def close(self):
        if self.live:
            self.stream.write("\r\033[K")
        self.file.close()


def _last_line(path: Path) -> str:
    try:
        with open(path, "rb") as f:
            f.seek(0, 2)
            f.seek(max(0, f.tell() - 400))
            lines = f.read().decode("utf-8", "replace").strip().splitlines()
        return lines[-1].split("] ", 1)[-1] if lines else ""
    except OSError:
        return ""


#: a task log's notes for the user (TaskLog's "[   1.0 s] note: ..." lines), shown on the console
NOTE = re.compile(r"^\[\s*[\d.]+ s\] (note: .*)$", re.M)


class _Pool:
    """Local spawned processes or a Dask cluster, behind submit() and futures with done()."""

    def __init__(self, jobs: int, scheduler: str | None):
        self.client = self.pool = None
        self.futures = []
        self.threads = max(1, (os.cpu_count() or 1) // max(1, jobs))
        if scheduler:
            from dask.distributed import Client
            try:
                # not the process's default client: one that failed to connect stayed set as
                # dask's scheduler, and later dask computations in this process (xarray,
                # ArviZ) tried that address
                self.client = Client(scheduler, timeout="20s", set_as_default=False)
            except (OSError, ValueError, TypeError) as e:    # unreachable, or not an address
                raise InputError(f"--scheduler {scheduler}: cannot connect to a Dask scheduler "
                                 f"there ({' '.join(str(e).split())})") from None
            self.threads = None          # the cluster's own configuration
            import uuid
            self.stop = f"frictionuq-stop-{uuid.uuid4().hex}"   # set when the run is interrupted
        elif jobs > 1:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            from ..interrupts import worker_initializer
            self.pool = ProcessPoolExecutor(jobs, mp_context=multiprocessing.get_context("spawn"),
                                            initializer=worker_initializer)

    @property
    def inline(self) -> bool:
        return self.client is None and self.pool is None

    def submit(self, wf, task):
        if self.client is not None:
            from ..interrupts import call_stoppable
            fut = self.client.submit(call_stoppable, execute, wf, task, self.threads, stop=self.stop,
                                     pure=False, key=f"{task.name}-{task.key[:12]}")
            self.futures.append(fut)
            return fut
        from ..interrupts import call_in_worker, sigint_held
        with sigint_held():       # a worker started here holds Ctrl-C from birth
            return self.pool.submit(call_in_worker, execute, wf, task, self.threads)

    def close(self, cancel: bool = False):
        """Shut down after the running tasks, or (cancel: interrupted) stop them at once: queued
        tasks cancelled, running ones stopped (a sampler between two steps, its chain kept)."""
        if self.pool is not None:
            if cancel:
                from ..interrupts import stop_pool
                stop_pool(self.pool)
            else:
                self.pool.shutdown(wait=True)
        if self.client is not None:
            if cancel:       # running tasks stop between two sampler steps, queued ones never start
                from distributed import Event
                try:
                    Event(self.stop, client=self.client).set()
                    self.client.cancel(self.futures)
                except Exception:        # the scheduler is gone: nothing of ours runs there
                    pass
            self.client.close()


def run(wf, targets=("all",), jobs: int = 1, scheduler: str | None = None, force: bool = False,
        stream=None) -> RunResult:
    """Bring the targets up to date. Returns what ran, was cached, failed or was skipped."""
    from .provenance import write as write_run
    tasks = plan(wf)
    order = closure(tasks, targets)
    todo, res = {}, RunResult()
    for n, runs, why in plan_status(wf, targets, force):
        if runs:
            todo[n] = why
        else:
            res.cached.append(n)
    if "ingest" in todo:     # a bad campaign is bad input: one line and exit 2, before any task
        from ..campaign import load_campaign
        load_campaign(wf.campaign)
    # the workers before any log is written: an unreachable --scheduler is bad input too
    pool = (_Pool(jobs, scheduler) if any(tasks[n].heavy for n in todo) else _Pool(1, None)) \
        if todo else None
    started = timestamp()
    stamp = time.strftime("%Y%m%d-%H%M%S")
    res.log_file = Path(wf.out) / "logs" / f"run-{stamp}.log"
    disp = _Display(res.log_file, stream)
    statuses = {n: {"status": "cached"} for n in res.cached}
    t0 = time.perf_counter()
    disp.line(f"workflow {wf.name} ({wf.path}): {len(order)} task(s), {len(todo)} to run, "
              f"{len(res.cached)} up to date; run folder {wf.out}")
    if not todo:
        disp.line("nothing to do: every target is up to date")
        disp.close()
        res.seconds = time.perf_counter() - t0
        return res
    running: dict[str, object] = {}
    pending = [n for n in order if n in todo]

    def finish(n, out):
        statuses[n] = {"status": "ran" if out["ok"] else "failed", "seconds": out["seconds"],
                       "error": out["error"]}
        with open(task_log_path(wf.out, n), errors="replace") as f:
            text = f.read()
        disp.file.write(f"--- log of {n} ---\n{text}")
        if out["ok"]:
            res.ran.append(n)
            disp.line(f"done    {n} ({out['seconds']:.1f} s)")
            for note in NOTE.findall(text):        # what the task asks the user to read
                disp.line(f"        {n}: {note}")
        else:
            res.failed[n] = out["error"]
            disp.line(f"FAILED  {n}: {out['error']}")

    with interrupts() as intr:
        try:
            while pending or running:
                intr.check()      # a Ctrl-C whose KeyboardInterrupt was swallowed (in a finaliser)
                progressed = False
                for n in list(pending):
                    deps = tasks[n].deps
                    bad = [d for d in deps if d in res.failed or d in res.skipped]
                    if bad:
                        pending.remove(n)
                        res.skipped[n] = f"dependency {bad[0]} did not finish"
                        statuses[n] = {"status": "skipped", "error": res.skipped[n]}
                        disp.line(f"skipped {n}: {res.skipped[n]}")
                        progressed = True
                        continue
                    if any(d in pending or d in running for d in deps):
                        continue
                    task = tasks[n]
                    pending.remove(n)
                    progressed = True
                    disp.line(f"{'queued ' if task.heavy and not pool.inline else 'start  '} {n} ({todo[n]})")
                    if task.heavy and not pool.inline:
                        running[n] = pool.submit(wf, task)
                    else:
                        if n == "report":
                            write_run(wf, statuses, started)
                        finish(n, execute(wf, task, pool.threads if task.heavy else None))
                for n, fut in list(running.items()):
                    if fut.done():
                        del running[n]
                        try:
                            out = fut.result()
                        except Exception as e:      # a worker died (killed, out of memory)
                            out = {"ok": False, "seconds": 0.0,
                                   "error": f"worker failed: {type(e).__name__}: {e}"}
                        finish(n, out)
                        progressed = True
                if running and not progressed:
                    done = len(res.ran) + len(res.failed)
                    parts = [f"{r}: {_last_line(task_log_path(wf.out, r))}" for r in running]
                    disp.status(f"[{done}/{len(todo)} done] " + " | ".join(parts))
                    time.sleep(0.25)
        except KeyboardInterrupt:
            disp.line("interrupted: finished tasks are kept; the next run resumes the rest")
            pool.close(cancel=True)
            write_run(wf, statuses, started)
            disp.close()
            raise
    pool.close()
    write_run(wf, statuses, started)
    res.seconds = time.perf_counter() - t0
    disp.line(f"finished in {res.seconds:.1f} s: {len(res.ran)} ran, {len(res.cached)} up to date, "
              f"{len(res.failed)} failed, {len(res.skipped)} skipped; log {res.log_file}")
    disp.close()
    return res


#: what a run folder holds (the stages' folders, the cache, logs and run.json): `clean` removes
#: a folder only when it holds nothing else, so a workflow whose output names a folder of the
#: user's (output = ".") cannot have it deleted
RUN_ENTRIES = {"ingest", "fit", "predict", "compare", "discrepancy", "advantage", "logs",
               ".cache", "run.json", "report"}


def clean(wf) -> list[Path]:
    """Remove the run folder and the report of a workflow. Returns what was removed. A run
    folder holding anything a run does not write is refused (InputError), nothing removed."""
    import shutil
    from ..errors import InputError
    out = Path(wf.out)
    if out.is_dir():
        foreign = sorted(p.name for p in out.iterdir() if p.name not in RUN_ENTRIES)
        if foreign:
            raise InputError(f"{wf.path}: [workflow].output {out} holds what no run wrote ("
                             f"{', '.join(foreign[:5])}{', ...' if len(foreign) > 5 else ''}); "
                             "not removed: delete it by hand if it is a run folder")
    elif out.exists():
        raise InputError(f"{wf.path}: [workflow].output {out} is a file, not a run folder; not removed")
    gone = []
    for p in (Path(wf.out), Path(wf.report_dir) / "index.html"):
        if p.is_dir():
            shutil.rmtree(p)
            gone.append(p)
        elif p.is_file():
            p.unlink()
            gone.append(p)
    rep = Path(wf.report_dir)
    if rep.is_dir() and not any(rep.iterdir()):      # the report's folder, left empty
        rep.rmdir()
    return gone
