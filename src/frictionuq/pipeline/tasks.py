"""What each task of the pipeline does: thin calls of the library (ingest, fit, law, advantage,
validate, predict, compare, report) on the run folder's layout

    RUN/ingest/                      the campaign in SI (frictionuq ingest)
    RUN/fit/<fit id>/                posterior.nc, fit.json, chain.h5 (one task each)
    RUN/fit/summary.json, law.json   gathered fits, force-dependence law
    RUN/advantage/                   advantage.csv, advantage.json
    RUN/predict/validation/          validation.json, <test>.bands.csv, <test>.png
    RUN/predict/<name>/              bands.csv, cycles.csv, prediction.json
    RUN/compare/<level>/<model>/     level.json; RUN/compare/compare.json, compare.csv
    RUN/discrepancy/                 discrepancy.json, refit/ (frictionuq discover)
    <report dir>/index.html

`execute` is the entry point of worker processes (spawned, or Dask workers): it takes plain,
picklable arguments and writes the task's log to RUN/logs/tasks/<task>.log as it goes, which the
runner reads for its progress display.
"""
from __future__ import annotations

import json
import shutil
import time
import traceback
from pathlib import Path

from .. import atomic
from ..errors import InputError
from . import cache
from ..wording import count

LOG_DIR = "logs/tasks"


def task_log_path(run_dir, name: str) -> Path:
    return Path(run_dir) / LOG_DIR / f"{cache._safe(name)}.log"


class TaskLog:
    """Line-buffered log file of one task (the runner tails it for progress)."""

    def __init__(self, run_dir, name: str):
        self.path = task_log_path(run_dir, name)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.f = open(self.path, "w", buffering=1)
        self.t0 = time.perf_counter()

    def __call__(self, msg: str) -> None:
        self.f.write(f"[{time.perf_counter() - self.t0:7.1f} s] {msg}\n")

    def close(self):
        self.f.close()


def _campaign(run_dir, ids=None):
    from ..ingest import load_ingested
    camp = load_ingested(Path(run_dir) / "ingest")
    if ids is not None:
        by = {t.id: t for t in camp.tests}
        return camp, [by[i] for i in ids]
    return camp, camp.tests


def _fresh_dir(d: Path, key: str, log) -> None:
    """A task's own output folder: kept when it holds an interrupted run of the same task key
    (the fit resumes from its chain.h5), emptied otherwise."""
    kf = d / cache.KEY_FILE
    if d.exists() and not (kf.is_file() and kf.read_text() == key):
        log(f"clearing {d} (an older or different run)")
        shutil.rmtree(d)
    elif d.exists():
        log(f"resuming in {d} (same task key)")
    d.mkdir(parents=True, exist_ok=True)
    kf.write_text(key)


# ------------------------------------------------------------------ stages

def _ingest(wf, task, log):
    from ..ingest import ingest
    m = ingest(wf.campaign, Path(wf.out) / "ingest")
    log(f"ingested {count(len(m['tests']), 'test')} of {m['name']!r}")


def own_dir(run_dir, task) -> Path | None:
    """The folder of its own a task keeps between runs (where an interrupted run resumes), or
    None for a task without one."""
    if task.stage == "fit" and "fit_id" in task.args:
        return Path(run_dir) / "fit" / task.args["fit_id"]
    if task.stage == "compare" and "level" in task.args:
        return Path(run_dir) / "compare" / task.args["level"] / task.args["model"]
    return None


def interrupted(run_dir, task) -> bool:
    """Whether the task's own folder holds an unfinished run of the same task key."""
    d = own_dir(run_dir, task)
    kf = d / cache.KEY_FILE if d is not None else None
    return kf is not None and kf.is_file() and kf.read_text() == task.key


def _fit(wf, task, log):
    from ..infer.fit import FitSpec, run_fit
    camp, tests = _campaign(wf.out, task.args["tests"])
    d = own_dir(wf.out, task)
    _fresh_dir(d, task.key, log)
    spec = FitSpec(task.args["fit_id"], tests, None if wf.config["fit"]["by"] == "test" and
                   len({t.applied for t in tests}) > 1 else tests[0].applied, wf.fit_config())
    run_fit(spec, Path(wf.out) / "fit", camp.name, resume=True, log=log)


def _fit_summary(wf, task, log):
    from ..advantage import write_advantage
    from ..infer.fit import write_summary
    fit_dir = Path(wf.out) / "fit"
    camp, _ = _campaign(wf.out)
    fits = [json.loads((fit_dir / dep.split(":", 1)[1] / "fit.json").read_text())["summary"]
            for dep in task.deps]
    summary = write_summary(fit_dir, camp, wf.config["fit"]["by"], wf.fit_config(), fits,
                            Path(wf.out) / "ingest", law=wf.config["law"]["enabled"],
                            family=wf.config["law"]["family"], extra={"workflow": str(wf.path)},
                            log=log)
    if summary["by"] == "applied":
        write_advantage(fit_dir, Path(wf.out) / "advantage")
    log(f"summary of {len(fits)} fit(s) written")


def _predict(wf, task, log):
    fit_dir = Path(wf.out) / "fit"
    p = wf.config["predict"]
    if task.name == "predict:validation":
        from ..validate import validate
        out = Path(wf.out) / "predict" / "validation"
        doc = validate(fit_dir, Path(wf.out) / "ingest", task.args["tests"], out,
                       n_draws=p["n_draws"], seed=wf.seed, log=log)
        for s in doc["tests"]:
            log(f"{s['test']}: coverage95 {s['coverage95']:.3f}, coverage50 {s['coverage50']:.3f}, "
                f"RMSE {s['rmse_N']:.4g} N, NRMSE {s['nrmse']:.4f}")
        return
    from ..predict import write_prediction
    e = task.args["input"]
    out = Path(wf.out) / "predict" / e["name"]
    if "record" in e or "file" in e:
        import numpy as np
        from ..groundmotion import displacement_history, load_source
        rec = load_source(e)
        t, x = displacement_history(rec, peak_m=e["peak_m"], fs_out=e["rate_hz"])
        csv = Path(wf.out) / "predict" / "inputs" / f"{e['name']}.csv"
        body = "time,displacement\n" + "".join(f"{a:.9g},{b:.9g}\n" for a, b in
                                                 zip(np.asarray(t), np.asarray(x)))
        atomic.write_text(csv, body)
        log(f"ground motion {e.get('record') or e['file']}: {t.size} samples at "
            f"{e['rate_hz']:g} Hz, peak "
            f"{e['peak_m'] * 1e3:g} mm")
        src = {k: e[k] for k in ("record", "file", "dt", "unit", "column", "peak_m", "rate_hz") if k in e}
        meta = write_prediction(fit_dir, out, input_csv=csv, applied=e["applied"],
                                n_draws=p["n_draws"], seed=wf.seed, clean_input=True, source=src)
    else:
        meta = write_prediction(fit_dir, out, harmonic=(e["amplitude_m"], e["frequency_hz"]),
                                applied=e["applied"], n_draws=p["n_draws"], seed=wf.seed)
    log(f"prediction {e['name']}: draws from {meta['draws_source']}")
    from ..extrapolation import notes
    for n in notes(meta):        # shown on the console too (runner: a log's "note: " lines)
        log(f"note: {n}")


def _compare(wf, task, log):
    from ..infer.compare import compare_level
    from ..infer.fit import jsonable
    _, tests = _campaign(wf.out, task.args["tests"])
    m = task.args["model"]
    d = own_dir(wf.out, task)
    _fresh_dir(d, task.key, log)
    cfg = wf.fit_config(compare_model=m)
    lv = compare_level(tests, {m: cfg}, wf.seed, log=log, work_dir=d / "chains")
    lv["id"] = task.args["level"]
    from .. import __version__
    from ..environment import environment
    atomic.write_json(d / "level.json", jsonable({
        "package_version": __version__, "environment": environment(), "seed": wf.seed,
        "config": cfg.to_json(), "tests": task.args["tests"], "level": lv}))


def _compare_summary(wf, task, log):
    from dataclasses import replace
    from ..infer.compare import merge_levels, write_compare
    camp, _ = _campaign(wf.out)
    models = wf.config["compare"]["models"]
    levels = []
    for lid in task.args["levels"]:
        docs = [json.loads((Path(wf.out) / "compare" / lid / m / "level.json").read_text())
                for m in models]
        # a level.json written before 2026-12-05 is the level itself, without its provenance
        levels.append(merge_levels([doc.get("level", doc) for doc in docs]))
    # the configurations as compared: the tests are those of the compared levels, not the fits'
    configs = {m: replace(wf.fit_config(compare_model=m), tests=None, kinds=None) for m in models}
    tests = [t for lv in levels for t in lv["tests"]]
    write_compare(Path(wf.out) / "compare", camp.name, Path(wf.out) / "ingest", configs, levels,
                  seed=wf.seed, offset="marginal", tests=tests, applied_unit=camp.applied_si_unit)
    log(f"comparison of {', '.join(models)} at {len(levels)} level(s) written")


def _discrepancy(wf, task, log):
    from dataclasses import replace
    from ..discrepancy.discover import discover
    # discover replaces its folder as a whole when it is done; a folder without its document is
    # an interrupted run's (or an older version's, with the task key in it): nothing to keep
    d = Path(wf.out) / "discrepancy"
    if d.is_dir() and not (d / "discrepancy.json").is_file():
        log(f"clearing {d} (an interrupted run)")
        shutil.rmtree(d)
    cfg = replace(wf.fit_config(), tests=tuple(task.args["tests"]), kinds=None)
    doc = discover(Path(wf.out) / "ingest", d, cfg, seed=wf.seed,
                   refit=wf.config["discrepancy"]["refit"],
                   extra_effects=tuple(wf.config["discrepancy"]["extra_effects"] or ()),
                   max_effects=wf.config["discrepancy"]["max_effects"],
                   check_seeds=tuple(wf.config["discrepancy"]["check_seeds"]), log=log)
    log(f"discrepancy: named effect(s) {', '.join(doc['named_effects']) or 'none'}")


def _report(wf, task, log):
    from ..report import render_report
    from .provenance import provenance
    out = Path(wf.report_dir) / "index.html"
    render_report(wf.out, out, workflow=wf.config, provenance=provenance(wf))
    log(f"report written: {out}")


RUNNERS = {"ingest": _ingest, "fit": _fit, "fit/summary": _fit_summary, "predict": _predict,
           "compare": _compare, "compare/summary": _compare_summary,
           "discrepancy": _discrepancy, "report": _report}


def runner_of(task):
    return RUNNERS.get(task.name) or RUNNERS[task.stage]


def execute(wf, task, numba_threads: int | None = None) -> dict:
    """Run one task (in this process or a worker). Returns {"ok", "seconds", "error"}; never
    raises for a task's own failure (the runner reports it), only for KeyboardInterrupt."""
    if numba_threads:
        import numba
        numba.set_num_threads(max(1, min(numba_threads, numba.config.NUMBA_NUM_THREADS)))
    log = TaskLog(wf.out, task.name)
    t0 = time.perf_counter()
    cache.forget(wf.out, task.name)
    try:
        log(f"start {task.name}")
        runner_of(task)(wf, task, log)
        secs = time.perf_counter() - t0
        cache.record(wf.out, task, secs)
        log(f"done {task.name} in {secs:.1f} s")
        return {"ok": True, "seconds": secs, "error": None}
    except (InputError, ValueError, OSError) as e:
        msg = " ".join(str(e).split()) or type(e).__name__
        log(f"FAILED: {msg}")
        log(traceback.format_exc())
        return {"ok": False, "seconds": time.perf_counter() - t0, "error": msg}
    except Exception as e:      # a bug: keep the traceback in the task's log, report one line
        log(traceback.format_exc())
        return {"ok": False, "seconds": time.perf_counter() - t0,
                "error": f"{type(e).__name__}: {' '.join(str(e).split())} (traceback in "
                         f"{task_log_path(wf.out, task.name)})"}
    finally:
        log.close()
