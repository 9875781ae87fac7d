"""discrepancy/truthfit.py: the baseline plus the hidden effects fitted from the generating
values of a hidden-effect campaign, the in-sample evidence the campaign carries (a tool for
judging the hidden-effect set; discover never sees the answer)."""
from __future__ import annotations

import numpy as np
import pytest

from frictionuq import published as pub
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits as F, rule
from frictionuq.discrepancy.hidden import LEVEL, hidden_campaign
from frictionuq.discrepancy.truthfit import generating_theta, truth_fit_gain
from frictionuq.infer.fit import FitConfig

PSI = 6894.757293168


@pytest.mark.parametrize("device", ["brfd", "mfd"])
def test_the_answer_keeps_the_3_stage_parameters_it_simulated_with(tmp_path, device):
    ans = hidden_campaign(tmp_path / "c", device, "stage2_nonlinear", seed=12, short=True)
    a_si = LEVEL[device] * (1.0 if device == "brfd" else PSI)
    assert ans["model_parameters"] == pub.published_params(device, a_si)


def test_the_start_takes_the_answer_first_the_baseline_for_the_rest(tmp_path):
    """generating_theta: the answer's values where it has them, the baseline's MAP elsewhere,
    clipped into the prior box in sampling coordinates (fs_* are bounded as ratios to fc_*)."""
    hidden_campaign(tmp_path / "c", "brfd", None, seed=12, short=True)
    tests = list(load_campaign(tmp_path / "c").tests)
    lp, _ = F.logpost_for(tests, ("stage2_nonlinear",), FitConfig(samples_per_cycle=100))
    sp = lp.space
    base = dict(zip(sp.names, sp.to_values(0.5 * (sp.lo + sp.hi))))     # mid-box
    base["force_offset"] = 12.5
    hi = sp.priors["p2"].upper
    ans = {"model_parameters": {"fc_fwd": 21000.0, "fs_fwd": 22000.0, "k2": 4e5, "other": 3.0},
           "effects": {"stage2_nonlinear": {"p2": 10 * hi}}}
    v = dict(zip(sp.names, sp.to_values(generating_theta(sp, ans, base))))
    assert list(v) == list(sp.names)
    for n, want in [("fc_fwd", 21000.0), ("fs_fwd", 22000.0), ("k2", 4e5), ("force_offset", 12.5),
                    ("sigma0", base["sigma0"])]:
        assert v[n] == pytest.approx(want, rel=1e-12), n
    assert hi * (1 - 1e-5) < v["p2"] < hi        # clipped inside the prior box
    assert np.isfinite(F.log_prob(lp, sp.to_theta(v)))
    ans["model_parameters"]["fs_fwd"] = 2.0 * 21000.0     # fs/fc above the ratio's bound 1.35
    v = dict(zip(sp.names, sp.to_values(generating_theta(sp, ans, base))))
    assert 1.34 * 21000.0 < v["fs_fwd"] < sp.priors["fs_fwd"].upper * 21000.0
    del base["force_offset"]
    with pytest.raises(KeyError, match="force_offset"):
        generating_theta(sp, ans, base)
    with pytest.raises(KeyError, match="model_parameters"):
        truth_fit_gain(tests, FitConfig(), {"effects": {}}, base, 0.0)


@pytest.mark.slow
def test_the_truth_fit_carries_the_evidence_of_a_strong_hidden_effect(tmp_path):
    """The BRFD campaign of the CI's stage2_nonlinear case (seed 12, p2 2.97; discover names it
    with +16.3 nats in-sample): from the generating values the curved stage 2 gains more than the
    rule's threshold over the baseline's MAP (found as the screening finds it), with p2 curved
    (over 1.5). Deterministic; about 15 s."""
    from frictionuq.infer.optimize import find_map
    ans = hidden_campaign(tmp_path / "c", "brfd", "stage2_nonlinear", seed=12, short=True)
    tests = list(load_campaign(tmp_path / "c").tests)
    cfg = FitConfig(samples_per_cycle=100)
    lp0, scales = F.logpost_for(tests, (), cfg)
    th_b, lp_b, _ = find_map(lp0, scales, np.random.default_rng([1, 17, 0]), n_random=1, n_prior=1)
    o = truth_fit_gain(tests, cfg, ans, F.values(lp0.space, th_b), lp_b)
    print(f"truth fit {o['gain']:+.2f} nats over the baseline's MAP, p2 {o['map']['p2']:.3f}")
    assert o["effects"] == ["stage2_nonlinear"]
    assert o["gain"] > rule.min_gain("stage2_nonlinear")
    assert o["map"]["p2"] > 1.5
