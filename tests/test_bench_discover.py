"""benchmarks/bench_discover.py's configurations: the speed case (--full) runs what `frictionuq
discover CAMPAIGN --out DIR` runs, and the short campaigns what the CI's end-to-end cases run
(tests/discover_check.py). Until 2026-12-04 --full ran the short campaigns' 100 samples per cycle
and a 3,000-step cap, under which the refit mostly stopped unconverged: the speed figure was not the
user's."""
from __future__ import annotations

import importlib.util
import sys
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _bench_discover():
    sys.path.insert(0, str(ROOT / "benchmarks"))       # it imports bench_fit's SAMPLERS
    try:
        spec = importlib.util.spec_from_file_location("bench_discover",
                                                      ROOT / "benchmarks" / "bench_discover.py")
        mod = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(mod)
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return mod


def _quiet(cfg):
    return replace(cfg, sampler=replace(cfg.sampler, progress=False)).to_json()


def test_the_speed_case_runs_the_clis_configuration():
    from frictionuq.cli.commands import discover_config
    from frictionuq.cli.options import build_parser
    bd = _bench_discover()
    cli = discover_config(build_parser().parse_args(["discover", "camp", "--out", "out"]))
    full = bd.bench_config(True, None, None, "raw", bd.SAMPLERS["chains"])
    assert full.to_json() == _quiet(cli)
    # the options still override it
    assert bd.bench_config(True, 100.0, 3000, "raw", {}).samples_per_cycle == 100.0
    assert bd.bench_config(True, 100.0, 3000, "raw", {}).sampler.max_steps == 3000


def test_the_short_campaigns_run_the_ci_cases_configuration():
    from frictionuq.infer.fit import FitConfig
    from frictionuq.infer.sampler import SamplerConfig
    bd = _bench_discover()
    short = bd.bench_config(False, None, None, "raw", bd.SAMPLERS["chains"])
    # tests/discover_check.py's configuration
    ci = FitConfig(samples_per_cycle=100, sampler=SamplerConfig(max_steps=3000, progress=False))
    assert short.to_json() == ci.to_json()


def _gain_table():
    spec = importlib.util.spec_from_file_location("gain_table", ROOT / "benchmarks" / "gain_table.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _doc(named, gains, heldout=None):
    """A discrepancy.json's fields that campaign_row reads; the candidates built by discover's own
    row function from rule.rank's fields (so that a renamed field fails here). heldout:
    {effect: held-out gain} of the candidates scored held out."""
    from frictionuq.discrepancy.discover import _candidate_rows
    heldout = heldout or {}
    ranked = [{"effect": e, "elpd_gain": heldout.get(e), "elpd_gain_se": None, "rmse_baseline": 20.0,
               "rmse_map": 19.0, "gain_per_unit": [], "map_gain": g,
               "screened_out": e not in heldout, "n_params": k} for e, k, g in gains]
    return {"named_effects": named, "rmse_before": 21.0, "rmse_after": 20.5,
            "candidates": _candidate_rows(ranked), "package_version": "0.test", "seed": 1,
            "config": {"samples_per_cycle": 100.0}, "environment": {"numba_cpu": "generic"}}


def _ans(hidden):
    return {"effects": {e: {"p2": 2.5} for e in hidden}, "noise_sd_N": 21.3}


def test_rows_keep_every_candidates_gains_and_the_gain_table_reads_them(tmp_path):
    bd, gt = _bench_discover(), _gain_table()
    runs = [  # (hidden, named, [(candidate, parameters, in-sample gain)])
        ([], [], [("eccentricity", 3, 6.2), ("stage2_nonlinear", 1, 1.9)], {"stage2_nonlinear": -3.0}),
        ([], [], [("eccentricity", 3, 3.4), ("stage2_nonlinear", 1, 0.1)]),
        (["stage2_nonlinear"], ["stage2_nonlinear"], [("stage2_nonlinear", 1, 25.7), ("eccentricity", 3, 2.0)],
         {"stage2_nonlinear": 25.5}),
        (["stage2_nonlinear"], [], [("stage2_nonlinear", 1, 13.6), ("eccentricity", 3, 7.0)]),
        (["stage2_nonlinear"], [], [("stage2_nonlinear", 1, 1.5), ("eccentricity", 3, 0.5)]),
        (["thermal_fade"], ["thermal_fade"], [("eccentricity", 3, 121.3), ("stage2_nonlinear", 1, 40.0)]),
    ]
    log = bd.RowLog(tmp_path / "rows.jsonl")
    for seed, (hidden, named, gains, *ho) in enumerate(runs):
        row = bd.campaign_row("mfd", seed, _ans(hidden), _doc(named, gains, *ho), 1.0, False)
        log.append(row)
        assert [c["map_gain"] for c in row["candidates"]] == [g for _, _, g in gains]
        assert [c["elpd_gain"] for c in row["candidates"]] == [(ho or [{}])[0].get(e) for e, _, _ in gains]
        assert row["right"] == (sorted(named) == sorted(hidden))
    assert row["hidden_parameters"] == {"thermal_fade": {"p2": 2.5}}
    assert row["made_by"] == {"package_version": "0.test", "seed": 1,
                              "config": {"samples_per_cycle": 100.0},
                              "environment": {"numba_cpu": "generic"}}
    rows = gt.read_rows([tmp_path / "rows.jsonl"])
    assert len(rows) == len(runs)      # every campaign's row, rewritten after each
    table = {t["effect"]: t for t in gt.gain_table(rows)}
    s2 = table["stage2_nonlinear"]
    # the thermal_fade campaign is neither clean nor stage2's: left out of both columns
    assert (s2["clean_n"], s2["clean_max"], s2["hidden_n"]) == (2, 1.9, 3)
    assert (s2["hidden_min"], s2["hidden_median"], s2["hidden_named"]) == (1.5, 13.6, 1)
    assert s2["hidden_above_clean"] == 2     # 25.7 and 13.6 above 1.9; 1.5 not
    assert abs(s2["chi2_ref"] - 5.414) < 1e-3      # chi2(1) 99.9 % point 10.83, halved
    # held-out gains only where scored: one clean, one hidden
    assert (s2["clean_heldout_n"], s2["clean_heldout_max"]) == (1, -3.0)
    assert (s2["hidden_heldout_n"], s2["hidden_heldout_min"], s2["hidden_heldout_median"]) == (1, 25.5, 25.5)
    assert table["eccentricity"]["clean_max"] == 6.2 and table["eccentricity"]["hidden_n"] == 0


def test_bad_rows_arguments_are_refused_in_one_line(tmp_path, capsys):
    import pytest
    bd, gt = _bench_discover(), _gain_table()
    with pytest.raises(SystemExit) as e:     # before any campaign is generated
        bd.main(["--rows", str(tmp_path), "--seeds", "1"])
    assert e.value.code == 2 and "a folder" in capsys.readouterr().err
    bad = tmp_path / "bad.jsonl"
    bad.write_text('{"hidden": "none", "candidates": []}\nnot json\n')
    with pytest.raises(SystemExit) as e:
        gt.main([str(bad)])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "bad.jsonl, line 2: not JSON" in err
    with pytest.raises(SystemExit) as e:
        gt.main([str(tmp_path / "missing.jsonl")])
    assert e.value.code == 2 and "no such file" in capsys.readouterr().err


def test_score_all_scores_every_candidate_and_leaves_the_rule(tmp_path, monkeypatch, capsys):
    """--score-all lowers only stage 1's threshold while discover runs (rule (e) keeps each
    effect's min_gain), restores it afterwards, and the row says it was on."""
    from frictionuq.discrepancy import rule, screen
    bd = _bench_discover()
    seen = []

    def fake_discover(*args, **kw):
        seen.append((screen.STAGE1_MIN_GAIN, screen._stage1_min_gain("eccentricity"),
                     screen._stage1_min_gain("stage2_nonlinear"), rule.min_gain("stage2_nonlinear")))
        return {**_doc([], [("stage2_nonlinear", 1, 1.0)]),
                "seconds_by_stage": {"screening": 1.0}, "reason": "none", "rounds": [{}]}

    monkeypatch.setattr(bd, "discover", fake_discover)
    monkeypatch.setattr(bd, "hidden_campaign", lambda *a, **k: _ans([]))
    before = screen.STAGE1_MIN_GAIN
    for flag in (["--score-all"], []):
        bd.main(flag + ["--seeds", "1", "--devices", "brfd", "--effects", "none",
                        "--rows", str(tmp_path / "rows.jsonl")])
        assert _gain_table().read_rows([tmp_path / "rows.jsonl"])[0]["score_all"] == bool(flag)
    s2 = rule.min_gain("stage2_nonlinear")
    inf = float("inf")
    assert seen == [(-inf, -inf, -inf, s2), (inf, rule.MIN_GAIN, s2, s2)]
    assert screen.STAGE1_MIN_GAIN == before == inf


def test_truth_fit_tells_a_miss_without_evidence_from_a_search_that_fell_short(monkeypatch):
    """--truth-fit: the evidence is the larger of the truth fit's gain (discrepancy.truthfit) and
    the hidden candidate's own in-sample gain; under the effect's threshold (rule.min_gain) the
    miss is the records', over it the search's. With two effects hidden, the truth fit's gain
    only (no single threshold)."""
    from frictionuq.discrepancy import rule
    bd = _bench_discover()
    seen = []

    def fake_truth_fit(tests, cfg, ans, base_map, base_lp):
        seen.append((tests, base_map, base_lp, cfg.min_kept_hz))
        return {"gain": ans["truth"]}

    planned = []

    def fake_plan(camp, by, cfg):
        planned.append(cfg.min_kept_hz)
        return [type("S", (), {"tests": [camp]})]

    monkeypatch.setattr(bd, "truth_fit_gain", fake_truth_fit)
    monkeypatch.setattr(bd, "load_campaign", lambda path: path)
    monkeypatch.setattr(bd, "plan", fake_plan)
    from frictionuq.infer.fit import FitConfig
    cfg = FitConfig(samples_per_cycle=100)
    need = rule.min_gain("stage2_nonlinear")
    for truth, own, evidence, none in [(3.5, 3.5, 3.5, True), (5.9, 4.8, 5.9, False),
                                       (-1.0, 0.0, 0.0, True), (-2.0, 7.0, 7.0, False)]:
        doc = _doc([], [("stage2_nonlinear", 1, own), ("eccentricity", 3, 9.0)])
        doc["levels"] = [{"models": {"baseline": {"map": {"k2": 1.0}, "log_prob_map": -5.0}}}]
        out = bd.truth_fit_fields("CAMP", {**_ans(["stage2_nonlinear"]), "truth": truth}, doc, cfg)
        assert out == {"truth_fit_gain": truth, "evidence": evidence, "min_gain": need,
                       "no_evidence": none}
    assert seen[-1] == (["CAMP"], {"k2": 1.0}, -5.0, None)
    out = bd.truth_fit_fields("CAMP", {**_ans(["stage2_nonlinear", "thermal_fade"]), "truth": 9.0},
                              doc, cfg)
    assert out == {"truth_fit_gain": 9.0}
    # with a noise effect among the candidates discover scored every model on records kept at
    # 50 Hz or more (its document's config): the truth fit plans and fits the same records
    doc["config"]["min_kept_hz"] = 50.0
    bd.truth_fit_fields("CAMP", {**_ans(["speed_weakening"]), "truth": 9.0}, doc, cfg)
    assert planned[-1] == 50.0 and seen[-1][3] == 50.0 and cfg.min_kept_hz is None
