"""`frictionuq discover CAMPAIGN --out DIR`: name the missing effect and show the gap shrink.

1. Screen (screen.py): per applied-force level, the baseline 3-stage model and every candidate
   effect of the library by the held-out tests' log predictive densities, leave one test out
   (ratios of Laplace evidences, predictive.py).
2. Decide (rule.decide): the best candidate, or "none" (the decision rule: rule.py). With
   max_effects > 1 (forward selection, _screen_rounds): after naming one, screen the remaining
   candidates again against the model with the effects named so far, by the same rule, until a
   round says "none" or max_effects are named. Real records can carry several effects (the ARTS
   loops: chatter, an overshoot at the take-up); the default names one, as the issue asks.
3. Refit by MCMC (infer.fit.run_fit) with the named effect(s), per level: the effect's parameters
   with 95 % intervals, and the RMSE after. The sampler starts from the screening's MAP of the
   named model on that level (polished, no second multi-start search: it cost 30 s of a 5-minute
   run on a full-length MFD campaign).
4. The gap before and after, per test (gap.py): residual diagnostics (diagnostics.py) at the
   baseline's MAP and, when an effect is named, at the MAP with it: which views show significant
   structure before and after (figures DIR/residuals-<model>-<test>.png), and the
   force-displacement loops of both models over the data with their residuals
   (DIR/loops-<test>.png).
5. Do the level's tests share one force zero? The between-tests check of every joint fit
   (infer.between) at the baseline's MAP (`between_tests`; _between says why this is a check
   and not a candidate of the screening).
6. With check seeds (seedcheck.py): screen again from other random starts; does every seed name
   the same effects?
7. Write DIR/discrepancy.json (forces in N) and the chains/posteriors of the refit under
   DIR/refit/.

rmse_before is the baseline's RMSE at its MAP (offset removed) on the fit's records;
candidate rmse_after values are at each candidate's MAP, beside rmse_before, the RMSE of its
round's baseline (the one rule (f) of screen.py compares with); the final rmse_after is the refit's
posterior-median prediction. noise_scale is the marginal sd of the measurement noise the refit
(or, with "none", the baseline) estimates: sigma_noise (a marginal sd), median over the tests;
with a noise effect (chatter) each test's sigma_noise times the rms of its gain g over the test,
i.e. the rms of the fitted noise sd. Such an effect does not change the force, so it closes no
RMSE; the gap it closes shows in the held-out score and in the bands; its diagnostics are
those of the residual in units of its noise model (divided by g). With a noise effect among the
candidates every model is screened on records kept at NOISE_EFFECT_MIN_KEPT_HZ or more
(infer.likelihood: the anti-alias filter would otherwise take 10-15 Hz chatter out of the slow
tests only).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import atomic
from ..environment import environment
from ..errors import InputError, check_seed
from ..errors import unknown as unknown_name
from ..infer.fit import FitConfig, FitSpec, jsonable, plan, run_fit
from ..infer.likelihood import NOISE_EFFECT_MIN_KEPT_HZ
from . import fits, rule, screen, seedcheck
from .gap import combined, level_gap
from ..workers import Workers


def _noise_scale(entry: dict, gain_rms: dict | None = None) -> float | None:
    """Median over the tests of the posterior mean of sigma_noise (the marginal sd of the
    measurement noise, AR(1) included: see infer.noisemodel), each times the rms of its noise
    effect's gain over the test when the fit has one (gain_rms: {test id: rms of g}), i.e. the
    rms of the fitted noise sd over the record."""
    gain_rms = gain_rms or {}
    vals = [st["mean"] * gain_rms.get(name[len("sigma_noise["):-1], 1.0)
            for name, st in entry["parameters"].items() if name.startswith("sigma_noise[")]
    return float(np.median(vals)) if vals else None


def _gain_rms(level_tests, cfg, effects, entry: dict) -> dict:
    """{test id: rms over its samples of the noise gain at the posterior means} for a fit with
    a noise effect (chatter), else {}."""
    from .. import params as P
    if not set(effects) & P.NOISE_EFFECTS:
        return {}
    lp, _ = fits.logpost_for(level_tests, effects, cfg)
    th = lp.space.to_theta({n: entry["parameters"][n]["mean"] for n in lp.space.names})[None, :]
    return {rec.id: float(np.sqrt(np.mean(lp.noise_gain(th, j)[0] ** 2)))
            for j, rec in enumerate(lp.records)}


def _between(spec, cfg, level: dict) -> dict | None:
    """Do the level's tests share one force zero? infer.between.offset_check at the baseline's
    MAP: each test's mean residual (y - force - the shared zero) against the noise of its
    residual there (lag-1 correlation and marginal sd by moments, localfit.whitening; a fit uses
    its posterior medians). None with one test, or with per-test zeros in every model.

    Why here and not as a candidate of the screening (tried 2026-12-02, evening): a test's own
    zero cannot be predicted from the other tests, so per-test zeros gain nothing held out on the
    unit that carries them; what they gain there comes through the other parameters. On short
    BRFD campaigns with zeros drawn in +-5 % of the friction force (a spread of 5.5 noise sds at
    seed 11) they scored +37.8 +- 29.9 nats (32.4 / 1.0 / 4.3 per test) and +28.7 +- 40.6 (36.6 /
    -3.3 / -4.6, seed 12): named at neither. The question is whether the zeros differ, which this
    chi-square answers at a stated false-alarm rate (ALPHA, tests/test_infer_between.py)."""
    from ..infer.between import offset_check
    from ..infer.localfit import whitening
    if len(spec.tests) < 2 or cfg.force_offset == "per_test":
        return None
    lp, _ = fits.logpost_for(spec.tests, (), cfg)
    m = level["models"]["baseline"]["map"]
    th = lp.space.to_theta({n: m[n] for n in lp.space.names})
    white = whitening(lp, th)
    means = [float(np.mean(lp.residuals(th[None, :], rec)[0])) for rec in lp.records]
    return {"level": spec.id, **offset_check(
        [r.id for r in lp.records], means, [r.n for r in lp.records],
        [s / np.sqrt(1.0 - phi**2) for phi, s in white], [phi for phi, _ in white])}


def _candidate_rows(ranked) -> list[dict]:
    return [{"effect": r["effect"], "elpd_gain": r["elpd_gain"], "elpd_gain_se": r["elpd_gain_se"],
             "rmse_before": r["rmse_baseline"], "rmse_after": r["rmse_map"],
             "gain_per_unit": r["gain_per_unit"],
             "map_gain": r["map_gain"], "screened_out": r["screened_out"],
             "n_params": r["n_params"], "min_gain": rule.min_gain(r["effect"])} for r in ranked]


def _screen_rounds(specs, cfg, seed, effects, extra_effects, max_effects, log,
                   workers=None) -> list[dict]:
    """Forward selection, one effect per round: round 1 screens the candidates against the plain
    3-stage model; while a round names an effect and fewer than max_effects are named, the next
    round takes the model with the effects named so far as its baseline (started from the named
    model's MAP of the round before, on each level) and screens the remaining candidates against
    it, by the same rule (rule.decide). [{"baseline_effects", "named", "reason", "ranked",
    "levels"}] per round."""
    named_so_far: list[str] = []
    rounds = []
    for r in range(max_effects):
        levels = []
        for i, s in enumerate(specs):
            cands = list(effects) if effects is not None else screen.candidates(s.tests, extra_effects)
            start = rounds[-1]["levels"][i]["models"][rounds[-1]["named"]]["map"] if rounds else None
            tag = f"round {r + 1}, " if max_effects > 1 else ""
            log(f"{tag}level {s.id}: screening {len(s.tests)} test(s)"
                + (f" against 3-stage + {' + '.join(named_so_far)}" if named_so_far else ""))
            lv = screen.screen_level(s.tests, cfg, seed, effects=cands, base_effects=named_so_far,
                                     base_start=start, log=lambda m, i=s.id: log(f"{tag}{i}: {m}"),
                                     workers=workers)
            lv["id"] = s.id
            levels.append(lv)
        ranked = rule.rank(levels) if len(levels[0]["models"]) > 1 else []
        named, reason = rule.decide(ranked, levels)
        log(f"{f'round {r + 1}: ' if max_effects > 1 else ''}named effect: {named} ({reason})")
        rounds.append({"baseline_effects": list(named_so_far), "named": named, "reason": reason,
                       "ranked": ranked, "levels": levels})
        if named == "none":
            break
        named_so_far.append(named)
    return rounds


def discover(campaign_path, out_dir, config: FitConfig | None = None, *, seed: int | None = None,
             effects=None, extra_effects=(), refit: bool = True, diagnostics: bool = True,
             max_effects: int = 1, jobs: int = 1, check_seeds=(), log=None) -> dict:
    """Run the workflow on a campaign; returns (and writes) the discrepancy document.
    effects: the candidates (default: screen.candidates, the spec's library); extra_effects:
    effects beyond the spec (params.BEYOND_SPEC) to screen as well. max_effects: how many
    effects may be named, one per round (_screen_rounds); named_effect is the first,
    named_effects all of them, and the refit and the gap are those of the model with all.
    jobs: processes for the screening's fits and the gap's diagnostics and figures
    (workers.Workers; the CLI's default is every core; 1 here, as inside a pipeline task, which
    has its own processes); the results do not depend on it. With jobs > 1 the workers are
    spawned: a script calling this must do so under `if __name__ == "__main__":` (Python's rule
    for spawned processes).

    check_seeds: seeds to screen the campaign again with (seedcheck.py): `seed_check` in the
    document says whether each names the same effects.

    seed: default config.seed (1 without a config); given beside a config with another seed
    than the default, the two must agree.

    campaign_path: a campaign folder, an ingested folder or a Campaign (checked by
    campaign.check_campaign; its records are then read from it, not from its folder). The
    report page is the report layer's: frictionuq.report.render_discrepancy_page(out_dir), as
    the CLI does.

    Decimated records are simulated as the config says (raw rate by default, as the fits)."""
    log = log or (lambda m: None)
    from ..campaign import Campaign, check_campaign
    camp = None
    if isinstance(campaign_path, Campaign):
        check_campaign(campaign_path)
        camp, campaign_path = campaign_path, campaign_path.path
    if seed is None:
        seed = config.seed if config is not None else FitConfig().seed
    elif config is not None and config.seed not in (seed, FitConfig().seed):
        raise InputError(f"discover: two seeds, seed={seed!r} and config.seed={config.seed!r}; "
                         "give one")
    check_seed(seed, "discover")
    cfg = replace(config or FitConfig(), seed=seed)  # recorded in discrepancy.json
    if cfg.effects:
        raise InputError("discover: the baseline is the plain 3-stage model; do not give effects")
    if cfg.likelihood not in ("iid", "ar1"):
        raise InputError(f"discover: likelihood {cfg.likelihood!r} is not supported by the "
                         "held-out screening; use ar1 (default) or iid")
    if not (isinstance(max_effects, int) and max_effects >= 1):
        raise InputError(f"discover: max_effects must be an integer >= 1, got {max_effects!r}")
    if not (isinstance(jobs, int) and jobs >= 1):
        raise InputError(f"discover: jobs must be an integer >= 1, got {jobs!r}")
    check_seeds = tuple(check_seeds)
    for s_ in check_seeds:
        check_seed(s_, "discover --check-seed")
    if seed in check_seeds or len(set(check_seeds)) < len(check_seeds):
        raise InputError(f"discover: check seeds {list(check_seeds)} must differ from each other "
                         f"and from the run's seed {seed}")
    from .. import params as P
    if isinstance(effects, str):          # one name, not its letters
        effects = (effects,)
    if isinstance(extra_effects, str):
        extra_effects = (extra_effects,)
    unknown = [e for e in effects or () if e not in P.EFFECTS]
    if unknown:
        raise InputError(f"discover: {unknown_name('effect', unknown[0], P.EFFECTS)}")
    bad = [e for e in extra_effects if e not in P.BEYOND_SPEC]
    if bad:
        what = ("is in the spec's library, which is screened already" if bad[0] in P.EFFECTS
                else "is not an effect")
        raise InputError(f"discover: extra effect {bad[0]!r} {what}; --extra-effect takes the "
                         f"effects beyond the spec: {', '.join(sorted(P.BEYOND_SPEC))}")
    noise = (set(effects or ()) | set(extra_effects)) & P.NOISE_EFFECTS
    if noise and cfg.force_offset == "per_test":
        raise InputError(f"discover: per-test force offsets cannot be screened with the noise "
                         f"effect {sorted(noise)[0]} (its gain turns a test's zero into a varying "
                         "signal); drop it from the candidates or use --force-offset shared")
    if noise:
        # every model of the comparison on the same records, kept at a rate that holds chatter
        cfg = replace(cfg, min_kept_hz=max(cfg.min_kept_hz or 0.0, NOISE_EFFECT_MIN_KEPT_HZ))
    # the output folder: a new one, or a previous run's, replaced as a whole once this run is
    # complete (no earlier refit/ or figure left beside the new document; nothing lost on failure)
    atomic.check_replaceable(campaign_path, Path(out_dir), "discrepancy.json", "campaign",
                             "a `frictionuq discover` output folder",
                             owned=("discrepancy.json", "report.html", "*.png", "refit"))
    with Workers(jobs) as workers, atomic.output_dir(out_dir) as tmp:
        return _run(campaign_path, tmp, cfg, seed, effects, extra_effects, refit, diagnostics,
                    max_effects, check_seeds, log, workers, camp)


def _run(campaign_path, out_dir, cfg, seed, effects, extra_effects, refit, diagnostics,
         max_effects, check_seeds, log, workers, camp=None) -> dict:
    """discover's work once its arguments are checked: the screening's and the gap's tasks on the
    workers' processes (kept open from the first round to the last figure)."""
    from .. import __version__
    from .. import params as P
    from ..campaign import load_campaign
    t0 = time.perf_counter()
    camp = camp if camp is not None else load_campaign(campaign_path)
    out = Path(out_dir)
    specs = plan(camp, "applied", cfg)
    rounds = _screen_rounds(specs, cfg, seed, effects, extra_effects, max_effects, log, workers)
    checks = [(s_, _screen_rounds(specs, replace(cfg, seed=s_), s_, effects, extra_effects,
                                  max_effects, lambda m, s_=s_: log(f"seed check {s_}: {m}"),
                                  workers)) for s_ in check_seeds]
    named_all = [r["named"] for r in rounds if r["named"] != "none"]
    named = named_all[0] if named_all else "none"
    levels = rounds[0]["levels"]
    # the levels of the round whose named model is the final one (its MAP per level)
    last = next((r for r in reversed(rounds) if r["named"] != "none"), rounds[0])
    final_maps = [lv["models"][last["named"] if named_all else "baseline"]["map"]
                  for lv in last["levels"]]
    rmse_before = float(np.mean([lv["models"]["baseline"]["rmse_map"] for lv in levels]))
    doc = {"package_version": __version__, "environment": environment(),
           "campaign": camp.name, "campaign_path": str(Path(campaign_path).resolve()),
           "seed": seed, "config": cfg.to_json(), "named_effect": named,
           "named_effects": named_all, "reason": rounds[0]["reason"],
           "decision_rule": rule.RULE, "extra_effects": list(extra_effects),
           "max_effects": max_effects,
           "alternatives": rule.alternatives(rounds[0]["ranked"], rounds[0]["named"]),
           "candidates": _candidate_rows(rounds[0]["ranked"]),
           "candidates_screened": [n for n in levels[0]["models"] if n != "baseline"],
           "rmse_before": rmse_before, "rmse_after": rmse_before, "noise_scale": None,
           "effect_parameters": {}, "levels": levels,
           "rounds": [{"round": i + 1, "baseline_effects": r["baseline_effects"],
                       "named_effect": r["named"], "reason": r["reason"],
                       "alternatives": rule.alternatives(r["ranked"], r["named"]),
                       "candidates": _candidate_rows(r["ranked"]),
                       **({"levels": r["levels"]} if i else {})} for i, r in enumerate(rounds)],
           "units": {"rmse": "N", "noise_scale": "N", "elpd": "nats", "seconds": "s"}}
    if checks:
        doc["seed_check"] = seedcheck.summarize(seed, named_all, checks)
        log(seedcheck.sentence(doc["seed_check"]))
    doc["between_tests"] = [b for b in (_between(s, cfg, lv) for s, lv in zip(specs, levels)) if b]
    for b in doc["between_tests"]:
        log(f"level {b['level']}: " + (
            f"the tests do not share one force zero (per-test mean residuals about the "
            f"baseline's zero spread by {b['spread_N']:.4g} N, chi-square {b['chi2']:.1f} on "
            f"{b['df']}, p = {b['p_value']:.2g}): --force-offset per_test gives each its own"
            if b["significant"] else f"the tests share one force zero within the noise (p = "
            f"{b['p_value']:.2g})"))
    t_refit = time.perf_counter()
    # where the time went (s): loading, the screening's rounds, seed checks and the between-tests
    # check; the MCMC refit; the residual diagnostics and their figures
    stages = {"screening": t_refit - t0}
    if refit:
        eff = tuple(named_all)
        entries = []
        for s, start in zip(specs, final_maps):
            spec = FitSpec(s.id, s.tests, s.applied, replace(cfg, effects=eff))
            entries.append(run_fit(spec, out / "refit", camp.name, resume=False, log=log,
                                   start=start))
        doc["refit"] = [{"id": e["id"], "converged": e["converged"], "rmse": e["rmse"],
                         "effects": list(eff)} for e in entries]
        doc["rmse_after"] = float(np.mean([e["rmse"] for e in entries]))
        scales = [v for v in (_noise_scale(e, _gain_rms(s.tests, cfg, eff, e))
                              for s, e in zip(specs, entries)) if v is not None]
        doc["noise_scale"] = float(np.median(scales)) if scales else None
        for n in (n for e_ in eff for n in P.EFFECTS[e_]):
            st = [e["parameters"][n] for e in entries if n in e["parameters"]]
            if st:
                doc["effect_parameters"][n] = {k: st[0][k] for k in ("mean", "sd", "q2.5", "q97.5")}
                doc["effect_parameters"][n]["unit"] = P.PARAMS[n].unit
    elif named_all:
        doc["rmse_after"] = next(r for r in last["ranked"] if r["effect"] == last["named"])["rmse_map"]
        # no refit, so no intervals: the named effects' parameters at each level's MAP
        doc["effect_parameters_map"] = {
            lv["id"]: {n: {"value": float(m[n]), "unit": P.PARAMS[n].unit}
                       for e_ in named_all for n in P.EFFECTS[e_] if n in m}
            for lv, m in zip(last["levels"], final_maps)}
    stages["refit"] = time.perf_counter() - t_refit
    t_diag = time.perf_counter()
    if diagnostics:
        doc["diagnostics"], doc["combined_diagnostics"] = [], []
        for s_, lv, fm in zip(specs, levels, final_maps):
            gap = level_gap(s_.tests, cfg, lv["models"]["baseline"]["map"], named_all, fm, seed,
                            out, log, workers)
            doc["diagnostics"] += gap
            doc["combined_diagnostics"] += combined(s_.id, gap, log)
    stages["diagnostics"] = time.perf_counter() - t_diag
    doc["seconds"] = time.perf_counter() - t0
    doc["seconds_by_stage"] = stages
    atomic.write_json(out / "discrepancy.json", jsonable(doc))
    return doc
