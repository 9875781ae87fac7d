"""The end-to-end check of the discrepancy workflow on one seeded hidden-effect campaign, shared
by tests/test_discrepancy_discover.py (one effect hidden, or none) and
tests/test_discrepancy_discover_rounds.py (the MCMC refit and forward selection's rounds): two
files, so that pytest-xdist (--dist loadfile) runs the slowest cases on both workers."""
from __future__ import annotations

import json
import re

import numpy as np

from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import fits
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.params import BEYOND_SPEC, EFFECTS, NOISE_EFFECTS, REGULAR_NULL


def check_discover(tmp_path, device, effect, seed, refit, also=None, max_effects=1):
    """A short 3-test campaign (two harmonics, a Kobe replay) of a paper device with one hidden
    effect at random realistic parameters, or none: the screening names it, or says none; with
    the MCMC refit, the effect's parameters are inside their 95 % intervals and rmse_after is
    within 1.2 times the generator's noise scale (the refit case is the MFD's). Fixed seeds, so each case either always passes or
    always fails; the false-alarm guard is the decision rule (screen.py), measured on the clean
    campaigns of benchmarks/bench_discover.py: 0 false alarms in 100 short ones (one-sided 95 %
    bound 3 %; docs/log-discrepancy.md). The CI's hidden-effect cases are not a random sample of
    that benchmark: stage2_nonlinear's case (BRFD seed 12) was added on 2026-12-04 with the
    regular effects' threshold (rule.min_gain); the larger set (every effect, both devices, refits) is
    that benchmark. With max_effects > 1, discover names effects one per
    round (forward selection): a second hidden effect (`also`) is named too, and the gap checks
    are those of the model with both; with one hidden effect the next round says none."""
    from frictionuq.discrepancy.discover import discover
    from frictionuq.infer.fit import FitConfig
    from frictionuq.infer.sampler import SamplerConfig
    from frictionuq.report import render_discrepancy_page
    ans = hidden_campaign(tmp_path / "c", device, effect, seed=seed, short=True,
                          answer_path=tmp_path / "answer.json", also=also)
    cfg = FitConfig(samples_per_cycle=100, sampler=SamplerConfig(max_steps=3000, progress=False))
    hidden = list(ans["effects"])
    extra = tuple(e for e in hidden if e in BEYOND_SPEC)
    d = discover(tmp_path / "c", tmp_path / "out", cfg, seed=1, refit=refit, extra_effects=extra,
                 max_effects=max_effects)
    assert sorted(d["named_effects"]) == sorted(hidden), (d["reason"], d["candidates"], d["rounds"])
    doc = json.loads((tmp_path / "out" / "discrepancy.json").read_text())
    assert doc["named_effect"] == (d["named_effects"] or ["none"])[0] and doc["package_version"]
    assert doc["seed"] == 1 and doc["max_effects"] == max_effects
    # where the time went: the three stages, in order, within the whole run's seconds
    st = doc["seconds_by_stage"]
    assert list(st) == ["screening", "refit", "diagnostics"] and min(st.values()) >= 0.0
    assert sum(st.values()) <= doc["seconds"]
    assert (st["refit"] > 1.0) == refit, st
    assert doc["environment"]["packages"]["numba"] and doc["environment"]["numba_cpu"]
    # the other candidates passing the rule, listed beside each round's name (rule.alternatives)
    for r in [doc] + doc["rounds"]:
        named_r = r["named_effect"]
        assert all(a["effect"] != named_r for a in r["alternatives"])
        assert named_r != "none" or r["alternatives"] == []
        scored = {c["effect"] for c in r["candidates"] if not c["screened_out"]}
        assert {a["effect"] for a in r["alternatives"]} <= scored
    # each candidate row carries the RMSE of its round's baseline (rule (f) compares with it)
    assert all(c["rmse_before"] == doc["rmse_before"] for c in doc["candidates"])
    # a round after the last hidden effect (if max_effects allows one) said none
    assert len(doc["rounds"]) == min(len(hidden) + 1, max_effects), doc["rounds"]
    assert {c["effect"] for c in doc["candidates"]} >= {"reversal_hump", "eccentricity", "thermal_fade",
                                                        "rate_strengthening", "stage2_nonlinear"}
    # the generator's noise scale: its stationary sd, or with a noise effect (chatter) the rms of
    # its sd over the records (hidden_campaign's noise_rms_N; the same number without one)
    noise = ans["noise_rms_N"]
    if effect is None:
        # nothing hidden: the baseline's MAP (after the nested recheck, discrepancy.recheck) is
        # as good as the least-squares fit from the generating values. Before that recheck its
        # own search ended ~400 nats below them on this campaign (v_s at its upper bound, sigma0
        # at its lower one) and rate_strengthening, which reached them, was named (+322 nats)
        from frictionuq import published as pub
        from frictionuq.infer.fit import plan
        lv = doc["levels"][0]["models"]["baseline"]
        tests = plan(load_campaign(tmp_path / "c"), "applied", cfg)[0].tests
        lp, _ = fits.logpost_for(tests, (), cfg)
        vals = dict(lv["map"])
        vals.update({k: v for k, v in pub.published_params(
            device, ans["applied"] * (1.0 if device == "brfd" else 6894.757293168)).items() if k in vals})
        best = fits.log_prob(lp, fits.refit(lp, lp.space.to_theta(vals)))
        assert lv["log_prob_map"] >= best - 5.0, (lv["log_prob_map"], best)
    by = {(g["test"], g["model"]): g for g in doc["diagnostics"]}
    tag = f"with {' + '.join(doc['named_effects'])}"       # the model with every named effect
    # the level's tests taken together (combine.py): one entry per model, every test either
    # combined or excluded for its null's short blocks
    ids = [t["id"] for t in ans["tests"]]
    models = list(dict.fromkeys(g["model"] for g in doc["diagnostics"]))
    assert [c["model"] for c in doc["combined_diagnostics"]] == (models if len(ids) >= 2 else [])
    for c in doc["combined_diagnostics"]:
        assert sorted(c["tests"] + c["excluded"]) == sorted(ids)
        # Fisher's combination needs independent p-values: each test its own permutations
        seeds = [by[(t, c["model"])]["diagnostics"]["seed"] for t in ids]
        assert len(set(seeds)) == len(seeds), seeds
        assert set(c["significant"]) <= set(c["views"])
    noise_effect = next((e for e in hidden if e in NOISE_EFFECTS), None)
    if noise_effect:
        # the force is not what it changes: the gap it closes is in the noise. Pooled over the
        # tests, the squared residual of the model with every named effect (the noise gain left
        # out) is several times larger inside the hidden window than outside it, and so is the
        # baseline's when the noise effect is the only one hidden (with another one hidden the
        # baseline's force misfit fills the rest of the record too: 1.47 at this seed); divided
        # by the fitted gain, the ratio is near 1
        from frictionuq.infer.fit import plan
        from frictionuq.noise import chatter_gain, since_reversal
        tests = plan(load_campaign(tmp_path / "c"), "applied", cfg)[0].tests
        p = ans["effects"][noise_effect]
        ratios = {}
        # the MAP of the model with every named effect: the last naming round's (round 1's
        # levels are the document's own)
        last = [r for r in doc["rounds"] if r["named_effect"] != "none"][-1]
        final = last.get("levels", doc["levels"])[0]["models"][last["named_effect"]]["map"]
        for model, eff, m in (("baseline", (), doc["levels"][0]["models"]["baseline"]["map"]),
                              (tag, tuple(doc["named_effects"]), final)):
            lp, _ = fits.logpost_for(tests, eff, cfg)
            th = lp.space.to_theta({n: m[n] for n in lp.space.names})[None, :]
            for scaled in ((False, True) if eff else (False,)):
                inside, outside = [], []
                for j, rec in enumerate(lp.records):
                    e = lp.residuals(th, rec)[0]
                    g = lp.noise_gain(th, j)
                    e = e / g[0] if scaled else e
                    win = chatter_gain(since_reversal(rec.x, rec.eps), p["a_ch"], p["s_ch"], p["w_ch"])[0] > 2.0
                    inside.append(e[win] ** 2)
                    outside.append(e[~win] ** 2)
                ratios[model + (" / g" if scaled else "")] = float(
                    np.mean(np.concatenate(inside)) / np.mean(np.concatenate(outside)))
        assert ratios[tag] > 3.0 and 0.6 < ratios[tag + " / g"] < 1.5, ratios
        assert len(hidden) > 1 or ratios["baseline"] > 3.0, ratios
        assert all(g["diagnostics"]["scaled_by_noise_gain"] for g in doc["diagnostics"]
                   if g["model"] == tag)
        html = render_discrepancy_page(tmp_path / "out").read_text()
        assert f"{noise_effect} is a noise effect" in html
        if len(hidden) > 1:
            assert "Round 2, against the 3-stage model with" in html
    if any(e not in NOISE_EFFECTS for e in hidden):
        assert doc["rmse_after"] < doc["rmse_before"]
        # the gap shrinks per test too (as in the decision rule, an effect may leave no trace in
        # one test: all but one improved, none made worse by more than 5 %), loops of both drawn.
        # An effect whose null is regular is not asked for that spread by the rule (screen.py,
        # rule (b)), nor here: at least one test improved (a curved stage 2 shows in the replay;
        # at BRFD seed 12 the sines' RMSE rose 0.2 % while the replay's fell 2.5 %)
        ratios = [by[(t["id"], tag)]["rmse"] / by[(t["id"], "baseline")]["rmse"]
                  for t in ans["tests"]]
        need = 1 if set(hidden) <= REGULAR_NULL else len(ratios) - 1
        assert sum(r < 1.0 for r in ratios) >= need and max(ratios) < 1.05, ratios
        for t in ans["tests"]:
            assert (tmp_path / "out" / f"loops-{t['id']}.png").stat().st_size > 10_000
    if not refit and doc["named_effects"]:
        # no intervals without the refit, but the named effects' MAP values, per level, shown
        # (the free ones: a parameter the model fixes, chatter's b_ch by default, has no MAP)
        last_round = [r for r in doc["rounds"] if r["named_effect"] != "none"][-1]
        fitted = last_round.get("levels", doc["levels"])[0]["models"][last_round["named_effect"]]["map"]
        want = {n for e in doc["named_effects"] for n in EFFECTS[e] if n in fitted}
        maps = doc["effect_parameters_map"]
        assert list(maps) == [lv["id"] for lv in doc["levels"]]
        assert want and all(set(v) == want for v in maps.values()), (maps, want)
        for v in maps.values():
            assert all(v[n]["value"] == fitted[n] for n in want)
        assert doc["effect_parameters"] == {}
        assert "at its MAP (run with --no-refit" in render_discrepancy_page(tmp_path / "out").read_text()
    if refit:
        assert doc["rmse_after"] <= 1.2 * noise, (doc["rmse_after"], noise)
        assert 0.8 * noise <= doc["noise_scale"] <= 1.2 * noise, (doc["noise_scale"], noise)
        for n, v in ((n, v) for q in ans["effects"].values() for n, v in q.items()):
            st = doc["effect_parameters"][n]
            assert st["q2.5"] <= v <= st["q97.5"], (n, v, st)
        page = render_discrepancy_page(tmp_path / "out")
        html = page.read_text()
        assert f"Named effect: {effect}" in html and "loops" in html and "RMSE at its MAP (N)" in html
        assert "MAP gain on all units (nats)" in html and "tests combined" in html
        assert re.search(r"the baseline.{1,6}s RMSE at its MAP \d", html)   # the table's caption
        assert html.count("data:image/png;base64") >= 2 * len(ans["tests"]) + len(ans["tests"])
