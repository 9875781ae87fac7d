"""Residual diagnostics (frictionuq.discrepancy): features, the block-permutation null on AR(1)
noise, detection of each effect's signature, the figure.

The drive: a 25.4 mm, 0.5 Hz sine, 10 cycles at 1000 Hz (20 000 samples), the model force from
the published BRFD parameters at 267 N (fc ~ 37.5 kN). Residual noise: stationary AR(1),
phi = 0.95 (autocorrelation time (1+phi)/(1-phi) = 39 samples), marginal sd 300 N (0.8 % of fc).
Structured terms are about 1 % of fc, i.e. the size of the noise: a realistic missing effect.
All seeds are fixed, so each test is deterministic; the docstrings state the probability that a
correct implementation fails it over the seeds' randomness.
"""
import json

import numpy as np
import pytest
from scipy import stats

import frictionuq
from frictionuq.discrepancy import EXPECTED_SIGNATURES, build_figure, diagnose, features, residual_figure
from frictionuq.noise import ar1_from_normals
from frictionuq.published import published_params

FS, F0, CYCLES, AMP = 1000.0, 0.5, 10, 0.0254
PHI, SD = 0.95, 300.0
PHASE_VIEWS = ("displacement", "velocity", "since_reversal")
DRIFT_VIEWS = ("time", "cycle", "energy")


@pytest.fixture(scope="module")
def record():
    t = np.arange(int(CYCLES / F0 * FS)) / FS
    x = AMP * np.sin(2 * np.pi * F0 * t)
    p = published_params("brfd", 267.0)
    force = frictionuq.simulate(t, x, p)
    return t, x, p, force, features(t, x, force)


def _noise(seed, n):
    return ar1_from_normals(np.random.default_rng(seed).standard_normal(n), PHI, SD)


# ------------------------------------------------------------------------------------ features
def test_since_reversal_resets_and_grows_with_travel():
    """Deterministic (no randomness)."""
    t = np.arange(4000) / 1000.0
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    f = features(t, x, None)
    s, d = f["since_reversal"], f["direction"]
    rev = np.flatnonzero(np.diff(d) != 0) + 1
    assert rev.size == 4                                    # reversals at t = 0.5, 1.5, 2.5, 3.5 s
    assert np.allclose(t[rev], [0.5, 1.5, 2.5, 3.5], atol=2e-3)
    assert np.all(s[rev] < 1e-6)                            # reset at every reversal
    # before each reversal: the travel of the half-cycle (from x[0] = 0 for the first one)
    assert np.allclose(s[rev - 1], [0.01, 0.02, 0.02, 0.02], atol=1e-6)
    seg = slice(rev[0], rev[1])                             # grows with travel: s = |x - x_r|
    assert np.all(np.diff(s[seg]) >= 0)
    assert np.allclose(s[seg], np.abs(x[seg] - x[rev[0] - 1]))
    assert "energy" not in f and "applied" not in f


def test_energy_hand_case_and_monotone(record):
    """Deterministic."""
    t = np.arange(5.0)
    x = np.array([0.0, 1.0, 3.0, 2.0, 2.5])
    force = np.array([10.0, -20.0, 5.0, 4.0, 7.0])
    f = features(t, x, force, applied=np.full(5, 100.0))
    # E[k] = sum over j<k |F[j] (x[j+1]-x[j])|: 0, 10, 10+40, 50+5, 55+2
    assert np.allclose(f["energy"], [0.0, 10.0, 50.0, 55.0, 57.0])
    assert np.all(f["applied"] == 100.0)
    e = record[4]["energy"]
    assert e[0] == 0.0 and np.all(np.diff(e) >= 0)
    # about 4 A fc per cycle of a constant-friction loop
    assert e[-1] == pytest.approx(CYCLES * 4 * AMP * 37.5e3, rel=0.05)


def test_cycle_counts_a_five_cycle_sine():
    """Deterministic; also with a noisy displacement and a dead-band (seeded noise of 1 um, eps
    = 8 sd: the dead-band of frictionuq.noise, which misses no true reversal)."""
    t = np.arange(5000) / 1000.0
    x = 0.0254 * np.sin(2 * np.pi * 1.0 * t)
    assert features(t, x, None)["cycle"][-1] == 5
    noisy = x + np.random.default_rng(0).normal(0.0, 1e-6, x.size)
    assert features(t, noisy, None)["cycle"][-1] > 10        # noise wiggles at the turning points
    assert features(t, noisy, None, eps=8e-6)["cycle"][-1] == 5


# ------------------------------------------------------------------------- null: AR(1) noise
def test_null_ar1_noise_false_alarms_block_permutation_vs_iid(record):
    """20 replicates of AR(1) noise with no structure, family-wise alpha = 0.05 (Holm over the 6
    views + spectrum + high-frequency bursts). A correct level-0.05 test raises at most Binomial(20, 0.05) alarms, so
    it fails `<= 3` with probability P(X >= 4) = 1.6 % (computed below); offline, 300 other
    replicates gave 3 alarms (1 %), and these 20 give 0. The naive iid shuffle of the same residuals must flag
    almost every replicate: on AR(1) noise with tau = 39 samples its null is ~39 x too narrow
    (here 20/20 replicates, all 7 tests each)."""
    t, x, _, _, ft = record
    alarms, iid_alarms, views_hit = 0, 0, 0
    for rep in range(20):
        r = _noise(1000 + rep, x.size)
        dg = diagnose(t, x, r, features=ft, alpha=0.05, n_perm=199, seed=rep)
        assert dg["family_size"] == 8 and dg["correction"] == "holm"
        assert 30 <= dg["null"]["autocorrelation_length_samples"] <= 50
        alarms += bool(dg["significant"])
        iid = diagnose(t, x, r, features=ft, alpha=0.05, n_perm=199, seed=rep, block_length=1)
        iid_alarms += bool(iid["significant"])
        views_hit += len(iid["significant"])
    assert stats.binom.sf(3, 20, 0.05) < 0.02
    assert alarms <= 3
    assert iid_alarms >= 18 and views_hit >= 60


def _short_record():
    """5 cycles of the 0.5 Hz sine at 100 samples per cycle (n = 500): the size of discover's
    decimated records, where the blocks of the null are capped at n / 20 = 25 samples."""
    fs = 100 * F0
    t = np.arange(int(5 / F0 * fs)) / fs
    x = AMP * np.sin(2 * np.pi * F0 * t)
    p = published_params("brfd", 267.0)
    force = frictionuq.simulate(t, x, p)
    return t, x, 0.5 * (p["fc_fwd"] + p["fc_bwd"]), features(t, x, force)


def test_drift_views_calibrated_on_short_records_and_find_a_fade():
    """The drift views (time, cycle, energy) test a smooth trend per direction (module docstring).
    Null: 100 replicates of AR(1) noise, phi = 0.95, on the short record, alpha = 0.01
    family-wise. Offline the family-wise rate was 2.3 % (7 of 300; the blocks are capped below
    10 correlation lengths here, which the docstring warns of), so `<= 6` fails with probability
    about 1 %; the binned statistic these views used before raised 17 of these 100 (81 of 100 at
    phi = 0.99). Power: a thermal fade (3 % of fc, saturating in the dissipated energy, its mean
    per direction removed as a fit would) in the same noise, 20 seeds: 93 of 100 seeds found
    offline, so `>= 15` of 20 fails with probability below 1 %."""
    t, x, fc, ft = _short_record()
    d, e = ft["direction"], ft["energy"]
    fade = -d * 0.03 * fc * (1 - np.exp(-e / (0.5 * e[-1])))
    fade -= np.where(d > 0, fade[d > 0].mean(), fade[d < 0].mean())
    alarms = found = 0
    for seed in range(100):
        r = ar1_from_normals(np.random.default_rng(seed).standard_normal(t.size), PHI, SD)
        dg = diagnose(t, x, r, features=ft, seed=seed)
        assert dg["views"]["time"]["test"].startswith("trend") and dg["null"]["block_capped"]
        alarms += bool(dg["significant"])
        if seed < 20:
            dg = diagnose(t, x, r + fade, features=ft, seed=seed)
            found += bool(set(dg["significant"]) & set(DRIFT_VIEWS))
    assert stats.binom.sf(6, 100, 0.023) < 0.015
    assert alarms <= 6, alarms
    assert found >= 15, found


# ----------------------------------------------------------------------------- signatures
def _terms(ft, fc):
    d, s, e, v, x = (ft[k] for k in ("direction", "since_reversal", "energy", "velocity", "displacement"))
    return {
        # spec reversal_hump: d a_hump fc (s/l) exp(1 - s/l), a_hump = 0.015, l_hump = 2 mm
        "reversal_hump": d * 0.015 * fc * (s / 2e-3) * np.exp(1 - s / 2e-3),
        # eccentricity: g x (1 + eps cos(2 pi x / l_ecc + psi)), eps = 0.009, l_ecc = 10 mm
        "eccentricity": d * 0.009 * fc * np.cos(2 * np.pi * x / 0.01 + 0.3),
        # thermal_fade: g x (1 - kappa (1 - exp(-E / e_fade))), kappa = 0.0225, e_fade = 10 kJ
        "thermal_fade": -d * 0.0225 * fc * (1 - np.exp(-e / 1e4)),
        # rate_strengthening: g x (1 + beta ln(1 + |v| / v_ref)), beta = 0.009, v_ref = 10 mm/s
        "rate_strengthening": d * 0.009 * fc * np.log1p(np.abs(v) / 0.01),
        # speed_weakening: g x (1 - beta (1 - exp(-|v| / v_sw))), beta = 0.03, v_sw = 50 mm/s
        "speed_weakening": -d * 0.03 * fc * (1 - np.exp(-np.abs(v) / 0.05)),
    }


@pytest.mark.parametrize("effect", ["reversal_hump", "eccentricity", "thermal_fade", "rate_strengthening",
                                    "speed_weakening"])
def test_signature_lights_its_expected_view(record, effect):
    """AR(1) noise (one seed) plus the effect's term at 1-3 % of fc (rms 190-710 N against 300 N
    of noise), alpha = 0.01 family-wise, 999 permutations. Offline, every assertion below held on
    20/20 other noise seeds, and the expected views were still found on 9-12 of 12 seeds at half
    these sizes (speed_weakening, added later: 20/20 on seeds 20-39, half size not measured): the
    probability that a correct implementation fails on a seed is below 14 % with one-sided 95 %
    confidence (Clopper-Pearson upper bound for 0 of 20), and probably far below given the
    half-size margins; at this fixed seed the test passes or fails on every run. The views a term does not touch stay quiet (false alarm below alpha = 0.01 each). On a
    constant-amplitude sine, x, v and s are all functions of the phase given the direction, so a
    phase-locked effect lights displacement and since_reversal together (and often velocity)."""
    t, x, p, _, ft = record
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    r = _noise(7, x.size) + _terms(ft, fc)[effect]
    dg = diagnose(t, x, r, features=ft, alpha=0.01, n_perm=999, seed=3)
    sig = set(dg["significant"])
    expected = set(EXPECTED_SIGNATURES[effect]["views"])
    assert expected <= sig, (effect, dg["significant"])
    if effect == "thermal_fade":                          # a drift: the phase views stay quiet
        assert not sig & set(PHASE_VIEWS)
    else:                                                 # phase-locked: the drift views stay quiet
        assert {"displacement", "since_reversal"} <= sig and not sig & set(DRIFT_VIEWS)
    assert ("spectrum" in sig) == (effect == "eccentricity")
    if effect == "eccentricity":
        assert dg["spectrum"]["wavelength_m"] == pytest.approx(0.01, rel=0.10)
    if effect == "reversal_hump":        # the binned excess friction peaks within the first mm's
        b = dg["views"]["since_reversal"]["bins"]
        assert 0.5e-3 <= b["centre"][int(np.argmax(b["mean"]))] <= 6e-3
    if effect == "thermal_fade":         # a monotone drift down: last bins below the first
        b = dg["views"]["energy"]["bins"]
        assert np.mean(b["mean"][-3:]) < np.mean(b["mean"][:3]) - 200.0


def test_simulated_eccentricity_found_by_the_spectrum(record):
    """End to end with the simulator: data = simulate(eccentricity eps 0.02, l_ecc 8 mm) + AR(1)
    noise, model = the baseline. The bristle (presliding) length fc/sigma0 = 4 mm low-passes the
    eccentricity and shifts its phase oppositely in the two directions: the force difference is
    160 N rms, not 0.02 fc = 750 N amplitude (which is why the spectrum sums per-direction
    periodograms). One seed: p = 0.001 (smallest attainable), peak ratio 20 against a critical
    7; offline 15/15 other noise seeds passed (wavelength 7.7-8.0 mm), so a correct
    implementation fails on a seed with a probability below 18 % at one-sided 95 % confidence
    (Clopper-Pearson for 0 of 15); at this fixed seed it passes or fails on every run."""
    t, x, p, force, ft = record
    data = frictionuq.simulate(t, x, p, effects={"eccentricity": {"eps_ecc": 0.02, "l_ecc": 8e-3}})
    r = data - force + _noise(11, x.size)
    dg = diagnose(t, x, r, features=ft, alpha=0.01, n_perm=999, seed=5, spread=2 * SD)
    assert dg["spectrum"]["significant"]
    assert dg["spectrum"]["wavelength_m"] == pytest.approx(8e-3, rel=0.10)
    b = dg["views"]["displacement"]["bins"]
    assert np.allclose(np.array(b["mean_z"]) * 2 * SD, b["mean"], rtol=1e-9, atol=1e-6)
    json.dumps(dg, allow_nan=False)      # JSON-ready: plain floats, NaN as null


# --------------------------------------------------------------------------------- figure
def test_figure_png_and_one_axis_per_view(record, tmp_path):
    """Deterministic (one seeded diagnosis, 49 permutations)."""
    t, x, _, _, ft = record
    applied = 267.0 + _noise(3, x.size) / 100.0
    dg = diagnose(t, x, _noise(2, x.size), features={**ft, "applied": applied}, n_perm=49)
    assert "applied" in dg["views"] and dg["family_size"] == 9 and dg["chatter"] is not None
    fig = build_figure(dg)
    try:
        assert len(fig.axes) == len(dg["views"]) + 2
        labels = [ax.get_xlabel() for ax in fig.axes]
        assert "displacement x (mm)" in labels and "wavelength in displacement (mm)" in labels
        assert labels[-1] == "travel since last reversal s (mm)"
        assert all(ax.get_ylabel() for ax in fig.axes) and fig.legends
    finally:
        import matplotlib.pyplot as plt
        plt.close(fig)
    path = tmp_path / "resid.png"
    png = residual_figure(dg, path)
    assert png.startswith(b"\x89PNG\r\n\x1a\n") and path.read_bytes() == png


def _chatter_record():
    """A 1 Hz, 25.4 mm sine, 10 cycles at 100 Hz: the size of discover's decimated 1 Hz test."""
    t = np.arange(1000) / 100.0
    x = AMP * np.sin(2 * np.pi * 1.0 * t)
    return t, x, features(t, x, None)


def test_chatter_bursts_calibrated_found_and_not_fooled_by_a_repeated_misfit():
    """High-frequency bursts (chatter.py) on AR(1) noise, phi = 0.9, sd 100 N.
    Null: 100 replicates, 199 permutations; a calibrated test gives p <= 0.05 in
    Binomial(100, 0.05) of them, so `<= 11` fails with probability 0.4 % (computed below;
    measured offline: 4.5 % of 200 at phi = 0.9, 1 Hz; 4.5 % of 200 white at 0.5 Hz; 3.0 % of
    200 at phi = 0.97, 0.2 Hz). Chatter: a 13 Hz, 150 N oscillation 4-12 mm after every reversal,
    its phase new at each reversal: found (Holm-adjusted p <= 0.01 among the 8 tests) in >= 18
    of 20 (offline 20 of 20), with the largest power in a bin inside 4-12 mm. A misfit that
    repeats at the same travel after every reversal (150 N, period 1.5 mm in s, same window) is
    not chatter: significant in <= 2 of 20 (offline 0 of 20)."""
    t, x, ft = _chatter_record()
    s = ft["since_reversal"]
    window = (s > 0.004) & (s < 0.012)
    n_rev = np.cumsum(np.r_[0, np.diff(ft["direction"]) != 0])
    rng = np.random.default_rng(2026)
    null_p = [diagnose(t, x, ar1_from_normals(rng.standard_normal(t.size), 0.9, 100.0),
                       features=ft, n_perm=199, seed=k)["chatter"]["p_value"] for k in range(100)]
    assert stats.binom.sf(11, 100, 0.05) < 0.005
    assert sum(p <= 0.05 for p in null_p) <= 11, sorted(null_p)[:15]
    found, fooled = 0, 0
    for k in range(20):
        r = ar1_from_normals(rng.standard_normal(t.size), 0.9, 100.0)
        phase = rng.uniform(0, 2 * np.pi, n_rev.max() + 1)[n_rev]
        dg = diagnose(t, x, r + 150.0 * np.sin(2 * np.pi * 13.0 * t + phase) * window,
                      features=ft, seed=k)
        ch = dg["chatter"]
        lo, hi = ch["peak_since_reversal_m"]
        found += ch["significant"] and ch["p_adjusted"] <= 0.01 and lo < 0.012 and hi > 0.004
        assert ch["highpass_hz"] == pytest.approx(8.0, rel=0.05) and ch["peak_rms_n"] > ch["hf_rms_n"]
        locked = 150.0 * np.sin(2 * np.pi * s / 0.0015) * window
        fooled += diagnose(t, x, r + locked, features=ft, seed=k)["chatter"]["significant"]
    assert found >= 18 and fooled <= 2, (found, fooled)


def test_chatter_skipped_where_the_band_does_not_fit_or_when_asked():
    """A record sampled too coarsely for HF_FACTOR x the drive frequency (a 1 Hz sine at 15 Hz)
    gets no burst test, and the Holm family is the views and the spectrum alone; nor does a
    record diagnosed with bursts=False."""
    t = np.arange(150) / 15.0
    x = AMP * np.sin(2 * np.pi * t)
    dg = diagnose(t, x, _noise(5, t.size), n_perm=49)
    assert dg["chatter"] is None and "chatter" not in dg["significant"]
    assert dg["family_size"] == len(dg["views"]) + (dg["spectrum"] is not None)
    t, x, ft = _chatter_record()          # asked not to (discover, on earthquake records)
    dg = diagnose(t, x, _noise(5, t.size), features=ft, n_perm=49, bursts=False)
    assert dg["chatter"] is None and dg["family_size"] == len(dg["views"]) + 1


def test_report_says_chatter_only_where_the_baseline_shows_it(tmp_path):
    """The discrepancy report's gap blocks name the tests whose baseline residuals carry
    significant bursts, say that no deterministic library effect closes them and point to the
    noise effect chatter; without such a test (or
    with bursts only under the new model) they say nothing about chatter. Deterministic."""
    from frictionuq.report.sections.discrepancy import gap_blocks
    label = "chatter (bursts > 9.6 Hz, strongest 7.7-11 mm after the reversal, 1.38e+03 N rms)"
    diags = [{"test": "sine-1Hz", "model": "baseline", "figure": "none.png", "rmse": 900.0,
              "significant_views": ["since_reversal", label]},
             {"test": "sine-0.5Hz", "model": "baseline", "figure": "none.png", "rmse": 800.0,
              "significant_views": ["applied"]},
             {"test": "sine-0.5Hz", "model": "with eccentricity", "figure": "none.png", "rmse": 700.0,
              "significant_views": [label]}]
    text = " ".join(b.get("text", "") for b in gap_blocks(tmp_path, {"diagnostics": diags}))
    assert "significant in sine-1Hz:" in text and "sine-0.5Hz" not in text.split("significant in")[1]
    assert "No deterministic effect of the library can close" in text and "--effect chatter" in text
    quiet = " ".join(b.get("text", "") for b in gap_blocks(tmp_path, {"diagnostics": diags[1:]}))
    assert "chatter" not in quiet
