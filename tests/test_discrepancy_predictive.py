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



#: the baseline's MAP on the short BRFD campaign with a hidden stage2_nonlinear (seed 11) as
#: find_map returned it at f5a2177 (2026-11-28): d3 a hair below a 180-nat drop of the
#: log-posterior (a step of 1e-5 of its box up)
EDGE_MAP = {"fc_fwd": 22647.443836910785, "fc_bwd": 13390.65918307448,
            "fs_fwd": 20383.01280409676, "fs_bwd": 14071.535631261155,
            "v_s": 0.0009954442246377317, "sigma0": 5610622.401341649,
            "sigma1": 1925.3747833240045, "sigma2": 2239.3781360137145,
            "k2": 308493.39095160045, "d2": 0.0014715932836847335, "k3": 16193918.17628524,
            "d3": 0.0005809783137193793, "w": 0.0002017211399388869,
            "force_offset": 7.108931791993311}


def test_laplace_evidence_is_stable_next_to_a_drop(tmp_path):
    """Two points 3e-7 of d3's box apart, log-posteriors 0.00005 nats apart (EDGE_MAP and its
    local refit, fits.refit), must have Laplace evidences within 1 nat. With the one-sided
    Jacobian of before (step 1e-6 of each box, up) they differed by 13 nats (-22,345.4 and
    -22,358.4): the refit point's step in d3 crosses the drop (jump / step read as a slope),
    EDGE_MAP's does not. The held-out score of every unit moved with it: the short
    stage2_nonlinear campaign of seed 11 was named (+48.8 nats) or not (+11.7) by where the MAP
    search stopped. log_evidence now steps each parameter both ways and keeps the smaller slope
    (gauss_newton_cov's ignore_jumps): -22,345.42 at both (measured 2026-11-28). The check that
    the old Jacobian does differ keeps the case a real drop. Deterministic, about 30 s."""
    hidden_campaign(tmp_path / "c", "brfd", "stage2_nonlinear", seed=11, short=True)
    tests = list(load_campaign(tmp_path / "c").tests)
    lp, _ = fits.logpost_for(tests, (), FitConfig(samples_per_cycle=100))
    sp = lp.space
    th = sp.to_theta(EDGE_MAP)
    i = sp.names.index("d3")
    up = th.copy()
    up[i] += 1e-5 * (sp.hi[i] - sp.lo[i])
    assert fits.log_prob(lp, up) < fits.log_prob(lp, th) - 100       # the case is at a drop
    th_r = fits.refit(lp, th)
    assert np.max(np.abs(th_r - th) / (sp.hi - sp.lo)) < 1e-5
    assert abs(fits.log_prob(lp, th_r) - fits.log_prob(lp, th)) < 0.01
    ev, ev_r = log_evidence(lp, th), log_evidence(lp, th_r)
    print(f"Laplace evidence {ev:.2f} at EDGE_MAP, {ev_r:.2f} at its refit")
    assert abs(ev - ev_r) < 1.0

    def one_sided(t):     # the evidence with the Jacobian of before: the step crosses the drop
        return fits.log_prob(lp, t) + 0.5 * np.linalg.slogdet(gauss_newton_cov(lp, t))[1]
    assert abs(one_sided(th) - one_sided(th_r)) > 5.0
    assert abs(one_sided(th) - ev) < 1.0        # where no step crosses it, the two agree
