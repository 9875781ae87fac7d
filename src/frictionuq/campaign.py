"""Campaigns (spec section 7): a folder with `campaign.toml` and one record file per test, read,
validated and converted to SI. The top of the data flow: everything downstream gets `Campaign`
objects whose records are SI arrays (s, m, N; `applied` in N, or Pa for a pressure).

`load_campaign(path)` reads either a campaign folder (campaign.toml) or a folder written by
`frictionuq ingest` (manifest.json, already SI; see frictionuq.ingest).

campaign.toml schema (unknown keys are refused, so a typo never passes silently):
    name = "..."                      required
    device, description = "..."       optional text
    [units]      time, displacement, force, applied           required (frictionuq.units)
    [geometry]   drum_radius (m), damping_radius (m), wrap_deg, mu_design, C_design   optional
    [columns]    time, displacement, force, applied: the CSV's own header names   optional
    [twin], [source]                  optional free tables (provenance), kept as metadata
    [[tests]]    id, file, applied (required); kind = harmonic|earthquake|other,
                 frequency_hz (> 0), amplitude (> 0, displacement unit), description (optional)
A test's `file` is a CSV, or an ARTS-format JSON record (.json / .json.gz) whose own unit keys
must agree with [units] (frictionuq.records).
"""
from __future__ import annotations

import hashlib
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import units as U
from .errors import InputError, bom_hint, not_a_file, unknown
from .records import MIN_SAMPLES, check_time, read_arts_json, read_csv

KINDS = ("harmonic", "earthquake", "other")
UNIT_KINDS = {"time": "time", "displacement": "displacement", "force": "force", "applied": "applied"}
TOP_KEYS = {"name", "device", "description", "units", "geometry", "columns", "tests", "twin", "source"}
TEST_KEYS = {"id", "file", "applied", "kind", "frequency_hz", "amplitude", "description"}
# a tuple, not a set: the order the geometry is written in (manifest.json, advantage.json) is then
# the same in every process (a set follows the per-process string hash seed)
GEOMETRY_KEYS = ("drum_radius", "damping_radius", "wrap_deg", "mu_design", "C_design")
COLUMN_KEYS = ("time", "displacement", "force", "applied")
ID_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")


@dataclass
class Record:
    """One test's samples in SI: t (s), x (m), force (N), applied (N or Pa, or None)."""
    t: np.ndarray
    x: np.ndarray
    force: np.ndarray
    applied: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.t.size)

    @property
    def rate_hz(self) -> float:
        return float(1.0 / np.median(np.diff(self.t)))


@dataclass
class Test:
    id: str
    file: str                      # as written in campaign.toml (relative to the campaign)
    applied: float                 # nominal applied force (N) or pressure (Pa), SI
    kind: str = "other"
    frequency_hz: float | None = None
    amplitude: float | None = None  # m
    description: str = ""
    sha256: str = ""               # of the source file as stored
    record: Record | None = None


@dataclass
class Campaign:
    name: str
    path: Path
    units: dict[str, str]          # the units of the source files (before conversion)
    tests: list[Test]
    device: str = ""
    description: str = ""
    geometry: dict[str, float] | None = None
    columns: dict[str, str] = field(default_factory=dict)
    meta: dict = field(default_factory=dict)   # [twin], [source] tables, toml hash
    ingested: bool = False

    @property
    def applied_si_unit(self) -> str:
        """'N' for a force, 'Pa' for a pressure."""
        return U.si_unit_of_applied(self.units["applied"])

    def test(self, test_id: str) -> Test:
        for t in self.tests:
            if t.id == test_id:
                return t
        raise InputError(f"campaign {self.name!r} has no test {test_id!r}; "
                         f"its tests: {', '.join(t.id for t in self.tests)}")

    def applied_levels(self) -> list[float]:
        """The distinct nominal applied levels (SI), ascending."""
        return sorted({round(t.applied, 9) for t in self.tests})

    def applied_display(self, value_si: float) -> str:
        """An applied level in the campaign's own unit, with the unit: '36 lb'."""
        unit = self.units["applied"]
        return f"{U.from_si(value_si, 'applied', unit):g} {unit}"


def check_campaign(camp: Campaign) -> None:
    """Validate a Campaign built in memory (a notebook's arrays, not load_campaign's files) as
    load_campaign validates files: unique valid ids, known kinds, applied >= 0, and per test a
    record of 1-D numeric arrays of one length (at least MIN_SAMPLES), finite, with time strictly
    increasing. Raises InputError naming the test, the array and the first bad sample."""
    if not isinstance(camp, Campaign):
        raise InputError(f"expected a Campaign (frictionuq.load_campaign), got {_type_name(camp)}")
    w = f"campaign {camp.name!r}"
    if not camp.tests:
        raise InputError(f"{w}: no tests; a campaign needs at least one test")
    try:
        U.si_unit_of_applied(camp.units["applied"])
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{w}: units must name the applied unit (units['applied'], e.g. 'N', 'lb' "
                         f"or 'psi'); got {camp.units!r}") from None
    seen = set()
    for te in camp.tests:
        if not isinstance(te, Test):
            raise InputError(f"{w}: tests must be Test objects, got {_type_name(te)}")
        if not (isinstance(te.id, str) and ID_PATTERN.match(te.id)):
            raise InputError(f"{w}: {te.id!r} is not a valid test id (letters, digits and ._+- "
                             "only, starting with a letter or digit)")
        if te.id in seen:
            raise InputError(f"{w}: duplicated test id {te.id!r}")
        seen.add(te.id)
        wt = f"{w}, test {te.id!r}"
        try:
            applied = float(te.applied)
        except (TypeError, ValueError):
            applied = float("nan")
        if not (np.isfinite(applied) and applied >= 0):
            raise InputError(f"{wt}: applied must be a finite number >= 0 (SI), got {te.applied!r}")
        if te.kind not in KINDS:
            raise InputError(f"{wt}: kind {te.kind!r} is not one of {', '.join(KINDS)}")
        r = te.record
        if not isinstance(r, Record):
            raise InputError(f"{wt}: no record (expected a Record of SI arrays t, x, force), got "
                             f"{_type_name(r)}")
        n = None
        for name in ("t", "x", "force", "applied"):
            v = getattr(r, name)
            if v is None and name == "applied":
                continue
            try:
                a = np.asarray(v, dtype=float)
            except (TypeError, ValueError):
                raise InputError(f"{wt}: record.{name} is not an array of numbers") from None
            if a.ndim != 1:
                raise InputError(f"{wt}: record.{name} must be 1-D, got shape {a.shape}")
            if n is None:
                n = a.size
                if n < MIN_SAMPLES:
                    raise InputError(f"{wt}: {n} samples; a record needs at least {MIN_SAMPLES}")
            elif a.size != n:
                raise InputError(f"{wt}: record.{name} has {a.size} samples, record.t has {n}")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise InputError(f"{wt}: record.{name} has {bad.size} NaN or infinite sample(s), the "
                                 f"first at index {int(bad[0])}")
            if name == "t":
                check_time(wt, a, line_offset=0, what="record.t, index")


def sha256_file(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# ------------------------------------------------------------------ campaign.toml

def _type_name(v) -> str:
    return {str: "text", int: "a number", float: "a number", bool: "true/false",
            list: "a list", dict: "a table", type(None): "nothing"}.get(type(v), type(v).__name__)


def _get(where: str, table: dict, key: str, kind, required: bool = True):
    if key not in table:
        if required:
            raise InputError(f"{where}: missing key {key!r}")
        return None
    v = table[key]
    if kind is float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{where}, key {key}: expected a number, got {_type_name(v)} ({v!r})")
        v = float(v)
        if not np.isfinite(v):
            raise InputError(f"{where}, key {key}: {v} is not finite")
        return v
    if not isinstance(v, kind):
        want = {str: "text", dict: "a table", list: "a list"}[kind]
        raise InputError(f"{where}, key {key}: expected {want}, got {_type_name(v)} ({v!r})")
    return v


def _unknown(where: str, table: dict, allowed, what: str) -> None:
    extra = sorted(set(table) - set(allowed))
    if extra:
        raise InputError(f"{where}: {unknown(what, extra[0], sorted(allowed))}")


def read_toml(folder: Path) -> tuple[dict, Path]:
    folder = Path(folder)
    if not folder.exists():
        raise InputError(f"{folder}: no such campaign folder")
    if not folder.is_dir():
        raise InputError(f"{folder}: a campaign is a folder holding campaign.toml")
    toml = folder / "campaign.toml"
    if not toml.is_file():
        raise InputError(f"{toml}: missing (a campaign folder needs campaign.toml, spec section 7)")
    raw = toml.read_bytes()
    try:
        return tomllib.loads(raw.decode("utf-8")), toml
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"{toml}: not valid TOML ({' '.join(str(e).split())}){bom_hint(raw)}") from None
    except UnicodeDecodeError:
        raise InputError(f"{toml}: not valid TOML (not UTF-8 text)") from None


def parse_config(doc: dict, toml: Path) -> dict:
    """Validate the parsed campaign.toml; return a normalised dict (values in file units)."""
    w = str(toml)
    _unknown(w, doc, TOP_KEYS, "key")
    cfg = {"name": _get(w, doc, "name", str).strip(),
           "device": _get(w, doc, "device", str, False) or "",
           "description": _get(w, doc, "description", str, False) or ""}
    if not cfg["name"]:
        raise InputError(f"{w}, key name: must not be empty")
    units = _get(w, doc, "units", dict)
    _unknown(f"{w}, table [units]", units, UNIT_KINDS, "unit key")
    cfg["units"] = {}
    for key, kind in UNIT_KINDS.items():
        u = _get(f"{w}, table [units]", units, key, str)
        try:
            U.factor(kind, u)
        except ValueError as e:
            raise InputError(f"{w}, key units.{key}: {e}") from None
        cfg["units"][key] = u
    geo = _get(w, doc, "geometry", dict, False)
    if geo is not None:
        _unknown(f"{w}, table [geometry]", geo, GEOMETRY_KEYS, "geometry key")
        cfg["geometry"] = {}
        for key in GEOMETRY_KEYS:
            v = _get(f"{w}, table [geometry]", geo, key, float, False)
            if v is not None:
                if not v > 0:
                    raise InputError(f"{w}, key geometry.{key}: must be > 0, got {v:g}")
                cfg["geometry"][key] = v
    cols = _get(w, doc, "columns", dict, False) or {}
    _unknown(f"{w}, table [columns]", cols, COLUMN_KEYS, "column key")
    cfg["columns"] = {k: _get(f"{w}, table [columns]", cols, k, str) for k in cols}
    used = {}                                 # header name -> the quantity read from it
    for k in ("time", "displacement", "force", "applied"):
        name = cfg["columns"].get(k, k)
        if name in used:
            raise InputError(f"{w}, table [columns]: {used[name]} and {k} are both read from "
                             f"column {name!r}; each quantity needs its own column")
        used[name] = k
    cfg["meta"] = {k: doc[k] for k in ("twin", "source") if k in doc}
    tests = _get(w, doc, "tests", list)
    if not tests:
        raise InputError(f"{w}: no [[tests]]; a campaign needs at least one test")
    seen: dict[str, int] = {}
    cfg["tests"] = []
    for i, t in enumerate(tests):
        wt = f"{w}, tests[{i}]"
        if not isinstance(t, dict):
            raise InputError(f"{wt}: expected a table ([[tests]]), got {_type_name(t)}")
        _unknown(wt, t, TEST_KEYS, "key")
        tid = _get(wt, t, "id", str)
        if not ID_PATTERN.match(tid):
            raise InputError(f"{wt}, key id: {tid!r} is not a valid test id (letters, digits and "
                             "._+- only, starting with a letter or digit)")
        if tid in seen:
            raise InputError(f"{wt}, key id: duplicated test id {tid!r} (also tests[{seen[tid]}])")
        seen[tid] = i
        entry = {"id": tid, "file": _get(wt, t, "file", str), "applied": _get(wt, t, "applied", float),
                 "kind": _get(wt, t, "kind", str, False) or "other",
                 "frequency_hz": _get(wt, t, "frequency_hz", float, False),
                 "amplitude": _get(wt, t, "amplitude", float, False),
                 "description": _get(wt, t, "description", str, False) or ""}
        if entry["applied"] < 0:
            raise InputError(f"{wt}, key applied: must be >= 0, got {entry['applied']:g}")
        if entry["kind"] not in KINDS:
            raise InputError(f"{wt}, key kind: {entry['kind']!r} is not one of {', '.join(KINDS)}")
        for k in ("frequency_hz", "amplitude"):
            if entry[k] is not None and not entry[k] > 0:
                raise InputError(f"{wt}, key {k}: must be > 0, got {entry[k]:g}")
        cfg["tests"].append(entry)
    return cfg


# ------------------------------------------------------------------ records

def read_record(folder: Path, test: dict, units: dict, columns: dict, where: str) -> tuple[Record, str]:
    """Read one test's file (CSV or ARTS JSON) and convert it to SI."""
    rel = test["file"]
    path = (folder / rel)
    if not_a_file(path):
        raise InputError(f"{where}, key file: {path}: {not_a_file(path)}")
    name = path.name.lower()
    if name.endswith(".json") or name.endswith(".json.gz"):
        cols, own, _ = read_arts_json(path)
        for key, u in own.items():
            try:
                f_own = U.factor(UNIT_KINDS[key], u)
            except ValueError:
                raise InputError(f"{path}, key {key} units: unknown unit {u!r}") from None
            if f_own != U.factor(UNIT_KINDS[key], units[key]):
                raise InputError(f"{path}: the record's {key} unit {u!r} contradicts the campaign's "
                                 f"units.{key} = {units[key]!r}")
        check_time(path, cols["time"], line_offset=0, what="key data, row")
    else:
        hdr = {k: columns.get(k, k) for k in ("time", "displacement", "force")}
        cols = read_csv(path, hdr, {"applied": columns.get("applied", "applied")})  # time checked
    si = {}
    for key, kind in (("time", "time"), ("displacement", "displacement"), ("force", "force"),
                      ("applied", "applied")):
        if key not in cols:
            continue
        with np.errstate(over="ignore"):
            si[key] = U.to_si(cols[key], kind, units[key])
        bad = np.flatnonzero(~np.isfinite(si[key]))
        if bad.size:      # finite in the file, beyond float range in SI (1e308 kN)
            k = int(bad[0])
            raise InputError(f"{path}, data row {k + 1}, {key}: "
                             f"{cols[key][k]:g} {units[key]} overflows when converted to SI")
    rec = Record(t=si["time"], x=si["displacement"], force=si["force"], applied=si.get("applied"))
    return rec, sha256_file(path)


def load_campaign(path, read_records: bool = True) -> Campaign:
    """A campaign folder (campaign.toml) or an ingested folder (manifest.json), validated, SI."""
    path = Path(path)
    if (path / "manifest.json").is_file() and not (path / "campaign.toml").is_file():
        from .ingest import load_ingested
        return load_ingested(path, read_records=read_records)
    doc, toml = read_toml(path)
    cfg = parse_config(doc, toml)
    tests = []
    for i, t in enumerate(cfg["tests"]):
        te = Test(id=t["id"], file=t["file"],
                  applied=float(U.to_si(t["applied"], "applied", cfg["units"]["applied"])),
                  kind=t["kind"], frequency_hz=t["frequency_hz"],
                  amplitude=(None if t["amplitude"] is None else
                             float(U.to_si(t["amplitude"], "displacement", cfg["units"]["displacement"]))),
                  description=t["description"])
        if read_records:
            te.record, te.sha256 = read_record(path, t, cfg["units"], cfg["columns"], f"{toml}, tests[{i}]")
        elif not_a_file(path / t["file"]):    # the records unread, but there to be read
            raise InputError(f"{toml}, tests[{i}], key file: {path / t['file']}: "
                             f"{not_a_file(path / t['file'])}")
        tests.append(te)
    meta = dict(cfg["meta"])
    meta["campaign_toml_sha256"] = sha256_file(toml)
    return Campaign(name=cfg["name"], path=path, units=cfg["units"], tests=tests,
                    device=cfg["device"], description=cfg["description"],
                    geometry=cfg.get("geometry"), columns=cfg["columns"], meta=meta)
