"""Section "provenance": package version, workflow file and hash, configuration, seeds, input
hashes, per-task run times and status (the `provenance` dict, format of run.json), the output
files of the run folder with what records their version, configuration and seed, and the
report's generation time."""
from __future__ import annotations

import json

from ... import __version__
from .. import blocks as B
from ..context import section_of
from ..tables import DASH, badge, kv_table, num, table

OK_STATUS = ("ran", "cached", "ok", "done", "skipped", "up-to-date")


def _seeds(ctx) -> str:
    seeds = []
    if ctx.provenance.get("seed") is not None:
        seeds.append(f"run: {ctx.provenance['seed']}")
    wf_seed = section_of(ctx.workflow, "workflow").get("seed")
    if wf_seed is not None:
        seeds.append(f"workflow: {wf_seed}")
    cfg = section_of(ctx.summary() or {}, "config")
    if cfg.get("seed") is not None:
        seeds.append(f"fits: {cfg['seed']}")
    return "; ".join(seeds) or "not recorded"


def _wall_seconds(started, finished) -> float | None:
    """Seconds between two ISO timestamps of the run record, None if either is missing/bad."""
    from datetime import datetime
    try:
        return (datetime.fromisoformat(str(finished)) - datetime.fromisoformat(str(started))
                ).total_seconds()
    except (TypeError, ValueError):
        return None


OUTPUT_SUFFIXES = (".json", ".csv", ".nc", ".h5", ".png")
MAX_OUTPUT_ROWS = 300


def _json_doc(path):
    """The JSON object in `path`, or None (unreadable, or not an object)."""
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return doc if isinstance(doc, dict) else None


def _recorded_by(path, run_dir, docs: dict) -> str:
    """What records an output file's package version, configuration and seed: the file itself
    (a JSON with package_version; the netCDF and HDF5 files' attributes) or the JSON beside it
    or one folder up. docs: {path: the JSON object or None} of the run folder's JSON files."""
    if path.suffix in (".nc", ".h5"):
        return "its own attributes"
    versioned = [p for p, d in docs.items() if d is not None and "package_version" in d]
    if path in versioned:
        seed = docs[path].get("seed")
        return "itself" + ("" if seed is None else f" (seed {seed})")
    for folder in (path.parent, path.parent.parent):
        beside = sorted(p for p in versioned if p.parent == folder and p != path)
        if beside:
            return ", ".join(str(p.relative_to(run_dir)) for p in beside)
    return DASH


def _outputs(ctx) -> list[dict]:
    from pathlib import Path
    run = Path(ctx.run_dir)
    if not run.is_dir():
        return [B.note(f"No run folder at {run}: no output files to list.")]
    files = sorted(p for p in run.rglob("*") if p.is_file() and p.suffix in OUTPUT_SUFFIXES
                   and not any(part.startswith(".") for part in p.relative_to(run).parts))
    if not files:
        return [B.note("No output files found in the run folder.")]
    docs = {p: _json_doc(p) for p in files if p.suffix == ".json"}     # each read once
    rows = [[str(p.relative_to(run)), num(p.stat().st_size / 1e3, 3), _recorded_by(p, run, docs)]
            for p in files[:MAX_OUTPUT_ROWS]]
    more = len(files) - len(rows)
    return [B.html(table(["file (in the run folder)", "size (kB)",
                          "version, configuration and seed recorded in"], rows,
                         caption=f"output files: {len(files)}" + (f", the first {len(rows)} listed"
                                                                  if more > 0 else "")))]


def build(ctx, generated: str) -> list[dict]:
    prov, wf = ctx.provenance, section_of(ctx.provenance, "workflow")
    info = [("frictionuq version of the run", prov.get("package_version", "not recorded")),
            ("frictionuq version of this report", __version__),
            ("workflow", wf.get("name") or section_of(ctx.workflow, "workflow").get("name") or "not recorded"),
            ("workflow file", wf.get("file", "not recorded")),
            ("workflow file sha256", wf.get("sha256", "not recorded")),
            ("seeds", _seeds(ctx)),
            ("run started", prov.get("started", "not recorded")),
            # the record the report reads is written just before it (the run's end comes after)
            ("run record written", prov.get("finished", "not recorded")),
            ("run folder", str(ctx.run_dir)),
            ("report generated", generated)]
    env = section_of(prov, "environment")
    if env:     # the software and machine of the run (frictionuq.environment)
        pk = env.get("packages") or {}
        info += [("Python", env.get("python", "not recorded")),
                 ("packages", ", ".join(f"{k} {v}" for k, v in pk.items() if v) or "not recorded"),
                 ("machine", f"{env.get('cpu') or '?'} ({env.get('cores') or '?'} cores), numba "
                             f"compiles for {env.get('numba_cpu') or '?'}, {env.get('platform') or '?'}"),
                 ("threads", f"numba {env.get('numba_threads') or '?'}, "
                             f"BLAS {env.get('blas_threads') or 'not recorded'}")]
    else:
        info.append(("software and machine", "not recorded (run made before frictionuq recorded them)"))
    out = [B.html(kv_table(info, caption="run"))]
    inputs = [i for i in prov.get("inputs") or [] if isinstance(i, dict)]
    if inputs:
        out.append(B.html(table(["input file", "sha256"], [[i.get("path", DASH), i.get("sha256", DASH)]
                                                          for i in inputs], caption="inputs")))
    else:
        out.append(B.note("No input hashes recorded."))
    tasks = [t for t in prov.get("tasks") or [] if isinstance(t, dict)]
    if tasks:
        rows, classes = [], []
        for t in tasks:
            status = str(t.get("status", DASH))
            if t.get("stage") == "report" and status.lower() != "failed":
                # the record is read while this task runs: whatever it says of the task is of
                # an earlier run (cached, or not run yet)
                status = "running (writes this page)"
            ok = (status.lower() in OK_STATUS or status.startswith("running")) and not t.get("error")
            rows.append([t.get("name", DASH), t.get("stage", DASH), badge(status, ok),
                         num(t.get("seconds"), 3), t.get("key") or DASH, t.get("error") or ""])
            classes.append("" if ok else "flagged")
        total = sum(float(t.get("seconds") or 0) for t in tasks)
        wall = _wall_seconds(prov.get("started"), prov.get("finished") or generated)
        out.append(B.html(table(["task", "stage", "status", "run time (s)", "cache key", "error"],
                                rows, row_classes=classes,
                                caption=f"tasks (their run times, each from when it last ran, "
                                        f"add up to {num(total, 4)} s"
                                        + ("" if wall is None else
                                           f"; this run had taken {num(wall, 4)} s when the "
                                           "record was written") + ")")))
    else:
        out.append(B.note("No task record."))
    out += _outputs(ctx)
    config = wf.get("config") if isinstance(wf.get("config"), dict) else ctx.workflow
    out.append(B.heading("Workflow configuration"))
    out.append(B.pre(json.dumps(config or {}, indent=2, sort_keys=False, default=str)))
    return out
