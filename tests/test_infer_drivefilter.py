"""The optional drive low-pass (frictionuq.infer.drivefilter, FitConfig.drive_lowpass): what it
keeps, what it removes, and that fit, predict and validate apply it alike. Deterministic (fixed
seeds); no statistical test here."""
import json

import numpy as np
import pandas as pd
import pytest

from frictionuq.infer import drivefilter
from frictionuq.infer.fit import FitConfig, fit_campaign, plan
from frictionuq.infer.likelihood import (default_eps, dominant_frequency, drive_cutoff, lowpass_drive,
                                         prepare_record)
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.campaign import load_campaign
from frictionuq.model import simulate
from frictionuq.predict import write_prediction

FS = 1024.0
AMP = 0.0254


def _noisy_sine(f=0.5, seconds=8.0, sd=3e-6, seed=0):
    t = np.arange(int(seconds * FS)) / FS
    clean = AMP * np.sin(2 * np.pi * f * t)
    return t, clean, clean + sd * np.random.default_rng(seed).standard_normal(t.size)


def test_keeps_the_motion_in_phase_and_at_the_ends():
    t, clean, _ = _noisy_sine()
    out = drivefilter.lowpass(clean, FS, 11.0)
    # a 0.5 Hz sine passes a zero-phase 11 Hz low-pass unchanged, ends included (line removed)
    assert np.max(np.abs(out - clean)) < 1e-4 * AMP
    t2 = np.linspace(0, 2, 2049)
    ramp = 0.01 + 0.02 * t2                     # a pure line is untouched (trend removal)
    np.testing.assert_allclose(drivefilter.lowpass(ramp, 1024.0, 5.0), ramp, rtol=0, atol=1e-12)


def test_removes_sensor_noise_and_most_of_the_velocity_noise():
    t, clean, x = _noisy_sine()
    out = drivefilter.lowpass(x, FS, 11.0)
    sd_in = np.std(x - clean)
    sd_out = np.std(out - clean)
    # white noise keeps about sqrt(11 / 512) = 0.15 of its sd; allow up to 0.25
    assert sd_out < 0.25 * sd_in
    v_noise_in = np.std(np.gradient(x - clean, t))
    v_noise_out = np.std(np.gradient(out - clean, t))
    assert v_noise_out < 0.05 * v_noise_in


def test_cutoff_rule_and_refused_values():
    assert drivefilter.cutoff_hz(FS, 0.56, None) is None
    assert drivefilter.cutoff_hz(FS, 0.56, 20) == pytest.approx(11.2)
    assert drivefilter.cutoff_hz(FS, 30.0, 20) is None          # 600 Hz: above 0.9 Nyquist
    assert drivefilter.check_multiple(None) is None
    assert drivefilter.check_multiple("off") is None
    assert drivefilter.check_multiple("auto") == "auto"
    assert drivefilter.check_multiple(20) == 20.0
    # "auto": on at 20 where the record has a dead band (measured), off on a clean drive
    assert drivefilter.resolve("auto", 1.2e-5) == drivefilter.AUTO_MULTIPLE == 20.0
    assert drivefilter.resolve("auto", 0.0) is None
    assert drivefilter.resolve(7, 0.0) == 7.0 and drivefilter.resolve("off", 1e-5) is None
    for bad in (0, -1.0, float("nan"), float("inf"), True, "20"):
        with pytest.raises(ValueError, match="drive_lowpass"):
            drivefilter.check_multiple(bad)


def test_prepare_record_filters_the_drive_only_when_asked():
    t, clean, x = _noisy_sine()
    y = simulate(t, clean, {"fc_fwd": 900.0, "fc_bwd": 900.0, "fs_fwd": 1000.0, "fs_bwd": 1000.0,
                           "v_s": 0.01, "sigma0": 1e6, "sigma1": 10.0, "sigma2": 100.0,
                           "k2": 1e5, "d2": 0.002, "k3": 5e5, "d3": 0.003, "w": 2e-4})
    off = prepare_record("a", t, x, y, q=4)
    on = prepare_record("a", t, x, y, q=4, drive_lowpass=20)
    assert off.drive_cutoff_hz is None
    np.testing.assert_array_equal(off.sim_drive.x, x)
    cut = 20 * dominant_frequency(t, x)[1]
    assert on.drive_cutoff_hz == pytest.approx(cut)
    np.testing.assert_allclose(on.sim_drive.x, drivefilter.lowpass(x, FS, cut), rtol=0, atol=0)
    assert on.eps == off.eps == default_eps(x)       # the dead band comes from the raw record
    np.testing.assert_array_equal(on.y, off.y)        # the measured force is not touched
    assert np.std(np.diff(on.sim_drive.v)) < 0.1 * np.std(np.diff(off.sim_drive.v))
    with pytest.raises(ValueError, match="drive_lowpass"):
        prepare_record("a", t, x, y, q=4, drive_lowpass=-2)


def test_auto_filters_a_measured_record_and_leaves_a_clean_drive_alone():
    """FitConfig's default drive_lowpass = "auto": a record with eps > 0 is filtered at 20 x its
    99 % frequency, one at eps = 0 is not (the same record as off, bit for bit)."""
    t, clean, x = _noisy_sine()
    y = np.zeros_like(t)
    auto = prepare_record("a", t, x, y, q=4, drive_lowpass="auto")
    assert auto.eps > 0 and auto.drive_cutoff_hz == pytest.approx(drive_cutoff(t, x, 20.0))
    at0 = prepare_record("a", t, clean, y, q=4, eps=0.0, drive_lowpass="auto")
    off = prepare_record("a", t, clean, y, q=4, eps=0.0)
    assert at0.drive_cutoff_hz is None
    np.testing.assert_array_equal(at0.sim_drive.x, off.sim_drive.x)
    assert FitConfig().drive_lowpass == "auto" and FitConfig(drive_lowpass="off").drive_lowpass is None


def test_on_the_twins_auto_and_extreme_change_the_force_by_much_less_than_the_noise(tmp_path):
    """The twins' records are clean drives rounded in their CSV (eps "auto" 1e-9 - 3e-8 m), so
    the defaults filter them and place their reversals at the extremes: on every BRFD twin test
    the force the model makes that way departs from the generator's (raw drive, eps = 0) by
    under 1 % of the twin's white force-noise sd (1 % of the friction force); the reversal rule
    alone changes nothing there."""
    from frictionuq.campaign import load_campaign as load
    from frictionuq.noise import default_eps as eps_of
    from frictionuq.published import published_params
    from frictionuq.twins import FORCE_WHITE_SD, write_twin
    write_twin("brfd", tmp_path / "tw")
    for te in load(tmp_path / "tw").tests:
        r, p = te.record, published_params("brfd", te.applied)
        e = eps_of(r.x)
        assert 0 < e < 5e-8, te.id
        gen = simulate(r.t, r.x, p, eps=0.0)
        fitted = simulate(r.t, lowpass_drive(r.t, r.x, drivefilter.resolve("auto", e))[0], p,
                          eps=e, reversal="extreme")
        noise_sd = FORCE_WHITE_SD * 0.5 * (p["fc_fwd"] + p["fc_bwd"])
        assert np.max(np.abs(fitted - gen)) < 0.01 * noise_sd, te.id
        np.testing.assert_array_equal(simulate(r.t, r.x, p, eps=e, reversal="extreme"), gen)

def _campaign(root, t, x, y):
    camp = root / "camp"
    (camp / "tests").mkdir(parents=True)
    np.savetxt(camp / "tests/h1.csv", np.column_stack([t, x, y]), delimiter=",",
               header="time,displacement,force", comments="", fmt="%.10g")
    (camp / "campaign.toml").write_text(
        'name = "tiny"\ndevice = "BRFD"\n[units]\ntime = "s"\ndisplacement = "m"\nforce = "N"\n'
        'applied = "N"\n[[tests]]\nid = "h1"\nfile = "tests/h1.csv"\napplied = 1000\n'
        'kind = "harmonic"\nfrequency_hz = 0.5\n')
    return camp


TRUTH = {"fc_fwd": 900.0, "fc_bwd": 850.0, "fs_fwd": 1000.0, "fs_bwd": 950.0, "v_s": 0.01,
         "sigma0": 1e6, "sigma1": 10.0, "sigma2": 100.0, "k2": 1e5, "d2": 0.002, "k3": 5e5,
         "d3": 0.003, "w": 2e-4, "force_offset": 0.0}
FREE = ("fc_fwd", "fc_bwd")
TINY = dict(nwalkers=8, chunk=100, min_steps=100, max_steps=100, burn_rounds=1, burn_max_rounds=1,
            burn_steps=50, n_random_starts=1, n_prior_starts=1, n_global_starts=0, progress=False)


@pytest.fixture(scope="module")
def fit_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("drivefilter")
    t, clean, x = _noisy_sine(f=0.5, seconds=4.0)
    y = simulate(t, clean, {k: v for k, v in TRUTH.items() if k != "force_offset"})
    y = y + 20.0 * np.random.default_rng(1).standard_normal(t.size)
    camp = _campaign(root, t, x, y)
    cfg = FitConfig(priors={k: v for k, v in TRUTH.items() if k not in FREE},
                    sampler=SamplerConfig(**TINY), n_predictive=4, drive_lowpass=20.0)
    fit_campaign(camp, root / "fit", config=cfg)
    return root, t, x


def test_fit_records_the_setting_and_predict_filters_a_measured_input_alike(fit_dir):
    root, t, x = fit_dir
    fit = root / "fit"
    summary = json.loads((fit / "summary.json").read_text())
    assert summary["config"]["drive_lowpass"] == 20.0
    rec = json.loads(next(fit.glob("*/fit.json")).read_text())["records"][0]
    assert rec["drive_cutoff_hz"] == pytest.approx(drive_cutoff(t, x, 20.0))
    X = root / "X.csv"
    pd.DataFrame({"time": t, "displacement": x}).to_csv(X, index=False, float_format="%.12g")
    meta = write_prediction(fit, root / "p", input_csv=X, applied=1000, n_draws=20)
    assert meta["input"]["drive_lowpass"] == 20.0
    # the bands keep the given displacement; the model ran on the filtered one
    b = pd.read_csv(root / "p" / "bands.csv")
    np.testing.assert_allclose(b["displacement"], x, rtol=1e-8, atol=1e-12)   # %.9g in the CSV
    xm = lowpass_drive(t, pd.read_csv(X)["displacement"].to_numpy(), 20.0)[0]
    assert np.std(xm - x) > 0.5e-6                  # the filter changes this drive (noise sd 3e-6)
    # ... and the prediction's model ran on the filtered drive: its median is the library's
    # predict() with the fit's filter, not without it
    from frictionuq.noise import default_eps
    from frictionuq.predict import predict
    xc = pd.read_csv(X)["displacement"].to_numpy()
    kw = dict(eps=default_eps(xc), n_draws=20, seed=1)
    a_si = meta["applied"]["si"]
    filt = predict(fit, a_si, t, xc, drive_lowpass=20.0, **kw).bands["force_model_median"]
    raw = predict(fit, a_si, t, xc, drive_lowpass=None, **kw).bands["force_model_median"]
    np.testing.assert_allclose(b["force_model_median"], filt, rtol=1e-8, atol=1e-6)
    assert np.max(np.abs(b["force_model_median"] - raw)) > 1e3 * np.max(np.abs(b["force_model_median"] - filt))
    h = write_prediction(fit, root / "h", harmonic=(AMP, 0.5), applied=1000, n_draws=20)
    assert h["input"]["drive_lowpass"] is None        # a generated sine is clean
    from frictionuq.validate import validate
    v = validate(fit, root / "camp", ["h1"], root / "v", n_draws=20, figures=False)
    assert v["tests"][0]["drive_lowpass"] == 20.0     # the measured test is filtered like the fit's


def test_the_default_fit_filters_its_measured_record_and_predict_follows_by_eps(tmp_path):
    """With FitConfig's defaults ("auto", "extreme") the noisy record is filtered at 20 x its
    99 % frequency; predict then filters a measured input (eps > 0) at 20 too, and a generated
    harmonic (eps = 0) not at all."""
    t, clean, x = _noisy_sine(f=0.5, seconds=4.0)
    y = simulate(t, clean, {k: v for k, v in TRUTH.items() if k != "force_offset"})
    y = y + 20.0 * np.random.default_rng(1).standard_normal(t.size)
    camp = _campaign(tmp_path, t, x, y)
    cfg = FitConfig(priors={k: v for k, v in TRUTH.items() if k not in FREE},
                    sampler=SamplerConfig(**TINY), n_predictive=4)
    fit_campaign(camp, tmp_path / "fit", config=cfg)
    summary = json.loads((tmp_path / "fit" / "summary.json").read_text())
    assert summary["config"]["drive_lowpass"] == "auto" and summary["config"]["reversal"] == "extreme"
    rec = json.loads(next((tmp_path / "fit").glob("*/fit.json")).read_text())["records"][0]
    assert rec["drive_cutoff_hz"] == pytest.approx(drive_cutoff(t, x, 20.0))
    X = tmp_path / "X.csv"
    pd.DataFrame({"time": t, "displacement": x}).to_csv(X, index=False, float_format="%.12g")
    meta = write_prediction(tmp_path / "fit", tmp_path / "p", input_csv=X, applied=1000, n_draws=10)
    assert meta["input"]["drive_lowpass"] == 20.0
    h = write_prediction(tmp_path / "fit", tmp_path / "h", harmonic=(AMP, 0.5), applied=1000,
                         n_draws=10)
    assert h["input"]["drive_lowpass"] is None


def test_predict_resolves_the_fits_setting_by_the_fits_and_the_inputs_eps(fit_dir):
    """fit_drive_lowpass: a clean drive (eps 0) is never filtered; a fit's number is used as is;
    a fit's "auto" filters where the fit's records were filtered: by the input's eps when the
    fit's eps was "auto", by the fit's own eps when it was a number (eps 0: the fit was not
    filtered, nor is the input). predict() takes "off" and refuses a bad value in one line."""
    from frictionuq.errors import InputError
    from frictionuq.predict import fit_drive_lowpass, predict
    def s(lp, eps="auto"):
        return {"config": {"drive_lowpass": lp, "eps": eps}}
    assert fit_drive_lowpass(s("auto"), 1e-5) == 20.0
    assert fit_drive_lowpass(s("auto"), 0.0) is None
    assert fit_drive_lowpass(s(20.0), 0.0) is None
    assert fit_drive_lowpass(s(7.0), 1e-5) == 7.0
    assert fit_drive_lowpass(s("auto", eps=0.0), 1e-5) is None
    assert fit_drive_lowpass(s("auto", eps=2e-5), 1e-5) == 20.0
    assert fit_drive_lowpass(s(None), 1e-5) is None and fit_drive_lowpass({}, 1e-5) is None
    root, t, x = fit_dir
    kw = dict(eps=1e-5, n_draws=4, seed=1)
    off = predict(root / "fit", 1000.0, t, x, drive_lowpass="off", **kw).bands
    none = predict(root / "fit", 1000.0, t, x, drive_lowpass=None, **kw).bands
    pd.testing.assert_frame_equal(off, none)
    for bad in ("on", -1.0, float("nan")):
        with pytest.raises(InputError, match="predict: drive_lowpass must be 'auto', 'off'"):
            predict(root / "fit", 1000.0, t, x, drive_lowpass=bad, **kw)


def test_plan_and_cli_refuse_a_bad_multiple(fit_dir, tmp_path, capsys):
    root, _, _ = fit_dir
    from frictionuq.cli import main
    from frictionuq.errors import InputError
    with pytest.raises(InputError, match="drive_lowpass must be 'auto', 'off' or a finite number > 0"):
        plan(load_campaign(root / "camp"), config=FitConfig(drive_lowpass=0.0))
    out = tmp_path / "never"
    with pytest.raises(SystemExit) as ex:            # argparse's usage error, in one line
        main(["fit", str(root / "camp"), "--out", str(out), "--drive-lowpass", "on"])
    err = capsys.readouterr().err
    assert ex.value.code == 2 and err.count("\n") == 1 and "--drive-lowpass" in err and "'auto', 'off'" in err
    # a number <= 0 or not finite: refused by the option's own type, naming it (before
    # 2026-12-05 by FitConfig, as "fit config: drive_lowpass ...")
    for cmd, bad in (("fit", "-3"), ("fit", "nan"), ("discover", "0"), ("compare", "-1")):
        with pytest.raises(SystemExit) as ex:
            main([cmd, str(root / "camp"), "--out", str(out), "--drive-lowpass", bad])
        err = capsys.readouterr().err
        assert ex.value.code == 2, err
        assert err.count("\n") == 1 and f"argument --drive-lowpass: takes 'auto', 'off' or a " \
            f"multiple > 0 (e.g. 20), got '{bad}'" in err, err
        assert not out.exists()
