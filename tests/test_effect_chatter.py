"""The `chatter` noise effect (docs/model-choices.md, "Effects beyond the spec"): more
measurement noise in a window after each reversal,

    noise = g(s) u,   g(s) = sqrt(1 + a_ch exp(-(s - s_ch)^2 / (2 w_ch^2))),

u the stationary (AR(1) or iid) noise, s the travel since the last reversal. It acts on the
likelihood and the predictive bands, never on the force. Checked here: the travel and the gain
follow their formulas; the force and the kernel vector ignore the effect; the likelihood equals
an independent sum of normal log-densities, and the baseline exactly at a_ch = 0; predictions
scale each draw's noise by its gain; the optimiser's noise step and the Laplace curvature of the
noise block; and a fit of a record with such noise recovers the window and covers the data
inside and outside it (slow). The hidden-effect case of `discover` is in
test_discrepancy_discover.py.
"""
from __future__ import annotations

import math
import warnings
from types import SimpleNamespace as NS

import numpy as np
import pytest
from scipy.stats import chi2, norm

from frictionuq import params as P, published
from frictionuq.discrepancy.features import features
from frictionuq.draws import Draws
from frictionuq.infer import outputs
from frictionuq.infer.fit import FitConfig, FitSpec, prepare
from frictionuq.infer.likelihood import LogPosterior, prepare_record
from frictionuq.infer.priors import TAIL_PRIOR, Prior
from frictionuq.infer.sampler import SamplerConfig, sample
from frictionuq.infer.space import Space
from frictionuq.model import simulate
from frictionuq.noise import ar1_from_normals, chatter_gain, since_reversal
from frictionuq.predict import add_noise, noise_gain

TRUTH = published.brfd_params(267.0)
A_CH, S_CH, W_CH = 15.0, 0.012, 0.003
B_CH = 0.2       # the fit's record keeps a fifth of the window's extra variance after its centre


def sine(f=0.5, amp=0.0254, cycles=4, per_cycle=200):
    t = np.arange(cycles * per_cycle) / (per_cycle * f)
    return t, amp * np.sin(2 * np.pi * f * t)


def test_travel_since_reversal_follows_the_detector():
    t, x = sine(cycles=2)
    s = since_reversal(x)
    assert np.array_equal(s, features(t, x, None)["since_reversal"])   # one definition
    assert s[0] == 0.0 and np.all(s >= 0.0)
    # first half-cycle (up from 0): s = x; after the top reversal s = x_top - x
    top = int(np.argmax(x[:200]))
    assert np.allclose(s[:top + 1], x[:top + 1])
    assert np.allclose(s[top + 2:top + 50], x[top] - x[top + 2:top + 50])


def test_gain_follows_its_formula():
    s = np.linspace(0, 0.05, 501)
    g = chatter_gain(s, [0.0, A_CH], [S_CH, S_CH], [W_CH, W_CH])
    assert g.shape == (2, s.size)
    assert np.array_equal(g[0], np.ones(s.size))                      # a_ch = 0: no effect
    assert math.isclose(g[1].max(), math.sqrt(1 + A_CH), rel_tol=1e-4)
    assert math.isclose(s[np.argmax(g[1])], S_CH, abs_tol=1e-4)
    assert np.allclose(g[1], np.sqrt(1 + A_CH * np.exp(-0.5 * ((s - S_CH) / W_CH) ** 2)))
    assert g[1][0] < 1.01 and g[1][-1] < 1.0 + 1e-6                     # 4 widths away


@pytest.mark.parametrize("b", [0.0, 0.2, 1.0])
def test_the_window_keeps_the_fraction_b_of_its_peak_after_its_centre(b):
    """b_ch: before the centre the bump, after it b + (1 - b) times the bump, so that far past the
    centre g = sqrt(1 + a b) until the next reversal; b = 0 is the bump itself (bit for bit), and
    the window is continuous with a continuous slope at the centre."""
    s = np.linspace(0, 0.05, 5001)
    g = chatter_gain(s, A_CH, S_CH, W_CH, b)[0]
    bump = np.exp(-0.5 * ((s - S_CH) / W_CH) ** 2)
    before, after = s <= S_CH, s > S_CH
    assert np.array_equal(g[before], np.sqrt(1 + A_CH * bump[before]))
    assert np.allclose(g[after], np.sqrt(1 + A_CH * (b + (1 - b) * bump[after])), rtol=1e-14)
    assert math.isclose(g[-1], math.sqrt(1 + A_CH * b), rel_tol=1e-9)      # 12 widths past s_ch
    assert math.isclose(g.max(), math.sqrt(1 + A_CH), rel_tol=1e-4)
    k = int(np.searchsorted(s, S_CH))            # the centre: no step, no kink (flat both sides)
    steepest = np.max(np.abs(np.diff(g)))
    assert abs(g[k] - g[k - 1]) < 0.01 * steepest and abs(g[k + 1] - g[k]) < 0.01 * steepest
    if b == 0.0:
        assert np.array_equal(g, chatter_gain(s, A_CH, S_CH, W_CH)[0])


def test_the_force_and_the_kernel_vector_ignore_it():
    t, x = sine(cycles=1)
    eff = {"chatter": {"a_ch": A_CH, "s_ch": S_CH, "w_ch": W_CH}}
    assert np.array_equal(simulate(t, x, TRUTH, eff), simulate(t, x, TRUTH))
    assert np.array_equal(P.pack(TRUTH, eff), P.pack(TRUTH))
    assert "chatter" in P.NOISE_EFFECTS and "chatter" in P.BEYOND_SPEC
    with pytest.raises(ValueError, match="a_ch"):
        P.pack(TRUTH, {"chatter": {"a_ch": -1.0}})


def test_the_tail_is_opt_in():
    """The default priors leave b_ch out (the one-bump window: b_ch = 0 in the likelihood);
    TAIL_PRIOR frees it, uniform on [0, 1]; the default's likelihood is that of b_ch = 0 freed,
    and another b_ch gives another one."""
    t, x = sine(cycles=2, per_cycle=100)
    y = simulate(t, x, TRUTH) + np.random.default_rng(1).normal(0, 300.0, t.size)
    test = NS(id="r", record=NS(t=t, x=x, force=y, applied=None), applied=267.0,
              kind="harmonic", frequency_hz=0.5)
    spaces = {}
    for name, pri in (("tail", {"b_ch": dict(TAIL_PRIOR)}), ("default", {})):
        cfg = FitConfig(samples_per_cycle=100, effects=("chatter",), priors=pri)
        spaces[name] = prepare(FitSpec("r", [test], 267.0, cfg))
    assert "b_ch" in spaces["tail"][2].names and spaces["tail"][2].priors["b_ch"].box() == (0.0, 1.0)
    assert "b_ch" not in spaces["default"][2].names and "b_ch" not in spaces["default"][2].fixed
    sd = spaces["default"][2]
    vals = {n: float(v) for n, v in zip(sd.names, sd.to_values(sd.to_theta(
        {n: 0.5 * (sd.priors[n].lower + sd.priors[n].upper) for n in sd.names})))}
    vals |= {"a_ch": A_CH, "s_ch": S_CH, "w_ch": W_CH}
    ll = {}
    for name, b in (("default", None), ("tail", 0.0), ("tail", 0.4)):
        sp, lp = spaces[name][2], spaces[name][3]
        th = sp.to_theta({n: (b if n == "b_ch" else vals[n]) for n in sp.names})
        ll[(name, b)] = float(lp.loglik_records(th[None]).sum())
    assert ll[("default", None)] == ll[("tail", 0.0)] != ll[("tail", 0.4)]


def _space(likelihood, fixed, chatter=True, tail=False):
    pri = {n: Prior(n, "uniform", 0.5 * v, 2.0 * v) for n, v in TRUTH.items()
           if n not in ("sigma1", "sigma2")}
    pri |= {n: Prior(n, "uniform", 0.0, 2.0 * TRUTH[n] + 1.0) for n in ("sigma1", "sigma2")}
    pri |= {"force_offset": Prior("force_offset", "uniform", -100.0, 100.0),
            "sigma_noise": Prior("sigma_noise", "loguniform", 1.0, 1e4),
            "noise_phi": Prior("noise_phi", "uniform", 0.0, 0.999)}
    if chatter:
        pri |= {"a_ch": Prior("a_ch", "uniform", 0.0, 100.0),
                "s_ch": Prior("s_ch", "uniform", 0.0, 0.05),
                "w_ch": Prior("w_ch", "loguniform", 5e-4, 0.0125)}
        if tail:
            pri["b_ch"] = Prior("b_ch", "uniform", 0.0, 1.0)
    return Space("three_stage", ("chatter",) if chatter else (), likelihood, pri, fixed)


@pytest.mark.parametrize("a_ch, b_ch", [(0.0, None), (3.0, None), (A_CH, None), (A_CH, 0.0),
                                        (A_CH, 0.3)])
def test_iid_likelihood_is_a_sum_of_normal_densities_with_sd_sigma_g(a_ch, b_ch):
    """b_ch None: not a parameter of the space (the one-bump window, its default 0)."""
    t, x = sine(cycles=2, per_cycle=100)
    y = simulate(t, x, TRUTH) + np.random.default_rng(1).normal(0, 300.0, t.size)
    sigma, off = 250.0, 12.0
    sp = _space("iid", {"sigma_noise": sigma}, tail=b_ch is not None)
    lp = LogPosterior(sp, [prepare_record("r", t, x, y, q=1, eps=0.0)])
    theta = sp.to_theta({**TRUTH, "force_offset": off, "a_ch": a_ch, "s_ch": S_CH, "w_ch": W_CH,
                         **({} if b_ch is None else {"b_ch": b_ch})})
    got = lp.loglik_records(theta[None])[0, 0]
    s, b = since_reversal(x), b_ch or 0.0
    bump = np.exp(-0.5 * ((s - S_CH) / W_CH) ** 2)
    g = np.sqrt(1 + a_ch * np.where(s > S_CH, b + (1 - b) * bump, bump))
    e = y - simulate(t, x, TRUTH) - off
    assert math.isclose(got, float(np.sum(norm.logpdf(e, scale=sigma * g))), rel_tol=1e-10)


def test_at_a_ch_zero_it_is_exactly_the_baseline():
    """AR(1) noise integrated out, as in every fit."""
    t, x = sine(cycles=2, per_cycle=100)
    y = simulate(t, x, TRUTH) + np.random.default_rng(1).normal(0, 300.0, t.size)
    r = [prepare_record("r", t, x, y, q=1, eps=0.0)]
    base, with_ch = _space("ar1", {}, chatter=False), _space("ar1", {})
    v0 = LogPosterior(base, r).loglik_records(base.to_theta({**TRUTH, "force_offset": 12.0})[None])
    v1 = LogPosterior(with_ch, r).loglik_records(with_ch.to_theta(
        {**TRUTH, "force_offset": 12.0, "a_ch": 0.0, "s_ch": S_CH, "w_ch": W_CH})[None])
    assert v0[0, 0] == v1[0, 0]
    v2 = LogPosterior(with_ch, r).loglik_records(with_ch.to_theta(
        {**TRUTH, "force_offset": 12.0, "a_ch": A_CH, "s_ch": S_CH, "w_ch": W_CH})[None])
    assert v2[0, 0] < v0[0, 0] - 5.0     # white noise without a window: the effect only costs


def test_prediction_noise_is_scaled_by_each_draws_gain():
    """predict.add_noise with predict.noise_gain: the noise sd is sigma g(s) draw by draw."""
    S, f = 2000, 0.5
    t, x = sine(cycles=1, per_cycle=400)
    draws = Draws({"a_ch": np.full(S, A_CH), "s_ch": np.full(S, S_CH), "w_ch": np.full(S, W_CH)},
                  "three_stage", ("chatter",), np.zeros(S), np.full(S, 2.0), np.zeros(S),
                  np.full(S, 400 * f), "test", [])
    g = noise_gain(x, draws, 0.0)
    assert np.allclose(g, chatter_gain(since_reversal(x), A_CH, S_CH, W_CH))
    e = add_noise(np.zeros((S, t.size)), draws, float(t[1] - t[0]), np.random.default_rng(0), gain=g)
    assert np.allclose(np.std(e, axis=0), 2.0 * g[0], rtol=0.08)
    plain = Draws({}, "three_stage", (), np.zeros(S), np.full(S, 2.0), np.zeros(S),
                  np.full(S, 400 * f), "test", [])
    assert noise_gain(x, plain, 0.0) is None


def _chatter_record(seed=4):
    t, x = sine(cycles=3, per_cycle=200)
    g = chatter_gain(since_reversal(x), A_CH, S_CH, W_CH)[0]
    e = g * ar1_from_normals(np.random.default_rng(seed).standard_normal(t.size), 0.6, 300.0)
    return t, x, simulate(t, x, TRUTH) + e


def test_noise_step_finds_the_window_and_the_curvature_is_finite():
    """noisefit.fit_noise moves only the noise parameters, to near the truth (model at the
    truth, AR(1) noise integrated out), and gauss_newton_cov then has a positive-definite noise
    block whose sds are small against the prior box (Laplace's evidence of the screening)."""
    from frictionuq.infer.localfit import gauss_newton_cov
    from frictionuq.infer.noisefit import fit_noise, noise_indices
    t, x, y = _chatter_record()
    sp = _space("ar1", {})
    lp = LogPosterior(sp, [prepare_record("r", t, x, y, q=1, eps=0.0)])
    start = sp.to_theta({**TRUTH, "force_offset": 0.0, "a_ch": 0.0, "s_ch": 0.03, "w_ch": 0.01})
    th = fit_noise(lp, start)
    idx = noise_indices(sp)
    assert [sp.names[i] for i in idx] == ["a_ch", "s_ch", "w_ch"]
    assert np.array_equal(np.delete(th, idx), np.delete(start, idx))
    v = dict(zip(sp.names, sp.to_values(th)))
    assert 5.0 < v["a_ch"] < 45.0 and abs(v["s_ch"] - S_CH) < 1.5e-3 and 0.5 < v["w_ch"] / W_CH < 2.0, v
    assert lp.log_prob(th[None])[0] > lp.log_prob(start[None])[0] + 50.0
    sd = np.sqrt(np.diag(gauss_newton_cov(lp, th)))[idx]
    assert np.all(np.isfinite(sd)) and np.all(sd < 0.2 * (sp.hi - sp.lo)[idx]), sd


# ---------------------------------------------------------------------------- a fit (slow)
SAMPLER = SamplerConfig(chunk=2000, min_steps=2000, max_steps=2000, burn_rounds=2,
                        burn_max_rounds=4, burn_steps=500, n_random_starts=2, n_prior_starts=2,
                        progress=False)


@pytest.fixture(scope="module")
def chatter_fit():
    """A BRFD 267 N sine, 4 cycles at 200 samples per cycle, with AR(1) noise (phi 0.8, sd 1 %
    of Fc) times g(s) at (A_CH, S_CH, W_CH, B_CH); fitted with the effect (default priors, the
    window's tail b_ch freed by TAIL_PRIOR)."""
    t, x = sine()
    fc = 0.5 * (TRUTH["fc_fwd"] + TRUTH["fc_bwd"])
    rng = np.random.default_rng(5)
    g = chatter_gain(since_reversal(x), A_CH, S_CH, W_CH, B_CH)[0]
    y = simulate(t, x, TRUTH) + g * ar1_from_normals(rng.standard_normal(t.size), 0.8, 0.01 * fc)
    test = NS(id="chatter-267N", record=NS(t=t, x=x, force=y, applied=None), applied=267.0,
              kind="harmonic", frequency_hz=0.5)
    cfg = FitConfig(seed=3, samples_per_cycle=200, effects=("chatter",), sampler=SAMPLER,
                    priors={"b_ch": dict(TAIL_PRIOR)})
    records, scales, space, logpost = prepare(FitSpec(test.id, [test], 267.0, cfg))
    assert records[0].q == 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # emcee's "chain shorter than 50 tau"
        res = sample(logpost, scales, 3, None, SAMPLER)
    return NS(space=space, logpost=logpost, res=res, y=y, s=since_reversal(x), g=g)


@pytest.mark.slow
def test_fit_recovers_the_window(chatter_fit):
    """The Mahalanobis distance of the truth from the posterior mean of (a_ch, s_ch, w_ch, b_ch)
    under the posterior covariance below the chi-square(4) 99.9 % point: false-alarm rate about
    0.1 % for a calibrated, near-Gaussian posterior (w_ch in its log coordinate). The full
    covariance, not the sum of marginal z^2: the window's amplitude, width and tail are
    correlated, and with correlated parameters that sum is not chi-square(4) (at full correlation
    its rate at that point would be 3.2 %). Measured at this seed: in the test's output."""
    sp, res = chatter_fit.space, chatter_fit.res
    draws = res.chain.reshape(-1, sp.ndim)
    truth = {"a_ch": A_CH, "s_ch": S_CH, "w_ch": math.log(W_CH), "b_ch": B_CH}
    cols = np.column_stack([draws[:, sp.names.index(n)] for n in truth])
    d = cols.mean(axis=0) - np.array(list(truth.values()))
    z2 = float(d @ np.linalg.solve(np.cov(cols.T), d))
    for n, c, v in zip(truth, cols.T, truth.values()):
        print(n, "posterior", c.mean(), "+-", c.std(), "truth", v)
    print("correlations", np.round(np.corrcoef(cols.T), 2).tolist())
    print("Mahalanobis^2", z2, "limit", chi2.ppf(0.999, 4))
    assert z2 < chi2.ppf(0.999, 4)
    lo = np.quantile(draws[:, sp.names.index("a_ch")], 0.025)
    assert lo > 2.0                      # the effect is clearly on


@pytest.mark.slow
def test_bands_cover_inside_and_outside_the_window(chatter_fit):
    """The posterior predictive 95 % band (noise scaled by each draw's g) covers the data
    between 88 % and 99.5 % of the samples both inside the window (g > 2) and outside it (g <
    1.1: the take-up, before the window; the tail keeps g at 2 after it). Measured at this seed:
    0.959 inside (369 samples), 0.970 outside (133). Before the tail (one-bump record, b_ch =
    0): 0.944 inside (143) and 0.960 outside (550), and that record fitted without the effect
    0.741 inside, 1.000 outside, i.e. the pooled noise too narrow in the window and too wide
    elsewhere. False-alarm rate: the samples are correlated (phi 0.8; about a fifth of them
    effective, as before), so a calibrated band's coverage has an sd of about 2.5 % inside (74
    effective) and 4.2 % outside (27), and 88 % is 2.8 and 1.7 sds below 95 %: about 0.3 % and
    5 % (rough figures, not simulated)."""
    c = chatter_fit
    post = outputs.posterior_draws(c.logpost, c.res, np.random.default_rng(0))
    pred = outputs.predictive(c.logpost, post, 400, np.random.default_rng(1))
    lo, hi = np.percentile(pred["rep"][0], [2.5, 97.5], axis=0)
    inside = (c.y >= lo) & (c.y <= hi)
    win, out = c.g > 2.0, c.g < 1.1
    print(f"coverage inside the window {inside[win].mean():.3f} ({win.sum()} samples), "
          f"outside {inside[out].mean():.3f} ({out.sum()} samples)")
    assert win.sum() >= 60
    assert 0.88 <= inside[win].mean() <= 0.995
    assert 0.88 <= inside[out].mean() <= 0.995


def test_records_with_chatter_keep_its_band():
    """A noise effect in the model floors every record's kept rate at NOISE_EFFECT_MIN_KEPT_HZ
    (FitConfig.record_options): at 100 samples per cycle a 0.2 Hz sine sampled at 100 Hz would
    be kept at 20 Hz, and the anti-alias filter would take most of a 12 Hz ring after each slip
    onset (hidden.stick_slip_bursts, the load path's chatter) out of it, while faster tests of
    the same level keep theirs (the cause of 8 misses in 10 on the bursts set before the floor,
    docs/log-discrepancy.md). Deterministic."""
    from frictionuq.discrepancy.hidden import stick_slip_bursts
    from frictionuq.infer.decimate import decimate
    from frictionuq.infer.likelihood import NOISE_EFFECT_MIN_KEPT_HZ, records_from_tests
    t = np.arange(2001) / 100.0
    x = 0.0254 * np.sin(2 * np.pi * 0.2 * t)
    ring = stick_slip_bursts(t, x, 0.003, {"f_osc": 12.3, "zeta_osc": 0.05, "amp_osc": 1000.0},
                             np.random.default_rng(0))
    test = NS(id="slow", record=NS(t=t, x=x, force=simulate(t, x, TRUTH) + ring, applied=None),
              applied=267.0, kind="harmonic", frequency_hz=0.2)
    kept = {}
    for name, cfg in (("plain", FitConfig(samples_per_cycle=100)),
                      ("chatter", FitConfig(samples_per_cycle=100, effects=("chatter",))),
                      ("floor", FitConfig(samples_per_cycle=100, min_kept_hz=40.0))):
        q = records_from_tests([test], **cfg.record_options())[0].q
        kept[name] = (q, float(np.sqrt(np.mean(decimate(ring, q) ** 2)) / np.sqrt(np.mean(ring ** 2))))
    assert NOISE_EFFECT_MIN_KEPT_HZ == 50.0
    assert kept["plain"][0] == 5 and kept["plain"][1] < 0.4, kept     # mostly filtered out
    assert kept["chatter"][0] == 2 and kept["chatter"][1] > 0.95, kept
    assert kept["floor"][0] == 2, kept
