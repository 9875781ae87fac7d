"""`frictionuq predict` / frictionuq.predict: posterior predictive bands and per-cycle figures.

One small fit is built once for the module (a few seconds): a synthetic 2-cycle, 0.2 Hz, 25.4 mm
record simulated with the published BRFD 267 N set plus a 300 N load-cell offset and AR(1)
noise (marginal sd 375 N), in a campaign whose applied unit is kN; only fc_fwd, fc_bwd and
force_offset are free (the rest fixed at the truth), with a tiny sampler (not converged by the
project's rule; irrelevant here)."""
from __future__ import annotations

import json
import sys
import types

import numpy as np
import pandas as pd
import pytest

from frictionuq import published
from frictionuq.cli import main
from frictionuq.errors import InputError
from frictionuq.infer.fit import FitConfig, fit_campaign
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.model import simulate
from frictionuq.draws import Draws
from frictionuq.cycles import CYCLE_COLUMNS, cycle_bounds, cycle_table
from frictionuq.predict import BAND_COLUMNS, add_noise, harmonic_input, predict, write_prediction

TRUTH = published.brfd_params(267.0)
OFFSET = 300.0
SIGMA = 375.0
AMP, FREQ = 0.0254, 0.2
FREE = ("fc_fwd", "fc_bwd", "force_offset")
TINY = dict(nwalkers=16, chunk=200, min_steps=200, max_steps=400, burn_rounds=1, burn_max_rounds=1,
            burn_steps=100, n_random_starts=1, n_prior_starts=1, progress=False)


def _campaign(root):
    camp = root / "camp"
    (camp / "tests").mkdir(parents=True)
    t = np.arange(0, 10.0, 0.01)
    x = AMP * np.sin(2 * np.pi * FREQ * t)
    rng = np.random.default_rng(0)
    phi = 0.5
    e = np.empty(t.size)
    e[0] = SIGMA * rng.standard_normal()
    for k in range(1, t.size):
        e[k] = phi * e[k - 1] + SIGMA * np.sqrt(1 - phi**2) * rng.standard_normal()
    y = simulate(t, x, TRUTH) + OFFSET + e
    return tiny_campaign(camp, t, x, y, "kN", 0.267)


def tiny_campaign(camp, t, x, y, applied_unit: str, applied: float):
    """Write a one-test campaign (test h1, SI columns, 0.2 Hz harmonic) to folder camp."""
    (camp / "tests").mkdir(parents=True, exist_ok=True)
    np.savetxt(camp / "tests/h1.csv", np.column_stack([t, x, y]), delimiter=",",
               header="time,displacement,force", comments="", fmt="%.10g")
    (camp / "campaign.toml").write_text(
        'name = "tiny"\ndevice = "BRFD"\n[units]\ntime = "s"\ndisplacement = "m"\nforce = "N"\n'
        f'applied = "{applied_unit}"\n[[tests]]\nid = "h1"\nfile = "tests/h1.csv"\n'
        f'applied = {applied:g}\nkind = "harmonic"\nfrequency_hz = 0.2\n')
    return camp


@pytest.fixture(scope="module")
def fit_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("predict")
    camp = _campaign(root)
    cfg = FitConfig(priors={k: v for k, v in TRUTH.items() if k not in FREE},
                    sampler=SamplerConfig(**TINY), n_predictive=10)
    fit_campaign(camp, root / "fit", config=cfg)
    return root / "fit"


def _bands(path):
    df = pd.read_csv(path)
    assert list(df.columns) == BAND_COLUMNS
    return df


def test_bands_ordered_noisy_wider_and_offset_excluded(fit_dir, tmp_path):
    meta = write_prediction(fit_dir, tmp_path / "p", harmonic=(AMP, FREQ), applied=0.267, n_draws=200)
    assert meta["applied"]["si"] == pytest.approx(267.0) and meta["applied"]["unit"] == "kN"
    assert meta["draws_source"] == "posterior of fit applied-0.267kN"
    b = _bands(tmp_path / "p" / "bands.csv")
    assert len(b) == 3 * 200 + 1
    for pre in ("force", "force_model"):
        q = b[[f"{pre}_q2.5", f"{pre}_q25", f"{pre}_median", f"{pre}_q75", f"{pre}_q97.5"]].to_numpy()
        assert np.all(np.diff(q, axis=1) >= 0), pre
    w_noisy = b["force_q97.5"] - b["force_q2.5"]
    w_model = b["force_model_q97.5"] - b["force_model_q2.5"]
    assert np.all(w_noisy > w_model)
    # the noise band is about +-1.96 sigma wide (sigma fitted near 375 N)
    assert np.median(w_noisy) == pytest.approx(3.92 * SIGMA, rel=0.2)
    # offset excluded by default: noisy and model medians agree within the Monte Carlo error
    assert abs(np.mean(b["force_median"] - b["force_model_median"])) < 0.1 * SIGMA
    write_prediction(fit_dir, tmp_path / "q", harmonic=(AMP, FREQ), applied=0.267, n_draws=200,
                     include_offset=True)
    b2 = _bands(tmp_path / "q" / "bands.csv")
    assert np.mean(b2["force_median"] - b2["force_model_median"]) == pytest.approx(OFFSET, abs=100)
    np.testing.assert_array_equal(b2["force_model_median"], b["force_model_median"])


def test_model_band_contains_the_true_noise_free_force(fit_dir):
    t, x = harmonic_input(AMP, FREQ)
    p = predict(fit_dir, 267.0, t, x, n_draws=300, seed=3, samples_per_cycle=200)
    F = simulate(t, x, TRUTH)
    tol = 1e-9 * np.max(np.abs(F))
    inside = (p.bands["force_model_q2.5"] - tol <= F) & (F <= p.bands["force_model_q97.5"] + tol)
    assert inside.mean() >= 0.9
    # and the band is informative: much narrower than the noise
    assert np.median(p.bands["force_model_q97.5"] - p.bands["force_model_q2.5"]) < SIGMA


def test_cycle_energy_is_the_loop_area(fit_dir):
    t, x = harmonic_input(AMP, FREQ)
    p = predict(fit_dir, 267.0, t, x, n_draws=50, seed=4, samples_per_cycle=200)
    assert list(p.cycles.columns) == CYCLE_COLUMNS and list(p.cycles["cycle"]) == [1, 2, 3]
    np.testing.assert_allclose(p.cycles["t_start"], [0, 5, 10], atol=1e-12)
    np.testing.assert_allclose(p.cycles["t_end"], [5, 10, 15], atol=1e-12)
    for c, (i0, i1) in enumerate([(0, 200), (200, 400), (400, 600)]):
        xs = x[i0:i1 + 1]
        # shoelace area of the closed (F, x) polygon of every draw: an independent loop integral
        areas = []
        for F in p.F_model[:, i0:i1 + 1]:
            xc, Fc = np.append(xs, xs[0]), np.append(F, F[0])
            areas.append(0.5 * np.sum((Fc[1:] + Fc[:-1]) * np.diff(xc)))
        areas = np.array(areas)
        row = p.cycles.iloc[c]
        assert row["energy_q2.5"] <= row["energy_median"] <= row["energy_q97.5"]
        # closing the polygon adds F dx over x[i1] -> x[i0] = 0 for a whole period
        assert row["energy_median"] == pytest.approx(np.median(areas), rel=1e-9)
        assert row["peak_force_median"] == pytest.approx(np.median(np.max(np.abs(p.F_model[:, i0:i1 + 1]), axis=1)))
    # steady cycles dissipate slightly less than the Coulomb rectangle 2 A (fc_fwd + fc_bwd)
    coulomb = 2 * AMP * (TRUTH["fc_fwd"] + TRUTH["fc_bwd"])
    assert 0.85 * coulomb < p.cycles["energy_median"].iloc[2] < coulomb


def _fake_law(monkeypatch, params, calls):
    mod = types.ModuleType("frictionuq.infer.lawdraws")

    def draws_at(fit_dir, applied_si, n, rng):
        calls.append(applied_si)
        return {k: np.full(n, float(v)) for k, v in params.items()}, "three_stage", ()
    mod.draws_at = draws_at
    monkeypatch.setitem(sys.modules, "frictionuq.infer.lawdraws", mod)
    from frictionuq.infer import law
    monkeypatch.setattr(law, "law_entry",
                        lambda fit_dir: {"file": "law.json", "family": "fake", "sha256": "0" * 64})


def test_law_draws_between_levels_and_coulomb_energy(fit_dir, tmp_path, monkeypatch):
    """At an applied force that was not fitted the law's draws are used (here a fake law
    returning one Coulomb-like parameter set: no backlash, stiff bristles, no viscosity), so
    the model band collapses onto that set's force and the energy per cycle is the Coulomb
    rectangle 2 A (fc_fwd + fc_bwd) = 4 fc A."""
    fc_f, fc_b = 1000.0, 1500.0
    coul = dict(fc_fwd=fc_f, fc_bwd=fc_b, fs_fwd=fc_f, fs_bwd=fc_b, v_s=1e-3, sigma0=1e10,
                sigma1=0.0, sigma2=0.0, k2=0.0, d2=0.0, k3=0.0, d3=0.0, w=1e-7)
    calls = []
    _fake_law(monkeypatch, coul, calls)
    meta = write_prediction(fit_dir, tmp_path / "p", harmonic=(AMP, FREQ), applied=0.2, n_draws=50)
    assert calls == [pytest.approx(200.0)]             # 0.2 kN -> 200 N
    assert meta["draws_source"] == "force-dependence law" and meta["law"]["family"] == "fake"
    b = _bands(tmp_path / "p" / "bands.csv")
    t, x = harmonic_input(AMP, FREQ)
    np.testing.assert_allclose(b["force_model_q2.5"], b["force_model_q97.5"], rtol=0, atol=1e-6)
    np.testing.assert_allclose(b["force_model_median"], simulate(t, x, coul), rtol=1e-8, atol=1e-6)
    cyc = pd.read_csv(tmp_path / "p" / "cycles.csv")
    np.testing.assert_allclose(cyc["energy_median"], 2 * AMP * (fc_f + fc_b), rtol=0.01)
    np.testing.assert_allclose(cyc["peak_force_median"], fc_b, rtol=0.01)
    # the noise still comes from the nearest fitted level's posterior
    assert np.median(b["force_q97.5"] - b["force_q2.5"]) == pytest.approx(3.92 * SIGMA, rel=0.25)


def test_same_seed_same_bytes(fit_dir, tmp_path):
    paths = []
    for name, seed in (("a", 7), ("b", 7), ("c", 8)):
        write_prediction(fit_dir, tmp_path / name, harmonic=(0.01, 0.5), applied=0.267, n_draws=100, seed=seed)
        paths.append((tmp_path / name / "bands.csv").read_bytes())
    assert paths[0] == paths[1]
    assert paths[0] != paths[2]


def test_record_input_cycles_between_turning_points(fit_dir, tmp_path):
    t = np.arange(0, 12.5, 0.01)                      # 2.5 cycles at 0.2 Hz, 100 Hz
    x = AMP * np.sin(2 * np.pi * FREQ * t)
    X = tmp_path / "X.csv"
    pd.DataFrame({"time": t, "displacement": x, "extra": 1}).to_csv(X, index=False, float_format="%.10g")
    meta = write_prediction(fit_dir, tmp_path / "p", input_csv=X, applied=0.267, n_draws=50)
    assert meta["input"]["kind"] == "record" and meta["input"]["eps_m"] < 1e-6
    b = _bands(tmp_path / "p" / "bands.csv")
    np.testing.assert_allclose(b["time"], t, rtol=1e-9)
    cyc = pd.read_csv(tmp_path / "p" / "cycles.csv")
    # turning points at t = 1.25 (top), 3.75, 6.25 (top), 8.75, 11.25 (top): 2 complete cycles
    np.testing.assert_allclose(cyc["t_start"], [1.25, 6.25], atol=0.011)
    np.testing.assert_allclose(cyc["t_end"], [6.25, 11.25], atol=0.011)
    assert np.all(cyc["energy_median"] > 0)


def test_cycle_bounds_of_a_record():
    t = np.linspace(0, 3, 601)
    x = np.sin(2 * np.pi * t)
    b = cycle_bounds(x)
    assert len(b) == 2 and all(j - i == 200 for i, j in b)
    # wiggles of 3 % of the amplitude (a ground motion's small reversals) cut no cycle; before,
    # every one of them did (the demo's Kobe table listed 44 "cycles", some of 0.01-0.02 s)
    wiggly = x + 0.03 * np.sin(2 * np.pi * 40 * t)
    from frictionuq.noise import reversal_indices
    assert reversal_indices(wiggly, 0.0).size > 100
    bw = cycle_bounds(wiggly)
    assert len(bw) == 2 and all(abs(i - i0) <= 3 and abs(j - j0) <= 3 for (i, j), (i0, j0) in zip(bw, b))
    assert cycle_bounds(x[:150]) == []                # fewer than 3 reversals: no complete cycle
    F = np.where(np.gradient(x) > 0, 2.0, -3.0)[None, :]
    tab = cycle_table(t, x, F, b)
    np.testing.assert_allclose(tab["energy_median"], 2 * 2.0 + 2 * 3.0, rtol=0.02)


def test_noise_correlation_is_converted_to_the_prediction_rate():
    S, n = 4, 40000
    d = Draws({}, "three_stage", (), np.zeros(S), np.full(S, 2.0), np.full(S, 0.81),
              np.full(S, 100.0), "test", [])
    e = add_noise(np.zeros((S, n)), d, 0.005, np.random.default_rng(0))    # 200 Hz: half a step
    r1 = np.mean([np.corrcoef(row[1:], row[:-1])[0, 1] for row in e])
    assert r1 == pytest.approx(0.9, abs=0.01)         # 0.81 ** 0.5
    assert np.std(e) == pytest.approx(2.0, rel=0.05)


@pytest.mark.parametrize("case", ["missing-file", "missing-column", "text-cell", "time-back",
                                  "amplitude", "frequency", "not-fit-dir", "no-level-no-law",
                                  "applied-text", "out-not-empty", "mm-harmonic", "mm-input",
                                  "clean-harmonic", "file-as-fit-dir", "fast-harmonic", "fast-input"])
def test_bad_input_exit_2_one_line_nothing_written(fit_dir, tmp_path, capsys, case):
    X = tmp_path / "X.csv"
    rows = [(k * 0.01, float(0.01 * np.sin(k * 0.1))) for k in range(50)]
    good = "time,displacement\n" + "\n".join(f"{a!r},{b!r}" for a, b in rows) + "\n"
    out = tmp_path / "out"
    src = ["--harmonic", "0.01,0.5"]
    applied, fdir = "0.267", str(fit_dir)
    if case == "missing-file":
        src, frag = ["--input", str(tmp_path / "none.csv")], "file not found"
    elif case == "missing-column":
        X.write_text(good.replace("displacement", "disp"))
        src, frag = ["--input", str(X)], "missing column 'displacement'"
    elif case == "text-cell":
        X.write_text(good.replace("\n0.05,", "\nabc,"))
        src, frag = ["--input", str(X)], "line 7"
    elif case == "time-back":
        X.write_text(good.replace("\n0.05,", "\n0.01,"))
        src, frag = ["--input", str(X)], "time is not strictly increasing"
    elif case == "amplitude":
        src, frag = ["--harmonic=-0.01,0.5"], "amplitude"
    elif case == "frequency":
        src, frag = ["--harmonic", "0.01,0"], "frequency"
    elif case == "not-fit-dir":
        fdir, frag = str(tmp_path), "not a fit output folder"
    elif case == "file-as-fit-dir":        # said "no such fit output folder" until 2026-12-05
        X.write_text(good)
        fdir, frag = str(X), "X.csv: is a file, not a fit output folder"
    elif case == "no-level-no-law":
        # in the user's unit, SI beside it
        applied, frag = "0.1", "applied force 0.1 kN (100 N) (fitted: 0.267 kN (267 N)) and no usable force-dependence law"
    elif case == "applied-text":
        applied, frag = "heavy", "not a number"
    elif case == "mm-harmonic":        # 25 mm typed as 25 (m): refused, not predicted
        src, frag = ["--harmonic", "25,1"], ("harmonic input: the drive's amplitude is 25 m, above "
                                             "1 m, which no damper test reaches")
    elif case == "mm-input":
        X.write_text("time,displacement\n" + "".join(f"{a!r},{1e3 * b!r}\n" for a, b in rows))
        src, frag = ["--input", str(X)], "X.csv: the drive's amplitude is 13.15 m, above 1 m"
    elif case == "clean-harmonic":
        src, frag = ["--harmonic", "0.01,0.5", "--clean-input"], "a harmonic is always clean"
    elif case == "fast-harmonic":      # 0.1 mm at 1 MHz (628 m/s): until 2026-12-06 predicted
        src, frag = ["--harmonic", "0.0001,1e6"], (
            "harmonic input: its peak speed 2 pi f A is 628.3 m/s (0.0001 m at 1e+06 Hz), above "
            "10 m/s, which no damper test reaches")
    elif case == "fast-input":         # a 15 cm glitch at t = 0.2 s: 15 m/s into it and out of it
        X.write_text("time,displacement\n" + "".join(
            f"{a!r},{b + (0.15 if k == 20 else 0.0)!r}\n" for k, (a, b) in enumerate(rows)))
        src, frag = ["--input", str(X)], ("X.csv: the drive moves at 15.05 m/s between t = 0.2 s "
                                          "and 0.21 s, above 10 m/s, which no damper test reaches")
    else:
        out.mkdir()
        (out / "keep.txt").write_text("mine")
        frag = "not empty"
    code = main(["predict", fdir, *src, "--applied", applied, "--out", str(out), "--draws", "20"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.count("\n") == 1 and frag in err, err
    if case == "out-not-empty":
        assert [p.name for p in out.iterdir()] == ["keep.txt"]
    else:
        assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]


def test_a_generated_drive_is_predicted_clean_and_its_source_recorded(fit_dir, tmp_path):
    """clean_input: a CSV that is a generated drive (the pipeline's ground-motion histories) gets
    the harmonic's treatment, dead band 0 and no drive filter, not a measured record's noise
    estimate; prediction.json records where it came from."""
    t = np.arange(0, 12.5, 0.01)
    X = tmp_path / "X.csv"
    pd.DataFrame({"time": t, "displacement": AMP * np.sin(2 * np.pi * FREQ * t)}).to_csv(
        X, index=False, float_format="%.9g")
    src = {"record": "kobe", "peak_m": 0.01, "rate_hz": 100.0}
    meta = write_prediction(fit_dir, tmp_path / "p", input_csv=X, applied=0.267, n_draws=20,
                            clean_input=True, source=src)
    inp = meta["input"]
    assert inp["kind"] == "generated record" and inp["eps_m"] == 0.0 and inp["drive_lowpass"] is None
    assert inp["source"] == src and "clean generated drive" in inp["eps_rule"]
    measured = write_prediction(fit_dir, tmp_path / "m", input_csv=X, applied=0.267, n_draws=20)
    assert measured["input"]["kind"] == "record" and measured["input"]["eps_m"] > 0


def test_library_refuses_two_inputs(fit_dir, tmp_path):
    with pytest.raises(InputError, match="exactly one input"):
        write_prediction(fit_dir, tmp_path / "p", applied=0.267)


def test_cli_predict_writes_the_three_files(fit_dir, tmp_path, capsys):
    out = tmp_path / "p"
    assert main(["predict", str(fit_dir), "--harmonic", "0.02,0.1", "--applied", "0.267",
                 "--out", str(out), "--draws", "40", "--seed", "3"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["bands.csv", "cycles.csv", "prediction.json"]
    meta = json.loads((out / "prediction.json").read_text())
    assert meta["n_draws"] == 40 and meta["seed"] == 3 and meta["input"]["frequency_hz"] == 0.1
    assert meta["units"]["force"] == "N" and meta["units"]["energy"] == "J"
    assert "applied 0.267 kN" in capsys.readouterr().out


def test_refuses_incomplete_fit_folders_and_oversized_requests(fit_dir, tmp_path):
    (tmp_path / "summary.json").write_text((fit_dir / "summary.json").read_text())
    with pytest.raises(InputError, match="fit.json: missing"):
        write_prediction(tmp_path, tmp_path / "p", harmonic=(AMP, FREQ), applied=0.267)
    (tmp_path / "summary.json").write_text('{"fits": []}')
    with pytest.raises(InputError, match="key fits"):
        write_prediction(tmp_path, tmp_path / "p", harmonic=(AMP, FREQ), applied=0.267)
    assert not (tmp_path / "p").exists()
    n = 100_001
    with pytest.raises(InputError, match="too large"):
        predict(fit_dir, 267.0, np.arange(n, dtype=float), np.zeros(n), n_draws=400)


def test_an_input_beyond_the_fitted_records_is_flagged(fit_dir, tmp_path, capsys):
    """prediction.json's fitted_range says when the input's amplitude or peak speed exceeds the
    fitted records' by more than BEYOND_FACTOR, and the command line notes it; a harmonic inside
    the fitted range is not flagged."""
    from frictionuq.extrapolation import BEYOND_FACTOR
    inside = write_prediction(fit_dir, tmp_path / "in", harmonic=(AMP, FREQ), applied=0.267, n_draws=20)
    r = inside["fitted_range"]
    assert r["beyond"] == [] and r["amplitude_m"] == pytest.approx(AMP, rel=1e-3)
    assert r["fitted_amplitude_m"] >= AMP * 0.99 and r["factor"] == BEYOND_FACTOR
    assert main(["predict", str(fit_dir), "--harmonic", f"{4 * AMP},{FREQ}", "--applied", "0.267",
                 "--out", str(tmp_path / "far"), "--draws", "20"]) == 0
    err = capsys.readouterr().err
    assert "note: the input goes beyond the fitted records (amplitude, peak speed)" in err, err
    doc = json.loads((tmp_path / "far" / "prediction.json").read_text())
    assert doc["fitted_range"]["beyond"] == ["amplitude", "peak speed"]


def test_the_library_warns_where_the_cli_notes(fit_dir, tmp_path, capsys):
    """predict() in a notebook warns (ResultWarning) of the unconverged fit and of an input
    beyond the fitted range, which the CLI says in its own notes (and does not repeat)."""
    from frictionuq.errors import ResultWarning
    t, x = harmonic_input(AMP, FREQ)
    with pytest.warns(ResultWarning, match="not converged"):
        predict(fit_dir, 267.0, t, x, n_draws=20, seed=1, samples_per_cycle=200)
    with pytest.warns(ResultWarning, match="beyond 1.5 times the fitted"):
        predict(fit_dir, 267.0, t, 10 * x, n_draws=20, seed=1, samples_per_cycle=200)
    # a measured record in memory: eps and the drive filter as predict --input takes them
    from frictionuq.noise import default_eps
    rng = np.random.default_rng(5)
    xm = x + 2e-6 * rng.standard_normal(x.size)
    with pytest.warns(ResultWarning):
        p = predict(fit_dir, 267.0, t, xm, eps="auto", drive_lowpass="auto", n_draws=20, seed=1)
    assert p.eps == pytest.approx(default_eps(xm)) and p.eps > 0
    assert main(["predict", str(fit_dir), "--harmonic", f"{AMP},{FREQ}", "--applied", "0.267",
                 "--out", str(tmp_path / "w"), "--draws", "20"]) == 0
    err = capsys.readouterr().err
    assert "ResultWarning" not in err and "note: the bands are drawn from fit(s) not converged" in err


def test_results_from_unconverged_fits_say_so(fit_dir, tmp_path, capsys):
    """The fixture's fit is tiny and not converged: prediction.json and validation.json list it
    under not_converged_fits and the command line notes it (before, nothing outside the report
    said so)."""
    summary = json.loads((fit_dir / "summary.json").read_text())
    ids = [f["id"] for f in summary["fits"] if not f["converged"]]
    assert ids, "the fixture's fit was expected not to converge"
    assert main(["predict", str(fit_dir), "--harmonic", f"{AMP},{FREQ}", "--applied", "0.267",
                 "--out", str(tmp_path / "p"), "--draws", "20"]) == 0
    assert "note: the bands are drawn from fit(s) not converged" in capsys.readouterr().err
    doc = json.loads((tmp_path / "p" / "prediction.json").read_text())
    assert set(doc["not_converged_fits"]) <= set(ids) and doc["not_converged_fits"]


def test_an_unfitted_level_without_a_law_says_what_can_be_done(fit_dir):
    """One fitted level: no law can be fitted, and the message says so (it suggested running
    `frictionuq law`, which then refused)."""
    t, x = harmonic_input(AMP, FREQ)
    with pytest.raises(InputError, match="none can be fitted: it needs fits at 2 or more applied "
                                         "forces > 0, this folder has 1"):
        predict(fit_dir, 500.0, t, x, n_draws=20)


def test_a_level_typed_to_a_few_digits_is_that_level(fit_dir, tmp_path):
    """--applied within draws.REL_TOL (1e-3) of a fitted level is that level, as `table` (4
    digits) and fit ids (6) show it; it went to the law (or was refused without one) at 1e-6.
    Further away, as before, the law (none here: refused)."""
    meta = write_prediction(fit_dir, tmp_path / "p", harmonic=(AMP, FREQ), applied=0.26705, n_draws=20)
    assert meta["draws_source"].startswith("posterior of fit ") and "nearest the requested" in meta["draws_source"]
    exact = write_prediction(fit_dir, tmp_path / "q", harmonic=(AMP, FREQ), applied=0.267, n_draws=20)
    assert "nearest" not in exact["draws_source"]
    with pytest.raises(InputError, match="no usable force-dependence law"):
        write_prediction(fit_dir, tmp_path / "r", harmonic=(AMP, FREQ), applied=0.2675, n_draws=20)


def test_validate_says_where_it_extrapolates(fit_dir, tmp_path, capsys):
    """validate scores a measured test whose amplitude is three times the fitted records': like
    predict, it records the input's range (validation.json) and says it extrapolates (the CLI's
    note), which it did not until 2026-12-05."""
    from frictionuq.cli import main
    t = np.arange(0, 10.0, 0.01)
    x = 3 * AMP * np.sin(2 * np.pi * FREQ * t)
    camp = tiny_campaign(tmp_path / "big", t, x, simulate(t, x, TRUTH) + OFFSET, "kN", 0.267)
    assert main(["validate", str(fit_dir), str(camp), "--test", "h1", "--out", str(tmp_path / "v"),
                 "--draws", "20"]) == 0
    err = capsys.readouterr().out
    doc = json.loads((tmp_path / "v" / "validation.json").read_text())
    r = doc["tests"][0]
    assert r["fitted_range"]["beyond"] == ["amplitude", "peak speed"] and not r["applied_range"]["beyond"]
    assert "note: h1: the input goes beyond the fitted records (amplitude, peak speed)" in err, err


def test_a_record_written_before_the_amplitude_rename_still_gives_its_note():
    """prediction.json and validation.json written before 2026-12-05 name the input's amplitude
    stroke_m (the same figure); the report and the task log still read their note."""
    from frictionuq.extrapolation import notes
    old = {"fitted_range": {"stroke_m": 0.03, "fitted_stroke_m": 0.01, "peak_speed_m_s": 0.2,
                            "fitted_peak_speed_m_s": 0.1, "beyond": ["stroke", "peak speed"]}}
    (line,) = notes(old)
    assert "amplitude (largest |x - median x|) 0.03 m against 0.01 m" in line
