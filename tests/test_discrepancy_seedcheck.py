"""`discover --check-seed` (frictionuq.discrepancy.seedcheck): the campaign screened again from
other random starts, and whether every seed names the same effects. The screening itself is
replaced by a stub that records its seeds and answers per seed (what the real screening finds
from other starts on the real 25 lb records is measured in docs/log-discrepancy.md)."""
from __future__ import annotations

import json
import re
from html import unescape

import pytest

from frictionuq.discrepancy import seedcheck
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.errors import InputError


def _round(named, gains=()):
    ranked = [{"effect": e, "elpd_gain": g, "map_gain": g + 1.0} for e, g in gains]
    return {"named": named, "reason": f"reason for {named}", "ranked": ranked,
            "baseline_effects": [], "levels": [{"id": "L", "models": {
                "baseline": {"rmse_map": 100.0, "map": {}}}}]}


def test_summarize_says_stable_only_when_every_seed_names_the_same():
    same = seedcheck.summarize(1, ["eccentricity"], [(2, [_round("eccentricity", [("eccentricity", 30.0)])])])
    assert same["stable"] and same["seeds"] == [1, 2]
    assert same["named_effects"] == [["eccentricity"], ["eccentricity"]]
    assert same["runs"][0]["candidates"] == [{"effect": "eccentricity", "elpd_gain": 30.0,
                                              "map_gain": 31.0}]
    assert "all name eccentricity" in seedcheck.sentence(same)
    differ = seedcheck.summarize(1, ["eccentricity"], [(2, [_round("none")]),
                                                       (3, [_round("eccentricity")])])
    assert not differ["stable"] and differ["named_effects"] == [["eccentricity"], [], ["eccentricity"]]
    s = seedcheck.sentence(differ)
    assert "depends on the searches' random starts" in s and "seed 2: none" in s, s
    # forward selection: the same first name but another second one is not the same answer
    two = seedcheck.summarize(1, ["chatter", "takeup_overshoot"],
                              [(2, [_round("chatter"), _round("reversal_hump")])])
    assert not two["stable"]


@pytest.fixture
def stubbed(tmp_path, monkeypatch):
    """discover with its screening, between-tests check and diagnostics replaced: the run's seed
    names nothing, seed 2 eccentricity, seed 3 nothing."""
    from frictionuq.discrepancy import discover as D
    calls = []

    def screen(specs, cfg, seed, *args, **kw):
        calls.append((seed, cfg.seed))
        return [_round("eccentricity", [("eccentricity", 40.0)]) if seed == 2 else _round("none")]

    monkeypatch.setattr(D, "_screen_rounds", screen)
    monkeypatch.setattr(D, "_between", lambda *a: None)
    monkeypatch.setattr(D, "level_gap", lambda *a, **kw: [])     # the CLI's diagnostics
    hidden_campaign(tmp_path / "c", "brfd", None, seed=11, short=True)
    return D, calls


def test_discover_screens_again_with_each_check_seed_and_reports_it(tmp_path, stubbed):
    D, calls = stubbed
    doc = D.discover(tmp_path / "c", tmp_path / "out", seed=1, refit=False, diagnostics=False,
                     check_seeds=(2, 3))
    # each check seed is a whole screening with its own starts (the config's seed too)
    assert calls == [(1, 1), (2, 2), (3, 3)]
    sc = doc["seed_check"]
    assert sc["seeds"] == [1, 2, 3] and sc["named_effects"] == [[], ["eccentricity"], []]
    assert not sc["stable"] and doc["named_effect"] == "none"   # the main seed's answer stands
    on_disk = json.loads((tmp_path / "out" / "discrepancy.json").read_text())
    assert on_disk["seed_check"] == sc
    from frictionuq.report import render_discrepancy_page
    html = unescape(render_discrepancy_page(tmp_path / "out").read_text())
    assert "Seed check: the name depends on the searches' random starts" in html
    assert "seed 2: eccentricity" in html
    # where the run's time went, in its provenance (discrepancy.json's seconds_by_stage)
    assert re.search(r"seed 1, in \d+ s \(screening \d+ s, refit 0 s, diagnostics 0 s\)\.", html), html
    # without check seeds: one screening, no seed_check
    calls.clear()
    doc = D.discover(tmp_path / "c", tmp_path / "out2", seed=1, refit=False, diagnostics=False)
    assert calls == [(1, 1)] and "seed_check" not in doc


@pytest.mark.parametrize("seeds", [(1,), (2, 2), (-1,)])
def test_bad_check_seeds_are_refused_before_any_work(tmp_path, stubbed, seeds):
    D, calls = stubbed
    with pytest.raises(InputError, match="check"):
        D.discover(tmp_path / "c", tmp_path / "out", seed=1, refit=False, check_seeds=seeds)
    assert calls == [] and not (tmp_path / "out").exists()


def test_cli_check_seed_prints_the_sentence(tmp_path, stubbed, capsys):
    from frictionuq.cli import main
    code = main(["discover", str(tmp_path / "c"), "--out", str(tmp_path / "out"), "--no-refit",
                 "--check-seed", "2", "--jobs", "1"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "Seed check: the name depends on the searches' random starts (seed 1: none; seed 2: " \
           "eccentricity)" in out
    code = main(["discover", str(tmp_path / "c"), "--out", str(tmp_path / "out"),
                 "--check-seed", "1"])
    assert code == 2 and "check seeds [1] must differ" in capsys.readouterr().err
