"""The discrepancy workflow end to end (frictionuq.discrepancy.discover and `frictionuq
discover`) on seeded hidden-effect campaigns: one effect hidden, or none (the check itself:
tests/discover_check.py). Slow tests, in their own file so that pytest-xdist (--dist loadfile)
runs them beside the other slow files; the refit and forward-selection cases are in
test_discrepancy_discover_rounds.py, on the other worker."""
from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from discover_check import check_discover
from frictionuq.discrepancy.hidden import hidden_campaign


@pytest.mark.slow
@pytest.mark.parametrize("device, effect, seed", [
    ("brfd", None, 7),
    ("brfd", None, 12),     # a false alarm before the rule's in-sample condition (e)
    # the effects beyond the spec (opt-in candidates). ("mfd", "takeup_overshoot", 7), here since
    # 2026-11-23, left CI on 2026-12-06 for the suite's time (175 s, the second slowest case of
    # this file): takeup_overshoot has its CI case in test_discrepancy_discover_rounds.py (BRFD,
    # named in round 1 with chatter hidden too), the MFD its thermal_fade refit there; this one
    # runs in the benchmark, `benchmarks/bench_discover.py --devices mfd --effects
    # takeup_overshoot --extra-effects takeup_overshoot --seeds 7` (the CI's configuration)
    ("brfd", "speed_weakening", 11),
    # ("brfd", "stage2_nonlinear", 11) was here until 2026-11-28: a favourable draw (named in 2 of
    # 18 short campaigns), and named or not by a 13-nat error of the Laplace evidence next to a
    # drop of the log-posterior in d3 (+48.8 or +11.7 nats held out with the same MAP height).
    # The evidence is mended (test_discrepancy_predictive.py::
    # test_laplace_evidence_is_stable_next_to_a_drop; the case is named again, +38.8 +- 8.1 nats,
    # 400 s), and it stays out of CI for time: a favourable draw shows little that the two tests
    # of its pieces do not. The candidate search that names it on the full-length campaign:
    # test_discrepancy_screen.py::test_candidate_search_starts_from_the_baselines_global_searches
    # Seed 12 since 2026-12-04 (night), a typical draw (p2 2.97; +15.1 nats held out, -1.0 / 6.8
    # / 9.3, near the hidden campaigns' median), named by the regular effects' threshold
    # (rule.min_gain) where MIN_GAIN and the per-unit spread refused it
    ("brfd", "stage2_nonlinear", 12),
])
def test_discover_names_the_hidden_effect_or_none(tmp_path, device, effect, seed):
    """One effect hidden, or none, screened without a refit: named, or none (check_discover)."""
    check_discover(tmp_path, device, effect, seed, refit=False)


def test_cli_discover_refuses_bad_input(tmp_path, capsys):
    from frictionuq.cli import main
    code = main(["discover", str(tmp_path / "no-such-campaign"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "no-such-campaign" in err, err
    assert not (tmp_path / "out" / "discrepancy.json").exists()


@pytest.mark.parametrize("command", ["discover", "predict", "validate", "ingest"])
def test_an_earlier_output_holding_a_users_file_is_not_replaced(tmp_path, capsys, command):
    """Rerunning into an earlier output folder replaces it whole; one that also holds a file the
    user put there is refused before any work, the file kept (before: deleted without a word)."""
    from frictionuq.cli import main
    twin = str(Path(__file__).resolve().parents[1] / "data" / "brfd-twin")
    out = tmp_path / "out"
    out.mkdir()
    marker = {"discover": "discrepancy.json", "predict": "prediction.json",
              "validate": "validation.json", "ingest": "manifest.json"}[command]
    (out / marker).write_text("{}")
    (out / "notes.txt").write_text("mine")
    argv = {"discover": ["discover", twin, "--out", str(out)],
            "predict": ["predict", str(tmp_path), "--harmonic", "0.01,0.5", "--applied", "1",
                        "--out", str(out)],
            "validate": ["validate", str(tmp_path), twin, "--test", "h-35N-0.5Hz", "--out", str(out)],
            "ingest": ["ingest", twin, "--out", str(out)]}[command]
    if command in ("predict", "validate"):          # a fit folder to read: refused before it
        (tmp_path / "summary.json").write_text(json.dumps(
            {"campaign": "brfd-twin", "fits": [{"id": "applied-35N", "applied": 35.0,
                                                "tests": ["h-35N-0.5Hz"], "converged": True}]}))
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "that also holds notes.txt, which frictionuq did not write" in err, err
    assert (out / "notes.txt").read_text() == "mine"


@pytest.mark.slow
def test_cli_discover_on_a_clean_mfd_campaign(tmp_path, capsys):
    """`frictionuq discover` end to end on a clean short MFD campaign: says none, prints the
    candidates, writes discrepancy.json and the report page."""
    from frictionuq.cli import main
    hidden_campaign(tmp_path / "c", "mfd", None, seed=11, short=True)
    code = main(["discover", str(tmp_path / "c"), "--out", str(tmp_path / "out"), "--no-refit"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "named effect: none" in out and "report.html" in out
    assert re.search(r"^time: \d+ s \(screening \d+ s, refit 0 s, diagnostics \d+ s\)$", out, re.M), out
    doc = json.loads((tmp_path / "out" / "discrepancy.json").read_text())
    assert doc["named_effect"] == "none" and doc["config"]["samples_per_cycle"]
    assert doc["alternatives"] == [] and doc["environment"]["numba_cpu"]
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Named effect: none" in html and "frictionuq" in html and "seed 1" in html
    # each candidate's threshold (rule.min_gain): lower for an effect whose null is regular
    needs = {c["effect"]: c["min_gain"] for c in doc["candidates"]}
    assert needs["eccentricity"] == 20.0 and 5.0 < needs["stage2_nonlinear"] < 5.5, needs
    assert "needs (nats)" in out and "gain the rule asks" in html
    # the level's tests taken together (combine.py): in the document and on the page
    assert [c["model"] for c in doc["combined_diagnostics"]] == ["baseline"]
    assert "tests combined" in html


def test_discover_screens_a_noise_effect_on_records_that_keep_its_band(tmp_path, monkeypatch):
    """With chatter among the candidates every model of the screening (the baseline included)
    sees records kept at NOISE_EFFECT_MIN_KEPT_HZ or more (the same records for all, so their
    scores compare); without it the decimation is the config's. The screening itself is
    replaced by a stub that records what it was given."""
    from frictionuq.discrepancy import discover as D
    from frictionuq.infer.fit import FitConfig
    from frictionuq.infer.likelihood import records_from_tests

    class Stop(Exception):
        pass

    seen = {}

    def stub(specs, cfg, *args, **kw):
        seen["floor"] = cfg.min_kept_hz
        seen["q"] = [r.q for r in records_from_tests(specs[0].tests, **cfg.record_options())]
        raise Stop

    monkeypatch.setattr(D, "_screen_rounds", stub)
    hidden_campaign(tmp_path / "c", "brfd", None, seed=11, short=True)
    for extra, floor, q in (((), None, [5, 2, 1]), (("chatter",), 50.0, [2, 2, 1])):
        with pytest.raises(Stop):
            D.discover(tmp_path / "c", tmp_path / "out", FitConfig(samples_per_cycle=100),
                       extra_effects=extra)
        assert seen == {"floor": floor, "q": q}, (extra, seen)


def test_discover_replaces_its_output_folder_as_a_whole(tmp_path, monkeypatch):
    """--out: the campaign folder (or one holding it) and a foreign non-empty folder are refused;
    a previous run's folder is replaced once the new run is complete, so no earlier refit/ stays
    beside the new document, and a failed run leaves it as it was. The run itself is a stub that
    writes what the given folder receives."""
    from frictionuq.discrepancy import discover as D
    from frictionuq.errors import InputError
    camp = tmp_path / "c"
    hidden_campaign(camp, "brfd", None, seed=11, short=True)
    with pytest.raises(InputError, match="must differ from the campaign folder"):
        D.discover(camp, camp)
    with pytest.raises(InputError, match="must differ from the campaign folder"):
        D.discover(camp, tmp_path)
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep")
    with pytest.raises(InputError, match="is not a `frictionuq discover` output folder"):
        D.discover(camp, tmp_path / "mine")
    assert (tmp_path / "mine" / "notes.txt").read_text() == "keep"

    def stub(campaign_path, out, *args):
        (out / "discrepancy.json").write_text(json.dumps({"run": "new"}))
        return {"run": "new"}

    out = tmp_path / "out"
    (out / "refit" / "applied-66N").mkdir(parents=True)
    (out / "discrepancy.json").write_text(json.dumps({"run": "old"}))
    monkeypatch.setattr(D, "_run", stub)
    assert D.discover(camp, out) == {"run": "new"}
    assert sorted(p.name for p in out.iterdir()) == ["discrepancy.json"]

    def boom(campaign_path, out, *args):
        (out / "discrepancy.json").write_text("half")
        raise RuntimeError("interrupted")

    (out / "refit").mkdir()
    monkeypatch.setattr(D, "_run", boom)
    with pytest.raises(RuntimeError):
        D.discover(camp, out)
    assert json.loads((out / "discrepancy.json").read_text()) == {"run": "new"}
    assert (out / "refit").is_dir()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


def test_the_library_takes_the_configs_seed_and_a_campaign_object(tmp_path, monkeypatch):
    """discover(..., FitConfig(seed=5)) runs with seed 5 (before: the keyword's default 1 won
    silently); two different seeds are refused; a loaded Campaign is accepted as fit_campaign
    accepts one (before: a TypeError from pathlib). The work itself is stubbed."""
    from frictionuq.campaign import load_campaign
    from frictionuq.discrepancy import discover as D
    from frictionuq.errors import InputError
    from frictionuq.infer.fit import FitConfig
    seen = {}

    def fake_run(campaign_path, out_dir, cfg, seed, *rest):
        seen.update(path=campaign_path, seed=seed, cfg_seed=cfg.seed, camp=rest[-1])
        return {}
    monkeypatch.setattr(D, "_run", fake_run)
    twin = Path(__file__).resolve().parents[1] / "data" / "brfd-twin"
    D.discover(str(twin), tmp_path / "a", FitConfig(seed=5))
    assert seen["seed"] == 5 and seen["cfg_seed"] == 5
    D.discover(str(twin), tmp_path / "b", FitConfig(), seed=7)
    assert seen["seed"] == 7
    with pytest.raises(InputError, match="two seeds, seed=7 and config.seed=5"):
        D.discover(str(twin), tmp_path / "c", FitConfig(seed=5), seed=7)
    camp = load_campaign(twin)
    D.discover(camp, tmp_path / "d")
    assert seen["camp"] is camp and Path(seen["path"]) == twin and seen["seed"] == 1


def test_a_name_that_makes_a_test_worse_is_said():
    """The real 25 lb pair of arts-d1 (a new user's trial, 2026-12-05): eccentricity named while
    the 1 Hz test's RMSE rose; the console and the page say so (the diagnostics' RMSE at the MAP
    points), and point to --check-seed when no seed check was run."""
    from frictionuq.discrepancy.gap import tests_made_worse, worse_sentence
    diag = [{"test": "a", "model": "baseline", "rmse": 1034.1},
            {"test": "b", "model": "baseline", "rmse": 1013.1},
            {"test": "a", "model": "with eccentricity", "rmse": 1001.9},
            {"test": "b", "model": "with eccentricity", "rmse": 1023.3}]
    doc = {"named_effect": "eccentricity", "named_effects": ["eccentricity"], "diagnostics": diag}
    assert tests_made_worse(doc) == [{"test": "b", "before": 1013.1, "after": 1023.3}]
    assert worse_sentence(doc) == ("with eccentricity the RMSE of 1 test rises (b 1013 -> 1023 N): "
                                   "the name rests on the other tests; `--check-seed N` screens "
                                   "again with another seed and says whether it names the same")
    assert worse_sentence(dict(doc, seed_check={"agree": False})).endswith("rests on the other tests")
    assert worse_sentence(dict(doc, diagnostics=diag[:3])) is None
