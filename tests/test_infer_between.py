"""Do a joint fit's tests share one force zero (frictionuq.infer.between)?

The check's false-alarm rate is ALPHA (1 %) when the noise model holds; measured here on
seeded AR(1) records (2,000 replicate sets of three tests). Each seeded case either always
passes or always fails; the Monte Carlo bounds below are wide enough that correct code fails
them with probability about 1.5e-4 (binomial tails: 9e-5 for the null's, 6e-5 for the power's)."""
from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
import pytest
from scipy.signal import lfilter

from frictionuq import published
from frictionuq.infer import between
from frictionuq.infer.fit import FitConfig, FitSpec, prepare
from frictionuq.model import simulate


@pytest.mark.parametrize("phi, theta", [(0.0, 0.0), (0.8, 0.0), (0.95, -0.3), (0.5, -0.45)])
def test_long_run_variance_is_the_arma_impulse_responses(phi, theta):
    """LRV = sigma_a^2 (sum psi)^2 and Var = sigma_a^2 sum psi^2 for the ARMA(1,1)'s impulse
    response psi, summed numerically; the module's closed form takes the marginal sd."""
    psi = lfilter([1.0, theta], [1.0, -phi], np.r_[1.0, np.zeros(20000)])
    sigma = np.sqrt(np.sum(psi**2))                    # marginal sd for unit innovations
    assert between.long_run_variance(sigma, phi, theta) == pytest.approx(np.sum(psi) ** 2, rel=1e-9)


def _ar1_means(rng, k, n, phi, sd, reps):
    e = rng.standard_normal((reps, k, n)) * sd * np.sqrt(1 - phi**2)
    e[..., 0] /= np.sqrt(1 - phi**2)                   # stationary start
    return lfilter([1.0], [1.0, -phi], e, axis=-1).mean(axis=-1)


def test_false_alarms_at_alpha_and_power_against_a_moved_zero():
    """Three AR(1) tests (1,500 samples, phi 0.8, sd 100 N) with one zero: 1 % of 2,000
    replicates flagged (bounds 6-40 alarms, i.e. 0.3-2 %); the same with one test's zero moved
    by 5 of its standard errors: flagged as often as the chi-square's noncentral power (0.88)
    says, within 4 Monte Carlo sds."""
    rng = np.random.default_rng(0)
    k, n, phi, sd, reps = 3, 1500, 0.8, 100.0, 2000
    m = _ar1_means(rng, k, n, phi, sd, reps)
    se = np.sqrt(between.long_run_variance(sd, phi) / n)
    ids = ["a", "b", "c"]
    null = [between.offset_check(ids, mi, [n] * k, [sd] * k, [phi] * k)["significant"] for mi in m]
    assert 6 <= sum(null) <= 40, sum(null)
    moved = m + np.array([5 * se, 0.0, 0.0])
    hits = [between.offset_check(ids, mi, [n] * k, [sd] * k, [phi] * k)["significant"] for mi in moved]
    # the power of a chi-square test with noncentrality sum ((d_j - mean d) / se)^2 = 25 x 2/3
    from scipy import stats
    power = stats.ncx2.sf(stats.chi2.isf(between.ALPHA, k - 1), k - 1, 25 * 2 / 3)
    assert abs(np.mean(hits) - power) < 4 * np.sqrt(power * (1 - power) / reps), (np.mean(hits), power)
    assert between.offset_check(["a"], [1.0], [n], [sd], [phi]) is None


def _records(zeros, seed=0, phi=0.8):
    """Three BRFD 267 N sines (0.2 Hz, 100 Hz, 3 cycles) with AR(1) noise of 1 % of fc and the
    given load-cell zeros (N), as campaign tests."""
    truth = published.brfd_params(267.0)
    fc = 0.5 * (truth["fc_fwd"] + truth["fc_bwd"])
    rng = np.random.default_rng(seed)
    t = np.arange(0, 15.0, 0.01)
    tests = []
    for j, (amp, z) in enumerate(zip((0.0254, 0.02, 0.015), zeros)):
        x = amp * np.sin(2 * np.pi * 0.2 * t)
        e = lfilter([1.0], [1.0, -phi], rng.standard_normal(t.size) * 0.01 * fc * np.sqrt(1 - phi**2))
        y = simulate(t, x, truth) + z + e
        tests.append(NS(id=f"sine-{j}", record=NS(t=t, x=x, force=y, applied=None), applied=267.0,
                        kind="harmonic", frequency_hz=0.2))
    return tests, truth, 0.01 * fc


def _check_at_truth(zeros, phi=0.8):
    """between.check_fit of the three records, the model at the true parameters (the shared
    offset 0) and the noise at its true sd and phi: the fit's path without the sampling."""
    tests, truth, sd = _records(zeros, phi=phi)
    spec = FitSpec("s", tests, 267.0, FitConfig(samples_per_cycle=500, drive_lowpass="off"))
    _, _, space, lp = prepare(spec)
    assert all(r.q == 1 for r in lp.records)
    th = space.to_theta({**{n: truth[n] for n in space.names if n in truth}, "force_offset": 0.0})
    post = {"theta": th[None, None, :], "sigma_noise": np.full((1, 1, 3), sd),
            "noise_phi": np.full((1, 1, 3), phi)}
    pred = {"model": [lp.simulate(th[None, :], r) for r in lp.records]}
    return between.check_fit(lp, post, pred)


def test_check_fit_passes_a_shared_zero_and_flags_a_moved_one():
    """On the fit's own records and model: one zero for the three tests is not flagged; the
    third test's zero 600 N off (about 6 of its standard errors) is, and its mean residual is
    the largest and near 600 N."""
    same = _check_at_truth((0.0, 0.0, 0.0))
    assert not same["significant"], same
    moved = _check_at_truth((0.0, 0.0, 600.0))
    assert moved["significant"] and moved["p_value"] < 1e-6, moved
    m = moved["mean_residual_N"]
    assert max(m, key=m.get) == "sine-2" and 450 < m["sine-2"] < 750, m
    assert moved["se_N"]["sine-2"] < 150


def test_the_report_says_whether_the_zeros_agree():
    from frictionuq.report.sections.fits import _between_tests
    assert _between_tests(None) == []
    bt = between.offset_check(["a", "b"], [1500.0, -1500.0], [3000, 3000], [2600.0] * 2, [0.93] * 2)
    html = str(_between_tests(bt))
    assert "differ beyond the noise" in html and "a 1500 N" in html
    ok = between.offset_check(["a", "b"], [10.0, -10.0], [3000, 3000], [2600.0] * 2, [0.93] * 2)
    assert "agree within the noise" in str(_between_tests(ok))


def test_the_report_names_zeros_pressing_on_the_per_test_box():
    from frictionuq.report.sections.fits import _per_test_offsets
    assert _per_test_offsets(None) == []
    html = str(_per_test_offsets({"box_N": [-15000.0, 15000.0], "at_box_edge": ["sine-2Hz"]}))
    assert "its own force zero" in html and "[-15000, 15000] N" in html
    assert "pressing against that box: sine-2Hz" in html
    assert "none presses against it" in str(_per_test_offsets({"box_N": [-1.0, 1.0], "at_box_edge": []}))
