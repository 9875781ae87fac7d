"""The `takeup_overshoot` effect (docs/model-choices.md, "Effects beyond the spec").

    h = 1 + a_d                                  until slip starts after a reversal,
    h = 1 + a_d * exp(-(s - s_b) / l_to)         from then on,   a_d = a_to_fwd (d = +1) or a_to_bwd

Slip starts at the first sample after a reversal where the backlash line reaches its cap,
L >= h g_d, or where s >= d2 + d3 (take-up complete), whichever comes first; s_b is the travel
there. h multiplies g (the friction level) wherever g appears: in F1, in the z update (h of the
step's start sample) and in the cap of the backlash line. Tests: the neutral value
gives exactly the baseline force; the force equals a direct numpy evaluation of h fed through the
kernel's other per-sample factor path (applied tracking with a signal equal to h); the effect acts
where the formula says (after the take-up of the direction whose amplitude is set, gone far
beyond it) and round-trips through the parameter validation.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictionuq import kernel, params as P
from frictionuq.discrepancy.features import reversal_state
from frictionuq.model import pack_batch, prepare, simulate, simulate_batch

NAME = "takeup_overshoot"
# a band-brake-like damper: friction 1-1.1 kN, 2 mm backlash, pre-sliding fc/sigma0 = 0.2 mm
BASE = dict(fc_fwd=1000.0, fc_bwd=1100.0, fs_fwd=1100.0, fs_bwd=1200.0, v_s=1e-3, sigma0=5e6,
            sigma1=100.0, sigma2=500.0, k2=3e4, d2=1.5e-3, k3=2e6, d3=0.5e-3, w=2e-4)


# as fitted to the real ARTS records: the take-up line reaches the friction level well before
# d2 + d3 (here at s ~ 2 mm, against d2 + d3 = 4.5 mm)
STEEP = BASE | {"d3": 3e-3}


def sine(f=0.5, amp=0.0254, cycles=3, fs=400.0):
    t = np.arange(int(cycles * fs / f) + 1) / fs
    return t, amp * np.sin(2 * np.pi * f * t)


def travel_since_reversal(x, eps=0.0):
    d, x_r, _ = reversal_state(x, eps)
    return d, np.maximum(0.0, d * (x - x_r))


def softplus(q, w):
    return w * (np.maximum(q / w, 0.0) + np.log1p(np.exp(-np.abs(q / w))))


def h_numpy(t, x, p, a_fwd, a_bwd, l_to, eps=0.0):
    """The effect's factor on g at every sample, straight from the formula (spec sections 1 and
    4 for v, s, the backlash line L and g_d)."""
    d, x_r, n_rev = reversal_state(x, eps)
    s = np.maximum(0.0, d * (x - x_r))
    v = prepare(t, x).v
    a = np.where(d > 0, a_fwd, a_bwd)
    fc = np.where(d > 0, p["fc_fwd"], p["fc_bwd"])
    fs = np.where(d > 0, p["fs_fwd"], p["fs_bwd"])
    g_d = fc + (fs - fc) * np.exp(-(v / p["v_s"]) ** 2)
    sp2 = softplus(s - p["d2"], p["w"])
    L = p["k2"] * np.clip(s - sp2, 0.0, p["d2"]) + p["k3"] * sp2
    starts = (L >= (1.0 + a) * g_d) | (s >= p["d2"] + p["d3"])
    h = 1.0 + a
    for r in np.unique(n_rev):                        # each half-cycle: slip starts once
        k = np.flatnonzero(n_rev == r)
        hit = k[starts[k]]
        if hit.size:
            after = k[k > hit[0]]
            xs = s[after] - s[hit[0]]
            h[after] = np.where(xs <= 0.0, 1.0 + a[after], 1.0 + a[after] * np.exp(-xs / l_to))
    return h


# ---------------------------------------------------------------------------- neutral value
@pytest.mark.parametrize("l_to", [1e-6, 3e-3, 0.2])
@pytest.mark.parametrize("eps", [0.0, 1e-5])
def test_neutral_value_is_exactly_the_baseline(l_to, eps):
    t, x = sine()
    x = x + np.random.default_rng(3).normal(0, 2e-6, x.size)     # noisy: many tiny reversals
    base = simulate(t, x, BASE, eps=eps)
    eff = {NAME: {"a_to_fwd": 0.0, "a_to_bwd": 0.0, "l_to": l_to}}
    assert np.array_equal(simulate(t, x, BASE, eff, eps=eps), base)
    # the kernel's effect-enabled specialisation (an applied signal passed, so the effect code
    # is compiled in) must switch itself off at the neutral value too
    drive = prepare(t, x, np.ones_like(t))
    vec = P.pack(BASE, eff)
    F = kernel.simulate_one(drive.x, drive.v, drive.u, drive.dt, drive.applied, drive.a_med, vec,
                            kernel.THREE_STAGE, eps, np.zeros(0, np.uint8))
    assert np.array_equal(F, base)
    # neutral next to another effect that is on: the same as that effect alone
    other = {"reversal_hump": {"a_hump": 0.3, "l_hump": 2e-3}}
    assert np.array_equal(simulate(t, x, BASE, other | eff, eps=eps), simulate(t, x, BASE, other, eps=eps))


def test_default_is_neutral():
    t, x = sine()
    assert np.array_equal(simulate(t, x, BASE, {NAME: {}}), simulate(t, x, BASE))
    assert P.check_effects({NAME: {}}) == {NAME: {"a_to_fwd": 0.0, "a_to_bwd": 0.0, "l_to": 3e-3}}


# ---------------------------------------------------------------------------- the formula
@pytest.mark.parametrize("a_fwd,a_bwd,l_to", [(0.5, 0.0, 2e-3), (0.0, -0.3, 1e-3),
                                              (1.5, 0.4, 5e-3), (-0.5, 2.0, 0.5e-3)])
@pytest.mark.parametrize("eps", [0.0, 1e-5])
def test_force_equals_g_times_the_numpy_factor(a_fwd, a_bwd, l_to, eps):
    """The effect is g -> g*h(s[k]) at every sample, z update included. The kernel applies the
    factor of `applied_tracking` (beta_app = 1: a[k]/a_med) in exactly the same places, so the
    force with a signal a = h must equal the force of the effect, to rounding. The median of h
    must be exactly 1: the sine is followed by a long forward ramp whose samples (more than half
    of the record) lie more than 40 l_to past the take-up, where h == 1.0 exactly."""
    t, x = sine(f=0.2, cycles=2)
    dt = t[1] - t[0]
    v_end = (x[-1] - x[-2]) / dt
    n_ramp = int(1.2 * t.size) + int((0.3 - x[-1]) / (v_end * dt))   # up to x ~ 0.3 m and beyond
    t = np.concatenate([t, t[-1] + dt * np.arange(1, n_ramp + 1)])
    x = np.concatenate([x, x[-1] + v_end * dt * np.arange(1, n_ramp + 1)])
    if eps:
        x = x + np.random.default_rng(1).normal(0, 2e-6, x.size)
    for p in (BASE, STEEP):
        h = h_numpy(t, x, p, a_fwd, a_bwd, l_to, eps)
        assert np.median(h) == 1.0
        F = simulate(t, x, p, {NAME: {"a_to_fwd": a_fwd, "a_to_bwd": a_bwd, "l_to": l_to}}, eps=eps)
        F_ref = simulate(t, x, p, {"applied_tracking": {"beta_app": 1.0}}, eps=eps, applied=h)
        np.testing.assert_allclose(F, F_ref, rtol=0, atol=1e-9 * np.abs(F_ref).max())
        assert np.abs(F - simulate(t, x, p, eps=eps)).max() > 0.01 * p["fc_fwd"]


def test_overshoot_where_the_formula_says():
    """Forward amplitude only: nothing changes before the first forward take-up, the forward
    force peaks above the friction level right after the take-up by about a_fwd * fc, and the
    force is back on the baseline far past the take-up (h == 1 there; the bristle state forgets
    within a few pre-sliding lengths fc/sigma0)."""
    a, l_to = 0.6, 1e-3
    t, x = sine(f=0.2, cycles=2)
    d, s = travel_since_reversal(x)
    F0 = simulate(t, x, BASE)
    F = simulate(t, x, BASE, {NAME: {"a_to_fwd": a, "a_to_bwd": 0.0, "l_to": l_to}})
    dF = F - F0
    s_tu = BASE["d2"] + BASE["d3"]
    # the first half-cycle is forward (the sine starts upwards): before its take-up the backlash
    # line is below the (raised) cap, so the force changes only through the micro-damping term
    # sigma1 a(v) z of F1 (a(v) = sigma0 |v| / g), whose blend weight m(s - d2 - d3) is small there
    first = np.arange(x.size) < np.flatnonzero(d < 0)[0]
    before = first & (s < BASE["d2"] + 0.2e-3)
    np.testing.assert_allclose(F[before], F0[before], rtol=0, atol=1e-3 * BASE["fc_fwd"])
    # after each forward take-up: force above the baseline, peak ~ a*fc within a few l_to
    fwd_tu = (d > 0) & (s > s_tu) & (s < s_tu + 3 * l_to)
    assert dF[fwd_tu].max() > 0.5 * a * BASE["fc_fwd"]
    assert dF[fwd_tu].max() < 1.05 * a * BASE["fs_fwd"]
    assert np.all(dF[(d > 0) & (s > s_tu) & (s < s_tu + l_to)] > 0)
    # far past the take-up the effect is gone (a exp(-25) ~ 1e-11)
    far = s > s_tu + 25 * l_to + 30 * BASE["fc_bwd"] / BASE["sigma0"]
    assert far.sum() > 100
    np.testing.assert_allclose(F[far], F0[far], rtol=0, atol=1e-6 * BASE["fc_fwd"])


@pytest.mark.parametrize("a", [0.5, -0.4])
def test_slip_starts_where_the_line_reaches_the_breakaway_level(a):
    """With a steep take-up line (STEEP), slip starts where the line reaches (1 + a) g, before
    d2 + d3: the force follows the line up (a > 0) or only up to (1 + a) g (a < 0), and the
    decay of h starts there, not at d2 + d3."""
    l_to = 1e-3
    t, x = sine(f=0.1, cycles=1.5, fs=2000.0)
    d, s = travel_since_reversal(x)
    F0 = simulate(t, x, STEEP)
    F = simulate(t, x, STEEP, {NAME: {"a_to_fwd": a, "l_to": l_to}})
    fwd = (d > 0) & (np.arange(x.size) > np.flatnonzero(d < 0)[0])     # the second forward half
    sp2 = softplus(s - STEEP["d2"], STEEP["w"])
    L = STEEP["k2"] * np.clip(s - sp2, 0.0, STEEP["d2"]) + STEEP["k3"] * sp2
    g = STEEP["fc_fwd"]                                                  # sliding: v >> v_s
    s_b = s[fwd][np.argmax(L[fwd] >= (1 + a) * g)]
    assert s_b < STEEP["d2"] + STEEP["d3"] - 1e-3
    k_peak = np.flatnonzero(fwd)[np.argmax(F[fwd])] if a > 0 else None
    if a > 0:       # the peak is the breakaway level, at the slip start
        assert F[k_peak] == pytest.approx((1 + a) * g, rel=0.03)
        assert abs(s[k_peak] - s_b) < 0.1e-3
    else:           # capped at (1 + a) g at the slip start, then recovering to g with l_to
        k = fwd & (s > s_b) & (s < s_b + l_to)
        np.testing.assert_allclose(F[k], (1 + a * np.exp(-(s[k] - s_b) / l_to)) * g, rtol=0.03)
        assert np.all(F[k] <= F0[k] + 1e-9 * g) and (F0[k] - F[k]).max() > 0.2 * abs(a) * g
    far = fwd & (s > s_b + 25 * l_to + 30 * g / STEEP["sigma0"])
    assert far.sum() > 100
    np.testing.assert_allclose(F[far], F0[far], rtol=0, atol=1e-6 * g)


def test_undershoot_and_direction():
    """A negative backward amplitude lowers the backward friction after its take-up (the force
    is less negative), and leaves the forward half-cycles of the first cycle untouched."""
    t, x = sine(f=0.2, cycles=2)
    d, s = travel_since_reversal(x)
    F0 = simulate(t, x, BASE)
    F = simulate(t, x, BASE, {NAME: {"a_to_fwd": 0.0, "a_to_bwd": -0.4, "l_to": 2e-3}})
    first_bwd = np.flatnonzero(d < 0)[0]
    assert np.array_equal(F[:first_bwd], F0[:first_bwd])
    s_tu = BASE["d2"] + BASE["d3"]
    k = (d < 0) & (s > s_tu) & (s < s_tu + 2e-3)
    assert np.all(F[k] > F0[k])                       # backward force is negative: less friction
    assert (F - F0)[k].max() > 0.2 * BASE["fc_bwd"]


def test_decay_length_scales_the_transient():
    """The change of the force, as a function of travel beyond the take-up, stretches with l_to."""
    t, x = sine(f=0.1, cycles=1, fs=2000.0)
    d, s = travel_since_reversal(x)
    F0 = simulate(t, x, BASE)
    s_tu = BASE["d2"] + BASE["d3"]
    widths = []
    for l_to in (1e-3, 4e-3):
        dF = simulate(t, x, BASE, {NAME: {"a_to_fwd": 0.5, "l_to": l_to}}) - F0
        k = (d > 0) & (s > s_tu)
        above = s[k][dF[k] > 0.5 * dF[k].max()]
        widths.append(above.max() - s_tu)
    assert 2.5 < widths[1] / widths[0] < 5.5


def test_batch_matches_single_calls():
    t, x = sine()
    sets = [BASE, BASE | {"fc_fwd": 1200.0}]
    eff = {NAME: {"a_to_fwd": 0.4, "a_to_bwd": -0.2, "l_to": 2e-3}}
    M = pack_batch(sets, eff)
    assert M.shape == (2, kernel.NPARAM) == (2, len(P.VECTOR_NAMES))
    out = simulate_batch(t, x, M)
    for i, p in enumerate(sets):
        assert np.array_equal(out[i], simulate(t, x, p, eff))


# ---------------------------------------------------------------------------- parameters
def test_parameters_in_the_vector_and_metadata():
    assert P.EFFECTS[NAME] == ("a_to_fwd", "a_to_bwd", "l_to")
    assert kernel.NPARAM == len(P.VECTOR_NAMES)
    assert [P.INDEX[n] for n in P.EFFECTS[NAME]] == [24, 25, 26]      # appended after the spec's
    assert P.VECTOR_NAMES[:24][-1] == "beta_app"
    for n in ("a_to_fwd", "a_to_bwd"):
        p = P.PARAMS[n]
        assert (p.unit, p.lower, p.upper, p.neutral, p.default, p.effect) == ("1", -0.95, 5.0, 0.0, 0.0, NAME)
    p = P.PARAMS["l_to"]
    assert (p.unit, p.lower, p.upper, p.neutral, p.default, p.log_scale) == ("m", 1e-6, 0.2, None, 3e-3, True)
    assert NAME in P.NEEDS_BACKLASH and NAME not in P.NEEDS_APPLIED


def test_round_trip_through_validation():
    eff = {NAME: {"a_to_fwd": 0.7, "a_to_bwd": -0.25, "l_to": 1.5e-3}}
    vec = P.pack(BASE, eff)
    assert {n: vec[P.INDEX[n]] for n in P.EFFECTS[NAME]} == eff[NAME]
    assert P.unpack(vec) == BASE
    # every other effect parameter stays at its neutral value
    others = [i for n, i in P.INDEX.items() if n not in P.BASE_NAMES and n not in P.EFFECTS[NAME]]
    np.testing.assert_array_equal(vec[others], P.neutral_vector()[[i - len(P.BASE_NAMES) for i in others]])
    assert P.check_effects(eff) == eff
    assert P.check_effects({NAME: {"a_to_fwd": 0.2}})[NAME] == {"a_to_fwd": 0.2, "a_to_bwd": 0.0, "l_to": 3e-3}


@pytest.mark.parametrize("name,value", [("a_to_fwd", -1.0), ("a_to_bwd", 5.5), ("l_to", 0.0),
                                        ("l_to", 0.3), ("a_to_fwd", math.nan)])
def test_out_of_bounds_refused(name, value):
    with pytest.raises(ValueError, match=name):
        P.pack(BASE, {NAME: {name: value}})


def test_refused_with_lugre_and_unknown_parameter():
    t, x = sine()
    with pytest.raises(ValueError, match="three_stage"):
        simulate(t, x, BASE, {NAME: {"a_to_fwd": 0.3}}, model="lugre")
    with pytest.raises(ValueError, match="a_to"):
        P.pack(BASE, {NAME: {"a_to": 0.3}})


def test_finite_over_the_bounds():
    t, x = sine()
    for a_f, a_b, l_to in [(-0.95, 5.0, 1e-6), (5.0, -0.95, 0.2), (-0.95, -0.95, 1e-3)]:
        for p in (BASE, BASE | {"d2": 0.0, "d3": 0.0}, BASE | {"d3": 0.0}):
            F = simulate(t, x, p, {NAME: {"a_to_fwd": a_f, "a_to_bwd": a_b, "l_to": l_to}})
            assert np.all(np.isfinite(F))
