"""Paper twins (frictionuq.twins): the shipped data/brfd-twin and data/mfd-twin are exactly what
the generator writes, they follow the published parameters, the noise is what the README says,
and the units are the papers'."""
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import frictionuq
from frictionuq import published as pub, twins
from frictionuq.cli import main
from frictionuq.errors import InputError
from frictionuq.units import to_si

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = {"brfd": ROOT / "data" / "brfd-twin", "mfd": ROOT / "data" / "mfd-twin"}
UNITS = {"brfd": {"time": "s", "displacement": "mm", "force": "kN", "applied": "N"},
         "mfd": {"time": "s", "displacement": "in", "force": "kip", "applied": "psi"}}


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _read_si(device, path):
    """A twin CSV in SI: t (s), x (m), force (N), applied (file unit)."""
    df = pd.read_csv(path)
    u = UNITS[device]
    return (to_si(df["time"].to_numpy(), "time", u["time"]),
            to_si(df["displacement"].to_numpy(), "displacement", u["displacement"]),
            to_si(df["force"].to_numpy(), "force", u["force"]),
            df["applied"].to_numpy())


def _spec(device, test_id):
    return next(s for s in twins.programme(device) if s["id"] == test_id)


@pytest.mark.parametrize("device", ["brfd", "mfd"])
def test_regeneration_is_byte_identical(device, tmp_path):
    m = twins.write_twin(device, tmp_path / device, seed=2016)
    new, old = _files(tmp_path / device), _files(SHIPPED[device])
    assert sorted(new) == sorted(old)
    for name in old:
        assert new[name] == old[name], f"{device}: {name} differs from the shipped file"
    assert len(m["tests"]) == len([n for n in old if n.startswith("tests/")])


def test_shipped_size_limit():
    total = sum(len(b) for d in SHIPPED.values() for b in _files(d).values())
    assert total < 15e6


@pytest.mark.parametrize("device,n_harm,n_eq", [("brfd", 20, 4), ("mfd", 8, 4)])
def test_programme_and_campaign_toml(device, n_harm, n_eq):
    doc = tomllib.loads((SHIPPED[device] / "campaign.toml").read_text())
    assert doc["units"] == UNITS[device]
    kinds = [t["kind"] for t in doc["tests"]]
    assert kinds.count("harmonic") == n_harm and kinds.count("earthquake") == n_eq
    assert doc["twin"]["generator"] == "frictionuq.twins"
    assert doc["twin"]["seed"] == 2016
    assert doc["twin"]["package_version"] == frictionuq.__version__
    assert "AR(1)" in doc["twin"]["noise"]
    ids = {t["id"] for t in doc["tests"]}
    if device == "brfd":
        assert doc["geometry"]["drum_radius"] == 0.15 and doc["geometry"]["wrap_deg"] == 670
        assert doc["geometry"]["mu_design"] == 0.39 and doc["geometry"]["damping_radius"] == 0.10
        assert {f"h-{a:g}N-{f:g}Hz" for a in pub.BRFD_APPLIED_N for f in pub.BRFD_FREQS_HZ} <= ids
        assert {"eq-66N-imperial-valley", "eq-133N-imperial-valley", "eq-66N-hollister",
                "eq-133N-hollister"} <= ids
    else:
        assert "geometry" not in doc
        assert {f"h-{p:g}psi-{f:g}Hz" for p in pub.MFD_PRESSURES_PSI for f in pub.MFD_FREQS_HZ} <= ids
        assert {"eq-500psi-imperial-valley", "eq-1000psi-imperial-valley", "eq-500psi-kobe",
                "eq-1000psi-kobe"} <= ids
    for t in doc["tests"]:
        assert (SHIPPED[device] / t["file"]).is_file()
        if t["kind"] == "harmonic":
            assert t["frequency_hz"] in (pub.BRFD_FREQS_HZ if device == "brfd" else pub.MFD_FREQS_HZ)
            assert t["amplitude"] == (25.4 if device == "brfd" else 1.0)


@pytest.mark.parametrize("device", ["brfd", "mfd"])
def test_loads_as_a_campaign(device):
    c = frictionuq.load_campaign(SHIPPED[device])
    assert len(c.tests) == len(twins.programme(device))


@pytest.mark.parametrize("device,test_id,disp,force_mag,applied", [
    ("brfd", "h-267N-0.05Hz", 25.4, 37.8, 267.0),      # mm, kN, N
    ("brfd", "eq-66N-hollister", 10.0, 13.3, 66.0),
    ("mfd", "h-1500psi-0.5Hz", 1.0, 0.457e-3 * 1500, 1500.0),   # in, kip, psi
    ("mfd", "eq-500psi-kobe", 0.4, 0.457e-3 * 500, 500.0),
])
def test_units_are_the_papers(device, test_id, disp, force_mag, applied):
    df = pd.read_csv(SHIPPED[device] / "tests" / f"{test_id}.csv")
    assert list(df.columns) == ["time", "displacement", "force", "applied"]
    assert np.max(np.abs(df["displacement"])) == pytest.approx(disp, rel=1e-6)
    assert np.max(np.abs(df["force"])) == pytest.approx(force_mag, rel=0.15)
    assert np.median(df["applied"]) == pytest.approx(applied, rel=0.02)
    assert np.diff(df["time"]).min() == pytest.approx(0.01, abs=1e-9)


def _plateaus(t, x, f, freq, amp, sigma2):
    """Mean friction force while sliding steadily, forward (x in [0.4A, 0.8A], v > 0) and
    backward, after the first cycle (the first half-cycle starts from rest); the viscous term
    sigma2*v of the model (up to 0.5 % of the force at 53 N) is taken off."""
    v = np.gradient(x, t)
    f = f - sigma2 * v
    late = t > 1.0 / freq
    fw = late & (v > 0) & (x > 0.4 * amp) & (x < 0.8 * amp)
    bw = late & (v < 0) & (x < -0.4 * amp) & (x > -0.8 * amp)
    assert fw.sum() > 100 and bw.sum() > 100
    return f[fw].mean(), f[bw].mean()


@pytest.mark.parametrize("device,test_id,level,freq", [
    ("brfd", "h-267N-0.05Hz", 267.0, 0.05),
    ("brfd", "h-53N-0.05Hz", 53.0, 0.05),
    ("mfd", "h-1500psi-0.05Hz", 1500.0, 0.05),
    ("mfd", "h-500psi-0.05Hz", 500.0, 0.05),
])
def test_sliding_plateau_is_the_published_friction_force(device, test_id, level, freq):
    t, x, f, _ = _read_si(device, SHIPPED[device] / "tests" / f"{test_id}.csv")
    p = twins.params_at(device, level)
    amp = pub.BRFD_AMPLITUDE_M if device == "brfd" else pub.MFD_AMPLITUDE_M
    fwd, bwd = _plateaus(t, x, f, freq, amp, p["sigma2"])
    # noise on the mean of ~1500 samples: white 1 %/sqrt(1500) + AR(1) 0.5 %/sqrt(~80): ~0.06 %
    # of Fc (sd); the bound is 0.4 % of Fc
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    assert fwd == pytest.approx(p["fc_fwd"], abs=0.004 * fc)
    assert bwd == pytest.approx(-p["fc_bwd"], abs=0.004 * fc)
    if device == "brfd":      # and that is Table 2, in kN
        i = pub.BRFD_APPLIED_N.index(level)
        assert fwd / 1e3 == pytest.approx(pub._BRFD_TABLE2_KN["fc_fwd"][i], rel=0.01)
        assert -bwd / 1e3 == pytest.approx(pub._BRFD_TABLE2_KN["fc_bwd"][i], rel=0.01)


@pytest.mark.parametrize("device,test_id", [("brfd", "h-133N-0.2Hz"), ("brfd", "eq-133N-imperial-valley"),
                                            ("mfd", "h-800psi-0.5Hz"), ("mfd", "eq-1000psi-imperial-valley")])
def test_file_force_is_published_model_plus_stated_noise(device, test_id):
    """Re-simulate from the file's own columns: the residual is the README's noise."""
    t, x, f, applied = _read_si(device, SHIPPED[device] / "tests" / f"{test_id}.csv")
    spec = _spec(device, test_id)
    p = twins.params_at(device, spec["level"])
    clean = frictionuq.simulate(t, x, p, model="three_stage", eps=0.0)
    r = f - clean
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    sd_expected = np.hypot(twins.FORCE_WHITE_SD, twins.FORCE_AR_SD) * fc
    assert np.std(r) == pytest.approx(sd_expected, rel=0.1)
    assert abs(np.mean(r)) < 0.2 * sd_expected
    # lag-1 autocorrelation of white (var w) + AR(1) (var s, phi): phi s / (w + s) = 0.18
    w, s = twins.FORCE_WHITE_SD**2, twins.FORCE_AR_SD**2
    rho = np.corrcoef(r[:-1], r[1:])[0, 1]
    assert rho == pytest.approx(twins.FORCE_AR_PHI * s / (w + s), abs=0.06)
    # the applied column: the nominal level with ~1 % noise
    assert np.median(applied) == pytest.approx(spec["level"], rel=0.03)
    assert 0.002 < np.std(applied / spec["level"]) < 0.03


def test_seed_changes_noise_not_the_noise_free_part():
    spec = _spec("brfd", "h-66N-0.5Hz")
    a = twins.make_test("brfd", spec, seed=2016)
    b = twins.make_test("brfd", spec, seed=7)
    assert np.array_equal(a["t"], b["t"]) and np.array_equal(a["x"], b["x"])
    assert np.array_equal(a["force_clean"], b["force_clean"])
    assert not np.allclose(a["force"], b["force"])
    assert not np.allclose(a["applied"], b["applied"])
    ra, rb = a["force"] - a["force_clean"], b["force"] - b["force_clean"]
    assert np.std(ra) == pytest.approx(np.std(rb), rel=0.1)
    assert abs(np.corrcoef(ra, rb)[0, 1]) < 0.1
    # the same seed gives the same test, whatever else is generated (per-test streams)
    again = twins.make_test("brfd", spec, seed=2016)
    assert again["csv"] == a["csv"]
    shipped = (SHIPPED["brfd"] / "tests" / "h-66N-0.5Hz.csv").read_text()
    assert a["csv"] == shipped


def test_noise_streams_are_per_test():
    n1, a1 = twins.noise(2016, "h-35N-0.05Hz", 500, 1000.0, 35.0)
    n2, a2 = twins.noise(2016, "h-35N-0.1Hz", 500, 1000.0, 35.0)
    n3, _ = twins.noise(2016, "h-35N-0.05Hz", 500, 1000.0, 35.0)
    assert np.array_equal(n1, n3) and not np.allclose(n1, n2)


def test_cli_twin(tmp_path, capsys):
    out = tmp_path / "mfd"
    assert main(["twin", "mfd", "--out", str(out), "--seed", "5"]) == 0
    assert "12 tests, seed 5" in capsys.readouterr().out
    doc = tomllib.loads((out / "campaign.toml").read_text())
    assert doc["twin"]["seed"] == 5
    # same drive and noise-free force as the shipped twin, different noise
    new = pd.read_csv(out / "tests" / "eq-500psi-kobe.csv")
    old = pd.read_csv(SHIPPED["mfd"] / "tests" / "eq-500psi-kobe.csv")
    assert new["displacement"].equals(old["displacement"]) and new["time"].equals(old["time"])
    assert not new["force"].equals(old["force"])


def test_bad_arguments_and_atomic_failure(tmp_path):
    with pytest.raises(ValueError, match="unknown twin device"):
        twins.write_twin("xfd", tmp_path / "x")
    with pytest.raises(ValueError, match="seed"):
        twins.write_twin("brfd", tmp_path / "x", seed=-1)
    # a failure half-way (no accelerograms where it looks) leaves an earlier twin as it was
    out = tmp_path / "keep"
    out.mkdir()
    toml = '[twin]\ngenerator = "frictionuq.twins"\nseed = 1\n'
    (out / "campaign.toml").write_text(toml)
    with pytest.raises(InputError, match="ground-motion file not found"):
        twins.write_twin("brfd", out, root=tmp_path / "no-ground-motions")
    assert [p.name for p in out.iterdir()] == ["campaign.toml"]
    assert (out / "campaign.toml").read_text() == toml
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep"]
    # a folder that is not a twin (or a file) is never replaced: refused before any work
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.txt").write_text("mine")
    (tmp_path / "afile").write_text("mine")
    for target, why in ((mine, "is not empty and is not a twin campaign"),
                        (tmp_path / "afile", "exists and is not a folder")):
        with pytest.raises(InputError, match=why):
            twins.write_twin("brfd", target)
    assert (mine / "thesis.txt").read_text() == "mine" and (tmp_path / "afile").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "keep", "mine"]
