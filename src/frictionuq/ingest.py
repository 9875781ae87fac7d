"""`frictionuq ingest`: validate a whole campaign and write it in SI.

Output folder (replaced as a whole, only once everything has been read and validated, so a bad
campaign leaves an existing --out exactly as it was):
    manifest.json      format, package version, the campaign's metadata, its source units, the
                       SI units written, and per test: id, nominal applied level (SI and as
                       given), kind, frequency, amplitude, samples, duration, sampling rate,
                       source file and its SHA-256, written file and its SHA-256
    tests/<id>.csv     time (s), displacement (m), force (N)[, applied (N or Pa)]

`load_ingested` reads such a folder back into a `Campaign` (checking every file's hash, so a
corrupted or edited file is detected).
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from . import atomic
from .campaign import Campaign, Record, Test, load_campaign, sha256_file
from .environment import environment
from .errors import InputError
from .records import read_csv

FORMAT = "frictionuq-ingested/1"
#: every value written to round-trip exactly (17 significant digits): at 10, times of an absolute
#: clock (1.7e9 s) lost their fraction, and the records fitted from an ingested folder differed
#: from the campaign's own (the eps estimate moved with the rounding)
FLOAT_FMT = "%.17g"


def _csv_bytes(rec: Record) -> bytes:
    cols = [rec.t, rec.x, rec.force] + ([rec.applied] if rec.applied is not None else [])
    header = "time,displacement,force" + (",applied" if rec.applied is not None else "")
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack(cols), fmt=FLOAT_FMT, delimiter=",", header=header, comments="")
    return buf.getvalue().encode()


def ingest(campaign_dir, out) -> dict:
    """Validate `campaign_dir` and write it in SI to `out`. Returns the manifest."""
    from . import __version__
    camp_path, out = Path(campaign_dir), Path(out)
    camp = load_campaign(camp_path)
    if camp.ingested:
        raise InputError(f"{camp_path}: already an ingested (SI) folder; nothing to ingest")
    atomic.check_replaceable(camp_path, out, "manifest.json", "campaign", "an ingested campaign",
                             owned=("manifest.json", "tests"))
    from .units import SI
    manifest = {
        "format": FORMAT, "package_version": __version__, "environment": environment(),
        "name": camp.name, "device": camp.device,
        "description": camp.description, "source_folder": str(camp_path.resolve()),
        "source_units": camp.units, "columns": camp.columns, "geometry": camp.geometry,
        "units": {"time": SI["time"], "displacement": SI["displacement"], "force": SI["force"],
                  "applied": camp.applied_si_unit},
        "meta": camp.meta, "tests": []}
    with atomic.output_dir(out) as tmp:
        (tmp / "tests").mkdir()
        for te in camp.tests:
            r = te.record
            data = _csv_bytes(r)
            rel = f"tests/{te.id}.csv"
            (tmp / rel).write_bytes(data)
            manifest["tests"].append({
                "id": te.id, "applied": te.applied, "applied_as_given": camp.applied_display(te.applied),
                "kind": te.kind, "frequency_hz": te.frequency_hz, "amplitude_m": te.amplitude,
                "description": te.description, "samples": r.n,
                "duration_s": float(r.t[-1] - r.t[0]), "rate_hz": r.rate_hz,
                "has_applied_signal": r.applied is not None,
                "source_file": te.file, "source_sha256": te.sha256,
                "file": rel, "sha256": sha256_file(tmp / rel)})
        atomic.write_json(tmp / "manifest.json", manifest)
    return manifest


def load_ingested(path, read_records: bool = True) -> Campaign:
    """An ingested folder -> Campaign with SI records (units = SI)."""
    path = Path(path)
    mpath = path / "manifest.json"
    try:
        m = json.loads(mpath.read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise InputError(f"{mpath}: cannot read the manifest ({' '.join(str(e).split())})") from None
    if not isinstance(m, dict) or m.get("format") != FORMAT:
        raise InputError(f"{mpath}: not a frictionuq ingested manifest (format {FORMAT!r})")

    def damaged(where, key, v):
        return InputError(f"{mpath}, {where}key {key}: {'missing' if v is None else repr(v)} is not "
                          "a valid value; the manifest was edited or damaged: ingest the campaign again")

    def field(d, key, where, kind, optional=False):
        """d[key] checked: a damaged manifest is named, not a KeyError."""
        v = d.get(key)
        if not ((v is None and optional) or (isinstance(v, kind) and not isinstance(v, bool))):
            raise damaged(where, key, v)
        return v
    for key, kind in (("name", str), ("source_units", dict), ("package_version", str), ("tests", list)):
        field(m, key, "", kind)
    tests = []
    for i, t in enumerate(m["tests"]):
        if not isinstance(t, dict):
            raise damaged("", f"tests[{i}]", t)
        w = f"tests[{i}], "
        te = Test(id=field(t, "id", w, str), file=field(t, "file", w, str),
                  applied=float(field(t, "applied", w, (int, float))), kind=field(t, "kind", w, str),
                  frequency_hz=field(t, "frequency_hz", w, (int, float), optional=True),
                  amplitude=field(t, "amplitude_m", w, (int, float), optional=True),
                  description=t.get("description", ""), sha256=field(t, "sha256", w, str))
        if read_records:
            f = path / t["file"]
            if not f.is_file():
                raise InputError(f"{mpath}, tests[{i}]: file {f} not found")
            if sha256_file(f) != t["sha256"]:
                raise InputError(f"{f}: its SHA-256 differs from the manifest's (edited or "
                                 "corrupted); ingest the campaign again")
            hdr = {"time": "time", "displacement": "displacement", "force": "force"}
            cols = read_csv(f, hdr, {"applied": "applied"})
            te.record = Record(cols["time"], cols["displacement"], cols["force"], cols.get("applied"))
        tests.append(te)
    # source units are kept for display (e.g. applied levels shown as '36 lb')
    return Campaign(name=m["name"], path=path, units=m["source_units"], tests=tests,
                    device=m.get("device", ""), description=m.get("description", ""),
                    geometry=m.get("geometry"), columns=m.get("columns", {}),
                    meta=dict(m.get("meta", {}), manifest_package_version=m["package_version"]),
                    ingested=True)
