"""The `speed_weakening` effect (docs/model-choices.md, "Effects beyond the spec").

    g(v) is multiplied by  h(v) = 1 - beta_sw * (1 - exp(-|v| / v_sw))

wherever g appears (F1 with the sample velocity v, the z update with the step velocity u, the
cap of the backlash line), like the spec's rate_strengthening, which it mirrors: friction that
*falls* with the sliding speed over the whole stroke, as the real ARTS loops read (fits with the
Stribeck bounds widened put v_s at 0.63-0.74 of the peak speed, docs/log-calibration.md).
The kernel is checked against the pure-Python oracle for every effect in tests/test_kernel.py;
here: the neutral value gives exactly the baseline, the steady sliding force follows the formula,
the effect lowers friction where the speed is high and leaves it where the speed is low, and the
parameters round-trip through the validation.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictionuq import kernel, params as P
from frictionuq.model import pack_batch, simulate, simulate_batch

NAME = "speed_weakening"
BASE = dict(fc_fwd=1000.0, fc_bwd=1100.0, fs_fwd=1100.0, fs_bwd=1200.0, v_s=1e-3, sigma0=5e6,
            sigma1=100.0, sigma2=500.0, k2=3e4, d2=1.5e-3, k3=2e6, d3=0.5e-3, w=2e-4)
# pure LuGre friction without Stribeck drop or viscous term: the steady sliding force is g(v)
FLAT = BASE | {"fs_fwd": 1000.0, "fs_bwd": 1100.0, "sigma1": 0.0, "sigma2": 0.0,
               "sigma0": 1e8, "d2": 0.0, "d3": 0.0}


def sine(f=0.5, amp=0.0254, cycles=3, fs=2000.0):
    t = np.arange(int(cycles * fs / f) + 1) / fs
    return t, amp * np.sin(2 * np.pi * f * t)


def h(v, beta, v_sw):
    return 1.0 - beta * (1.0 - np.exp(-np.abs(v) / v_sw))


@pytest.mark.parametrize("v_sw", [1e-7, 0.05, 10.0])
@pytest.mark.parametrize("model", ["three_stage", "lugre"])
def test_neutral_value_is_exactly_the_baseline(v_sw, model):
    t, x = sine()
    x = x + np.random.default_rng(3).normal(0, 2e-6, x.size)
    F0 = simulate(t, x, BASE, model=model)
    F = simulate(t, x, BASE, {NAME: {"beta_sw": 0.0, "v_sw": v_sw}}, model=model)
    assert np.array_equal(F, F0)


def test_default_is_neutral():
    t, x = sine()
    assert np.array_equal(simulate(t, x, BASE, {NAME: {}}), simulate(t, x, BASE))
    assert P.check_effects({NAME: {}}) == {NAME: {"beta_sw": 0.0, "v_sw": 5e-2}}


@pytest.mark.parametrize("beta, v_sw", [(0.3, 0.03), (0.6, 0.1), (0.1, 0.005)])
def test_steady_sliding_force_follows_the_formula(beta, v_sw):
    """With a stiff bristle (pre-sliding 10 um) and no Stribeck or viscous terms, the force while
    sliding is g(v) h(v) to within the bristle lag: checked at every sample with |v| above 20 %
    of its peak, in both directions, after the start-up transient (z starts at 0 at peak speed)."""
    t, x = sine()
    v = np.gradient(x, t)
    F = simulate(t, x, FLAT, {NAME: {"beta_sw": beta, "v_sw": v_sw}}, model="lugre")
    fc = np.where(v > 0, FLAT["fc_fwd"], -FLAT["fc_bwd"])
    sl = (np.abs(v) > 0.2 * np.abs(v).max()) & (t > 0.05)
    np.testing.assert_allclose(F[sl], fc[sl] * h(v[sl], beta, v_sw), rtol=2e-3)
    # and the effect is visible: at peak speed the friction is lower by the formula's fraction
    k = int(np.argmax(v))
    assert F[k] < FLAT["fc_fwd"] * (1 - 0.9 * beta * (1 - math.exp(-v[k] / v_sw)))


def test_weakens_where_fast_not_where_slow():
    """At the middle of the stroke (peak speed) the friction drops by beta(1-exp(-v/v_sw)); right
    at the stroke ends, where the speed is near zero, it is close to the baseline's."""
    t, x = sine()
    v = np.gradient(x, t)
    beta, v_sw = 0.3, 0.05
    F0 = simulate(t, x, BASE)
    F = simulate(t, x, BASE, {NAME: {"beta_sw": beta, "v_sw": v_sw}})
    fast = (np.abs(v) > 0.95 * np.abs(v).max()) & (t > 0.6)     # after the first take-up
    visc = BASE["sigma2"] * v                                    # the viscous term is not scaled
    ratio = (F - visc)[fast] / (F0 - visc)[fast]
    np.testing.assert_allclose(ratio, h(v[fast], beta, v_sw), rtol=2e-3)
    # at the stroke ends (|v| < 0.1 mm/s) the force is the bristle's state from the last
    # pre-sliding distance (fc/sigma0 = 0.2 mm) before the stop, travelled at ~1 cm/s: weakened
    # by a quarter of the mid-stroke drop or less (here a fifth)
    slow = np.abs(v) < 1e-4
    drop_mid = 1.0 - h(np.abs(v).max(), beta, v_sw)
    assert slow.sum() >= 4 and np.all(1.0 - F[slow] / F0[slow] < 0.25 * drop_mid)
    assert np.all(F[slow] / F0[slow] < 1.0)


def test_batch_matches_single_calls():
    t, x = sine(cycles=1)
    eff = {NAME: {"beta_sw": 0.4, "v_sw": 0.02}}
    M = pack_batch([BASE, BASE | {"fc_fwd": 900.0}], eff)
    out = simulate_batch(t, x, M)
    assert np.array_equal(out[0], simulate(t, x, BASE, eff))
    assert np.array_equal(out[1], simulate(t, x, BASE | {"fc_fwd": 900.0}, eff))


def test_parameters_in_the_vector_and_metadata():
    assert P.EFFECTS[NAME] == ("beta_sw", "v_sw")
    assert kernel.NPARAM == len(P.VECTOR_NAMES) == 29
    assert [P.INDEX[n] for n in P.EFFECTS[NAME]] == [27, 28]          # appended at the end
    p = P.PARAMS["beta_sw"]
    assert (p.unit, p.lower, p.upper, p.neutral, p.default) == ("1", 0.0, 0.95, 0.0, 0.0)
    p = P.PARAMS["v_sw"]
    assert (p.unit, p.lower, p.upper, p.neutral, p.default, p.log_scale) == ("m/s", 1e-7, 10.0, None, 5e-2, True)
    assert NAME in P.BEYOND_SPEC and NAME not in P.NEEDS_BACKLASH | P.NEEDS_APPLIED


def test_round_trip_through_validation():
    eff = {NAME: {"beta_sw": 0.25, "v_sw": 0.07}}
    vec = P.pack(BASE, eff)
    assert {n: vec[P.INDEX[n]] for n in P.EFFECTS[NAME]} == eff[NAME]
    others = [i for n, i in P.INDEX.items() if n not in P.BASE_NAMES and n not in P.EFFECTS[NAME]]
    np.testing.assert_array_equal(vec[others], P.neutral_vector()[[i - len(P.BASE_NAMES) for i in others]])
    assert P.check_effects({NAME: {"beta_sw": 0.2}})[NAME] == {"beta_sw": 0.2, "v_sw": 5e-2}


@pytest.mark.parametrize("name,value", [("beta_sw", -0.1), ("beta_sw", 0.96), ("v_sw", 0.0),
                                        ("v_sw", 11.0), ("beta_sw", math.nan)])
def test_out_of_bounds_refused(name, value):
    with pytest.raises(ValueError, match=name):
        P.pack(BASE, {NAME: {name: value}})


def test_priors_scale_with_the_record():
    from frictionuq.infer.priors import RecordScales, effect_priors
    pr = effect_priors(NAME, RecordScales(f_scale=1e3, asym=0.0, noise_hf=5.0, amp=0.02, v_max=0.15))
    assert (pr["beta_sw"].dist, pr["beta_sw"].lower, pr["beta_sw"].upper) == ("uniform", 0.0, 0.6)
    assert pr["v_sw"].dist == "loguniform"
    assert pr["v_sw"].lower == pytest.approx(0.015) and pr["v_sw"].upper == pytest.approx(0.45)


def test_finite_over_the_bounds():
    t, x = sine()
    for beta, v_sw in [(0.95, 1e-7), (0.95, 10.0), (0.0, 1e-7), (0.5, 1e-3)]:
        for model in ("three_stage", "lugre"):
            F = simulate(t, x, BASE, {NAME: {"beta_sw": beta, "v_sw": v_sw}}, model=model)
            assert np.all(np.isfinite(F))
