"""Paper twins: synthetic campaigns that reproduce each seed paper's test programme with its
published parameters (spec section 6), in the campaign format of spec section 7.

`write_twin("brfd" | "mfd", out_dir, seed=2016)` writes `campaign.toml`, `tests/<id>.csv` and a
`README.md` into `out_dir` (atomically: the folder appears complete or not at all) and returns a
manifest-like dict (`tests`: one dict per test).

How a test is made (everything deterministic for a given seed and package version):

* Drive. Harmonic tests: x = A sin(2 pi f t) over 10 cycles at 100 Hz, t = 0 .. 10/f inclusive.
  Earthquake tests: a real accelerogram (frictionuq.groundmotion.RECORDS), baseline-corrected and
  double-integrated (frictionuq.groundmotion.displacement_history: velocity-polynomial baseline,
  acausal Butterworth high-pass 0.1 Hz, total order 4, zero pads, 10 s of each pad kept so the
  drive starts and ends at rest), resampled to 100 Hz and scaled to the paper's peak (BRFD
  0.01 m, MFD 0.4 in).
* The displacement and time are rounded to the file's format (`%.7g` in the paper's units)
  first, and the force is simulated from the rounded drive: the file's own columns reproduce the
  noise-free force exactly (frictionuq.simulate, model three_stage, eps = 0, the published
  parameters at the test's applied level).
* Force noise, in N, scaled by the test's friction force Fc = (fc_fwd + fc_bwd)/2: white Gaussian
  with sd 1 % of Fc, plus a stationary AR(1) part with phi 0.9 and marginal sd 0.5 % of Fc.
* `applied`: the measured applied force (BRFD, N) or pressure (MFD, psi): the nominal level
  times (1 + white noise of sd 0.5 % + a slow stationary AR(1) wander, phi 0.99, marginal sd
  1 %). The force does not follow it (the twin has no applied_tracking effect: beta_app = 0).
* Random numbers: every test has its own stream `numpy.random.default_rng([seed, crc32(id)])`,
  so a test's noise does not depend on which other tests exist or on their order. Draw order in
  a stream: force white, force AR(1) innovations, applied white, applied AR(1) innovations.
"""
from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np

from . import __version__, atomic, published as pub
from .atomic import output_dir
from .groundmotion import RECORDS, displacement_history, ground_motions_dir, load_record
from .model import simulate
from .noise import ar1_from_normals
from .units import from_si, to_si

FLOAT_FORMAT = "%.7g"
FS_HZ = 100.0
CYCLES = 10
DEFAULT_SEED = 2016

# noise model (fractions of the test's friction force, resp. of the nominal applied level)
FORCE_WHITE_SD = 0.01
FORCE_AR_PHI = 0.9
FORCE_AR_SD = 0.005
APPLIED_WHITE_SD = 0.005
APPLIED_AR_PHI = 0.99
APPLIED_AR_SD = 0.01

# ground-motion processing of the earthquake drives
GM_F_CORNER = 0.1      # Hz
GM_ORDER = 4
GM_PAD_KEEP = 10.0     # s of each zero pad kept

NOISE_DESCRIPTION = (
    f"force: white Gaussian, sd {FORCE_WHITE_SD:.1%} of the test's Fc = (fc_fwd+fc_bwd)/2, plus "
    f"stationary AR(1) phi {FORCE_AR_PHI:g}, marginal sd {FORCE_AR_SD:.1%} of Fc; applied: "
    f"nominal x (1 + white sd {APPLIED_WHITE_SD:.1%} + stationary AR(1) phi {APPLIED_AR_PHI:g}, "
    f"marginal sd {APPLIED_AR_SD:.1%}); stream numpy.random.default_rng([seed, crc32(test id)])")

DEVICES = {
    "brfd": {
        "name": "brfd-twin", "device": "BRFD",
        "paper": "Downey et al. (2016), High capacity variable friction damper based on band "
                 "brake technology, Eng. Struct. 113, 287-298",
        "units": {"time": "s", "displacement": "mm", "force": "kN", "applied": "N"},
        "levels": pub.BRFD_APPLIED_N, "level_unit": "N", "freqs": pub.BRFD_FREQS_HZ,
        "amplitude_m": pub.BRFD_AMPLITUDE_M,
        "eq_levels": pub.BRFD_EQ_APPLIED_N, "eq_peak_m": pub.BRFD_EQ_PEAK_M,
        "eq_records": ("imperial-valley", "hollister"),
    },
    "mfd": {
        "name": "mfd-twin", "device": "MFD",
        "paper": "Cao, Downey, Laflamme, Taylor, Ricles (2015), Variable friction device for "
                 "structural control based on duo-servo vehicle brake: modeling and "
                 "experimental validation, J. Sound Vib.",
        "units": {"time": "s", "displacement": "in", "force": "kip", "applied": "psi"},
        "levels": pub.MFD_PRESSURES_PSI, "level_unit": "psi", "freqs": pub.MFD_FREQS_HZ,
        "amplitude_m": pub.MFD_AMPLITUDE_M,
        "eq_levels": pub.MFD_EQ_APPLIED_PSI, "eq_peak_m": pub.MFD_EQ_PEAK_M,
        "eq_records": ("imperial-valley", "kobe"),
    },
}


def _device(device: str) -> dict:
    try:
        return DEVICES[str(device).lower()]
    except KeyError:
        raise ValueError(f"unknown twin device {device!r}; use one of: {', '.join(DEVICES)}") from None


def params_at(device: str, level: float) -> dict[str, float]:
    """Published SI parameters of `device` at applied level `level` (N for the BRFD, psi for the MFD)."""
    return pub.brfd_params(level) if str(device).lower() == "brfd" else pub.mfd_params(level)


def programme(device: str) -> list[dict]:
    """The paper's test programme: one dict per test (id, kind, level, frequency_hz or record)."""
    d = _device(device)
    u = d["level_unit"]
    tests = []
    for level in d["levels"]:
        for f in d["freqs"]:
            tests.append({"id": f"h-{level:g}{u}-{f:g}Hz", "kind": "harmonic", "level": float(level),
                          "frequency_hz": float(f)})
    for level in d["eq_levels"]:
        for rec in d["eq_records"]:
            tests.append({"id": f"eq-{level:g}{u}-{RECORDS[rec].label}", "kind": "earthquake",
                          "level": float(level), "record": rec})
    return tests


def _fmt(values: np.ndarray) -> np.ndarray:
    return np.char.mod(FLOAT_FORMAT, np.asarray(values, dtype=float))


def _rounded(values_si: np.ndarray, kind: str, unit: str) -> tuple[np.ndarray, np.ndarray]:
    """(strings in `unit`, the SI values those strings stand for)."""
    s = _fmt(from_si(np.asarray(values_si, dtype=float), kind, unit))
    return s, to_si(s.astype(float), kind, unit)


def harmonic_drive(frequency_hz: float, amplitude_m: float, fs: float = FS_HZ,
                   cycles: int = CYCLES) -> tuple[np.ndarray, np.ndarray]:
    n = int(round(cycles / frequency_hz * fs))
    t = np.arange(n + 1) / fs
    return t, amplitude_m * np.sin(2 * np.pi * frequency_hz * t)


def earthquake_drive(record: str, peak_m: float, fs: float = FS_HZ, root=None):
    gm = load_record(record, root=root)
    return displacement_history(gm, peak_m, fs_out=fs, f_corner=GM_F_CORNER, order=GM_ORDER,
                                pad_keep=GM_PAD_KEEP)


def _ar1(rng, n: int, phi: float, sd: float) -> np.ndarray:
    """Stationary AR(1) with marginal sd `sd` from the test's stream (frictionuq.noise)."""
    return ar1_from_normals(rng.standard_normal(n), phi, sd)


def stream(seed: int, test_id: str) -> np.random.Generator:
    """The independent random stream of one test."""
    return np.random.default_rng([int(seed), zlib.crc32(test_id.encode("utf-8"))])


def noise(seed: int, test_id: str, n: int, fc_n: float, nominal: float):
    """(force noise in N, applied signal in the nominal's unit) of one test."""
    rng = stream(seed, test_id)
    f_white = rng.standard_normal(n) * FORCE_WHITE_SD * fc_n
    f_ar = _ar1(rng, n, FORCE_AR_PHI, FORCE_AR_SD * fc_n)
    a_white = rng.standard_normal(n) * APPLIED_WHITE_SD
    a_ar = _ar1(rng, n, APPLIED_AR_PHI, APPLIED_AR_SD)
    return f_white + f_ar, nominal * (1.0 + a_white + a_ar)


def make_test(device: str, spec: dict, seed: int = DEFAULT_SEED, root=None) -> dict:
    """One test of the twin: SI arrays (t, x, force, force_clean, applied) and the CSV text."""
    d = _device(device)
    units = d["units"]
    if spec["kind"] == "harmonic":
        t, x = harmonic_drive(spec["frequency_hz"], d["amplitude_m"])
    else:
        t, x = earthquake_drive(spec["record"], d["eq_peak_m"], root=root)
    t_s, t = _rounded(t, "time", units["time"])
    x_s, x = _rounded(x, "displacement", units["displacement"])
    p = params_at(device, spec["level"])
    clean = simulate(t, x, p, model="three_stage", eps=0.0)
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    f_noise, applied = noise(seed, spec["id"], t.size, fc, spec["level"])
    f_s, force = _rounded(clean + f_noise, "force", units["force"])
    a_s = _fmt(applied)            # already in the applied unit (N or psi)
    rows = "\n".join(",".join(r) for r in zip(t_s.tolist(), x_s.tolist(), f_s.tolist(), a_s.tolist()))
    csv = "time,displacement,force,applied\n" + rows + "\n"
    return {"t": t, "x": x, "force": force, "force_clean": clean, "applied": a_s.astype(float),
            "params": p, "fc": fc, "csv": csv}


def _toml_str(s: str) -> str:
    out = s.replace("\\", "\\\\").replace('"', '\\"')
    return f'"{out}"'


def _toml_val(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    return _toml_str(str(v))


def _record_line(key: str) -> str:
    r = RECORDS[key]
    return f"data/ground-motions/{r.folder}/{r.file}: {r.description}"


def _campaign_toml(device: str, seed: int, tests: list[dict]) -> str:
    d = _device(device)
    dev = str(device).lower()
    units = d["units"]
    desc = (f"Data twin of the {d['device']} paper's test programme ({d['paper']}): the published "
            "parameters (spec section 6) simulated with the 3-stage model on the paper's drives, "
            "plus measurement noise. Regenerate with: "
            f"frictionuq twin {dev} --out data/{d['name']} --seed {seed}")
    L = [f"name = {_toml_str(d['name'])}", f"device = {_toml_str(d['device'])}",
         f"description = {_toml_str(desc)}", "", "[units]"]
    L += [f"{k} = {_toml_str(v)}" for k, v in units.items()]
    if dev == "brfd":
        L += ["", "[geometry]"]
        L += [f"{k} = {_toml_val(float(v))}" for k, v in pub.BRFD_GEOMETRY.items()]
    twin = {"generator": "frictionuq.twins", "seed": int(seed), "package_version": __version__,
            "model": "three_stage", "eps": 0.0,
            "parameters": f"frictionuq.published.{dev}_params(applied) (spec section 6)",
            "noise": NOISE_DESCRIPTION, "float_format": FLOAT_FORMAT, "sampling_hz": FS_HZ,
            "ground_motion_processing": (
                "frictionuq.groundmotion.displacement_history: velocity-polynomial baseline "
                f"(degree 2), acausal Butterworth high-pass {GM_F_CORNER:g} Hz total order "
                f"{GM_ORDER} with zero pads (Boore & Bommer 2005; Boore 2005), trapezoid double "
                f"integration, {GM_PAD_KEEP:g} s of each pad kept, resampled to {FS_HZ:g} Hz, "
                f"scaled to peak |x| = {from_si(d['eq_peak_m'], 'displacement', units['displacement']):g} "
                f"{units['displacement']}")}
    L += ["", "[twin]"] + [f"{k} = {_toml_val(v)}" for k, v in twin.items()]
    L += ["", "[twin.records]"] + [f"{k} = {_toml_str(_record_line(k))}" for k in d["eq_records"]]
    for t in tests:
        L += ["", "[[tests]]", f"id = {_toml_str(t['id'])}", f"file = {_toml_str(t['file'])}",
              f"applied = {_toml_val(float(t['level']))}", f"kind = {_toml_str(t['kind'])}"]
        if t["kind"] == "harmonic":
            amp = from_si(d["amplitude_m"], "displacement", units["displacement"])
            L += [f"frequency_hz = {_toml_val(t['frequency_hz'])}",
                  f"amplitude = {_toml_val(float(FLOAT_FORMAT % amp))}"]
        else:
            L += [f"description = {_toml_str(_record_line(t['record']))}"]
    return "\n".join(L) + "\n"


def _readme(device: str, seed: int, tests: list[dict], data_bytes: int) -> str:
    d = _device(device)
    dev = str(device).lower()
    u = d["units"]
    n_h = sum(t["kind"] == "harmonic" for t in tests)
    n_eq = len(tests) - n_h
    peak = from_si(d["eq_peak_m"], "displacement", u["displacement"])
    amp = from_si(d["amplitude_m"], "displacement", u["displacement"])
    levels = ", ".join(f"{v:g}" for v in d["levels"])
    freqs = ", ".join(f"{v:g}" for v in d["freqs"])
    eql = " and ".join(f"{v:g}" for v in d["eq_levels"])
    recs = "\n".join(f"* `{k}`: {_record_line(k)}" for k in d["eq_records"])
    return f"""# {d['name']}: data twin of the {d['device']} paper

A synthetic test campaign (campaign format: spec section 7) that reproduces the test programme of
{d['paper']}, with the paper's published parameters (spec section 6,
`frictionuq.published.{dev}_params`) and the 3-stage model (`frictionuq.simulate`, model
`three_stage`, eps = 0). It is the ground truth for checking that calibration recovers known
parameters. **Generated: do not edit by hand.**

Regenerate (byte-identical for the same seed and package version; the test suite checks it):

    frictionuq twin {dev} --out data/{d['name']} --seed {seed}

Seed: {seed}. Generator: `frictionuq.twins` (package version {__version__}).

## Tests ({len(tests)})

* {n_h} harmonic tests: applied {levels} {d['level_unit']} x {freqs} Hz, amplitude {amp:g} {u['displacement']},
  {CYCLES} cycles, sampled at {FS_HZ:g} Hz; ids like `{tests[0]['id']}`.
* {n_eq} earthquake tests at {eql} {d['level_unit']}: ground displacement scaled to a peak of
  {peak:g} {u['displacement']} (the paper's rig limit), {FS_HZ:g} Hz; ids like `{tests[-1]['id']}`.

Accelerograms (copies with their SOURCE.md in `data/ground-motions/`; see its README.md for why
these records and for their licences):

{recs}

Earthquake drive: `frictionuq.groundmotion.displacement_history`: velocity-polynomial baseline
(degree 2) and acausal Butterworth high-pass ({GM_F_CORNER:g} Hz, total order {GM_ORDER}) with zero
pads (Boore & Bommer 2005; Boore 2005), trapezoid double integration, {GM_PAD_KEEP:g} s of each pad
kept so the drive starts and ends at rest, resampled to {FS_HZ:g} Hz, scaled to the peak.

## Columns and units (the paper's own units, declared in campaign.toml `[units]`)

| column | unit | what |
| --- | --- | --- |
| time | {u['time']} | sample time |
| displacement | {u['displacement']} | the drive (noise-free command) |
| force | {u['force']} | simulated damper force plus noise |
| applied | {u['applied']} | measured applied {'force' if dev == 'brfd' else 'pressure'}: nominal plus noise |

Numbers are written with `{FLOAT_FORMAT}`; the force was simulated from the rounded time and
displacement, so the file's columns reproduce the noise-free force exactly. Size: {len(tests)} CSV
files and campaign.toml, {data_bytes / 1e6:.1f} MB, at the paper's 100 Hz with 7 significant
digits (no decimation was needed to stay small).

## Noise model

{NOISE_DESCRIPTION}.
The force does not follow the `applied` signal (no applied_tracking effect in the truth).
"""


def _is_twin(folder: Path) -> bool:
    """Whether `folder` holds a campaign this module wrote (its campaign.toml has a [twin] table
    naming this generator) and nothing else: a file the user added (notes, another test) would be
    lost with the folder, so such a folder is not replaced."""
    import tomllib
    try:
        doc = tomllib.loads((folder / "campaign.toml").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    if not (isinstance(doc.get("twin"), dict) and doc["twin"].get("generator") == "frictionuq.twins"):
        return False
    own = {"campaign.toml", "README.md"} | {str(t.get("file")) for t in doc.get("tests") or []
                                            if isinstance(t, dict)}
    return all(p.relative_to(folder).as_posix() in own for p in folder.rglob("*") if p.is_file())


def write_twin(device: str, out_dir, seed: int = DEFAULT_SEED, root=None) -> dict:
    """Write the twin campaign of `device` ("brfd" or "mfd") into `out_dir` (replaced atomically)
    and return a manifest-like dict. `root`: the ground-motions folder (default: data/ground-motions)."""
    d = _device(device)
    dev = str(device).lower()
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    seed = int(seed)
    specs = programme(dev)
    for s in specs:
        s["file"] = f"tests/{s['id']}.csv"
    root = ground_motions_dir() if root is None else Path(root)
    manifest_tests = []
    # only an empty folder or an earlier twin (a campaign.toml with its [twin] table) is replaced
    atomic.check_replaceable(None, Path(out_dir), "campaign.toml", "", "a twin campaign",
                             is_previous=_is_twin)
    with output_dir(out_dir) as tmp:
        (tmp / "tests").mkdir()
        for s in specs:
            made = make_test(dev, s, seed=seed, root=root)
            (tmp / s["file"]).write_bytes(made["csv"].encode("ascii"))
            entry = {"id": s["id"], "file": s["file"], "kind": s["kind"], "applied": s["level"],
                     "applied_unit": d["units"]["applied"], "n_samples": int(made["t"].size)}
            if s["kind"] == "harmonic":
                entry["frequency_hz"] = s["frequency_hz"]
            else:
                entry["record"] = s["record"]
            manifest_tests.append(entry)
        toml = _campaign_toml(dev, seed, specs).encode("utf-8")
        (tmp / "campaign.toml").write_bytes(toml)
        size = len(toml) + sum((tmp / s["file"]).stat().st_size for s in specs)
        (tmp / "README.md").write_bytes(_readme(dev, seed, specs, size).encode("utf-8"))
    return {"name": d["name"], "device": d["device"], "seed": seed, "out_dir": str(out_dir),
            "units": dict(d["units"]), "package_version": __version__, "tests": manifest_tests}
