"""`frictionuq simulate`: parameters from JSON, a displacement record from CSV, the force to CSV.

P.json: {"fc_fwd": ..., ..., "w": ..., "effects": {"reversal_hump": {"a_hump": 0.3, ...}}}, the
spec's SI names (likelihood-only `sigma_noise`, `force_offset` are accepted and ignored).
X.csv: columns `time` (s), `displacement` (m), optionally `applied` (N or Pa, for the
`applied_tracking` effect). F.csv: `time`, `displacement`, `force` (N), written atomically,
with a provenance sidecar `F.csv.json` (package version, model, eps, parameters, effects and the
SHA-256 of both inputs).
"""
from __future__ import annotations

import io
import json
from pathlib import Path

import numpy as np

from . import atomic
from .environment import environment
from .errors import InputError, not_a_file
from . import model as M
from .model import simulate
from .records import read_csv
from .units import AMPLITUDE_PLAUSIBLE_M, check_drive, metres_note


def read_params(path) -> tuple[dict, dict | None]:
    """(base parameters, effects) from a parameter JSON file; errors name the file and key."""
    path = Path(path)
    if not_a_file(path):
        raise InputError(f"{path}: {not_a_file(path)}")
    def no_repeats(pairs):
        keys = [k for k, _ in pairs]
        rep = next((k for i, k in enumerate(keys) if k in keys[:i]), None)
        if rep is not None:     # json keeps the last silently; which one was meant?
            raise InputError(f"{path}, key {rep}: given twice; give each parameter once")
        return dict(pairs)
    try:
        doc = json.loads(path.read_text(), object_pairs_hook=no_repeats)
    except json.JSONDecodeError as e:
        raise InputError(f"{path}: not valid JSON (line {e.lineno}, column {e.colno}: {e.msg})") from None
    except UnicodeDecodeError:
        raise InputError(f"{path}: not valid JSON (not UTF-8 text)") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object of parameter names and values")
    effects = doc.pop("effects", None)
    if effects is not None and not (isinstance(effects, dict)
                                    and all(isinstance(v, dict) for v in effects.values())):
        raise InputError(f"{path}, key effects: expected {{effect name: {{parameter: value}}}}")
    for k, v in doc.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise InputError(f"{path}, key {k}: expected a number, got {v!r}")
    return doc, effects


def read_drive(path) -> dict[str, np.ndarray]:
    """{time, displacement[, applied]} (SI) of a drive CSV (simulate's and predict's input),
    checked as the model takes it; errors name the file and line (e.g. the applied signal's)."""
    cols = read_csv(path, {"time": "time", "displacement": "displacement"}, {"applied": "applied"})
    try:
        M.prepare(cols["time"], cols["displacement"], cols.get("applied"))
    except ValueError as e:
        raise InputError(f"{path}: {e}") from None
    return cols


def simulate_files(params_path, input_path, out_path, model: str = "three_stage", eps: float = 0.0,
                   reversal: str = "detection") -> int:
    """Simulate the force for the record in `input_path`; write `out_path`. reversal: the rule
    (model.REVERSAL_RULES; `fit` uses "extreme" on measured records by default). Returns the
    sample count."""
    params, effects = read_params(params_path)
    cols = read_drive(input_path)
    import math
    if not (math.isfinite(float(eps)) and float(eps) >= 0):
        raise InputError(f"--eps {eps!r}: the reversal dead-band must be finite and >= 0 m")
    if float(eps) > AMPLITUDE_PLAUSIBLE_M:
        raise InputError(f"--eps {eps!r}: {float(eps):g} m is {metres_note()}")
    check_drive(cols["time"], cols["displacement"], str(input_path))
    inputs = {Path(params_path).resolve(), Path(input_path).resolve()}
    for o in (Path(out_path), Path(f"{out_path}.json")):     # refused before anything is written
        if o.is_dir():
            raise InputError(f"cannot write the file {o}: it is a folder")
        if o.resolve() in inputs:       # the output (or its sidecar) would replace an input
            raise InputError(f"--out {out_path}: writing {o} would replace an input file "
                             "(--params or --input); choose another name")
    try:
        F = simulate(cols["time"], cols["displacement"], params, effects=effects, model=model,
                     eps=eps, applied=cols.get("applied"), reversal=reversal)
    except InputError:
        raise
    except ValueError as e:
        raise InputError(f"{params_path}: {e}") from None
    buf = io.StringIO()
    np.savetxt(buf, np.column_stack([cols["time"], cols["displacement"], F]), fmt="%.12g",
               delimiter=",", header="time,displacement,force", comments="")
    from . import __version__
    from .campaign import sha256_file
    atomic.write_text(out_path, buf.getvalue())
    atomic.write_json(f"{out_path}.json", {
        "package_version": __version__, "environment": environment(),
        "command": "simulate", "model": model, "eps_m": eps, "reversal": reversal,
        "parameters": params, "effects": effects or {},
        "params_file": str(params_path), "params_sha256": sha256_file(params_path),
        "input_file": str(input_path), "input_sha256": sha256_file(input_path),
        "samples": int(F.size), "units": {"time": "s", "displacement": "m", "force": "N"}})
    return int(F.size)
