"""The screening's held-out score (frictionuq.discrepancy.predictive): the ratio of Laplace
evidences log Z(train + held) - log Z(train) against brute-force Monte Carlo of the held-out
likelihood over the training fit's Gaussian approximation, on a held-out block that informs the
parameters enough for the Occam factor to matter and little enough for Monte Carlo to have a
usable effective sample size (there the two must agree)."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp

from frictionuq import published as pub
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits, screen
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.discrepancy.predictive import log_evidence
from frictionuq.infer.fit import FitConfig, plan
from frictionuq.infer.likelihood import LogPosterior, records_from_tests
from frictionuq.infer.localfit import clip_in, gauss_newton_cov


@pytest.mark.slow
def test_evidence_ratio_matches_monte_carlo(tmp_path):
    # the CI campaign of before 2026-11-25 (night), whose Kobe replay is its first 20 s. On the
    # strong-motion window (hidden.strong_motion), split into 2, 3, 4, 5, 6 or 8 blocks, the two
    # agree within 1 nat on 14 of the 16 blocks where Monte Carlo's ESS is above 200, and differ
    # by 1.4 and 1.9 nats on the other two (docs/log-discrepancy.md)
    ans = hidden_campaign(tmp_path / "c", "brfd", None, seed=3, short=True, eq_seconds=20.0,
                          eq_from="start")
    cfg = FitConfig(samples_per_cycle=100)
    tests = plan(load_campaign(tmp_path / "c"), "applied", cfg)[0].tests
    assert [t.id for t in tests] == ["h-0.2Hz", "h-0.5Hz", "eq-kobe"]
    lp_all, _ = fits.logpost_for(tests, (), cfg)
    sp = lp_all.space
    held = records_from_tests([screen.blocks(tests[2], 2)[1]], samples_per_cycle=100, eps=cfg.eps,
                              simulate_at=cfg.simulate_at)          # the Kobe replay's second half
    lp_tr = LogPosterior(sp, lp_all.records[:2])                   # trained on the two harmonics
    lp_joint = LogPosterior(sp, lp_all.records[:2] + held)
    truth = pub.published_params("brfd", ans["applied"])
    th_tr = fits.refit(lp_tr, sp.to_theta({n: truth.get(n, 0.0) for n in sp.names}))
    th_joint = fits.refit(lp_joint, th_tr)
    score = log_evidence(lp_joint, th_joint) - log_evidence(lp_tr, th_tr)
    heights = fits.log_prob(lp_joint, th_joint) - fits.log_prob(lp_tr, th_tr)
    assert heights - score > 1.0, (heights, score)     # the Occam factor matters here (1.18)

    draws = th_tr + np.random.default_rng(0).standard_normal((40_000, sp.ndim)) @ \
        np.linalg.cholesky(gauss_newton_cov(lp_tr, th_tr)).T
    ll = LogPosterior(sp, held).loglik_records(clip_in(sp, draws)).sum(axis=1)
    w = np.exp(ll - ll.max())
    assert w.sum() ** 2 / np.sum(w**2) > 200, "Monte Carlo's effective sample size too small"
    mc = float(logsumexp(ll) - np.log(ll.size))
    # measured: evidence ratio -5782.87, Monte Carlo -5783.50 (ESS 452); the heights alone
    # (no Occam factor) -5781.69 are 1.81 off, and so would be a log det term of twice its size
    assert abs(score - mc) < 1.0, (score, mc, heights)
