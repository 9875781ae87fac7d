"""Provenance of a run folder: package version, workflow file and hash, seed, input hashes, and
per task its key, status in the last run and run time (from the cache manifests). Written to
RUN/run.json by the runner and shown in the report."""
from __future__ import annotations

import json
from pathlib import Path

from .. import atomic
from ..environment import environment, timestamp
from . import cache

RUN_FILE = "run.json"


def provenance(wf, statuses: dict | None = None, started: str | None = None) -> dict:
    from .. import __version__
    from .plan import plan
    tasks = plan(wf)
    prev = {}
    p = Path(wf.out) / RUN_FILE
    if p.is_file():
        try:
            prev = json.loads(p.read_text())
        except ValueError:
            prev = {}
    statuses = statuses if statuses is not None else {
        t["name"]: t for t in prev.get("tasks", [])}
    rows = []
    for name, t in tasks.items():
        m = cache.read(wf.out, name) or {}
        st = statuses.get(name, {})
        rows.append({"name": name, "stage": t.stage, "key": t.key,
                     "status": st.get("status", "cached" if m else "not run"),
                     "seconds": m.get("seconds", st.get("seconds")),
                     "finished": m.get("finished"), "error": st.get("error")})
    ingest = tasks["ingest"].parts
    camp = Path(wf.campaign)
    inputs = [{"path": str(wf.path), "sha256": wf.sha256},
              {"path": str(camp / "campaign.toml"), "sha256": ingest["campaign_toml"]}]
    from ..campaign import load_campaign
    c = load_campaign(camp, read_records=False)
    for te in c.tests:
        inputs.append({"path": str(camp / te.file), "sha256": ingest["records"][te.id]})
    return {"package_version": __version__, "environment": environment(),
            "workflow": {"name": wf.name, "file": str(wf.path), "sha256": wf.sha256,
                         "config": wf.config},
            "seed": wf.seed, "started": started or prev.get("started"),
            "finished": timestamp(), "inputs": inputs, "tasks": rows}


def write(wf, statuses: dict, started: str) -> dict:
    doc = provenance(wf, statuses, started)
    atomic.write_json(Path(wf.out) / RUN_FILE, doc)
    return doc
