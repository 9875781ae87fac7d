"""The inference layer's likelihood pieces: the vectorised log-posterior never returns NaN, the
integrated noise marginal (frictionuq.infer.noisemodel) agrees with brute-force integration over
sigma_noise and noise_phi, the iid and AR(1) forms agree where they must, the unbounded sampling
coordinates carry the right Jacobian, and a seeded sampler run is reproducible."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import integrate

from frictionuq import published
from frictionuq.infer import noisemodel
from frictionuq.infer.likelihood import LogPosterior, UnboundedPosterior, gauss_loglik, prepare_record
from frictionuq.infer.priors import default_priors, record_scales
from frictionuq.infer.sampler import SamplerConfig, sample
from frictionuq.infer.space import Space
from frictionuq.model import simulate


# ---------------------------------------------------------------------------- fixtures
def _synthetic(n_per_cycle=100, cycles=2, seed=0):
    truth = published.brfd_params(267.0)
    t = np.arange(cycles * n_per_cycle) / n_per_cycle * 5.0        # 0.2 Hz
    x = 0.0254 * np.sin(2 * np.pi * 0.2 * t)
    fc = 0.5 * (truth["fc_fwd"] + truth["fc_bwd"])
    y = simulate(t, x, truth) + 0.01 * fc * np.random.default_rng(seed).standard_normal(t.size)
    return t, x, y, truth


class _Rec:
    def __init__(self, t, x, force):
        self.t, self.x, self.force = t, x, force


@pytest.fixture(scope="module")
def small_fit():
    t, x, y, truth = _synthetic()
    rec = prepare_record("syn", t, x, y, q=1, eps=0.0)
    scales = record_scales([_Rec(t, x, y)])
    space = Space("three_stage", (), "ar1", default_priors(scales, likelihood="ar1"))
    return LogPosterior(space, [rec]), scales, truth


# ---------------------------------------------------------------------------- -inf, never NaN
def test_log_posterior_outside_prior_or_invalid_is_minus_inf(small_fit):
    lp, _, truth = small_fit
    sp = lp.space
    th0 = sp.to_theta({**truth, "force_offset": 0.0})
    assert np.isfinite(lp.log_prob(th0[None])).all()
    bad = np.repeat(th0[None], 8, axis=0)
    bad[0, 0] = sp.hi[0] + 1.0                      # above a bound
    bad[1, 3] = sp.lo[3] - 1.0                      # below a (relative) bound
    bad[2, 5] = np.nan
    bad[3, 6] = np.inf
    bad[4, 7] = -np.inf
    bad[5, sp.names.index("d2")] = -1e-3            # negative gap length: invalid parameter
    bad[6, sp.names.index("force_offset")] = 1e9
    bad[7] = np.nan
    out = lp(bad)
    assert out.shape == (8, 2)
    assert not np.isnan(out).any()
    assert np.all(out[:, 0] == -np.inf)
    assert np.all(np.isfinite(out[:, 1]))           # blobs stay finite for the HDF5 backend
    # a valid row in the same batch is unaffected
    mixed = np.vstack([bad[:2], th0[None]])
    assert np.isfinite(lp(mixed)[2, 0]) and np.allclose(lp(mixed)[2], lp(th0[None])[0])


def test_unbounded_posterior_never_nan_and_finite_inside(small_fit):
    lp, _, truth = small_fit
    up = UnboundedPosterior(lp)
    sp = lp.space
    u0 = sp.to_u(sp.to_theta({**truth, "force_offset": 0.0}))
    rng = np.random.default_rng(3)
    U = u0 + rng.normal(0, 3, size=(16, sp.ndim))
    U[0, 0], U[1, 1], U[2, 2], U[3] = np.nan, np.inf, -np.inf, 1e6
    out = up(U)
    assert not np.isnan(out).any()
    assert np.all(out[:3, 0] == -np.inf)
    assert np.all(np.isfinite(out[4:, 0]) | (out[4:, 0] == -np.inf))
    assert np.isfinite(up.log_prob(u0[None])[0])


def test_unbounded_coordinates_roundtrip_and_jacobian(small_fit):
    sp = small_fit[0].space
    rng = np.random.default_rng(1)
    th = sp.lo + (sp.hi - sp.lo) * rng.uniform(0.01, 0.99, size=(5, sp.ndim))
    assert np.allclose(sp.from_u(sp.to_u(th)), th, rtol=1e-10, atol=0)
    u = sp.to_u(th)
    h = 1e-6
    num = np.empty(5)
    for w in range(5):
        J = [(sp.from_u(u[w] + h * e) - sp.from_u(u[w] - h * e)) / (2 * h) for e in np.eye(sp.ndim)]
        num[w] = np.sum(np.log(np.abs(np.diag(np.array(J)))))
    assert np.allclose(sp.log_jac_u(u), num, atol=1e-6)


# ---------------------------------------------------------------------------- noise marginal
def _brute_marginal(e, a, b, phi_range=None):
    """log of the integral of p(e | sigma, phi) p(sigma) [p(phi)] by quadrature; p(sigma) is
    log-uniform on [a, b] for the marginal sd and phi uniform on phi_range."""
    def lik(sigma, phi):
        ll = gauss_loglik(e[None], np.array([sigma]), np.array([phi]))[0]
        return math.exp(ll - SHIFT)

    def over_sigma(phi):
        f = lambda ls: lik(math.exp(ls), phi) / math.log(b / a)    # d sigma / sigma = d ln sigma
        return integrate.quad(f, math.log(a), math.log(b), limit=400, epsabs=0, epsrel=1e-10)[0]

    if phi_range is None:
        return math.log(over_sigma(0.0)) + SHIFT
    lo, hi = phi_range
    val = integrate.quad(over_sigma, lo, hi, limit=400, epsabs=0, epsrel=1e-9, points=[0.5, 0.9])[0]
    return math.log(val / (hi - lo)) + SHIFT


SHIFT = 0.0


def _residuals(n=40, phi=0.6, sd=2.0, seed=5):
    rng = np.random.default_rng(seed)
    e = np.empty(n)
    e[0] = sd * rng.standard_normal()
    for k in range(1, n):
        e[k] = phi * e[k - 1] + sd * math.sqrt(1 - phi**2) * rng.standard_normal()
    return e


def test_iid_marginal_matches_quadrature():
    global SHIFT
    e = _residuals(phi=0.0)
    a, b = 1e-3, 1e3                      # wide: the (0, inf) closed form equals the bounded integral
    SHIFT = float(gauss_loglik(e[None], np.array([2.0]), np.array([0.0]))[0])
    brute = _brute_marginal(e, a, b)
    got = noisemodel.log_marginal(e[None], "iid", (a, b))[0]
    assert got == pytest.approx(brute, abs=1e-6)


def test_ar1_marginal_matches_quadrature_over_sigma_and_phi():
    global SHIFT
    e = _residuals(phi=0.6)
    a, b = 1e-3, 1e3
    SHIFT = float(gauss_loglik(e[None], np.array([2.0]), np.array([0.6]))[0])
    brute = _brute_marginal(e, a, b, phi_range=(0.0, noisemodel.PHI_MAX))
    got = noisemodel.log_marginal(e[None], "ar1", (a, b))[0]
    # the phi integral is a 600-point trapezoid rule: about 1e-4 relative accuracy
    assert got == pytest.approx(brute, abs=2e-3)
    # phi fixed: only the sigma integral
    brute_fixed = math.log(integrate.quad(
        lambda ls: math.exp(float(gauss_loglik(e[None], np.array([math.exp(ls)]), np.array([0.6]))[0]) - SHIFT)
        / math.log(b / a), math.log(a), math.log(b), limit=400, epsabs=0, epsrel=1e-10)[0]) + SHIFT
    got_fixed = noisemodel.log_marginal(e[None], "ar1", (a, b), phi_fixed=0.6)[0]
    # the closed form puts the log-uniform prior on the innovation sd sigma sqrt(1 - phi^2):
    # the same density, with bounds shifted by that factor (negligible for these wide bounds)
    assert got_fixed == pytest.approx(brute_fixed, abs=1e-6)


def test_iid_and_ar1_forms_agree_where_they_must():
    rng = np.random.default_rng(2)
    E = rng.normal(0, 3.0, size=(4, 50))
    bounds = (1e-2, 1e2)
    iid = noisemodel.log_marginal(E, "iid", bounds)
    assert np.allclose(iid, noisemodel.log_marginal(E, "ar1", bounds, phi_fixed=0.0))
    # with sigma fixed: iid = sum of normal log-densities; ar1 = the exact AR(1) likelihood
    s = 2.5
    ref = np.sum(-0.5 * (E / s) ** 2 - math.log(s) - 0.5 * math.log(2 * math.pi), axis=1)
    assert np.allclose(noisemodel.log_marginal(E, "iid", bounds, sigma_fixed=s), ref)
    got = noisemodel.log_marginal(E, "ar1", bounds, sigma_fixed=s, phi_fixed=0.7)
    assert np.allclose(got, gauss_loglik(E, np.full(4, s), np.full(4, 0.7)))
    # strongly autocorrelated residuals: the AR(1) marginal prefers them to the iid one
    e = _residuals(n=200, phi=0.95)[None]
    assert noisemodel.log_marginal(e, "ar1", bounds)[0] > noisemodel.log_marginal(e, "iid", bounds)[0] + 10


def test_draw_noise_conditional_posterior_centres_on_truth():
    e = _residuals(n=4000, phi=0.6, sd=2.0, seed=9)
    E = np.repeat(e[None], 400, axis=0)
    sig, phi = noisemodel.draw_noise(E, "ar1", np.random.default_rng(0))
    assert abs(np.mean(phi) - 0.6) < 0.05 and abs(np.mean(sig) - 2.0) < 0.2
    assert np.std(phi) > 0 and np.std(sig) > 0


# ---------------------------------------------------------------------------- reproducibility
def test_same_seed_same_chain(small_fit, tmp_path):
    lp, scales, _ = small_fit
    cfg = SamplerConfig(nwalkers=32, chunk=20, max_steps=20, min_steps=20, burn_rounds=1,
                        burn_steps=10, burn_max_rounds=1, n_random_starts=0, n_prior_starts=1,
                        progress=False)
    runs = [sample(lp, scales, seed=11, backend_path=tmp_path / f"c{i}.h5", cfg=cfg, resume=False)
            for i in range(2)]
    assert np.array_equal(runs[0].chain, runs[1].chain)
    assert np.array_equal(runs[0].log_prob, runs[1].log_prob)
    assert isinstance(runs[0].n_steps, int) and isinstance(runs[0].burn, int)
    other = sample(lp, scales, seed=12, backend_path=tmp_path / "c2.h5", cfg=cfg, resume=False)
    assert not np.array_equal(runs[0].chain, other.chain)


def test_noise_draws_from_the_stored_statistics_equal_those_from_a_resimulation(small_fit, tmp_path):
    """The sampler stores every record's residual statistics with each step (emcee blobs) and
    outputs.posterior_draws draws sigma_noise and noise_phi from them; the draws equal those
    from re-simulating every kept draw's residuals (the previous way, 14 s of a discover run)."""
    from frictionuq.infer import outputs
    lp, scales, _ = small_fit
    cfg = SamplerConfig(nwalkers=32, chunk=20, max_steps=40, min_steps=20, burn_rounds=1,
                        burn_steps=10, burn_max_rounds=1, n_random_starts=0, n_prior_starts=1,
                        thin_output=1, progress=False)
    res = sample(lp, scales, seed=3, backend_path=tmp_path / "c.h5", cfg=cfg, resume=False)
    D, W, _ = res.chain.shape
    assert res.noise_stats.shape == (D, W, 1, len(noisemodel.STATS))
    flat = res.chain.reshape(-1, lp.space.ndim)
    e = lp.residuals(flat, lp.records[0])
    want = np.column_stack(noisemodel.suff_stats(e)).reshape(D, W, -1)
    assert np.allclose(res.noise_stats[:, :, 0, :], want, rtol=1e-9, atol=0)
    assert np.allclose(res.blobs[:, :, 0], lp.loglik_records(flat).reshape(D, W), rtol=1e-12)
    post = outputs.posterior_draws(lp, res, np.random.default_rng(4))
    # posterior_draws is (walker, draw), walker by walker
    e_w = lp.residuals(np.transpose(res.chain, (1, 0, 2)).reshape(-1, lp.space.ndim), lp.records[0])
    ref_s, ref_phi = noisemodel.draw_noise(e_w, "ar1", np.random.default_rng(4))
    assert np.allclose(post["noise_phi"][:, :, 0].ravel(), ref_phi, rtol=1e-9)
    assert np.allclose(post["sigma_noise"][:, :, 0].ravel(), ref_s, rtol=1e-9)


def test_noise_prior_overrides_that_would_be_ignored_are_refused():
    """noise_phi is integrated out under a uniform prior and sigma_noise under a log-uniform
    one: a distribution override of either would be silently ignored, so it is refused."""
    import pytest
    from frictionuq.campaign import load_campaign
    from frictionuq.errors import InputError
    from frictionuq.infer import fit as F
    camp = load_campaign("data/brfd-twin")
    for bad in ({"noise_phi": {"dist": "uniform", "lower": 0.0, "upper": 0.5}},
                {"sigma_noise": {"dist": "normal", "lower": 1.0, "upper": 1e4, "mu": 10, "sd": 1}}):
        spec = F.plan(camp, "test", F.FitConfig(tests=("h-267N-0.5Hz",), priors=bad))[0]
        with pytest.raises(InputError, match="integrated out"):
            F.prepare(spec)
    ok = F.plan(camp, "test", F.FitConfig(tests=("h-267N-0.5Hz",), priors={"noise_phi": 0.5}))[0]
    assert F.prepare(ok)[2].noise_config()["phi_fixed"] == 0.5


def test_interrupted_run_resumes_without_losing_steps(small_fit, tmp_path):
    """A run stopped after 40 stored steps and resumed to 60 gives exactly the chain of an
    uninterrupted 60-step run (positions, random state and the independence proposal are all
    restored from the HDF5 file), and the first 40 steps are the stored ones. Here with the
    ensemble's stored run; the default's, independent chains, is the next test."""
    import emcee
    lp, scales, _ = small_fit
    kw = dict(nwalkers=32, chunk=20, min_steps=20, burn_rounds=2, burn_steps=10, burn_max_rounds=2,
              n_random_starts=0, n_prior_starts=1, progress=False, tau_factor=1e9,
              stored_run="ensemble")
    full = sample(lp, scales, seed=3, backend_path=tmp_path / "full.h5",
                  cfg=SamplerConfig(max_steps=60, thin_output=1, **kw), resume=False)
    part = tmp_path / "part.h5"
    sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=40, thin_output=1, **kw),
           resume=False)
    first = emcee.backends.HDFBackend(str(part), read_only=True).get_chain()
    assert first.shape[0] == 40
    res = sample(lp, scales, seed=3, backend_path=part,
                 cfg=SamplerConfig(max_steps=60, thin_output=1, **kw), resume=True)
    after = emcee.backends.HDFBackend(str(part), read_only=True).get_chain()
    assert after.shape[0] == 60 and np.array_equal(after[:40], first)
    assert np.array_equal(after, emcee.backends.HDFBackend(str(tmp_path / "full.h5"), read_only=True).get_chain())
    assert res.n_steps == full.n_steps == 60
    # resumed, not recomputed from the same seed (which would give the same chain too)
    assert res.resumed_from == [40] and full.resumed_from == []


def test_independent_chains_run_reproduces_and_resumes(small_fit, tmp_path):
    """The default stored run, independent chains: it has `run_walkers` walkers (the burn-in
    keeps its 32), the same seed gives the same chain, and a run stopped after 40 stored steps
    and resumed to 60 equals the uninterrupted one (the random walk's covariance is restored
    with the proposal)."""
    import emcee
    lp, scales, _ = small_fit
    assert SamplerConfig().stored_run == "chains" and SamplerConfig().run_walkers == 16
    kw = dict(nwalkers=32, run_walkers=8, chunk=20,
              min_steps=20, burn_rounds=2, burn_steps=10, burn_max_rounds=2, n_random_starts=0,
              n_prior_starts=1, progress=False, tau_factor=1e9, thin_output=1)
    full = sample(lp, scales, seed=3, backend_path=tmp_path / "full.h5",
                  cfg=SamplerConfig(max_steps=60, **kw), resume=False)
    assert full.chain.shape[1] == 8 and full.n_steps == 60
    again = sample(lp, scales, seed=3, backend_path=tmp_path / "again.h5",
                   cfg=SamplerConfig(max_steps=60, **kw), resume=False)
    assert np.array_equal(full.chain, again.chain)
    part = tmp_path / "part.h5"
    sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=40, **kw), resume=False)
    res = sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=60, **kw),
                 resume=True)
    assert res.resumed_from == [40]          # resumed, not recomputed from the same seed
    after = emcee.backends.HDFBackend(str(part), read_only=True).get_chain()
    assert np.array_equal(after, emcee.backends.HDFBackend(str(tmp_path / "full.h5"), read_only=True).get_chain())


def test_a_run_resumed_mid_chunk_checks_and_stops_where_the_uninterrupted_one_does(small_fit,
                                                                                    tmp_path):
    """A run interrupted between two checks (here capped at 50 stored steps, checks every 20)
    and resumed stops at the same step as the uninterrupted run, with the same chain: the resumed
    session replays the stored checks (the rule held at 40 steps), checks at 60 and 80 as the
    uninterrupted run does, and stops at 80 (the rule held at three checks in a row). On the
    code before, it checked at 70, 90, 110, 130 with the count and tau started afresh, and
    stopped at 130. A finished run resumed again runs no step. The rule is made loose (every check after
    the first holds) so that the stop is deterministic."""
    import emcee
    lp, scales, _ = small_fit
    kw = dict(nwalkers=32, run_walkers=8, chunk=20, min_steps=20, burn_rounds=2, burn_steps=10,
              burn_max_rounds=2, n_random_starts=0, n_prior_starts=1, progress=False,
              thin_output=1, tau_factor=1e-6, tau_rtol=1e6, r_hat_max=1e6, ess_min=1e-6,
              n_global_starts=0,
              confirm_checks=3)
    full = sample(lp, scales, seed=3, backend_path=tmp_path / "full.h5",
                  cfg=SamplerConfig(max_steps=200, **kw), resume=False)
    assert (full.n_steps, full.converged_tau) == (80, True)
    assert [h["steps"] for h in full.history] == [20, 40, 60, 80]
    part = tmp_path / "part.h5"
    cut = sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=50, **kw),
                 resume=False)
    assert (cut.n_steps, cut.converged_tau) == (50, False)
    msgs = []
    res = sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=200, **kw),
                 resume=True, log=msgs.append)
    assert res.resumed_from == [50] and (res.n_steps, res.converged_tau) == (80, True)
    assert [h["steps"] for h in res.history] == [60, 80]
    assert any("replayed on the 50 stored steps" in m and "held at the last 1 in a row" in m
               for m in msgs)
    assert np.array_equal(emcee.backends.HDFBackend(str(part), read_only=True).get_chain(),
                          emcee.backends.HDFBackend(str(tmp_path / "full.h5"), read_only=True).get_chain())
    assert np.array_equal(res.chain, full.chain)
    done = sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=200, **kw),
                  resume=True)
    assert (done.n_steps, done.converged_tau, done.history) == (80, True, [])


def test_tempered_chains_run_reproduces_and_resumes(small_fit, tmp_path):
    """The stored run with parallel tempering (temperatures=3): the backend holds all 3 x 8
    walkers, the result only the 8 untempered chains, every stored walker's log-posterior is the
    untempered one at its coordinates (swaps move states whole), the history records the swap
    rates, and a run stopped after 40 steps and resumed to 60 equals the uninterrupted one."""
    import emcee
    from frictionuq.infer.likelihood import UnboundedPosterior
    lp, scales, _ = small_fit
    kw = dict(nwalkers=32, run_walkers=8, temperatures=3, chunk=20, min_steps=20, burn_rounds=2,
              burn_steps=10, burn_max_rounds=2, n_random_starts=0, n_prior_starts=1,
              progress=False, tau_factor=1e9, thin_output=1)
    full = sample(lp, scales, seed=3, backend_path=tmp_path / "full.h5",
                  cfg=SamplerConfig(max_steps=60, **kw), resume=False)
    be = emcee.backends.HDFBackend(str(tmp_path / "full.h5"), read_only=True)
    assert be.get_chain().shape == (60, 24, lp.space.ndim)
    assert full.chain.shape[1] == 8 and full.n_steps == 60
    D, R = lp.space.ndim, len(lp.records)
    again = UnboundedPosterior(lp, stats=True)(be.get_chain().reshape(-1, D))
    assert np.allclose(again[:, 0], be.get_log_prob().ravel())
    assert np.allclose(again[:, 1:1 + R], be.get_blobs().reshape(-1, again.shape[1] - 1)[:, :R])
    assert all(len(h["swap_acceptance"]) == 2 for h in full.history)
    part = tmp_path / "part.h5"
    sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=40, **kw), resume=False)
    res = sample(lp, scales, seed=3, backend_path=part, cfg=SamplerConfig(max_steps=60, **kw),
                 resume=True)
    assert res.resumed_from == [40]
    assert np.array_equal(emcee.backends.HDFBackend(str(part), read_only=True).get_chain(), be.get_chain())
    assert np.array_equal(res.chain, full.chain)
