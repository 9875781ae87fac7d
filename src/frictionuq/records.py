"""Readers of one test record: a CSV file or an ARTS-format JSON record (`.json`, `.json.gz`).

Both return the raw columns in the file's own units; `frictionuq.campaign` converts to SI. Every
problem raises `InputError` with one line naming the file, the line or key, and what is wrong.

CSV: a header row, then one row per sample. Line numbers in messages are the file's own (the
header is line 1), so `sed -n 7p file.csv` shows the offending row.

ARTS JSON (ARTS Lab, `Dataset-Friction-Damper-with-Backlash`; see data/brfd-arts-*/README.md):
an object with `data` (rows of `t [s]`, `x [in]`, `F friction force [kip]`, `v [in/s]`,
`F_act1 [lb]`, `F_act2 [lb]`), `dt`, `sampling freq` and the unit keys `time units`,
`displacement units`, `friction force units`, `actuator force units`. The measured applied force
is |F_act1| + |F_act2| (spec section 7: only one band actuator is active at a time).
"""
from __future__ import annotations

import gzip
import json
import re
import zlib
from pathlib import Path

import numpy as np
import pandas as pd

from .errors import InputError, not_a_file

MIN_SAMPLES = 10
ARTS_UNIT_KEYS = {"time": "time units", "displacement": "displacement units",
                  "force": "friction force units", "applied": "actuator force units"}
ARTS_NAMES = ("t [s]", "x [in]", "F friction force [kip]", "v [in/s]", "F_act1 [lb]", "F_act2 [lb]")
ARTS_COLUMNS = len(ARTS_NAMES)


def _numeric_column(path, df: pd.DataFrame, header: str, logical: str) -> np.ndarray:
    """One column as float64; refuses text, empty cells, NaN and inf, naming the line."""
    col = df[header]
    num = pd.to_numeric(col, errors="coerce")
    bad = num.isna() | ~np.isfinite(num.to_numpy(dtype=float, na_value=np.nan))
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raw = col.iloc[i]
        if pd.isna(raw) or (isinstance(raw, str) and not raw.strip()):
            what = "empty cell"
        else:
            try:
                v = float(raw)
                what = f"{raw!r} is not finite" if not np.isnan(v) else f"{raw!r} is NaN"
            except (TypeError, ValueError):
                what = f"{raw!r} is not a number"
        raise InputError(f"{path}, line {int(col.index[i]) + 2}, column {header!r} ({logical}): {what}")
    return num.to_numpy(dtype=float)


def _open(path, mode="rt", **kw):
    """open(), or gzip.open() for a .gz file (records may be stored compressed)."""
    return (gzip.open if Path(path).suffix.lower() == ".gz" else open)(path, mode, **kw)


def read_csv(path, columns: dict[str, str], optional: dict[str, str] | None = None
             ) -> dict[str, np.ndarray]:
    """Columns of a CSV file: `columns` maps a logical name (time, displacement, ...) to the
    header to read; `optional` likewise for columns that may be absent. Extra columns are
    ignored. Returns {logical: float64 array} (file units)."""
    path = Path(path)
    if not_a_file(path):
        raise InputError(f"{path}: {not_a_file(path)}")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty")
    try:
        # blank lines kept as rows, then dropped, so that the index stays the file's line - 2
        df = pd.read_csv(path, dtype=str, keep_default_na=False, skipinitialspace=True,
                         skip_blank_lines=False)
    except pd.errors.EmptyDataError:
        raise InputError(f"{path}: the file is empty") from None
    except UnicodeDecodeError:      # pandas names a position in its own buffer: find the line
        raise InputError(f"{path}{_first_non_utf8_line(path)}: not UTF-8 text; save the file as "
                         "UTF-8 (e.g. a Latin-1 degree sign or micro sign)") from None
    except pd.errors.ParserError as e:
        raise InputError(_parser_error(path, e)) from None
    except (OSError, EOFError, zlib.error) as e:     # a damaged or truncated .gz, or I/O
        what = "not a readable compressed file" if path.suffix.lower() == ".gz" else "cannot read"
        raise InputError(f"{path}: {what} ({' '.join(str(e).split()) or type(e).__name__})") from None
    df.columns = [str(c).strip() for c in df.columns]
    blank = df.apply(lambda c: c.isna() | (c.astype(str).str.strip() == "")).all(axis=1)
    df = df[~blank.to_numpy()]
    names = [c.strip() for c in _header(path)]   # pandas renames a repeat NAME.1: read it here
    dup = next((c for i, c in enumerate(names) if c in names[:i]), None)
    if dup is not None:
        raise InputError(f"{path}: the header repeats column {dup!r}; give each column once")
    out = {}
    for logical, header in columns.items():
        if header not in df.columns:
            sep = next((d for d in (";", "\t", "|") if len(df.columns) == 1
                        and d in str(df.columns[0])), None)
            hint = (f" (the file looks {'tab' if sep == chr(9) else repr(sep)}-separated: "
                    "frictionuq reads comma-separated CSV)") if sep else ""
            raise InputError(f"{path}: missing column {header!r} ({logical}); "
                             f"the header has: {', '.join(map(repr, df.columns))}{hint}")
    if len(df) < MIN_SAMPLES:
        raise InputError(f"{path}: {len(df)} samples; a record needs at least {MIN_SAMPLES}")
    for logical, header in columns.items():
        out[logical] = _numeric_column(path, df, header, logical)
    for logical, header in (optional or {}).items():
        if header in df.columns:
            out[logical] = _numeric_column(path, df, header, logical)
    if "time" in out:        # named by the file's own line (blank lines counted)
        check_time(path, out["time"], lines=df.index.to_numpy() + 2)
    return out


def _parser_error(path, e: Exception) -> str:
    """pandas' tokenizer message in the file's terms (its line numbers are the file's own)."""
    m = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", str(e))
    if m:
        want, line, saw = m.groups()
        return (f"{path}, line {line}: {saw} values, but the header names {want} columns; "
                "remove the extra values or name their column in the header")
    return f"{path}: not a readable CSV file ({' '.join(str(e).split())})"


def _first_non_utf8_line(path) -> str:
    """', line N' of the first line of a (possibly gzipped) file that is not UTF-8, or ''."""
    try:
        with _open(path, "rb") as f:
            for n, line in enumerate(f, 1):
                try:
                    line.decode("utf-8")
                except UnicodeDecodeError:
                    return f", line {n}"
    except (OSError, EOFError, zlib.error):
        pass
    return ""


def _header(path) -> list[str]:
    """The CSV's header row as written (its first non-blank line)."""
    import csv
    with _open(path, "rt", newline="", encoding="utf-8", errors="replace") as f:
        for row in csv.reader(f):
            if any(c.strip() for c in row):
                return row
    return []


def check_time(path, t: np.ndarray, line_offset: int = 2, what: str = "line", lines=None) -> None:
    """Time must be strictly increasing; names the first offending line (or row): sample k's
    is lines[k] when given, else k + line_offset."""
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        k = int(bad[0]) + 1
        at = int(lines[k]) if lines is not None else k + line_offset
        raise InputError(f"{path}, {what} {at}: time is not strictly increasing "
                         f"({t[k - 1]:.10g} then {t[k]:.10g})")


def _load_json(path: Path):
    try:
        with _open(path, "rt", encoding="utf-8") as f:
            return json.load(f)
    except (OSError, EOFError, UnicodeDecodeError, zlib.error) as e:
        raise InputError(f"{path}: cannot read ({' '.join(str(e).split())})") from None
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None


def _arts_cell(i: int, j: int, v) -> str:
    """Where a cell is and what it holds, as JSON writes it (null, true, "text")."""
    return f"row {i}, column {j} ({ARTS_NAMES[j]}): {json.dumps(v)}"


def read_arts_json(path) -> tuple[dict[str, np.ndarray], dict[str, str], dict]:
    """An ARTS-format JSON record -> (columns {time, displacement, force, applied} in the
    record's units, the record's units {time, displacement, force, applied}, other metadata)."""
    path = Path(path)
    if not_a_file(path):
        raise InputError(f"{path}: {not_a_file(path)}")
    if path.stat().st_size == 0:
        raise InputError(f"{path}: the file is empty")
    d = _load_json(path)
    if not isinstance(d, dict):
        raise InputError(f"{path}: an ARTS record is a JSON object, got a {type(d).__name__}")
    for key in ("data",) + tuple(ARTS_UNIT_KEYS.values()):
        if key not in d:
            raise InputError(f"{path}: missing key {key!r} of the ARTS record format")
    units = {}
    for logical, key in ARTS_UNIT_KEYS.items():
        if not isinstance(d[key], str):
            raise InputError(f"{path}, key {key!r}: expected a unit name, got {d[key]!r}")
        units[logical] = d[key]
    rows = d["data"]
    if not isinstance(rows, list):
        raise InputError(f"{path}, key 'data': expected a list of rows")
    if len(rows) < MIN_SAMPLES:
        raise InputError(f"{path}: {len(rows)} samples; a record needs at least {MIN_SAMPLES}")
    try:
        a = np.array(rows, dtype=float)
    except (ValueError, TypeError):
        a = None
    if a is None or a.ndim != 2 or a.shape[1] != ARTS_COLUMNS:
        for i, r in enumerate(rows):
            if not isinstance(r, list) or len(r) != ARTS_COLUMNS:
                raise InputError(f"{path}, key data, row {i}: expected {ARTS_COLUMNS} values "
                                 f"({', '.join(ARTS_NAMES)})")
            for j, v in enumerate(r):
                if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
                    raise InputError(f"{path}, key data, {_arts_cell(i, j, v)} is not a number")
        raise InputError(f"{path}, key data: rows are not numeric")  # pragma: no cover
    fin = np.isfinite(a)
    if not fin.all():
        i, j = map(int, np.argwhere(~fin)[0])
        what = "is not a number" if rows[i][j] is None else "is not finite"
        raise InputError(f"{path}, key data, {_arts_cell(i, j, rows[i][j])} {what}")
    cols = {"time": a[:, 0], "displacement": a[:, 1], "force": a[:, 2],
            "applied": np.abs(a[:, 4]) + np.abs(a[:, 5])}
    meta = {k: d[k] for k in ("dt", "sampling freq") if k in d}
    if "dt" in d:
        try:
            dt = float(d["dt"])
        except (TypeError, ValueError):
            raise InputError(f"{path}, key 'dt': {d['dt']!r} is not a number") from None
        med = float(np.median(np.diff(a[:, 0])))
        if not (dt > 0 and abs(med - dt) <= 0.01 * dt):
            raise InputError(f"{path}, key 'dt': {dt:g} contradicts the time column "
                             f"(median step {med:g})")
    return cols, units, meta
