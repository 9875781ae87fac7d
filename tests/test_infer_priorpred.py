"""Prior predictive check (frictionuq.infer.priorpred): the default priors cover real and twin
records; a prior that excludes the data is caught."""
import pytest

from frictionuq.campaign import load_campaign
from frictionuq.infer import fit as F
from frictionuq.infer.priorpred import outside, prior_predictive


def _logpost(path, test_id, priors=None):
    camp = load_campaign(path)
    spec = F.plan(camp, "test", F.FitConfig(tests=(test_id,), priors=priors or {}))[0]
    return F.prepare(spec)[3]


@pytest.mark.parametrize("path,test_id", [("data/brfd-twin", "h-267N-0.5Hz"),
                                          ("data/mfd-twin", "h-500psi-0.05Hz"),
                                          ("data/brfd-arts-d2", "sine-1Hz-36lb-1in"),
                                          ("data/brfd-arts-d1", None)])
def test_default_priors_cover_the_data(path, test_id):
    test_id = test_id or load_campaign(path).tests[0].id
    r = prior_predictive(_logpost(path, test_id), n=200, seed=0)
    rec = r["records"][test_id]
    assert rec["non_finite_draws"] == 0
    assert r["passed"], rec
    assert outside(r) == []
    # and the priors are not absurdly wide: the measured peak is not in the extreme percent
    assert 0.02 < rec["peak_N"]["quantile_of_measured"] < 0.98


def test_a_prior_that_excludes_the_data_fails():
    # friction forces confined to 1-10 N on a 39 kN record: no prior draw reaches the data
    bad = {"fc_fwd": {"dist": "loguniform", "lower": 1.0, "upper": 10.0},
           "fc_bwd": {"dist": "loguniform", "lower": 1.0, "upper": 10.0}}
    r = prior_predictive(_logpost("data/brfd-twin", "h-267N-0.5Hz", bad), n=200, seed=0)
    assert not r["passed"]
    # the fit's log line names the figures that failed (it read as the rule itself before)
    said = outside(r)
    assert said and all(p.startswith("test h-267N-0.5Hz: ") for p in said), said
    assert any("peak" in p and "above the prior predictive's q99" in p and p.endswith(" kN")
               for p in said), said
