"""Parallel tempering of the stored run's chains (infer.tempering): exact on a unimodal target,
and between two separated modes it gives the modes' weights where untempered chains cannot.
Fixed seeds: deterministic; each check's false-alarm rate is stated."""
from __future__ import annotations

import emcee
import numpy as np
import pytest

from frictionuq.infer.proposal import RandomWalkMove
from frictionuq.infer.tempering import TemperedMove, default_ratio, ladder, swap_rates, tempered_moves

MODE = np.array([4.0, 4.0])      # modes at -MODE and +MODE, unit covariance: 11.3 sd apart
W_LOW = 0.3                      # weight of the mode at -MODE


def _bimodal(x):
    """[log-posterior, log-likelihood, 0] of a two-Gaussian mixture likelihood under a flat
    prior on [-12, 12]^2 (the blob layout of the fit's target: the likelihood first)."""
    x = np.atleast_2d(x)
    a = -0.5 * np.sum((x + MODE) ** 2, axis=1) + np.log(W_LOW)
    b = -0.5 * np.sum((x - MODE) ** 2, axis=1) + np.log(1 - W_LOW)
    ll = np.logaddexp(a, b)
    inside = np.all(np.abs(x) < 12, axis=1)
    return np.column_stack([np.where(inside, ll, -np.inf), np.where(inside, ll, -1e300),
                            np.zeros(len(x))])


def _gauss(x):
    """The same layout for a correlated 2-D Gaussian likelihood (mean (1, -1), sds 1 and 2,
    correlation 0.6) under a flat prior on [-30, 30]^2."""
    x = np.atleast_2d(x)
    cov = np.array([[1.0, 1.2], [1.2, 4.0]])
    d = x - np.array([1.0, -1.0])
    ll = -0.5 * np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d)
    inside = np.all(np.abs(x) < 30, axis=1)
    return np.column_stack([np.where(inside, ll, -np.inf), ll, np.zeros(len(x))])


def _run(target, chains, levels, steps, seed, start, ratio=0.5):
    betas = ladder(levels, ratio)
    base = [(RandomWalkMove(np.eye(2) * 0.8), 1.0)]
    moves = tempered_moves(base, betas, chains, n_records=1) if levels > 1 else base
    s = emcee.EnsembleSampler(chains * levels, 2, target, vectorize=True, moves=moves)
    s.random_state = np.random.RandomState(seed).get_state()
    s.run_mcmc(np.tile(start, (levels, 1)), steps, progress=False, skip_initial_state_check=True)
    return s.get_chain(discard=steps // 5)[:, :chains], moves


def test_ladder_and_default_ratio():
    assert np.allclose(ladder(4, 0.5), [1, 0.5, 0.25, 0.125])
    assert default_ratio(12) == pytest.approx(1 - 1 / np.sqrt(6))
    assert default_ratio(2) == 0.3


def test_tempered_chains_keep_the_posterior_at_beta_one():
    """On a correlated Gaussian, the cold chains of a 4-level ladder give its means within 4.5
    Monte Carlo standard errors (the se from the chains' own autocorrelation time; false-alarm
    rate about 1e-5 per check, 4 checks) and its variances within 10 %, and swaps are accepted."""
    rng = np.random.default_rng(1)
    chain, moves = _run(_gauss, 8, 4, 6000, 2, rng.standard_normal((8, 2)))
    flat = chain.reshape(-1, 2)
    tau = emcee.autocorr.integrated_time(chain, quiet=True)
    se = np.sqrt(np.array([1.0, 4.0]) * tau / flat.shape[0])
    assert np.all(np.abs(flat.mean(axis=0) - [1.0, -1.0]) < 4.5 * se), (flat.mean(axis=0), se)
    assert np.allclose(flat.var(axis=0), [1.0, 4.0], rtol=0.10), flat.var(axis=0)
    rates = swap_rates(moves)
    assert rates.shape == (3,) and np.all(rates > 0.2), rates


def test_tempering_finds_both_modes_with_their_weights():
    """Every chain starts in the heavier mode. Without tempering no chain ever leaves it (the
    barrier is 16 nats at beta 1): the lighter mode's weight comes out 0. With a 6-level ladder
    (beta down to 1/32, the barrier 0.5 nats there) the cold chains give the weight 0.3
    within 5 standard errors of its estimate (se from the mode indicator's autocorrelation time:
    false-alarm rate below 1e-6), and every cold chain visits both modes."""
    start = MODE + 0.3 * np.random.default_rng(3).standard_normal((8, 2))
    plain, _ = _run(_bimodal, 8, 1, 6000, 4, start)
    assert np.mean(plain.sum(axis=-1) < 0) == 0.0
    chain, moves = _run(_bimodal, 8, 6, 6000, 4, start)
    low = (chain.sum(axis=-1) < 0).astype(float)
    tau = emcee.autocorr.integrated_time(low[:, :, None], quiet=True)[0]
    se = np.sqrt(W_LOW * (1 - W_LOW) * tau / low.size)
    assert abs(low.mean() - W_LOW) < 5 * se, (low.mean(), se, tau)
    assert np.all(low.mean(axis=0) > 0.05) and np.all(low.mean(axis=0) < 0.95)
    assert np.all(swap_rates(moves) > 0.1)


def test_swaps_keep_coordinates_log_prob_and_blobs_together():
    """A swap moves a state's coordinates, log-posterior and blobs as one: after many steps every
    walker's stored log-posterior is still the target's at its coordinates."""
    start = MODE + 0.3 * np.random.default_rng(5).standard_normal((4, 2))
    betas = ladder(3, 0.3)
    moves = tempered_moves([(RandomWalkMove(np.eye(2) * 0.8), 1.0)], betas, 4, 1)
    s = emcee.EnsembleSampler(12, 2, _bimodal, vectorize=True, moves=moves)
    s.random_state = np.random.RandomState(6).get_state()
    s.run_mcmc(np.tile(start, (3, 1)), 300, progress=False)
    ch, lp, bl = s.get_chain(), s.get_log_prob(), s.get_blobs()
    again = _bimodal(ch.reshape(-1, 2))
    assert np.allclose(lp.ravel(), again[:, 0])
    assert np.allclose(bl.reshape(-1, 2)[:, 0], again[:, 1])
    assert isinstance(moves[0][0], TemperedMove) and moves[0][0].swaps[1].sum() > 0


def test_tempering_is_refused_where_it_cannot_run():
    from frictionuq.errors import InputError
    from frictionuq.infer.sampler import SamplerConfig
    with pytest.raises(InputError, match="temperatures > 1 needs stored_run"):
        SamplerConfig(temperatures=3, stored_run="ensemble")
    with pytest.raises(InputError, match="temper_ratio must be in"):
        SamplerConfig(temperatures=3, temper_ratio=1.5)
    with pytest.raises(InputError, match="temperatures must be an integer >= 1"):
        SamplerConfig(temperatures=0)


def test_the_report_names_the_tempered_copies():
    from frictionuq.report.sections.fits import _stored_run
    rec = {"config": {"sampler": {"stored_run": "chains", "temperatures": 4}}}
    assert _stored_run(rec, {"walkers": 16}) == (
        "16 independent chains (independence move and random walk), each with 3 tempered copies "
        "(parallel tempering; only the untempered chains are the posterior)")
    rec["config"]["sampler"]["temperatures"] = 1
    assert _stored_run(rec, {"walkers": 16}) == "16 independent chains (independence move and random walk)"
