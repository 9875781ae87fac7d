"""Ground motions: readers of the real accelerograms, baseline correction, double integration,
scaling and resampling (frictionuq.groundmotion)."""
import hashlib
import os
import platform
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from frictionuq import groundmotion as G
from frictionuq.errors import InputError

ROOT = Path(__file__).resolve().parents[1]
GM = ROOT / "data" / "ground-motions"
SHARED = ROOT.parent / "shared" / "data" / "real"
G_SI = 9.80665


# ----------------------------------------------------------------- synthetic, known displacement

DT = 0.005
T_END = 40.0


def _wavelet(t, amp, f0, tc, s):
    """x = amp exp(-((t-tc)/s)^2) sin(2 pi f0 (t-tc)) and its exact second derivative."""
    u = t - tc
    w = 2 * np.pi * f0
    g = np.exp(-(u / s) ** 2)
    gp = -2 * u / s**2 * g
    gpp = (-2 / s**2 + 4 * u**2 / s**4) * g
    x = amp * g * np.sin(w * u)
    a = amp * (gpp * np.sin(w * u) + 2 * gp * w * np.cos(w * u) - g * w**2 * np.sin(w * u))
    return x, a


def _synthetic():
    """A displacement at rest at both ends (two Gabor wavelets, 0.5 and 1.5 Hz, peak ~3 cm) and
    its exact acceleration."""
    t = np.arange(int(round(T_END / DT)) + 1) * DT
    x1, a1 = _wavelet(t, 0.03, 0.5, 18.0, 3.0)
    x2, a2 = _wavelet(t, 0.01, 1.5, 22.0, 2.0)
    return t, x1 + x2, a1 + a2


def _record(a, name="synthetic"):
    return G.GroundMotion(name=name, source="synthetic", dt=DT, a=np.asarray(a, float), unit_in_file="m/s^2")


# drifts of the acceleration, m/s^2: constant, linear, both (a constant acceleration offset of
# 0.01 m/s^2 alone moves a 40 s record by 0.01*40^2/2 = 8 m)
DRIFTS = {
    "constant": lambda t: 0.01 + 0 * t,
    "linear": lambda t: 5e-4 * t,
    "constant+linear": lambda t: 0.01 - 1e-3 * t,
}


@pytest.mark.parametrize("drift", list(DRIFTS))
def test_known_displacement_recovered_through_drift(drift):
    t, x_true, a_true = _synthetic()
    rec = _record(a_true + DRIFTS[drift](t))
    peak = 0.01
    tt, x = G.displacement_history(rec, peak)
    assert tt.shape == t.shape and np.allclose(tt, t)
    ref = x_true * peak / np.max(np.abs(x_true))
    assert np.max(np.abs(x)) == pytest.approx(peak, rel=1e-12)
    # the 0.1 Hz high-pass barely touches 0.5-1.5 Hz content: error well under 0.5 % of the peak
    assert np.max(np.abs(x - ref)) < 0.005 * peak
    # without correction the displacement is badly wrong: metres against a few centimetres
    _, x_raw = G.integrate(rec.a, DT)
    assert np.max(np.abs(x_raw - x_true)) > 20 * np.max(np.abs(x_true))


def test_drift_alone_is_removed():
    t = np.arange(int(round(T_END / DT)) + 1) * DT
    rec = _record(DRIFTS["constant+linear"](t))
    _, _, v, x = G.baseline_correct(rec)
    assert np.max(np.abs(x)) < 1e-9
    assert np.max(np.abs(v)) < 1e-9
    _, x_raw = G.integrate(rec.a, DT)
    assert np.max(np.abs(x_raw)) > 1.0


def test_filter_alone_removes_constant_offset_but_not_linear_drift():
    """Step 1 (velocity polynomial) is what removes a linear drift; the high-pass alone does not."""
    t, x_true, a_true = _synthetic()
    ref_peak = np.max(np.abs(x_true))
    _, _, _, x = G.baseline_correct(_record(a_true + DRIFTS["constant"](t)), poly_degree=None)
    assert np.max(np.abs(x - x_true)) < 0.005 * ref_peak
    _, _, _, x = G.baseline_correct(_record(a_true + DRIFTS["linear"](t)), poly_degree=None)
    assert np.max(np.abs(x - x_true)) > 0.05 * ref_peak


def test_high_pass_removes_long_period_noise():
    """A slow (0.02 Hz) non-polynomial error of the acceleration: the filter takes it out."""
    t, x_true, a_true = _synthetic()
    slow = 0.005 * np.sin(2 * np.pi * 0.02 * t + 0.7)
    rec = _record(a_true + slow)
    _, _, _, x = G.baseline_correct(rec)
    peak = np.max(np.abs(x_true))
    _, x_raw = G.integrate(rec.a, DT)
    raw_err = np.max(np.abs(x_raw - x_true))
    err = np.max(np.abs(x - x_true))
    assert raw_err > 5 * peak                  # ~0.3 m against a 3 cm signal
    # a 4th-order acausal high-pass at 0.1 Hz passes 1/626 of 0.02 Hz; with the end effects of
    # a non-polynomial error the residual is ~8 % of the peak: 100 times less than before
    assert err < 0.1 * peak and err < raw_err / 100


@pytest.mark.parametrize("fs_out", [100.0, 97.0, 400.0])
def test_resampling(fs_out):
    t, x_true, a_true = _synthetic()
    peak = 0.4 * 0.0254
    tt, x = G.displacement_history(_record(a_true), peak, fs_out=fs_out)
    assert tt[0] == 0.0 and tt[-1] <= T_END + 1e-9 and T_END - tt[-1] < 1 / fs_out
    assert np.allclose(np.diff(tt), 1 / fs_out)
    assert np.max(np.abs(x)) == pytest.approx(peak, rel=1e-12)
    ref = np.interp(tt, t, x_true) * peak / np.max(np.abs(x_true))
    assert np.max(np.abs(x - ref)) < 0.005 * peak


def test_unscaled_history_and_pad_keep():
    t, x_true, a_true = _synthetic()
    tt, x = G.displacement_history(_record(a_true), None)
    assert np.max(np.abs(x - x_true)) < 0.005 * np.max(np.abs(x_true))
    tt, x = G.displacement_history(_record(a_true), None, pad_keep=10.0)
    assert tt[0] == 0.0 and tt[-1] == pytest.approx(T_END + 20.0)


def test_pad_keep_starts_a_truncated_record_at_rest():
    """Hollister starts in strong motion: the original window does not start at rest, the
    window with 10 s of pad does (Boore 2005: keep the pads)."""
    rec = G.load_record("hollister")
    _, x0 = G.displacement_history(rec, 0.01)
    _, x10 = G.displacement_history(rec, 0.01, pad_keep=10.0)
    assert abs(x0[0]) > 0.05 * 0.01
    assert abs(x10[0]) < 0.005 * 0.01 and abs(x10[-1]) < 0.005 * 0.01


@pytest.mark.parametrize("kw", [{"f_corner": 0.0}, {"f_corner": 150.0}, {"order": 3},
                                {"order": 0}, {"taper": 0.7}, {"poly_degree": 0}, {"pad_keep": -1.0}])
def test_bad_processing_parameters(kw):
    t, _, a = _synthetic()
    with pytest.raises(ValueError):
        G.displacement_history(_record(a), 0.01, **kw)


# ---------------------------------------------------------------------- the shipped real records

# (folder, file, reader kwargs, stated npts, stated dt, stated PGA in g) from each SOURCE.md
SHIPPED = [
    ("eq-impvall1979-elcentro12", "RSN175_IMPVALL.H_H-E12140.AT2", {}, 7814, 0.005, 0.145),
    ("eq-impvall1979-elcentro12", "RSN175_IMPVALL.H_H-E12230.AT2", {}, 7810, 0.005, 0.118),
    ("eq-hollister1961-cityhall", "Hollister-01_181.dat", {"dt": 0.005}, 8092, 0.005, 0.059),
    ("eq-hollister1961-cityhall", "Hollister-01_271.dat", {"dt": 0.005}, 8096, 0.005, 0.115),
    ("eq-kobe1995-jma-benchmark", "kobe.txt", {"column": 0}, 6000, 0.005, 0.841),
    ("eq-kobe1995-jma-benchmark", "kobe.txt", {"column": 1}, 6000, 0.005, 0.631),
    ("eq-kobe1995-jma-benchmark", "elcentro_impvall1979_fnfp.txt", {"column": 0}, 6000, 0.005, 0.313),
    ("eq-kobe1995-jma-benchmark", "elcentro_impvall1979_fnfp.txt", {"column": 1}, 6000, 0.005, 0.215),
]
# in shared/data/real only (not used by the twins): parsed when that folder is there
NOT_SHIPPED = [
    ("eq-elcentro1940", "RSN6_IMPVALL.I_I-ELC180.AT2", {}, 5372, 0.01, 0.281),
    ("eq-impvall1979-elcentro6", "RSN181_IMPVALL.H_H-E06140.AT2", {}, 7817, 0.005, 0.447),
    ("eq-impvall1979-elcentro6", "RSN181_IMPVALL.H_H-E06230.AT2", {}, 7818, 0.005, 0.449),
]


def _at2_npts(path):
    return int(re.search(r"NPTS\s*=\s*(\d+)", path.read_text().splitlines()[3]).group(1))


def _check_record(path, kw, npts, dt, pga_g):
    rec = G.read_record(path, **kw)
    assert rec.npts == npts
    if path.suffix == ".AT2":
        assert rec.npts == _at2_npts(path)
    assert rec.dt == pytest.approx(dt)
    assert rec.t[-1] == pytest.approx((npts - 1) * dt)
    # SOURCE.md states the PGA to 3 decimals of g
    assert abs(rec.pga / G_SI - pga_g) <= 0.0005 + 1e-9
    assert np.all(np.isfinite(rec.a))
    return rec


@pytest.mark.parametrize("folder,name,kw,npts,dt,pga", SHIPPED, ids=lambda v: str(v))
def test_shipped_records_parse(folder, name, kw, npts, dt, pga):
    _check_record(GM / folder / name, kw, npts, dt, pga)


@pytest.mark.skipif(not SHARED.is_dir(), reason="shared/data/real not present")
@pytest.mark.parametrize("folder,name,kw,npts,dt,pga", NOT_SHIPPED, ids=lambda v: str(v))
def test_other_real_at2_records_parse(folder, name, kw, npts, dt, pga):
    _check_record(SHARED / folder / name, kw, npts, dt, pga)


def test_shipped_copies_are_unchanged():
    """Every shipped file has the sha256 its SOURCE.md states, and every folder has a SOURCE.md."""
    folders = sorted(p for p in GM.iterdir() if p.is_dir())
    assert [p.name for p in folders] == ["eq-hollister1961-cityhall", "eq-impvall1979-elcentro12",
                                         "eq-kobe1995-jma-benchmark"]
    for folder in folders:
        source = (folder / "SOURCE.md").read_text()
        stated = dict((f, h) for f, h in re.findall(r"\|\s*`([^`]+)`\s*\|\s*`([0-9a-f]{64})`", source))
        data_files = sorted(p.name for p in folder.iterdir() if p.name != "SOURCE.md")
        assert sorted(stated) == data_files
        for f, h in stated.items():
            assert hashlib.sha256((folder / f).read_bytes()).hexdigest() == h, f


@pytest.mark.parametrize("key", list(G.RECORDS))
def test_twin_records_load_and_integrate(key):
    rec = G.load_record(key)
    assert rec.name == key and rec.npts > 5000
    t, x = G.displacement_history(rec, 0.01, fs_out=100.0, pad_keep=10.0)
    assert np.max(np.abs(x)) == pytest.approx(0.01)
    assert np.allclose(np.diff(t), 0.01)
    assert abs(x[0]) < 1e-4 and abs(x[-1]) < 1e-4     # at rest (within 1 % of the peak)


def test_unknown_record_key():
    with pytest.raises(InputError, match="unknown ground motion"):
        G.load_record("loma-prieta")


# ---------------------------------------------------------------------------------- bad files

AT2_HEAD = ("PEER NGA STRONG MOTION DATABASE RECORD\nTest event, 1/1/2000, Nowhere, 090\n"
            "ACCELERATION TIME SERIES IN UNITS OF G\n")


def _at2(npts=12, dt=".0050", values=None):
    vals = values if values is not None else [f"{0.001 * i:.7E}" for i in range(12)]
    body = "\n".join("  ".join(vals[i:i + 5]) for i in range(0, len(vals), 5))
    return AT2_HEAD + f"NPTS=   {npts}, DT=   {dt} SEC,\n" + body + "\n"


def _raises_one_line(fn, path, *match):
    with pytest.raises(InputError) as e:
        fn()
    msg = str(e.value)
    assert "\n" not in msg and str(path) in msg
    for m in match:
        assert m in msg, msg
    return msg


def test_at2_good_synthetic(tmp_path):
    p = tmp_path / "ok.AT2"
    p.write_text(_at2())
    rec = G.read_at2(p)
    assert rec.npts == 12 and rec.dt == 0.005
    assert rec.a[-1] == pytest.approx(0.011 * G_SI)
    assert rec.description == "Test event, 1/1/2000, Nowhere, 090"


def test_at2_old_header_form(tmp_path):
    p = tmp_path / "old.AT2"
    vals = [f"{0.001 * i:.7E}" for i in range(12)]
    p.write_text(AT2_HEAD + "   12    0.0050    NPTS, DT\n" + "  ".join(vals) + "\n")
    assert G.read_at2(p).npts == 12


def test_at2_npts_mismatch(tmp_path):
    p = tmp_path / "short.AT2"
    p.write_text(_at2(npts=13))
    _raises_one_line(lambda: G.read_at2(p), p, "NPTS mismatch", "NPTS=13", "12 values")


def test_at2_non_numeric_value(tmp_path):
    vals = [f"{0.001 * i:.7E}" for i in range(12)]
    vals[7] = "0.00x1"
    p = tmp_path / "bad.AT2"
    p.write_text(_at2(values=vals))
    _raises_one_line(lambda: G.read_at2(p), p, "line 6", "non-numeric", "0.00x1")


def test_at2_missing_header(tmp_path):
    p = tmp_path / "nohead.AT2"
    p.write_text("PEER NGA STRONG MOTION DATABASE RECORD\n0.1 0.2\n")
    _raises_one_line(lambda: G.read_at2(p), p, "missing header")
    p2 = tmp_path / "nonpts.AT2"
    p2.write_text(AT2_HEAD + "DT= .005\n" + "0.1 " * 12 + "\n")
    _raises_one_line(lambda: G.read_at2(p2), p2, "line 4", "NPTS")


def test_at2_bad_dt_and_unit(tmp_path):
    p = tmp_path / "dt0.AT2"
    p.write_text(_at2(dt="0.0"))
    _raises_one_line(lambda: G.read_at2(p), p, "time step")
    p2 = tmp_path / "cm.AT2"
    p2.write_text(_at2().replace("IN UNITS OF G", "IN CM/S/S"))
    _raises_one_line(lambda: G.read_at2(p2), p2, "line 3")


def test_single_column_errors(tmp_path):
    p = tmp_path / "acc.dat"
    p.write_text("0.1\n0.2\nabc\n" + "0.1\n" * 10)
    _raises_one_line(lambda: G.read_single_column(p, dt=0.005), p, "line 3", "non-numeric")
    p.write_text("0.1\n0.2 0.3\n" + "0.1\n" * 10)
    _raises_one_line(lambda: G.read_single_column(p, dt=0.005), p, "line 2", "one value")
    p.write_text("0.1\n0.2\n")
    _raises_one_line(lambda: G.read_single_column(p, dt=0.005), p, "only 2")
    p.write_text("0.1\n" * 20)
    _raises_one_line(lambda: G.read_record(p), p, "give dt")
    _raises_one_line(lambda: G.read_single_column(p, dt=-1), p, "time step")
    _raises_one_line(lambda: G.read_single_column(p, dt=0.01, unit="furlong"), p, "furlong")


def test_column_file_errors(tmp_path):
    p = tmp_path / "two.txt"
    head = "%Acc. in cm/sec^2 and dt=0.005 sec.\r\n"
    rows = "".join(f"1.0\t\t{2.0 if k % 2 == 0 else 2.5}\r\n" for k in range(12))
    p.write_bytes((head + rows).encode())
    rec = G.read_columns(p, column=1)
    assert rec.dt == 0.005 and rec.a[0] == pytest.approx(0.02)
    p.write_bytes((head + rows + "1.0\r\n").encode())
    _raises_one_line(lambda: G.read_columns(p), p, "line 14", "expected 2 values")
    p.write_bytes((head + rows.replace("2.0", "2,0x", 1)).encode())
    _raises_one_line(lambda: G.read_columns(p), p, "line 2", "non-numeric")
    p.write_bytes(("%no metadata here\n" + rows).encode())
    _raises_one_line(lambda: G.read_columns(p), p, "missing header", "dt")
    _raises_one_line(lambda: G.read_columns(p, dt=0.01), p, "missing header", "unit")
    p.write_bytes((head + rows).encode())
    _raises_one_line(lambda: G.read_columns(p, column=2), p, "column 2")


def test_records_without_a_ground_motion_or_read_from_the_wrong_column(tmp_path):
    """Refused with one line (until 2026-12-05 an all-zero record passed the workflow's load and
    its prediction wrote NaN; `column` on a one-column file was ignored; a time column was read
    as accelerations)."""
    p = tmp_path / "zeros.txt"
    p.write_text("0\n" * 1000)
    _raises_one_line(lambda: G.read_record(p, dt=0.01), p, "every acceleration value is 0.0",
                     "no ground motion")
    q = tmp_path / "one.txt"
    q.write_text("".join(f"{np.sin(k / 5):.4f}\n" for k in range(200)))
    assert G.read_record(q, dt=0.01).npts == 200
    _raises_one_line(lambda: G.read_record(q, dt=0.01, column=3), q, "column 3 requested",
                     "one value per line")
    r = tmp_path / "time-acc.txt"
    r.write_text("".join(f"{k * 0.01:.2f} {np.sin(k / 5):.4f}\n" for k in range(200)))
    _raises_one_line(lambda: G.read_record(r, dt=0.01, unit="g"), r, "column 0 increases on every "
                     "line, like a time column", "(0 to 1)")
    assert G.read_record(r, dt=0.01, unit="g", column=1).npts == 200


def test_missing_file(tmp_path):
    p = tmp_path / "nope.AT2"
    _raises_one_line(lambda: G.read_at2(p), p, "not found")


def test_a_shipped_record_missing_says_what_the_variable_must_name(tmp_path, monkeypatch):
    """FRICTIONUQ_GROUND_MOTIONS names the ground-motions folder itself; the message said "the
    folder holding data/ground-motions", and set so, the path was still wrong."""
    monkeypatch.setenv("FRICTIONUQ_GROUND_MOTIONS", str(tmp_path))
    with pytest.raises(InputError) as e:
        G.load_record("kobe")
    msg = str(e.value)
    assert "\n" not in msg and str(tmp_path / G.RECORDS["kobe"].folder) in msg
    assert f"data/ground-motions folder itself, the one holding {G.RECORDS['kobe'].folder}/" in msg
    monkeypatch.setenv("FRICTIONUQ_GROUND_MOTIONS", str(GM))
    assert G.load_record("kobe") is not None


_CORETYPE_SCRIPT = """
import hashlib
import os
import platform
from frictionuq.groundmotion import displacement_history, load_record
h = hashlib.sha256()
for key in ("hollister", "kobe"):
    t, x = displacement_history(load_record(key), peak_m=0.01, fs_out=100.0, pad_keep=10.0)
    h.update(x.tobytes())
print(h.hexdigest())
"""


@pytest.mark.skipif(platform.machine() not in ("x86_64", "AMD64"), reason="OpenBLAS x86 core types")
def test_drives_are_the_same_bits_whatever_blas_kernels_run():
    """The twins' earthquake drives do not depend on the CPU's OpenBLAS kernels (the shipped
    twins are regenerated byte for byte on any machine): the processed displacement of two
    records has the same bits under OpenBLAS's SSE3 (Prescott) and AVX2 (Haswell) kernels.
    With numpy's polyfit (LAPACK) in the velocity baseline it did not (measured 2026-11-25)."""
    digests = set()
    for core in ("Prescott", "Haswell"):
        env = {**os.environ, "OPENBLAS_CORETYPE": core}
        out = subprocess.run([sys.executable, "-c", _CORETYPE_SCRIPT], env=env, check=True,
                             capture_output=True, text=True).stdout.split()
        digests.add(out[-1])
    assert len(digests) == 1
