"""Parameter validation of the public simulator (frictionuq.model / frictionuq.params), and
property-based tests over the whole physical parameter box (hypothesis): the force is finite,
and it matches the oracle (tests/oracle.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st

from frictionuq import params as P
from frictionuq.model import pack_batch, simulate, simulate_batch
from oracle import oracle_simulate

GOOD = dict(fc_fwd=1000.0, fc_bwd=1100.0, fs_fwd=1100.0, fs_bwd=1200.0, v_s=1e-3, sigma0=1e6,
            sigma1=100.0, sigma2=500.0, k2=5e4, d2=1.5e-3, k3=8e5, d3=0.5e-3, w=2e-4)
T = np.linspace(0.0, 4.0, 401)
X = 0.01 * np.sin(2 * np.pi * 0.5 * T)


def raises_naming(name, *args, **kwargs):
    with pytest.raises(ValueError) as exc:
        simulate(T, X, *args, **kwargs)
    assert repr(name) in str(exc.value) or name in str(exc.value), str(exc.value)
    return str(exc.value)


# ---------------------------------------------------------------------------- validation
def test_good_parameters_run():
    F = simulate(T, X, GOOD)
    assert F.shape == T.shape and np.all(np.isfinite(F))


def test_unknown_parameter():
    msg = raises_naming("fc_forward", GOOD | {"fc_forward": 1.0})
    assert "unknown" in msg


def test_effect_parameter_among_base_parameters():
    msg = raises_naming("kappa", GOOD | {"kappa": 0.1})
    assert "effects" in msg


@pytest.mark.parametrize("name", P.BASE_NAMES)
def test_missing_parameter(name):
    p = dict(GOOD)
    del p[name]
    msg = raises_naming(name, p)
    assert "missing" in msg


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("name", ["fc_fwd", "sigma0", "d2", "w"])
def test_non_finite_parameter(name, bad):
    raises_naming(name, GOOD | {name: bad})


@pytest.mark.parametrize("name", P.BASE_NAMES)
def test_out_of_bounds_parameter(name):
    p = P.PARAMS[name]
    raises_naming(name, GOOD | {name: p.upper * 2 + 1})
    raises_naming(name, GOOD | {name: p.lower - max(abs(p.lower), 1.0)})
    # the bounds themselves are accepted
    assert np.all(np.isfinite(simulate(T, X, GOOD | {name: p.lower})))
    assert np.all(np.isfinite(simulate(T, X, GOOD | {name: p.upper})))


def test_non_numeric_parameter():
    raises_naming("sigma1", GOOD | {"sigma1": "lots"})


def test_likelihood_names_are_ignored():
    F = simulate(T, X, GOOD)
    extra = {n: P.PARAMS[n].lower for n in P.LIKELIHOOD_NAMES}
    assert np.array_equal(simulate(T, X, GOOD | extra), F)


def test_unknown_effect():
    msg = raises_naming("thermal_fading", GOOD, {"thermal_fading": {"kappa": 0.1}})
    assert "unknown effect" in msg


def test_unknown_effect_parameter():
    raises_naming("kapa", GOOD, {"thermal_fade": {"kapa": 0.1}})
    # a parameter of another effect is refused too
    raises_naming("p2", GOOD, {"thermal_fade": {"kappa": 0.1, "p2": 2.0}})


@pytest.mark.parametrize("name,value", [("kappa", 1.0), ("p2", 0.0), ("beta_app", 2.0),
                                        ("e_fade", math.nan), ("l_hump", -1e-3)])
def test_effect_parameter_out_of_bounds(name, value):
    raises_naming(name, GOOD, {P.PARAMS[name].effect: {name: value}}, applied=np.ones_like(T))


def test_missing_effect_parameters_take_their_defaults():
    eff = {"thermal_fade": {"kappa": 0.3}}
    full = {"thermal_fade": {"kappa": 0.3, "e_fade": P.PARAMS["e_fade"].default}}
    assert np.array_equal(simulate(T, X, GOOD, eff), simulate(T, X, GOOD, full))


def test_lugre_refuses_stage2_nonlinear():
    msg = raises_naming("stage2_nonlinear", GOOD, {"stage2_nonlinear": {"p2": 2.0}}, model="lugre")
    assert "three_stage" in msg
    # the three-stage model takes it
    assert np.all(np.isfinite(simulate(T, X, GOOD, {"stage2_nonlinear": {"p2": 2.0}})))


def test_unknown_model():
    raises_naming("viscous", GOOD, model="viscous")


def test_applied_tracking_needs_the_applied_signal():
    msg = raises_naming("applied_tracking", GOOD, {"applied_tracking": {"beta_app": 0.5}})
    assert "applied" in msg
    F = simulate(T, X, GOOD, {"applied_tracking": {"beta_app": 0.5}}, applied=np.full(T.size, 50.0))
    assert np.all(np.isfinite(F))


def test_applied_signal_needs_a_positive_median():
    with pytest.raises(ValueError, match="median"):
        simulate(T, X, GOOD, {"applied_tracking": {"beta_app": 0.5}}, applied=np.zeros(T.size))


def test_bad_eps():
    for eps in (-1e-6, math.nan):
        with pytest.raises(ValueError, match="eps"):
            simulate(T, X, GOOD, eps=eps)
    # "auto" (the fit's word) or a dict: said so, with where the estimate comes from (a raw
    # "could not convert string to float" or TypeError before)
    for eps in ("auto", {}):
        with pytest.raises(ValueError, match=r"eps \(reversal dead-band\) must be a number of m >= 0.*default_eps"):
            simulate(T, X, GOOD, eps=eps)


def test_a_value_that_is_text_or_a_bool_is_refused_as_by_the_cli():
    for bad in ("805", True):
        msg = raises_naming("fc_fwd", {**GOOD, "fc_fwd": bad})
        assert f"expected a number, got {bad!r}" in msg


def test_an_effect_given_a_number_instead_of_its_parameters():
    msg = raises_naming("thermal_fade", GOOD, {"thermal_fade": 0.2})
    assert "must be a mapping {parameter: value} (its parameters: kappa, e_fade), got 0.2" in msg


@pytest.mark.parametrize("name,value", [("sigma0", -1.0), ("w", math.nan), ("kappa", 1.5),
                                        ("d3", 0.5)])
def test_simulate_batch_bad_row_names_the_parameter(name, value):
    M = pack_batch([GOOD, GOOD | {"fc_fwd": 900.0}, GOOD])
    M[1, P.INDEX[name]] = value
    with pytest.raises(ValueError) as exc:
        simulate_batch(T, X, M)
    assert name in str(exc.value)
    # check=False skips the bound check (the caller has done it); rows 0 and 2 are unaffected
    if name != "w":
        out = simulate_batch(T, X, np.delete(M, 1, axis=0), check=False)
        assert np.array_equal(out[0], simulate(T, X, GOOD))


def test_simulate_batch_list_with_a_bad_mapping():
    with pytest.raises(ValueError) as exc:
        simulate_batch(T, X, [GOOD, GOOD | {"k3": -5.0}])
    assert "k3" in str(exc.value)


def test_simulate_batch_applied_tracking_without_signal():
    M = pack_batch([GOOD, GOOD], {"applied_tracking": {"beta_app": 0.4}})
    with pytest.raises(ValueError, match="applied_tracking"):
        simulate_batch(T, X, M)


def test_simulate_batch_matrix_shape():
    with pytest.raises(ValueError, match="shape"):
        simulate_batch(T, X, np.ones((2, 5)))


@pytest.mark.parametrize("t,x,what", [
    (T[::-1], X, "increasing"),
    (T, np.where(np.arange(T.size) == 7, np.nan, X), "x"),
    (T[:-1], X, "length"),
    (T[:1], X[:1], "2 samples"),
])
def test_bad_records(t, x, what):
    with pytest.raises(ValueError, match=what):
        simulate(t, x, GOOD)


# ---------------------------------------------------------------------------- property based
def _log_uniform(lo, hi):
    a, b = math.log10(lo), math.log10(hi)
    return st.floats(a, b).map(lambda e: min(max(10.0 ** e, lo), hi))


def _param_strategy(name):
    """Uniform in log space for a scale parameter, else 0, uniform, or log-uniform down to
    1e-12 of the upper bound (a linear draw alone would almost never give small values)."""
    p = P.PARAMS[name]
    if p.log_scale:
        return _log_uniform(p.lower, p.upper)
    if p.lower == 0.0:
        return st.one_of(st.just(0.0), st.floats(p.lower, p.upper),
                         _log_uniform(p.upper * 1e-12, p.upper))
    return st.floats(p.lower, p.upper)


base_params = st.fixed_dictionaries({n: _param_strategy(n) for n in P.BASE_NAMES})


@st.composite
def physical_params(draw):
    """The whole box except for the friction levels, which keep physical ratios:
    fc_bwd/fc_fwd in [0.1, 10] and fs/fc in [0.8, 2] per direction. (With fs/fc ~ 1e-6 the
    Stribeck sum fc + (fs-fc) exp(-(v/v_s)^2) cancels to 1e-6 of its terms, and two correct
    codes then differ by more than any fixed multiple of the force scale.)"""
    p = draw(base_params)
    lo, hi = P.PARAMS["fc_fwd"].lower, P.PARAMS["fc_fwd"].upper
    clip = lambda v: min(max(v, lo), hi)    # noqa: E731
    p["fc_fwd"] = clip(p["fc_fwd"])
    p["fc_bwd"] = clip(p["fc_fwd"] * 10 ** draw(st.floats(-1, 1)))
    p["fs_fwd"] = clip(p["fc_fwd"] * draw(st.floats(0.8, 2.0)))
    p["fs_bwd"] = clip(p["fc_bwd"] * draw(st.floats(0.8, 2.0)))
    return p


@st.composite
def records(draw):
    """Up to 400 samples, uneven dt (0.1 ms .. 0.1 s, jittered), amplitude 1 um .. 0.1 m, 1-3
    sines, sometimes a flat stretch and noise; a positive applied signal."""
    n = draw(st.integers(10, 400))
    seed = draw(st.integers(0, 2**32 - 1))
    dt0 = draw(_log_uniform(1e-4, 0.1))
    amp = draw(_log_uniform(1e-6, 0.1))
    cycles = draw(st.floats(0.3, 20.0))
    flat = draw(st.booleans())
    noise = draw(st.sampled_from([0.0, 1e-3, 0.1]))
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], dt0 * (1 + rng.uniform(-0.5, 0.5, n - 1))]).cumsum()
    ph = (t - t[0]) / (t[-1] - t[0])
    x = amp * np.sin(2 * np.pi * cycles * ph + rng.uniform(0, 2 * np.pi))
    for _ in range(int(rng.integers(0, 3))):
        x += amp * rng.uniform(0, 1) * np.sin(2 * np.pi * rng.uniform(0.3, 20) * ph + rng.uniform(0, 7))
    if flat and n > 20:
        i = int(rng.integers(0, n - 10))
        x[i:i + int(rng.integers(3, 10))] = x[i]
    x += noise * amp * rng.normal(size=n)
    a = np.abs(rng.normal(1.0, 0.5, n)) * 10 ** rng.uniform(0, 4) + 1e-6
    return t, x, a


def _effect_strategy(eff, model):
    if model == "lugre" and eff in P.NEEDS_BACKLASH:
        return st.none()
    return st.one_of(st.none(), st.fixed_dictionaries(
        {n: _param_strategy(n) for n in P.EFFECTS[eff]}))


@st.composite
def effect_sets(draw, model):
    eff = {}
    for name in P.EFFECTS:
        vals = draw(_effect_strategy(name, model))
        if vals is not None:
            eff[name] = vals
    return eff


# derandomize: the same examples on every run and machine (a property test is still a search,
# but one whose failure reproduces: the project's tests use fixed seeds)
SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow], derandomize=True,
                database=None)


def _term_scale(p, Fo, tr, x, t):
    """The largest magnitude among the terms summed into F (sigma0 z, sigma1 v, sigma1 a z,
    sigma2 v, Fb, F) and of sigma0 z_ss = g (the z update z_ss + (z - z_ss) e^(-a dt) rounds at
    the scale of z_ss, which over the box can exceed z by 1e8): rounding of the largest term
    bounds how well two correct codes agree."""
    v = np.gradient(x, t)
    vmax = float(np.abs(v).max())
    zs = np.abs(tr["z"]) * p["sigma0"]
    g = np.where(tr["g"] > 0, tr["g"], np.inf)
    az = float((p["sigma1"] * np.abs(v) * zs / g).max())
    return max(float(np.abs(Fo).max()), float(zs.max()), p["sigma1"] * vmax, az,
               p["sigma2"] * vmax, float(np.abs(tr["Fb"]).max()), float(tr["g"].max()), 1e-300)


@settings(max_examples=300, **SETTINGS)
@given(p=base_params, rec=records(), model=st.sampled_from(["three_stage", "lugre"]),
       eps=st.one_of(st.just(0.0), _log_uniform(1e-7, 1e-3)))
def test_finite_over_the_parameter_box(p, rec, model, eps):
    t, x, _ = rec
    F = simulate(t, x, p, model=model, eps=eps)
    assert F.shape == t.shape
    assert np.all(np.isfinite(F)), (p, model, eps)


@settings(max_examples=300, **SETTINGS)
@given(data=st.data(), p=base_params, rec=records(),
       model=st.sampled_from(["three_stage", "lugre"]))
def test_finite_with_random_effects(data, p, rec, model):
    t, x, a = rec
    eff = data.draw(effect_sets(model))
    F = simulate(t, x, p, eff, model=model, applied=a)
    assert np.all(np.isfinite(F)), (p, eff, model)


STAGE2_BUG = ("kernel bug: stage2_nonlinear with d2 below ~1e-15 m (p2 > 1): q = s - sp(s-d2) "
              "carries a rounding error ~ulp(s) >> d2, (q/d2)^p2 overflows, L = inf or NaN and "
              "Fb jumps to g_d right after a reversal (kernel.py simulate_into, `L = k2 * d2 * "
              "(q / d2) ** p2 + ...`). Fix: clamp q to d2 (q <= d2 holds exactly) before the power. "
              "See test_kernel.py::test_stage2_nonlinear_tiny_d2")
# the case hypothesis found (d2 = 5e-324, p2 = 10), with friction and stiffnesses of a real
# damper (hypothesis's own shrunk case, all k = 0, fails only on its particular record)
_T_EX = np.linspace(0.0, 4.0, 401)
_BUG_EXAMPLE = dict(
    p=GOOD | {"d2": 5e-324, "k2": 1e5, "w": 1e-5},
    rec=(_T_EX, 0.01 * np.sin(2 * np.pi * 0.5 * _T_EX), np.ones_like(_T_EX)),
    model="three_stage", eps=0.0, eff={"stage2_nonlinear": {"p2": 10.0}})


def _check_against_oracle(p, rec, model, eps, eff):
    t, x, a = rec
    if model == "lugre":
        eff = {k: v for k, v in eff.items() if k not in P.NEEDS_BACKLASH}
    F = simulate(t, x, p, eff, model=model, eps=eps, applied=a)
    Fo, tr = oracle_simulate(t, x, p, eff, model=model, eps=eps, applied=a, return_trace=True)
    scale = _term_scale(p, Fo, tr, x, t)
    # plus the rounding of the backlash line: q = s - sp(s - d2) is a cancellation, so k2*q
    # carries an absolute error of a few ulp(s) times k2 (the kernel and the oracle evaluate sp
    # differently), likewise k3*sp; an error dFb reaches F directly and through z = d Fb/sigma0,
    # as dFb (1 + sigma1 |v| / g)
    line = 0.0
    if model == "three_stage":
        g_pos = tr["g"][tr["g"] > 0]
        gain = 1 + p["sigma1"] * float(np.abs(np.gradient(x, t)).max()) / (
            float(g_pos.min()) if g_pos.size else np.inf)
        line = 16 * float(np.spacing(tr["s"].max())) * (p["k2"] + p["k3"]) * gain
    err = np.abs(F - Fo)
    k = int(err.argmax())
    assert err[k] <= 1e-9 * scale + line, (k, F[k], Fo[k], scale, line)


ORACLE_GIVEN = dict(p=physical_params(), rec=records(),
                    model=st.sampled_from(["three_stage", "lugre"]),
                    eps=st.one_of(st.just(0.0), _log_uniform(1e-7, 1e-3)),
                    eff=effect_sets("three_stage"))


@settings(max_examples=120, **SETTINGS)
@given(**ORACLE_GIVEN)
@example(**_BUG_EXAMPLE)
def test_matches_oracle_over_the_parameter_box(p, rec, model, eps, eff):
    """Kernel == oracle over the box (friction levels in physical ratios, see physical_params),
    with random effects. Tolerance 1e-9 of the largest term summed into F (over the box,
    sigma1 v or sigma0 z can exceed the resulting force by many orders of magnitude, so max|F|
    alone is no measure of rounding), plus the rounding of the backlash line.
    The case hypothesis found (a kernel bug, since fixed) is pinned by @example: see STAGE2_BUG."""
    _check_against_oracle(p, rec, model, eps, eff)


@settings(max_examples=300, **SETTINGS)
@given(**ORACLE_GIVEN)
def test_matches_oracle_over_the_parameter_box_except_tiny_d2(p, rec, model, eps, eff):
    """As above, without the known bug's domain (stage2_nonlinear with 0 < d2 < 1e-12 m), so that
    any other mismatch shows on its own (kept after the fix: more examples, cheaper)."""
    if "stage2_nonlinear" in eff and 0.0 < p["d2"] < 1e-12:
        p = p | {"d2": 0.0}
    _check_against_oracle(p, rec, model, eps, eff)


def test_a_pandas_series_is_taken_and_a_list_is_refused_with_the_form():
    """A notebook passes posterior means as a pandas Series: taken as the mapping it is. A list
    of values (or of effect names) is refused saying what form is expected (before: 'unknown
    parameter 805.0' and an AttributeError)."""
    import pandas as pd
    from frictionuq.published import brfd_params
    p = brfd_params(133.0)
    np.testing.assert_array_equal(P.pack(pd.Series(p)), P.pack(p))
    with pytest.raises(ValueError, match=r"params must be a mapping \{name: value\}.*got a list"):
        P.pack(list(p.values()))
    with pytest.raises(ValueError, match=r"effects must be a mapping \{effect: \{parameter"):
        P.pack(p, effects=["thermal_fade"])


def test_the_pure_lugre_model_needs_no_backlash_parameters():
    """model="lugre" never reads k2, d2, k3, d3, w: they may be left out (the force is the same
    as with any values of them); the 3-stage model still requires them."""
    from frictionuq.published import brfd_params
    p = brfd_params(133.0)
    t = np.arange(0, 4, 0.01)
    x = 0.02 * np.sin(2 * np.pi * 0.5 * t)
    lugre_only = {k: v for k, v in p.items() if k not in P.LUGRE_UNUSED}
    np.testing.assert_array_equal(simulate(t, x, lugre_only, model="lugre"),
                                  simulate(t, x, {**p, "d2": 0.01, "k3": 1.0}, model="lugre"))
    with pytest.raises(ValueError, match="missing parameter 'k2'"):
        simulate(t, x, lugre_only)


def test_a_summarys_parameter_means_simulate_directly():
    """The means of a fit's summary.json (per-test noise names included, e.g.
    sigma_noise[TEST]) go into simulate as they are: the likelihood-only names are ignored."""
    from frictionuq.published import brfd_params
    p = brfd_params(133.0)
    t = np.arange(0, 2, 0.01)
    x = 0.02 * np.sin(2 * np.pi * t)
    means = {**p, "force_offset": 12.0, "sigma_noise[h-1Hz]": 30.0, "noise_phi[h-1Hz]": 0.5}
    np.testing.assert_array_equal(simulate(t, x, means), simulate(t, x, p))
    with pytest.raises(ValueError, match="unknown parameter 'fc_fwd\\[h-1Hz\\]'"):
        P.pack({**p, "fc_fwd[h-1Hz]": 1.0})

