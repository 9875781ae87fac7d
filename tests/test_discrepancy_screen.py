"""Effect screening and naming (frictionuq.discrepancy.screen, discover, hidden): the decision
rule on constructed gains, the hidden-effect campaign generator, and the workflow on seeded
hidden-effect campaigns (one effect hidden; none hidden)."""
from __future__ import annotations

import json


import pytest

from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import screen
from frictionuq.discrepancy.hidden import hidden_campaign


def _row(effect, gains, n_params=2):
    import numpy as np
    from frictionuq.infer.compare import elpd_total
    t = elpd_total(gains)
    return {"effect": effect, "elpd_gain": t["elpd"], "elpd_gain_se": t["se"],
            "gain_per_unit": list(gains), "min_unit_gain": float(np.min(gains)),
            "n_params": n_params, "rmse_map": 1.0}


def test_decision_rule():
    # a clear winner improving every held-out test
    name, why = screen.decide([_row("reversal_hump", [900.0, 4000.0, 16000.0]),
                               _row("eccentricity", [50.0, -20.0, 3000.0], 3)])
    assert name == "reversal_hump" and "every held-out unit" in why
    # a large total carried by one test while another gets worse: not named
    name, why = screen.decide([_row("thermal_fade", [5000.0, -30.0, 10.0])])
    assert name == "none" and "thermal_fade" in why
    # small gains everywhere (a parameter fitted to noise): not named
    assert screen.decide([_row("rate_strengthening", [3.0, 4.0, 2.0])])[0] == "none"
    # two candidates within 2 SE of each other: the one with fewer parameters
    name, why = screen.decide([_row("eccentricity", [110.0, 210.0, 300.0], 3),
                               _row("reversal_hump", [100.0, 220.0, 280.0], 2)])
    assert name == "reversal_hump" and "fewer parameters" in why
    # with 5+ units the SE counts too: a gain carried by one unit is not enough
    assert screen.decide([_row("thermal_fade", [120.0, 110.0, 130.0, 125.0, 115.0])])[0] == "thermal_fade"
    assert screen.decide([_row("thermal_fade", [400.0, 6.0, 6.0, 7.0, 10.0])])[0] == "none"
    assert screen.decide([])[0] == "none"


def test_hidden_campaign_keeps_its_answer_out(tmp_path):
    ans = hidden_campaign(tmp_path / "c", "brfd", "eccentricity", seed=3, short=True,
                          answer_path=tmp_path / "answer.json")
    assert ans["effect"] == "eccentricity" and set(ans["parameters"]) == {"eps_ecc", "l_ecc", "psi_ecc"}
    files = {p.name for p in (tmp_path / "c").rglob("*")}
    assert "answer.json" not in files and not any("eccentricity" in f for f in files)
    text = (tmp_path / "c" / "campaign.toml").read_text()
    assert "eccentricity" not in text and "eps_ecc" not in text
    camp = load_campaign(tmp_path / "c")
    assert [t.kind for t in camp.tests] == ["harmonic", "harmonic", "earthquake"]
    assert json.loads((tmp_path / "answer.json").read_text())["parameters"] == ans["parameters"]
    again = hidden_campaign(tmp_path / "d", "brfd", "eccentricity", seed=3, short=True)
    assert again["parameters"] == ans["parameters"]           # seeded
    assert (tmp_path / "c" / "tests" / "h-0.2Hz.csv").read_bytes() == \
        (tmp_path / "d" / "tests" / "h-0.2Hz.csv").read_bytes()
    mfd = hidden_campaign(tmp_path / "m", "mfd", None, seed=1, short=True)
    assert mfd["effect"] == "none" and load_campaign(tmp_path / "m").applied_si_unit == "Pa"


@pytest.mark.slow
@pytest.mark.parametrize("device, effect, seed", [("brfd", "reversal_hump", 7), ("brfd", None, 7)])
def test_discover_names_the_hidden_effect_or_none(tmp_path, device, effect, seed):
    """A short 3-test campaign (two harmonics, a Kobe replay) with one hidden effect at random
    realistic parameters, or none: the screening names it, or says none. Fixed seeds; the
    false-alarm guard is the decision rule (every held-out test must gain > 5 nats); the larger
    set (every effect, both devices, refits) is benchmarks/bench_discover.py."""
    from frictionuq.discrepancy.discover import discover
    from frictionuq.infer.fit import FitConfig
    ans = hidden_campaign(tmp_path / "c", device, effect, seed=seed, short=True)
    d = discover(tmp_path / "c", tmp_path / "out", FitConfig(samples_per_cycle=100), seed=1,
                 refit=False)
    assert d["named_effect"] == ans["effect"], (d["reason"], d["candidates"])
    doc = json.loads((tmp_path / "out" / "discrepancy.json").read_text())
    assert doc["named_effect"] == ans["effect"] and doc["package_version"]
    assert {c["effect"] for c in doc["candidates"]} >= {"reversal_hump", "eccentricity", "thermal_fade",
                                                        "rate_strengthening", "stage2_nonlinear"}
    if effect:
        assert doc["rmse_after"] < doc["rmse_before"]
