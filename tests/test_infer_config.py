"""FitConfig (frictionuq.infer.config): a bad field is refused at construction with a one-line
InputError naming it, before any folder is made; the forms a notebook user writes are taken
(one name as a string, the --prior text form, a dict for the sampler). Deterministic."""
import pytest

from frictionuq.errors import InputError
from frictionuq.infer.config import FitConfig
from frictionuq.infer.sampler import SamplerConfig


@pytest.mark.parametrize("kw, message", [
    (dict(samples_per_cycle=-5), "samples_per_cycle must be a number > 0"),
    (dict(eps="automatic"), "eps must be 'auto' or a dead band in m >= 0"),
    (dict(eps=-1.0), "eps must be 'auto'"),
    (dict(likelihood="AR1"), "likelihood must be one of iid, ar1, arma"),
    (dict(model="maxwell"), "unknown model 'maxwell'"),
    (dict(effects="chater"), "unknown effect 'chater'"),
    (dict(model="lugre", effects=("stage2_nonlinear",)), "needs model 'three_stage'"),
    (dict(seed=-1), "seed must be an integer from 0 to 9223372036854775807, got -1"),
    (dict(seed=2**63), "seed must be an integer from 0 to 9223372036854775807, got 9223"),
    (dict(sampler="fast"), "sampler must be a SamplerConfig"),
    (dict(sampler={"max_steps": 0}), "max_steps must be an integer >= 1"),
    (dict(tests=[1, 2]), "tests must be a list of names"),
    (dict(priors={"fc_fwd": "uniform:100"}), "uniform takes 2 numbers"),
    (dict(priors=3.0), "priors must be a dict"),
    (dict(simulate_at="fine"), "simulate_at must be one of raw, kept"),
    (dict(n_predictive=-1), "n_predictive must be an integer >= 0"),
    (dict(priors={"sigma0": "uniform:1e6:1e5"}), "need 1 <= lower < upper"),
    (dict(priors={"sigma0": {"dist": "weird", "lower": 0, "upper": 1}}), "unknown dist 'weird'"),
    (dict(priors={"sigma0": float("nan")}), "nan is not finite"),
    (dict(priors={"sigma00": 1.0}), "unknown parameter 'sigma00'"),
    (dict(tests=[]), "tests is empty"),
    # a new user's trial (2026-12-05): each was taken, and a value nobody gave used
    (dict(priors={"sigma0": {"dist": "normal", "mu": 1e5}}), "a normal prior needs both mu and sd"),
    (dict(effects={"thermal_fade": {"kappa": 0.3}}), "effects takes names, got values too"),
    (dict(sampler={"max_step": 3}), "sampler: unknown field 'max_step'"),
])
def test_a_bad_field_is_refused_at_construction(kw, message):
    with pytest.raises(InputError, match=message) as e:
        FitConfig(**kw)
    assert "\n" not in str(e.value)


def test_the_forms_a_notebook_user_writes_are_taken():
    c = FitConfig(tests="sine-1Hz-36lb-1in", effects="chatter", kinds="harmonic",
                  priors={"b_ch": "uniform:0:1", "sigma1": 500.0}, sampler={"max_steps": 300})
    assert c.tests == ("sine-1Hz-36lb-1in",) and c.effects == ("chatter",)
    assert c.kinds == ("harmonic",)
    assert c.priors == {"b_ch": {"dist": "uniform", "lower": 0.0, "upper": 1.0}, "sigma1": 500.0}
    assert isinstance(c.sampler, SamplerConfig) and c.sampler.max_steps == 300
    assert FitConfig(priors=["b_ch=uniform:0:1"]).priors == {"b_ch": {"dist": "uniform",
                                                                      "lower": 0.0, "upper": 1.0}}
    # the JSON a fit records is the same as with the canonical forms
    assert c.to_json() == FitConfig(tests=("sine-1Hz-36lb-1in",), effects=("chatter",),
                                    kinds=("harmonic",),
                                    priors={"b_ch": {"dist": "uniform", "lower": 0.0, "upper": 1.0},
                                            "sigma1": 500.0},
                                    sampler=SamplerConfig(max_steps=300)).to_json()


def test_library_calls_refuse_before_any_work(tmp_path):
    """discover's candidate names and validate's test list are checked before a campaign is
    read (a misspelt effect failed after ~55 s of fitting; validate with no test wrote an empty
    validation.json)."""
    from frictionuq.discrepancy.discover import discover
    from frictionuq.validate import validate
    with pytest.raises(InputError, match="unknown effect 'chater'"):
        discover(tmp_path / "no-such-campaign", tmp_path / "out", effects=("chater",))
    with pytest.raises(InputError, match="no test given"):
        validate(tmp_path / "fit", tmp_path / "camp", [], tmp_path / "v")
    assert not (tmp_path / "out").exists() and not (tmp_path / "v").exists()


def test_the_reversal_rule_reaches_the_records():
    """FitConfig(reversal="extreme") reaches each FitRecord (the likelihood passes the record's
    rule to simulate_batch); with the record's eps and rule a clean sine's force is that of
    eps = 0, as test_kernel's test of the rule shows for simulate."""
    import numpy as np
    from frictionuq import published
    from frictionuq.infer.likelihood import prepare_record
    from frictionuq.model import simulate
    with pytest.raises(InputError, match="reversal must be one of detection, extreme"):
        FitConfig(reversal="late")
    assert FitConfig().reversal == "extreme"           # the default (docs/model-choices.md)
    assert FitConfig(reversal="detection").record_options()["reversal"] == "detection"
    opts = FitConfig(reversal="extreme", drive_lowpass="off").record_options()
    assert opts["reversal"] == "extreme"
    p = published.brfd_params(133.0)
    t = np.arange(0, 4, 1 / 256)
    x = 0.025 * np.sin(2 * np.pi * 0.5 * t)
    y = simulate(t, x, p)
    opts = {**opts, "eps": 2e-5, "samples_per_cycle": 512}
    rec = prepare_record("h", t, x, y, **opts)
    assert rec.reversal == "extreme" and rec.eps == 2e-5 and rec.q == 1
    from frictionuq.model import simulate_batch, pack_batch
    F = simulate_batch(rec.drive, None, pack_batch([p]), eps=rec.eps, reversal=rec.reversal)[0]
    np.testing.assert_array_equal(F, y)
