"""discover's between-tests check (frictionuq.discrepancy.discover._between: infer.between at the
baseline's MAP) on seeded campaigns whose tests carry load-cell zeros of their own
(hidden.hidden_campaign(zeros=True)), and the generator of those zeros."""
from __future__ import annotations

import json

import numpy as np
import pytest

from frictionuq import published as pub
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy.discover import discover
from frictionuq.discrepancy.hidden import ZERO_MIN_RANGE, ZERO_REL, draw_zeros, hidden_campaign
from frictionuq.infer.fit import FitConfig
from frictionuq.report import render_discrepancy_page


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory):
    d = tmp_path_factory.mktemp("zeros")
    ans = hidden_campaign(d / "z", "brfd", None, seed=11, short=True, zeros=True)
    clean = hidden_campaign(d / "c", "brfd", None, seed=11, short=True)
    return d, ans, clean


def test_zeros_are_the_clean_campaign_plus_a_constant_per_test(campaigns):
    """The same seed with and without zeros: the same force records but for each test's constant
    (drawn from a stream of their own), inside +-ZERO_REL of Fc, their range at least
    ZERO_MIN_RANGE of Fc."""
    d, ans, clean = campaigns
    p = pub.published_params("brfd", ans["applied"])
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    zeros = ans["test_zeros"]
    assert "test_zeros" not in clean and ans["effect"] == "none" and ans["effects"] == {}
    zc, cc = load_campaign(d / "z"), load_campaign(d / "c")
    assert sorted(zeros) == sorted(f"force_offset[{t.id}]" for t in zc.tests)
    for tz, tcl in zip(zc.tests, cc.tests):
        diff = tz.record.force - tcl.record.force
        assert np.ptp(diff) < 1e-5
        assert diff.mean() == pytest.approx(zeros[f"force_offset[{tz.id}]"], abs=1e-5)
        assert abs(diff.mean()) <= ZERO_REL * fc
    assert np.ptp(list(zeros.values())) >= ZERO_MIN_RANGE * fc
    z = draw_zeros(["a", "b"], 1000.0, np.random.default_rng(3))
    assert np.ptp(list(z.values())) >= ZERO_MIN_RANGE * 1000.0


@pytest.mark.slow
def test_discover_says_when_the_tests_do_not_share_a_zero(campaigns):
    """The baseline alone (no candidate: the check needs only its MAP). With the zeros (spread
    over 999 N, 5.5 noise sds): significant at 1 %, and each test's mean residual about the
    shared zero is its drawn zero's departure from their precision-weighted mean, within 4 of
    the check's own standard errors (a shift common to the zeros trades with the friction
    asymmetry, so only the departures are determined). The same seed without them: not
    significant (the check's false-alarm rate is ALPHA = 1 % when its noise model holds,
    tests/test_infer_between.py; this seeded case either always passes or always fails). The
    report says both."""
    d, ans, _ = campaigns
    cfg = FitConfig(samples_per_cycle=100)
    out = {}
    for name in ("z", "c"):
        discover(d / name, d / f"out-{name}", cfg, seed=1, effects=(), refit=False,
                 diagnostics=False)
        out[name] = json.loads((d / f"out-{name}" / "discrepancy.json").read_text())
    bz, bc = out["z"]["between_tests"][0], out["c"]["between_tests"][0]
    assert bz["significant"] and bz["p_value"] < 1e-6 and bz["df"] == 2, bz
    assert not bc["significant"], bc
    m, se = bz["mean_residual_N"], bz["se_N"]
    w = {t: 1.0 / se[t] ** 2 for t in se}
    zeros = {t: ans["test_zeros"][f"force_offset[{t}]"] for t in se}
    zw = sum(w[t] * zeros[t] for t in se) / sum(w.values())
    mw = sum(w[t] * m[t] for t in se) / sum(w.values())
    for t in se:
        assert abs((m[t] - mw) - (zeros[t] - zw)) <= 4 * se[t], (t, m[t] - mw, zeros[t] - zw, se[t])
    page = render_discrepancy_page(d / "out-z").read_text()
    assert "the tests do not share one force zero" in page and "--force-offset per_test" in page
    assert "share one force zero within the noise" in render_discrepancy_page(d / "out-c").read_text()
