"""The stage cache: one manifest per finished task, under RUN/.cache/.

A manifest records the task's key (see plan) and the SHA-256 of every file it wrote. A task is up
to date when its manifest exists, its key matches and every output file still has the recorded
hash: an edited, truncated or deleted output (a corrupted cache entry) makes the task stale and it
is recomputed. The manifest is written last and atomically, and removed before a task reruns, so
an interrupted task is never taken for a finished one.
"""
from __future__ import annotations

import hashlib
import json
import os
import re
from pathlib import Path

from .. import atomic
from ..environment import timestamp

CACHE_DIR = ".cache"
KEY_FILE = ".task-key"       # in a task's own output folder: lets an interrupted fit resume


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]", "_", name)


def manifest_path(run_dir, name: str) -> Path:
    return Path(run_dir) / CACHE_DIR / f"{_safe(name)}.json"


def resolve(run_dir, out: str) -> Path:
    p = Path(out)
    return p if p.is_absolute() else Path(run_dir) / p


def sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def output_files(run_dir, outputs) -> dict[str, str]:
    """{path: sha256} of every file of the outputs (folders walked; hidden files skipped)."""
    files = {}
    for out in outputs:
        p = resolve(run_dir, out)
        if p.is_file():
            files[out] = sha256(p)
        elif p.is_dir():
            for root, dirs, names in os.walk(p):
                dirs[:] = sorted(d for d in dirs if not d.startswith("."))
                for n in sorted(names):
                    if n.startswith("."):
                        continue
                    f = Path(root) / n
                    rel = f"{out}/{f.relative_to(p).as_posix()}"
                    files[rel] = sha256(f)
    return files


def key_deps(task) -> list[str]:
    return list(task.deps if task.key_deps is None else task.key_deps)


def outputs_digest(run_dir, name: str) -> str | None:
    """Digest of the outputs a finished task recorded (None: no cache entry)."""
    m = read(run_dir, name)
    if not m or "outputs" not in m:
        return None
    return hashlib.sha256(json.dumps(m["outputs"], sort_keys=True).encode()).hexdigest()


def dep_digests(run_dir, task) -> dict:
    return {d: outputs_digest(run_dir, d) for d in key_deps(task)}


def state(run_dir, task) -> tuple[bool, str]:
    """(up to date?, reason) for a planned task. Besides its own key and outputs, the outputs of
    the tasks it depends on must be those it was computed from (a dependency recomputed in
    another run makes it stale, as a newer prerequisite does in make)."""
    mp = manifest_path(run_dir, task.name)
    if not mp.is_file():
        return False, "never run (no cache entry)"
    try:
        m = json.loads(mp.read_text())
        recorded = m["outputs"]
        key = m["key"]
    except (OSError, ValueError, KeyError, TypeError):
        return False, "cache entry unreadable (corrupted): recompute"
    if key != task.key:
        return False, "inputs, settings or package version changed"
    for rel, h in recorded.items():
        p = resolve(run_dir, rel)
        if not p.is_file():
            return False, f"output {rel} is missing"
        if sha256(p) != h:
            return False, f"output {rel} changed since it was written (corrupted cache entry)"
    before = m.get("dep_outputs", {})
    for d, now in dep_digests(run_dir, task).items():
        if before.get(d) != now:
            return False, f"dependency {d} was recomputed since"
    return True, "up to date"


def record(run_dir, task, seconds: float) -> dict:
    from .. import __version__
    m = {"task": task.name, "stage": task.stage, "key": task.key, "package_version": __version__,
         "finished": timestamp(), "seconds": seconds,
         "outputs": output_files(run_dir, task.outputs), "dep_outputs": dep_digests(run_dir, task)}
    atomic.write_json(manifest_path(run_dir, task.name), m)
    return m


def read(run_dir, name: str) -> dict | None:
    try:
        return json.loads(manifest_path(run_dir, name).read_text())
    except (OSError, ValueError):
        return None


def forget(run_dir, name: str) -> None:
    manifest_path(run_dir, name).unlink(missing_ok=True)
