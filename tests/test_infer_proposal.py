"""The independence proposal (frictionuq.infer.proposal): its density and Hastings factor, the
marginal Johnson SU transforms, the burn-in's stability measure, and a seeded statistical harness
(as emcee's tests/integration/test_proposal.py) on a skewed target."""
from __future__ import annotations

import emcee
import numpy as np
import pytest
from scipy import special, stats
from scipy.stats import multivariate_t

from frictionuq.infer.proposal import (IndependenceMove, Proposal, RandomWalkMove, fit_marginal,
                                      proposal_change)


def test_plain_t_density_and_hastings_ratio():
    """With identity marginals the move's log q equals the multivariate t log density up to a
    constant, and its Hastings factor is log q(x) - log q(x')."""
    rng = np.random.default_rng(0)
    A = rng.standard_normal((4, 4))
    C, m = A @ A.T + np.eye(4), rng.standard_normal(4)
    mv = IndependenceMove(Proposal.gaussian(m, C, df=5, scale=1.0))
    ref = multivariate_t(loc=m, shape=C, df=5)
    x = rng.standard_normal((9, 4))
    assert np.ptp(ref.logpdf(x) - mv._logq(x)) < 1e-9
    y, f = mv._propose(x, np.random.RandomState(1))
    assert np.allclose(f, ref.logpdf(x) - ref.logpdf(y))


A0, A2 = 1.0, 1.5      # gamma shapes: skewness of log G -1.14 and -0.91 (the twin's fs: 1.0-1.1)


def _skewed(n, rng):
    """(n, 3) draws: x0 = log G, G ~ Gamma(A0) (left-skewed); x1 | x0 ~ N(0.8 x0, 0.5^2);
    x2 = -log G', G' ~ Gamma(A2) (right-skewed). Exact log density below."""
    x0 = np.log(rng.gamma(A0, size=n))
    return np.stack([x0, 0.8 * x0 + 0.5 * rng.standard_normal(n), -np.log(rng.gamma(A2, size=n))], 1)


def _log_p(x):
    """log G with G ~ Gamma(a) has log density a y - e^y - log Gamma(a)."""
    with np.errstate(over="ignore"):
        g0 = A0 * x[:, 0] - np.exp(x[:, 0]) - special.gammaln(A0)
        g2 = -A2 * x[:, 2] - np.exp(-x[:, 2]) - special.gammaln(A2)
    return g0 + stats.norm.logpdf(x[:, 1], 0.8 * x[:, 0], 0.5) + g2


def test_fit_marginal_uses_johnson_su_only_where_it_earns_its_parameters():
    rng = np.random.default_rng(1)
    assert fit_marginal(rng.standard_normal(4000))[1] == 0.0          # Gaussian: linear map
    a, b, loc, sc = fit_marginal(np.log(rng.gamma(2.0, size=4000)))    # skewed: Johnson SU
    assert b > 0 and sc > 0
    assert fit_marginal(np.full(10, 3.0)) == (0.0, 0.0, 3.0, 1.0)     # constant: no crash


def test_marginal_transform_density_jacobian_and_inverse():
    """log q(x) = log t(z(x)) + sum log dz_i/dx_i, with the Jacobian checked by finite
    differences; from_z inverts to_z."""
    rng = np.random.default_rng(2)
    p = Proposal.fit(_skewed(6000, rng), df=5, scale=1.1)
    assert np.all(p.b[[0, 2]] > 0)
    x = _skewed(7, rng)
    z, lj = p.to_z(x)
    assert np.allclose(p.from_z(z), x, atol=1e-10)
    h = 1e-6
    num = sum(np.log((p.to_z(x + h * e)[0][:, i] - p.to_z(x - h * e)[0][:, i]) / (2 * h))
              for i, e in enumerate(np.eye(3)))
    assert np.allclose(lj, num, atol=1e-6)
    mv = IndependenceMove(p)
    ref = multivariate_t(loc=p.mean, shape=p.cov * 1.1**2, df=5).logpdf(z) + lj
    assert np.ptp(ref - mv._logq(x)) < 1e-9
    y, f = mv._propose(x, np.random.RandomState(3))
    assert np.allclose(f, mv._logq(x) - mv._logq(y))


def _acceptance(p, n, rng):
    """Expected independence Metropolis-Hastings acceptance against the exact target:
    E[min(1, w(x') / w(x))], x ~ target, x' ~ q, w = p / q."""
    mv = IndependenceMove(p)
    x = _skewed(n, rng)
    y, _ = mv._propose(x, np.random.RandomState(4))
    lw_x, lw_y = _log_p(x) - mv._logq(x), _log_p(y) - mv._logq(y)
    return float(np.mean(np.exp(np.minimum(0.0, lw_y - lw_x))))


def test_su_marginals_raise_the_acceptance_on_skewed_marginals():
    """On a target with skewed marginals the fitted proposal is accepted more often than the
    plain t with the same moments (measured 0.61 against 0.54; the twin's Stribeck posterior:
    0.33 against 0.22). Fixed seeds: deterministic."""
    pool = _skewed(8000, np.random.default_rng(5))
    su = _acceptance(Proposal.fit(pool), 20000, np.random.default_rng(6))
    plain = _acceptance(Proposal.gaussian(pool.mean(0), np.cov(pool.T)), 20000, np.random.default_rng(6))
    assert su > plain + 0.05, (su, plain)


def test_independence_move_samples_a_skewed_target():
    """Seeded statistical harness: emcee with the fitted independence move (fitted to a small,
    shifted pool: a deliberately imperfect proposal) plus DE samples the skewed target; the means,
    variances and the 10 % / 90 % quantiles of x0 agree with the exact ones. The chain has >= 3,000
    effective draws; tolerances are > 5 standard errors (quantiles: of the binomial count), so the
    false-alarm rate is below 1e-5."""
    pool = _skewed(600, np.random.default_rng(7)) + np.array([0.2, 0.0, -0.1])
    moves = [(IndependenceMove(Proposal.fit(pool)), 0.5), (emcee.moves.DEMove(), 0.5)]
    s = emcee.EnsembleSampler(16, 3, _log_p, vectorize=True, moves=moves)
    s.random_state = np.random.RandomState(8).get_state()
    s.run_mcmc(_skewed(16, np.random.default_rng(9)), 4000, progress=False)
    ch = s.get_chain(discard=500, flat=True)
    tau = np.max(emcee.autocorr.integrated_time(s.get_chain(discard=500), quiet=True))
    check_skewed_sample(ch, ch.shape[0] / tau)


def check_skewed_sample(ch, n_eff):
    """Draws `ch` (n, 3) of the skewed target with `n_eff` effective draws: >= 3,000 of them,
    and the exact means, variances and 10 % / 90 % quantiles of x0 within 5 standard errors."""
    assert n_eff > 3000
    mean = np.array([special.digamma(A0), 0.8 * special.digamma(A0), -special.digamma(A2)])
    var0, var2 = special.polygamma(1, A0), special.polygamma(1, A2)
    var = np.array([var0, 0.64 * var0 + 0.25, var2])
    assert np.all(np.abs(ch.mean(0) - mean) < 5 * np.sqrt(var / n_eff))
    assert np.all(np.abs(ch.var(0) - var) < 5 * var * np.sqrt(2.0 / n_eff) * 2)
    for q in (0.1, 0.9):
        frac = np.mean(ch[:, 0] < np.log(stats.gamma.ppf(q, A0)))
        assert abs(frac - q) < 5 * np.sqrt(q * (1 - q) / n_eff)


def test_independence_move_samples_a_correlated_gaussian():
    """The same harness with a plain t proposal (shifted mean, wrong correlation) on a correlated
    3-D Gaussian; false-alarm rate below 1e-6."""
    C = np.array([[1.0, 0.8, 0.1], [0.8, 1.0, 0.3], [0.1, 0.3, 1.0]])
    P = np.linalg.inv(C)

    def lp(x):
        return -0.5 * np.einsum("ni,ij,nj->n", x, P, x)

    moves = [(IndependenceMove(Proposal.gaussian(np.full(3, 0.3), np.eye(3) * 1.5)), 0.5),
             (emcee.moves.DEMove(), 0.5)]
    s = emcee.EnsembleSampler(16, 3, lp, vectorize=True, moves=moves)
    s.random_state = np.random.RandomState(5).get_state()
    s.run_mcmc(np.random.default_rng(1).standard_normal((16, 3)), 4000, progress=False)
    ch = s.get_chain(discard=500, flat=True)
    tau = np.max(emcee.autocorr.integrated_time(s.get_chain(discard=500), quiet=True))
    n_eff = ch.shape[0] / tau
    assert n_eff > 3000
    se = 1.0 / np.sqrt(n_eff)
    assert np.all(np.abs(ch.mean(axis=0)) < 5 * se)
    assert np.all(np.abs(np.cov(ch.T) - C) < 5 * np.sqrt(2.0 / n_eff) + 0.01)


def test_proposal_change_measures_sd_ratio_and_mean_shift():
    old = (np.zeros(3), np.array([1.0, 2.0, 1.0]))
    new = (np.array([0.0, 1.0, 0.0]), np.array([1.0, 1.0, 3.0]))
    ratio, shift = proposal_change(old, new)
    assert ratio == pytest.approx(3.0) and shift == pytest.approx(1.0)
    assert proposal_change(None, new) == (float("inf"), float("inf"))
    assert proposal_change(new, new) == (1.0, 0.0)


def test_spread_is_robust_to_heavy_tails():
    """The widths the burn-in compares are quantile based: pairs of pools of 8,000 draws from the
    same Student t with 3 degrees of freedom (infinite kurtosis) differ by less than 10 % in width
    in each of five seeded pairs, where their sds differ by up to 2.1x (measured; above the
    burn-in's 1.25 in at least one pair). Deterministic."""
    sd_ratios = []
    for k in range(5):
        x = np.random.default_rng(12 + k).standard_t(3, (8000, 2))
        y = np.random.default_rng(30 + k).standard_t(3, (8000, 2))
        assert proposal_change(Proposal.fit(x).spread, Proposal.fit(y).spread)[0] < 1.1
        r = x.std(0) / y.std(0)
        sd_ratios.append(np.max(np.maximum(r, 1 / r)))
    assert max(sd_ratios) > 1.25


def test_attrs_round_trip():
    p = Proposal.fit(_skewed(3000, np.random.default_rng(10)))
    q = Proposal.from_attrs(p.to_attrs())
    x = _skewed(5, np.random.default_rng(11))
    assert np.array_equal(IndependenceMove(p)._logq(x), IndependenceMove(q)._logq(x))


def test_random_walk_gives_every_walker_its_own_displacement():
    """The stored run's random walk: 4,000 walkers' displacements in one step have the move's
    covariance, every entry within 5 standard errors of it (se of a sample covariance entry,
    sqrt((S_ij^2 + S_ii S_jj) / n); false-alarm rate below 1e-5 over the six entries), and are
    not one shared vector, as emcee's GaussianMove with a covariance matrix draws them (its rows
    all equal: the reason RandomWalkMove exists)."""
    cov = np.array([[1.0, 0.5, 0.0], [0.5, 2.0, -0.3], [0.0, -0.3, 0.5]])
    n = 4000
    x0 = np.zeros((n, 3))
    q, f = RandomWalkMove(cov).get_proposal(x0, np.random.RandomState(0))
    assert np.all(f == 0)
    se = np.sqrt((cov ** 2 + np.outer(np.diag(cov), np.diag(cov))) / n)
    assert np.all(np.abs(np.cov(q.T) - cov) < 5 * se), (np.cov(q.T), se)
    shared, _ = emcee.moves.GaussianMove(cov).get_proposal(x0, np.random.RandomState(0))
    assert np.allclose(shared, shared[0])
