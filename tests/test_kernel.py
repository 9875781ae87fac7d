"""The numba simulator (src/frictionuq/kernel.py via frictionuq.model) against the plain-Python
oracle (tests/oracle.py, written from the spec), and the model's physical properties: neutral
effects, continuity, monotone take-up after a reversal, steady sliding, no-backlash limit,
pure LuGre, batch == single.

Tolerance rule for kernel vs oracle: |F - Fo| <= 1e-9 * max(max|Fo|, 1 N) at every sample. The
kernel skips terms that round away and uses precomputed quotients (docs/model-choices.md), so it
differs from the literal evaluation by rounding only (~1e-15 relative); 1e-9 of the record's
force scale leaves room for rounding amplified through the bristle-state recursion and still
catches any modelling difference (those are >= 1e-6 of the force scale).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from frictionuq import kernel, params as P, published
from frictionuq.model import pack_batch, prepare, simulate, simulate_batch
from oracle import oracle_simulate

REL = 1e-9
# the kernel's effects; a noise effect (chatter) never reaches the kernel (test_effect_chatter.py
# checks that the force ignores it)
EFFECT_NAMES = tuple(e for e in P.EFFECTS if e not in P.NOISE_EFFECTS)


def assert_matches(F, Fo, rel=REL):
    scale = max(float(np.abs(Fo).max()), 1.0)
    err = np.abs(F - Fo)
    k = int(err.argmax())
    assert np.all(err <= rel * scale), (
        f"kernel vs oracle: max |dF| = {err[k]:.3e} N at sample {k} (F={F[k]!r}, oracle={Fo[k]!r}), "
        f"allowed {rel * scale:.3e} N")


# ---------------------------------------------------------------------------- random draws
def loguniform(rng, lo, hi):
    return float(10 ** rng.uniform(math.log10(lo), math.log10(hi)))


def draw_params(rng):
    """Realistic random base parameters (friction dampers from a lab brake to a building)."""
    fc = loguniform(rng, 10.0, 5e4)
    fc_b = fc * rng.uniform(0.7, 1.4)
    d2 = rng.uniform(0.0, 3e-3)
    d3 = rng.uniform(0.0, 3e-3)
    return dict(
        fc_fwd=fc, fc_bwd=fc_b,
        fs_fwd=fc * rng.uniform(1.0, 1.3), fs_bwd=fc_b * rng.uniform(1.0, 1.3),
        v_s=loguniform(rng, 1e-4, 1e-1),
        sigma0=fc / loguniform(rng, 1e-5, 1e-2),
        sigma1=fc * rng.uniform(0.0, 3.0),         # N s/m: sigma1*v is a few % of fc at cm/s
        sigma2=fc * rng.uniform(0.0, 3.0),
        k2=fc * rng.uniform(0.02, 0.5) / max(d2, 1e-4), d2=d2,
        k3=fc * rng.uniform(0.2, 0.9) / max(d3, 1e-4), d3=d3,
        w=loguniform(rng, 1e-5, 5e-4),
    )


def draw_effect(rng, name, p):
    fc = p["fc_fwd"]
    if name == "stage2_nonlinear":
        return {"p2": loguniform(rng, 0.3, 3.0)}
    if name == "thermal_fade":
        return {"kappa": rng.uniform(0.05, 0.6), "e_fade": fc * loguniform(rng, 1e-3, 1e-1)}
    if name == "reversal_hump":
        return {"a_hump": rng.uniform(0.05, 1.5), "l_hump": loguniform(rng, 1e-4, 5e-3)}
    if name == "eccentricity":
        return {"eps_ecc": rng.uniform(0.02, 0.5), "l_ecc": loguniform(rng, 1e-3, 0.1),
                "psi_ecc": rng.uniform(-math.pi, math.pi)}
    if name == "rate_strengthening":
        return {"beta_rate": rng.uniform(0.05, 2.0), "v_ref": loguniform(rng, 1e-4, 1e-1)}
    if name == "applied_tracking":
        return {"beta_app": rng.uniform(0.1, 1.5)}
    if name == "takeup_overshoot":
        return {"a_to_fwd": rng.uniform(-0.9, 2.0), "a_to_bwd": rng.uniform(-0.9, 2.0),
                "l_to": loguniform(rng, 1e-4, 1e-2)}
    if name == "speed_weakening":
        return {"beta_sw": rng.uniform(0.02, 0.9), "v_sw": loguniform(rng, 1e-4, 1.0)}
    raise KeyError(name)


def draw_record(rng, n=None, flat=None, noise=None):
    """Uneven sample times (dt jittered by up to +-50 %), displacement = sum of 1-3 sines with
    amplitudes 1 mm..3 cm and 0.5..6 cycles each (so a random number of reversals), optionally a
    flat (zero-velocity) stretch and a little measurement noise (many tiny reversals)."""
    n = int(rng.integers(300, 900)) if n is None else n
    dt0 = loguniform(rng, 2e-3, 3e-2)
    dt = dt0 * (1.0 + rng.uniform(-0.5, 0.5, n - 1))
    t = np.concatenate([[rng.uniform(0, 10)], dt]).cumsum()
    T = t[-1] - t[0]
    x = np.full(n, rng.uniform(-0.01, 0.01))
    for _ in range(int(rng.integers(1, 4))):
        x += loguniform(rng, 1e-3, 3e-2) * np.sin(2 * np.pi * rng.uniform(0.5, 6) * (t - t[0]) / T
                                                  + rng.uniform(0, 2 * np.pi))
    if flat if flat is not None else rng.random() < 0.3:
        i = int(rng.integers(0, n - 20))
        j = int(rng.integers(i + 5, min(i + n // 4, n)))
        x[i:j] = x[i]
    if noise if noise is not None else rng.random() < 0.25:
        x += rng.normal(0, 2e-6, n)
    return t, x


def draw_applied(rng, t):
    """A positive applied-force signal around a random level, sometimes with a deep dip (so that
    applied_tracking clips g at 0 for beta_app > 1)."""
    T = t[-1] - t[0]
    a0 = loguniform(rng, 10, 1e4)
    a = a0 * (1 + 0.3 * np.sin(2 * np.pi * rng.uniform(0.5, 5) * (t - t[0]) / T)
              + 0.05 * rng.normal(size=t.size))
    if rng.random() < 0.5:
        i = int(rng.integers(0, t.size - 30))
        a[i:i + 25] *= 0.15
    return np.abs(a) + 1e-3 * a0


CASES = ("none",) + EFFECT_NAMES + ("all",)


def build_case(seed, model, case):
    rng = np.random.default_rng(1000 + seed)
    p = draw_params(rng)
    t, x = draw_record(rng)
    applied = draw_applied(rng, t)
    eps = 0.0 if seed % 2 == 0 else loguniform(rng, 1e-6, 1e-4)
    if case == "none":
        effects = None
    elif case == "all":
        effects = {e: draw_effect(rng, e, p) for e in EFFECT_NAMES
                   if not (model == "lugre" and e in P.NEEDS_BACKLASH)}
    else:
        effects = {case: draw_effect(rng, case, p)}
    return t, x, p, effects, eps, applied


# ---------------------------------------------------------------------------- kernel == oracle
# stage2_nonlinear is refused with the LuGre model (tested in test_params)
MATCH_CASES = [(case, model) for case in CASES for model in ("three_stage", "lugre")
               if not (model == "lugre" and case in P.NEEDS_BACKLASH)]


@pytest.mark.parametrize("seed", range(16))
@pytest.mark.parametrize("case,model", MATCH_CASES)
def test_kernel_matches_oracle(seed, model, case):
    t, x, p, effects, eps, applied = build_case(seed, model, case)
    F = simulate(t, x, p, effects, model=model, eps=eps, applied=applied)
    Fo = oracle_simulate(t, x, p, effects, model=model, eps=eps, applied=applied)
    assert np.all(np.isfinite(F))
    assert_matches(F, Fo)


@pytest.mark.parametrize("seed", range(4))
def test_effects_change_the_force(seed):
    """The matching test above would pass vacuously if an effect did nothing in both codes; each
    drawn effect must move the force by more than the matching tolerance."""
    for case in EFFECT_NAMES:
        t, x, p, effects, eps, applied = build_case(seed, "three_stage", case)
        F0 = simulate(t, x, p, eps=eps)
        F = simulate(t, x, p, effects, eps=eps, applied=applied)
        assert np.abs(F - F0).max() > 1e-6 * np.abs(F0).max(), case


@pytest.mark.parametrize("d2,d3", [(0.0, 0.0), (0.0, 1e-3), (1e-3, 0.0)])
@pytest.mark.parametrize("seed", range(3))
def test_kernel_matches_oracle_without_a_stage(seed, d2, d3):
    rng = np.random.default_rng(seed)
    p = draw_params(rng) | {"d2": d2, "d3": d3}
    t, x = draw_record(rng)
    effects = {"stage2_nonlinear": {"p2": 2.0}, "reversal_hump": draw_effect(rng, "reversal_hump", p)}
    for eff in (None, effects):
        assert_matches(simulate(t, x, p, eff), oracle_simulate(t, x, p, eff))


@pytest.mark.parametrize("ratio", [0.5, 5.0, 599.0, 601.0, 2000.0])
@pytest.mark.parametrize("seed", range(2))
def test_kernel_matches_oracle_on_both_sides_of_the_shared_exponential(seed, ratio):
    """The blend's smooth steps come from one exponential exp(-s/w) while (d2 + d3)/w < 600 and
    from their own functions beyond (kernel._blend_terms): both branches, and the small-s range
    where tanh is taken from expm1, match the oracle. The record creeps out of each reversal
    (steps of w/20 for the first 2 w) so that many samples sit at s < w/2."""
    rng = np.random.default_rng(seed)
    p = draw_params(rng)
    p["d2"], p["d3"] = 0.7e-3, 0.3e-3
    p["w"] = 1e-3 / ratio
    span = p["d2"] + p["d3"] + 40 * p["w"] + 2e-3
    creep = np.arange(1, 41) * p["w"] / 20
    leg = np.concatenate([creep, np.linspace(creep[-1], span, 200)[1:]])
    x = np.concatenate([[0.0], leg, span - leg, leg, span - leg])
    t = np.arange(x.size) * 1e-3
    for eff in (None, {"reversal_hump": draw_effect(rng, "reversal_hump", p)}):
        F = simulate(t, x, p, eff)
        assert np.all(np.isfinite(F))
        assert_matches(F, oracle_simulate(t, x, p, eff))


def test_kernel_matches_oracle_with_applied_clipped_to_zero():
    """applied_tracking clipping g at 0 for a stretch (no friction there: z = 0, F1 = sigma2 v)."""
    rng = np.random.default_rng(5)
    p = draw_params(rng)
    t, x = draw_record(rng, n=600, flat=False, noise=False)
    a = np.full(t.size, 100.0)
    a[200:260] = 10.0                            # 1 + 1.5 (0.1 - 1) < 0: clipped
    eff = {"applied_tracking": {"beta_app": 1.5}}
    for model in ("three_stage", "lugre"):
        F = simulate(t, x, p, eff, model=model, applied=a)
        Fo, tr = oracle_simulate(t, x, p, eff, model=model, applied=a, return_trace=True)
        assert np.all(tr["g"][200:260] == 0.0)
        assert_matches(F, Fo)
        if model == "lugre":
            v = prepare(t, x).v
            np.testing.assert_allclose(F[200:260], p["sigma2"] * v[200:260], rtol=1e-12, atol=1e-9)


STAGE2_BUG = ("regression (fixed): stage2_nonlinear with d2 below ~1e-15 m: q = s - sp(s-d2) carries a "
              "rounding error ~ulp(s) >> d2, (q/d2)^p2 overflows (L = inf, or NaN when k2 = 0) and "
              "Fb jumps to g_d right after a reversal. Fixed in simulate_into: q is clamped to d2 "
              "(q <= d2 holds exactly)")


@pytest.mark.parametrize("d2,p2", [(1e-20, 20.0), (1e-300, 10.0), (5e-324, 2.0)])
def test_stage2_nonlinear_tiny_d2(d2, p2):
    """The force is continuous in d2 at 0: a stage-2 gap of 1e-20 m or less changes nothing
    measurable (the line changes by at most k2*d2). Found by hypothesis (test_params.py)."""
    p = dict(fc_fwd=1000.0, fc_bwd=1000.0, fs_fwd=1100.0, fs_bwd=1100.0, v_s=1e-3, sigma0=1e6,
             sigma1=100.0, sigma2=500.0, k2=1e5, d2=0.0, k3=8e5, d3=1e-3, w=1e-5)
    t = np.linspace(0, 4, 401)
    x = 0.01 * np.sin(2 * np.pi * 0.5 * t)
    F0 = simulate(t, x, p)
    F = simulate(t, x, p | {"d2": d2}, {"stage2_nonlinear": {"p2": p2}})
    np.testing.assert_allclose(F, F0, rtol=0, atol=1e-6 * 1000.0)


# ---------------------------------------------------------------------------- neutral effects
NEUTRAL_CASES = [(e, m) for e in EFFECT_NAMES for m in ("three_stage", "lugre")
                 if not (m == "lugre" and e in P.NEEDS_BACKLASH)]


def neutral_effect(rng, name, p):
    """The effect with its switch parameter at the neutral value, the others random and valid."""
    vals = draw_effect(rng, name, p)
    for n in P.EFFECTS[name]:
        if P.PARAMS[n].neutral is not None:
            vals[n] = P.PARAMS[n].neutral
    return vals


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("name,model", NEUTRAL_CASES)
def test_neutral_effect_reproduces_baseline_exactly(seed, name, model):
    rng = np.random.default_rng(50 + seed)
    p = draw_params(rng)
    t, x = draw_record(rng)
    applied = draw_applied(rng, t)
    base = simulate(t, x, p, model=model)
    eff = {name: neutral_effect(rng, name, p)}
    assert np.array_equal(simulate(t, x, p, eff, model=model, applied=applied), base)
    # the same through the kernel's effect-enabled specialisation (an applied signal is passed,
    # so the effect code is compiled in and must switch itself off at the neutral value)
    drive = prepare(t, x, applied)
    vec = P.pack(p, eff, model)
    code = kernel.THREE_STAGE if model == "three_stage" else kernel.LUGRE
    F = kernel.simulate_one(drive.x, drive.v, drive.u, drive.dt, drive.applied, drive.a_med, vec,
                            code, 0.0, np.zeros(0, np.uint8))
    assert np.array_equal(F, base)
    # and next to another effect that is on: same as that effect alone
    other = "eccentricity" if name != "eccentricity" else "thermal_fade"
    on = {other: draw_effect(rng, other, p)}
    assert np.array_equal(simulate(t, x, p, on | eff, model=model, applied=applied),
                          simulate(t, x, p, on, model=model, applied=applied))


# ---------------------------------------------------------------------------- continuity
def continuity_params(rng):
    """Random parameters whose length scales (w, fc/sigma0) and Stribeck velocity the fine
    sampling of the continuity test resolves."""
    p = draw_params(rng)
    p["w"] = loguniform(rng, 1e-4, 5e-4)
    p["sigma0"] = p["fc_fwd"] / loguniform(rng, 2e-4, 3e-3)
    p["v_s"] = loguniform(rng, 1e-3, 1e-1)
    p["d2"] = rng.uniform(0.5e-3, 3e-3)
    p["d3"] = rng.uniform(0.5e-3, 3e-3)
    return p


def signal_sine(t):
    return 0.01 * np.sin(2 * np.pi * 0.5 * t)


def signal_reversals(t):
    # three superposed sines: large and small reversals, some only a few mm after the last one
    return (0.008 * np.sin(2 * np.pi * 0.5 * t) + 0.003 * np.sin(2 * np.pi * 1.7 * t + 1.0)
            + 0.0015 * np.sin(2 * np.pi * 3.1 * t + 2.0))


def max_jump_ratio(sim, p, signal, eps, duration=2.2):
    """max|F[k+1]-F[k]| sampled 4x finer, divided by the same on the coarse sampling."""
    lmin = min(p["w"], p["fc_fwd"] / p["sigma0"], p["fc_bwd"] / p["sigma0"])
    dt = 0.05 * lmin / 0.1         # <= 5 % of the shortest length scale per step at 0.1 m/s
    jumps = []
    for h in (dt, dt / 4):
        t = np.arange(0.0, duration, h)
        F = sim(t, signal(t), p, eps=eps)
        jumps.append(np.abs(np.diff(F)).max())
    return jumps[1] / jumps[0], jumps


Z_RELEASE_BUG = ("regression (fixed): with eps > 0, s can fall back below d2+d3+5w within the dead band "
                 "after having passed it; the kernel then sets z = d*Fb/sigma0 again and the force "
                 "jumps (spec 4: 'from s >= d2+d3+5w on, z evolves freely'; F must be continuous). "
                 "Fixed: the release is latched until the next reversal; see test_z_release_is_latched")
CONTINUITY_CASES = [(seed, eps, signal) for seed in range(3) for eps in (0.0, 3e-5)
                    for signal in (signal_sine, signal_reversals)]


@pytest.mark.parametrize("seed,eps,signal", CONTINUITY_CASES)
def test_force_is_continuous(seed, eps, signal):
    """F is continuous in time for a continuous input. On a sampled record, continuity means the
    largest sample-to-sample jump is explained by the sampling: it shrinks in proportion to the
    step (F is Lipschitz in time once the step resolves w, fc/sigma0 and v_s). Sampling the same
    input 4x finer must therefore shrink the largest jump ~4x; we require at least 2.5x. A
    discontinuity anywhere (e.g. the blend restarting from a wrong F_r at a reversal, z jumping
    when it is set or released, a stage switching abruptly) is an O(fc) jump whatever the step,
    so the ratio would stay near 1; test_continuity_test_catches_a_wrong_F_r shows it does.
    (seed 2, eps > 0, reversals: caught the z re-set bug, see Z_RELEASE_BUG.)"""
    rng = np.random.default_rng(200 + seed)
    p = continuity_params(rng)
    ratio, jumps = max_jump_ratio(simulate, p, signal, eps)
    assert ratio < 0.4, (ratio, jumps)
    # and the fine record's largest jump is small against the friction level
    assert jumps[1] < 0.05 * min(p["fc_fwd"], p["fc_bwd"]), jumps


def _smooth_step(t, t0, T):
    """0 -> 1 over [t0, t0+T] with zero slope at both ends (half a cosine)."""
    return 0.5 * (1 - np.cos(np.pi * np.clip((t - t0) / T, 0.0, 1.0)))


RELEASE_P = dict(fc_fwd=1000.0, fc_bwd=1100.0, fs_fwd=1100.0, fs_bwd=1200.0, v_s=1e-3,
                 sigma0=1e6, sigma1=100.0, sigma2=500.0, k2=50e3, d2=1.5e-3, k3=0.8e6,
                 d3=0.5e-3, w=2e-4)
RELEASE_EPS = 1e-4


def dead_band_return(t):
    """Forward to just past s = d2+d3+5w, back by 0.8 eps (no reversal with dead band eps), on
    forward again: s falls back below d2+d3+5w after z was released."""
    s_free = RELEASE_P["d2"] + RELEASE_P["d3"] + 5 * RELEASE_P["w"]
    x1 = s_free + 0.5 * RELEASE_EPS
    return (x1 * _smooth_step(t, 0.0, 0.5) - 0.8 * RELEASE_EPS * _smooth_step(t, 0.5, 0.1)
            + 3e-3 * _smooth_step(t, 0.6, 0.5))


def test_z_release_is_latched_oracle():
    """The latched reading of the release rule is continuous on the dead-band return, and the
    per-sample reading (the kernel before the fix) is not: see Z_RELEASE_BUG."""
    def sim(mode):
        return lambda t, x, p, eps: oracle_simulate(t, x, p, eps=eps, z_release=mode)
    ratio, jumps = max_jump_ratio(sim("latched"), RELEASE_P, dead_band_return, RELEASE_EPS, 1.2)
    assert ratio < 0.4, (ratio, jumps)
    ratio, jumps = max_jump_ratio(sim("per_sample"), RELEASE_P, dead_band_return, RELEASE_EPS, 1.2)
    assert ratio > 0.8, (ratio, jumps)


def test_z_release_is_latched():
    """Kernel: no force jump when the motion turns back by less than eps just after the release
    of z (same criterion as test_force_is_continuous)."""
    ratio, jumps = max_jump_ratio(simulate, RELEASE_P, dead_band_return, RELEASE_EPS, 1.2)
    assert ratio < 0.4, (ratio, jumps)


def test_continuity_test_catches_a_wrong_F_r():
    """The continuity criterion fails for a blend that restarts from F_r = 0 (oracle variant),
    and passes for the correct oracle on the same input."""
    rng = np.random.default_rng(200)
    p = continuity_params(rng)
    p["w"] = 5e-4
    p["sigma0"] = p["fc_fwd"] / 3e-3

    def sim(bug):
        return lambda t, x, p, eps: oracle_simulate(t, x, p, eps=eps, _bug=bug)

    ratio_ok, _ = max_jump_ratio(sim(None), p, signal_sine, 0.0, duration=1.2)
    ratio_bad, _ = max_jump_ratio(sim("F_r=0"), p, signal_sine, 0.0, duration=1.2)
    assert ratio_ok < 0.4
    assert ratio_bad > 0.8


# ---------------------------------------------------------------------------- monotone take-up
def triangle(X, V, dt, legs=3):
    """0 -> +X -> -X -> +X at constant speed V (legs of length X, 2X, 2X): steady sliding, then
    sharp reversals. Returns t, x and the sample indices of the two turning points."""
    n1 = int(round(X / (V * dt)))
    seg = [np.linspace(0, X, n1 + 1), np.linspace(X, -X, 2 * n1 + 1)[1:],
           np.linspace(-X, X, 2 * n1 + 1)[1:]][:legs]
    x = np.concatenate(seg)
    t = np.arange(x.size) * dt
    return t, x, (n1, 3 * n1)


def monotone_params(rng, V):
    """Random parameters with sigma1 * V <= 0.5 min(fc): the micro-damping term
    sigma1 (v - a(v) z) = sigma1 v (1 - sigma0 |z| / g) then weakens with |z| more slowly than
    sigma0 z grows, so F1 is monotone in z at constant v (the condition is sigma1 |v| < g).
    v_s <= V/10, so g is constant (= fc) on the constant-speed legs."""
    p = draw_params(rng)
    p["sigma1"] = min(p["sigma1"], 0.5 * min(p["fc_fwd"], p["fc_bwd"]) / V)
    p["v_s"] = loguniform(rng, 1e-4, V / 10)
    return p


def check_monotone(F, i_turn1, i_turn2, p):
    tol = 1e-12 * max(p["fs_fwd"], p["fs_bwd"]) * 10
    # from the last sample of steady forward sliding to the last one of steady backward sliding
    # (at a turning sample v = 0: the viscous and micro-damping terms vanish there, so the force
    # legitimately moves back by sigma2 V as the motion stops; each leg ends before that)
    back = np.diff(F[i_turn1 - 1:i_turn2])       # forward -> backward: non-increasing
    fwd = np.diff(F[i_turn2 - 1:])               # backward -> forward: non-decreasing
    return bool(np.all(back <= tol) and np.all(fwd >= -tol)), back.max(), fwd.min()


@pytest.mark.parametrize("seed", range(8))
def test_force_monotone_through_backlash_after_reversal(seed):
    rng = np.random.default_rng(300 + seed)
    V = 0.02
    p = monotone_params(rng, V)
    lz = max(p["fs_fwd"], p["fs_bwd"]) / p["sigma0"]
    X = p["d2"] + p["d3"] + 40 * p["w"] + 40 * lz + 1e-3
    dt = min(p["w"], lz, 1e-4) / V / 4
    t, x, (i1, i2) = triangle(X, V, dt)
    assert x.size < 400_000
    F = simulate(t, x, p)
    ok, up, down = check_monotone(F, i1, i2, p)
    assert ok, (up, down)
    # the force crosses from the forward to the backward friction level and back
    assert F[i1] > 0.9 * p["fc_fwd"] and F[i2] < -0.9 * p["fc_bwd"]


def test_monotone_test_catches_a_lugre_restart():
    """Without the backlash rule that sets z (oracle variant "no_z_set"), the LuGre force after
    the hand-over continues from the pre-reversal bristle state and F overshoots back towards the
    old direction: the monotone check fails; the correct oracle passes on the same record."""
    # fc/sigma0 = 1 cm >> d2+d3: without the rule z is still far from its backward level at
    # the hand-over
    p = dict(fc_fwd=1000.0, fc_bwd=1200.0, fs_fwd=1100.0, fs_bwd=1300.0, v_s=1e-3, sigma0=1e5,
             sigma1=100.0, sigma2=500.0, k2=50e3, d2=1.5e-3, k3=0.8e6, d3=0.5e-3, w=2e-4)
    V = 0.02
    t, x, (i1, i2) = triangle(0.3, V, 2e-4 / V / 2, legs=2)
    assert check_monotone(oracle_simulate(t, x, p), i1, x.size - 1, p)[0]
    assert not check_monotone(oracle_simulate(t, x, p, _bug="no_z_set"), i1, x.size - 1, p)[0]


# ---------------------------------------------------------------------------- steady sliding
@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("model", ["three_stage", "lugre"])
@pytest.mark.parametrize("direction", [1, -1])
def test_steady_sliding_force(seed, model, direction):
    """Far from a reversal (s >> d2+d3+w, z relaxed) at constant v: F = d g(v) + sigma2 v."""
    rng = np.random.default_rng(400 + seed)
    p = draw_params(rng)
    V = direction * loguniform(rng, 1e-3, 0.1)
    rate = 1 + 0.7 * math.log1p(abs(V) / 1e-3)     # the rate_strengthening factor below
    lz = rate * max(p["fs_fwd"], p["fs_bwd"]) / p["sigma0"]   # relaxation length of z
    X = p["d2"] + p["d3"] + 40 * p["w"] + 40 * lz
    n = 3000
    t = np.linspace(0, X / abs(V), n) + 1.0
    x = 0.003 + V * (t - t[0])
    F = simulate(t, x, p, model=model)
    key = "fwd" if direction > 0 else "bwd"
    fc, fs = p["fc_" + key], p["fs_" + key]
    g = fc + (fs - fc) * math.exp(-(V / p["v_s"]) ** 2)
    expected = direction * g + p["sigma2"] * V
    tail = F[int(0.9 * n):]
    np.testing.assert_allclose(tail, expected, rtol=1e-9, atol=1e-9 * fc)
    # and with rate strengthening the level scales by 1 + beta ln(1 + |v|/v_ref)
    eff = {"rate_strengthening": {"beta_rate": 0.7, "v_ref": 1e-3}}
    F = simulate(t, x, p, eff, model=model)
    expected = direction * g * rate + p["sigma2"] * V
    np.testing.assert_allclose(F[int(0.9 * n):], expected, rtol=1e-9, atol=1e-9 * fc)


# ---------------------------------------------------------------------------- no backlash
@pytest.mark.parametrize("seed", range(4))
def test_no_backlash_is_lugre_away_from_reversals(seed):
    """d2 = d3 = 0: no backlash and z is never set, so the bristle state follows the pure LuGre
    model exactly; once the blend has saturated (s >= 40 w after a reversal) F equals the LuGre
    force. fc/sigma0 >> w, so a z wrongly set near the reversal would still show 40 w later."""
    rng = np.random.default_rng(500 + seed)
    p = draw_params(rng) | {"d2": 0.0, "d3": 0.0}
    p["w"] = loguniform(rng, 1e-5, 3e-5)
    p["sigma0"] = p["fc_fwd"] / loguniform(rng, 1e-3, 1e-2)
    t, x = draw_record(rng, n=1500, flat=True, noise=False)
    F3 = simulate(t, x, p)
    FL = simulate(t, x, p, model="lugre")
    _, tr = oracle_simulate(t, x, p, return_trace=True)
    assert not tr["z_set"].any()
    far = tr["s"] >= 40 * p["w"]
    assert far.mean() > 0.5
    scale = np.abs(FL).max()
    np.testing.assert_allclose(F3[far], FL[far], rtol=0, atol=1e-12 * scale)
    # near a reversal the force goes from F_r to the LuGre force, never beyond both
    near = ~far
    assert near.any()
    assert np.all(np.abs(F3) <= 1.0001 * max(np.abs(FL).max(), p["fs_fwd"], p["fs_bwd"]))


# ---------------------------------------------------------------------------- pure LuGre
@pytest.mark.parametrize("seed", range(4))
def test_pure_lugre_equals_oracle_F1(seed):
    """The LuGre model's force is the oracle's F1 (section 3), both from its own LuGre run and
    from the three-stage run without backlash (where z evolves freely too)."""
    rng = np.random.default_rng(600 + seed)
    p = draw_params(rng)
    t, x = draw_record(rng)
    FL = simulate(t, x, p, model="lugre")
    _, trL = oracle_simulate(t, x, p, model="lugre", return_trace=True)
    assert_matches(FL, trL["F1"])
    _, tr3 = oracle_simulate(t, x, p | {"d2": 0.0, "d3": 0.0}, return_trace=True)
    assert_matches(FL, tr3["F1"])


@pytest.mark.parametrize("direction", [1, -1])
def test_pure_lugre_ramp_closed_form(direction):
    """Constant-velocity ramp from z = 0: z(t) = z_ss (1 - exp(-a t)), F = sigma0 z +
    sigma1 (v - a z) + sigma2 v (a = sigma0 |v|/g); independent of the oracle."""
    p = dict(fc_fwd=800.0, fc_bwd=1000.0, fs_fwd=950.0, fs_bwd=1150.0, v_s=2e-3, sigma0=4e5,
             sigma1=300.0, sigma2=700.0, k2=1e5, d2=1e-3, k3=1e6, d3=1e-3, w=1e-4)
    V = direction * 3e-3
    t = np.linspace(0, 2.0, 801)
    F = simulate(t, V * t, p, model="lugre")
    key = "fwd" if V > 0 else "bwd"
    g = p["fc_" + key] + (p["fs_" + key] - p["fc_" + key]) * math.exp(-(V / p["v_s"]) ** 2)
    a = p["sigma0"] * abs(V) / g
    z = direction * g / p["sigma0"] * (1 - np.exp(-a * t))
    expected = p["sigma0"] * z + p["sigma1"] * (V - a * z) + p["sigma2"] * V
    np.testing.assert_allclose(F, expected, rtol=1e-10, atol=1e-9 * g)


# ---------------------------------------------------------------------------- batch == single
@pytest.mark.parametrize("parallel", [True, False])
@pytest.mark.parametrize("model", ["three_stage", "lugre"])
def test_batch_rows_equal_single_calls(parallel, model):
    rng = np.random.default_rng(700)
    sets = [draw_params(rng) for _ in range(6)]
    t, x = draw_record(rng, n=700)
    applied = draw_applied(rng, t)
    # no effects
    M = pack_batch(sets, model=model)
    out = simulate_batch(t, x, M, model=model, parallel=parallel)
    assert out.shape == (len(sets), t.size)
    for i, p in enumerate(sets):
        assert np.array_equal(out[i], simulate(t, x, p, model=model))
    # the same effects on every row
    names = [e for e in EFFECT_NAMES if not (model == "lugre" and e in P.NEEDS_BACKLASH)]
    eff = {e: draw_effect(rng, e, sets[0]) for e in names}
    out = simulate_batch(t, x, pack_batch(sets, eff, model=model), model=model, applied=applied,
                         parallel=parallel)
    for i, p in enumerate(sets):
        assert np.array_equal(out[i], simulate(t, x, p, eff, model=model, applied=applied))
    # a different effect (or none) per row
    per_row = [None] + [{names[i % len(names)]: draw_effect(rng, names[i % len(names)], p)}
                        for i, p in enumerate(sets[1:])]
    M = np.vstack([P.pack(p, e, model) for p, e in zip(sets, per_row)])
    out = simulate_batch(t, x, M, model=model, applied=applied, parallel=parallel)
    for i, (p, e) in enumerate(zip(sets, per_row)):
        assert np.array_equal(out[i], simulate(t, x, p, e, model=model, applied=applied)), i
    # a mapping of arrays and a list of mappings give the same matrix
    cols = {k: np.array([p[k] for p in sets]) for k in sets[0]}
    assert np.array_equal(pack_batch(cols, model=model), pack_batch(sets, model=model))
    assert np.array_equal(simulate_batch(t, x, sets, model=model, parallel=parallel),
                          simulate_batch(t, x, pack_batch(sets, model=model), model=model,
                                         parallel=parallel))


def test_batch_with_eps_and_prepared_drive():
    rng = np.random.default_rng(701)
    sets = [draw_params(rng) for _ in range(3)]
    t, x = draw_record(rng, n=500, noise=True)
    drive = prepare(t, x)
    out = simulate_batch(drive, None, pack_batch(sets), eps=2e-5, parallel=True)
    for i, p in enumerate(sets):
        assert np.array_equal(out[i], simulate(t, x, p, eps=2e-5))
        assert not np.array_equal(out[i], simulate(t, x, p))     # eps matters on a noisy record


def test_reversals_at_the_extreme():
    """reversal="extreme" starts each backlash at the sample after the motion's extreme: on a
    clean drive, with a dead band eps > 0 the force is then exactly that of eps = 0 (where the
    spec's causal rule starts it eps of travel late, after running LuGre pre-sliding backwards
    over the dead band, which biases a fit's sigma0: docs/model-choices.md); on a noisy drive
    the reversals are the causal detector's, moved back to their extremes."""
    from frictionuq.noise import reversal_flags, reversal_indices
    p = published.brfd_params(133.0)
    t = np.arange(0, 8, 1 / 1024)
    x = 0.025 * np.sin(2 * np.pi * 0.5 * t)
    exact = simulate(t, x, p)
    late = simulate(t, x, p, eps=1.3e-5)
    at_ext = simulate(t, x, p, eps=1.3e-5, reversal="extreme")
    np.testing.assert_array_equal(at_ext, exact)
    assert np.max(np.abs(late - exact)) > 10.0                     # the causal rule's lag shows
    xn = x + 1.3e-6 * np.random.default_rng(4).standard_normal(t.size)
    flags = reversal_flags(xn, 1.3e-5)
    det = reversal_indices(xn, 1.3e-5)
    at = np.flatnonzero(flags)
    assert at.size == det.size and np.all(at <= det)
    for k, j in zip(at, det):                                      # the sample after the extreme
        seg = xn[max(k - 200, 0):j]
        assert xn[k - 1] in (seg.max(), seg.min())
    with pytest.raises(ValueError, match="reversal must be one of detection, extreme"):
        simulate(t, x, p, eps=1e-5, reversal="early")
