"""The task graph of a workflow: which stage tasks exist, what each depends on, and its cache key.

    ingest -> fit:<level> (one per applied force or test) -> fit/summary (summary.json, the
    force-dependence law, mechanical advantage) -> predict:<name> (validation of measured tests,
    harmonics, ground motions); ingest -> compare:<level>:<model> -> compare/summary;
    ingest -> discrepancy (when enabled); everything -> report

A task's key is the SHA-256 of its name, the content it reads (the source files of the tests it
uses, with their campaign entries and the campaign's units and columns), the settings it uses (a
fit or comparison: its own FitConfig, whichever workflow section they come from; not the test
selection lists, whose effect is the tests named in the key), the keys of the tasks it depends on
and the package version. Changing one test or one setting therefore changes the keys of exactly
the tasks that depend on it: a test added at one level leaves the other levels' fits up to date,
a [fit.sampler] setting leaves comparisons that have their own [compare.sampler] up to date, and
an edited [units] table (the records read in other units) or [geometry] table (mechanical
advantage) reruns what reads it. Keys are known before anything runs (the campaign's test
table is read, not its records), so `--dry-run` and `status` can say what would run and why.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import InputError

STAGES = ("ingest", "fit", "predict", "compare", "discrepancy", "report")
TARGETS = STAGES + ("all",)


@dataclass
class Task:
    name: str                      # e.g. "fit:applied-36lb"
    stage: str                     # one of STAGES
    deps: list[str]
    parts: dict                    # what the key is made of (JSON-able)
    outputs: list[str]             # files/folders, relative to the run folder or absolute
    args: dict = field(default_factory=dict)   # what tasks.execute needs besides the workflow
    heavy: bool = False            # sampling: sent to a worker process / the Dask cluster
    key: str = ""
    # deps whose keys enter this task's key; None: all. A task that reads only some tests of
    # the ingested campaign names those tests' content in its parts instead, so that a change
    # to another test leaves it up to date.
    key_deps: list[str] | None = None


def _h(obj) -> str:
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


def _file_hashes(camp) -> dict[str, str]:
    from ..campaign import sha256_file
    return {t.id: sha256_file(Path(camp.path) / t.file) for t in camp.tests}


def _config_part(cfg) -> dict:
    """A FitConfig as key content: every setting but the test selection (tests, kinds), whose
    effect, the tests chosen, is in the task's test parts."""
    d = dataclasses.asdict(cfg)
    d.pop("tests")
    d.pop("kinds")
    return d


def _campaign_part(camp) -> dict:
    """What every task reading records takes from campaign.toml besides its test entries: the
    records' units and column names."""
    return {"units": camp.units, "columns": camp.columns}


def _test_parts(tests, hashes) -> list[dict]:
    return [{"id": t.id, "applied": t.applied, "kind": t.kind, "frequency_hz": t.frequency_hz,
             "amplitude": t.amplitude, "sha256": hashes[t.id]} for t in tests]


def _select(camp, wf, ids, kinds, where: str):
    known = {t.id for t in camp.tests}
    bad = [i for i in ids if i not in known]
    if bad:
        raise InputError(f"{wf.path}: {where}: campaign {camp.name!r} has no test {bad[0]!r}; "
                         f"its tests: {', '.join(sorted(known))}")
    return [t for t in camp.tests if (not ids or t.id in ids) and (not kinds or t.kind in kinds)]


def plan(wf) -> dict[str, Task]:
    """The tasks of a workflow, in dependency order, keys filled in."""
    from .. import __version__
    from ..campaign import load_campaign
    from ..infer.fit import plan as fit_plan
    camp = load_campaign(wf.campaign, read_records=False)
    hashes = _file_hashes(camp)
    cfg = wf.config
    tasks: list[Task] = []
    toml = Path(wf.campaign) / "campaign.toml"
    toml_hash = hashlib.sha256(toml.read_bytes()).hexdigest()
    tasks.append(Task("ingest", "ingest", [], {"campaign_toml": toml_hash, "records": hashes},
                      ["ingest"]))

    f = cfg["fit"]
    fit_tests = _select(camp, wf, f["tests"], f["kinds"], "[fit] tests/kinds")
    if not fit_tests:
        raise InputError(f"{wf.path}: [fit] tests/kinds select no test of campaign {camp.name!r}")
    fcfg = wf.fit_config()
    specs = fit_plan(camp, f["by"], fcfg)
    fit_names = []
    for s in specs:
        name = f"fit:{s.id}"
        fit_names.append(name)
        tasks.append(Task(name, "fit", ["ingest"],
                          {"config": _config_part(fcfg), "by": f["by"], "seed": wf.seed,
                           "campaign": _campaign_part(camp), "tests": _test_parts(s.tests, hashes)},
                          [f"fit/{s.id}"], {"fit_id": s.id, "tests": [t.id for t in s.tests]},
                          heavy=True, key_deps=[]))
    # the summary also writes the mechanical advantage, from the campaign's geometry
    tasks.append(Task("fit/summary", "fit", fit_names,
                      {"law": wf.section_hash("law"), "campaign": {
                          **_campaign_part(camp), "geometry": camp.geometry,
                          "device": camp.device, "name": camp.name}},
                      ["fit/summary.json", "fit/law.json", "advantage"]))

    p = cfg["predict"]
    pred_names = []
    if p["validate"]:
        vt = _select(camp, wf, p["validate"], [], "[predict] validate")
        pred_names.append("predict:validation")
        tasks.append(Task("predict:validation", "predict", ["ingest", "fit/summary"],
                          {"n_draws": p["n_draws"], "seed": wf.seed,
                           "campaign": _campaign_part(camp), "tests": _test_parts(vt, hashes)},
                          ["predict/validation"], {"tests": [t.id for t in vt]},
                          key_deps=["fit/summary"]))
    for e in p["harmonic"] + p["ground_motion"]:
        name = f"predict:{e['name']}"
        pred_names.append(name)
        ground = "record" in e or "file" in e
        outs = [f"predict/{e['name']}"] + ([f"predict/inputs/{e['name']}.csv"] if ground else [])
        parts = {"n_draws": p["n_draws"], "seed": wf.seed, "input": e}
        if "file" in e:      # the task's key: the file's path relative to the workflow, and its bytes
            parts["input"] = {**e, "file": os.path.relpath(e["file"], wf.path.parent)}
        if ground:
            from ..campaign import sha256_file
            if "record" in e:
                from ..groundmotion import RECORDS, ground_motions_dir
                ref = RECORDS[e["record"]]
                gm = ground_motions_dir() / ref.folder / ref.file
            else:
                gm = Path(e["file"])
            parts["record_sha256"] = sha256_file(gm) if gm.is_file() else "missing"
        tasks.append(Task(name, "predict", ["fit/summary"], parts,
                          outs, {"input": e}))

    c = cfg["compare"]
    cmp_names = []
    if c["enabled"]:
        ct = _select(camp, wf, c["tests"] or f["tests"], c["kinds"] or f["kinds"],
                     "[compare] tests/kinds")
        from dataclasses import replace
        levels = fit_plan(camp, "applied", replace(fcfg, tests=tuple(t.id for t in ct), kinds=None))
        for lv in levels:
            for m in c["models"]:
                name = f"compare:{lv.id}:{m}"
                cmp_names.append(name)
                tasks.append(Task(name, "compare", ["ingest"],
                                  {"config": _config_part(wf.fit_config(compare_model=m)),
                                   "seed": wf.seed, "campaign": _campaign_part(camp),
                                   "tests": _test_parts(lv.tests, hashes)},
                                  [f"compare/{lv.id}/{m}"],
                                  {"level": lv.id, "model": m, "tests": [t.id for t in lv.tests]},
                                  heavy=True, key_deps=[]))
        tasks.append(Task("compare/summary", "compare", cmp_names, {},
                          ["compare/compare.json", "compare/compare.csv"],
                          {"levels": [lv.id for lv in levels]}))
        cmp_names = ["compare/summary"]

    disc = []
    dc = cfg["discrepancy"]
    if dc["enabled"]:
        dtests = _select(camp, wf, dc["tests"] or f["tests"], dc["kinds"] or f["kinds"],
                         "[discrepancy] tests/kinds")
        disc = ["discrepancy"]
        tasks.append(Task("discrepancy", "discrepancy", ["ingest"],
                          {"discrepancy": {k: v for k, v in dc.items()
                                           if k not in ("tests", "kinds", "enabled")},
                           "config": _config_part(fcfg), "seed": wf.seed,
                           "campaign": _campaign_part(camp), "tests": _test_parts(dtests, hashes)},
                          ["discrepancy"], {"tests": [t.id for t in dtests]}, heavy=True,
                          key_deps=[]))

    if cfg["report"]["enabled"]:
        deps = ["ingest", "fit/summary"] + pred_names + cmp_names + disc
        tasks.append(Task("report", "report", deps,
                          {"report": wf.section_hash("report"), "workflow": wf.section_hash("workflow")},
                          [str(Path(wf.report_dir) / "index.html")]))

    by_name = {t.name: t for t in tasks}
    for t in tasks:        # dependency order: every dep precedes its dependents
        t.key = _h({"task": t.name, "parts": t.parts, "version": __version__,
                    "deps": {d: by_name[d].key for d in
                             (t.deps if t.key_deps is None else t.key_deps)}})
    return by_name


def closure(tasks: dict[str, Task], targets) -> list[str]:
    """The tasks needed for targets (stage names or task names, 'all'), in dependency order."""
    targets = list(targets) or ["all"]
    wanted = set()
    for tg in targets:
        if tg == "all":
            wanted.update(tasks)
        elif tg in STAGES:
            wanted.update(n for n, t in tasks.items() if t.stage == tg)
        elif tg in tasks:
            wanted.add(tg)
        else:
            raise InputError(f"unknown target {tg!r}; targets: {', '.join(TARGETS)} or a task "
                             f"name ({', '.join(tasks)})")
    if not wanted:
        raise InputError(f"targets {targets}: the workflow has no such tasks (is the stage "
                         "disabled in the workflow file?)")
    need = set()
    stack = list(wanted)
    while stack:
        n = stack.pop()
        if n not in need:
            need.add(n)
            stack.extend(tasks[n].deps)
    return [n for n in tasks if n in need]
