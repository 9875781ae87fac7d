"""Screening the effect library: which named effect closes the gap between model and data.

For every candidate effect of the spec's library (section 5) and the baseline 3-stage model, on
each applied-force level of a campaign:

1. the maximum a posteriori point on all tests of the level: for the baseline by
   infer.optimize.find_map (the multi-start search the fits start from); for a candidate by
   least squares from the baseline's MAP with the effect's parameters at their default and at
   N_EFFECT_STARTS prior draws, from find_map's heuristic starts (the effect neutral and at
   prior draws) and from a differential-evolution search (candidate.candidate_map);
2. stage 1: a candidate whose MAP on all tests is not more than min_gain(effect) above the
   baseline's (rule.MIN_GAIN; lower for an effect whose null is regular: rule (b) in
   discrepancy.rule)
   (each side refitted from the other's MAP first: recheck.cross_refit) is
   not scored held out (rule (e) refuses it whatever its held-out score; skipping its
   fold fits and evidences is most of the screening's saving on a campaign where one effect or
   none is present); it is listed with its in-sample gain; the candidates that pass the stage
   (the contenders) are each refitted from every other contender's MAP, their own effect's
   parameters kept (recheck.peer_refit), so that which contender is ahead does not rest on one
   search having found a basin the others missed, and the baseline again from those that rose;
3. leave-one-test-out: the MAP on the other tests (warm-started from step 1), and the held-out
   test's log predictive density given them, log p(y_k | y_-k) = log Z(all) - log Z(the others),
   each marginal likelihood by Laplace's method at its maximum, with the level's prior on both
   sides (discrepancy.predictive; each record's noise sd and AR(1) phi integrated out in the
   log-posterior). A level with a single test is split into 3 contiguous blocks of whole
   cycles, held out in turn.

The candidates' MAP searches (step 1), the cross and peer refits and each scored model's fold fits
(step 3) do not depend on each other: with a workers.Workers of two processes they run side by
side (discover's jobs; the CLI uses every core), with the serial run's results.

The gain of a candidate on held-out unit k is g_k = ll_k(candidate) - ll_k(baseline) (nats);
ELPD gain = sum_k g_k with SE = sqrt(K var(g_k)) (Vehtari et al. 2017), summed over levels.

Why this score (2026-11-25). On short campaigns two tests leave directions of the parameters
almost free (v_s, sigma0, d3, sigma1, sigma2), and the training MAP can sit anywhere along such a
ridge. The plug-in score log p(y_k | theta_MAP), used first, then swung by hundreds of nats on
the third test: on a clean BRFD campaign (seed 5) eccentricity, whose training fit was 1.6 nats
better, gained +194.0 / +110.8 / -0.3 (named: a false alarm). Monte Carlo over the training fit's
Gaussian approximation (200 draws) rested on 1-5 draws and still swung by up to 232 nats on clean
campaigns; Laplace's method for that integral missed a hidden thermal_fade (discrepancy.predictive
says why). The evidence ratio depends on the heights of the two maxima, not on where along a
ridge the training fit stops: on the clean BRFD campaigns of seeds 2 and 5 the largest
single-unit gains fell from 227 and 194 nats to 6.4 and 2.6. The full posterior predictive by
MCMC per fold would cost K + 1 MCMC runs per candidate. The named effect is then refitted by
MCMC (discover.py), which gives its parameters with intervals.

The decision rule (which candidate is named, its thresholds and why): discrepancy.rule.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from .. import params as P
from ..campaign import Record
from ..infer.fit import FitConfig
from ..infer.likelihood import LogPosterior
from ..infer.optimize import find_map
from .candidate import fit_candidate
from . import fits as F
from .predictive import log_evidence
from .recheck import baseline_from, cross_refit, nested_recheck, peer_refit, set_evidence
from .rule import MIN_UNIT_GAIN, min_gain
from ..workers import Workers

#: stage 1: a candidate whose MAP on all units is not more than min(its min_gain, this) above
#: the baseline's is not scored held out. inf: min_gain, as rule (e) asks of a name; a separate
#: name only so that benchmarks/bench_discover.py --score-all can score every candidate (-inf:
#: the held-out gains of candidates the rule refuses in stage 1, e.g. on clean campaigns),
#: leaving the rule as it is
STAGE1_MIN_GAIN = math.inf


def _stage1_min_gain(effect: str) -> float:
    """Stage 1's threshold for a candidate (nats over the baseline's MAP)."""
    return min(min_gain(effect), STAGE1_MIN_GAIN)


N_BLOCKS = 3


def candidates(tests, extra=()) -> list[str]:
    """The effects screened on these tests by default: the spec's library (applied_tracking only
    when every test has the measured applied-force signal), plus the effects beyond the spec
    named in `extra` (params.BEYOND_SPEC: opt-in, because takeup_overshoot outscored the true
    effect on a BRFD campaign with a hidden reversal_hump, +1147 against +655 nats, on records
    decimated to 100 samples per cycle; speed_weakening gains 45-87 nats in-sample on every real
    ARTS level under the AR(1) likelihood, and nothing with independent errors)."""
    has_applied = all(t.record.applied is not None for t in tests)
    return [e for e in P.EFFECTS if (e not in P.NEEDS_APPLIED or has_applied)
            and (e not in P.BEYOND_SPEC or e in extra)]


def blocks(test, n: int = N_BLOCKS) -> list:
    """A single test split into n contiguous blocks (Test objects), each at least one cycle."""
    r = test.record
    edges = np.linspace(0, r.n, n + 1).astype(int)
    out = []
    for i in range(n):
        s = slice(edges[i], edges[i + 1])
        rec = Record(r.t[s], r.x[s], r.force[s], None if r.applied is None else r.applied[s])
        out.append(replace(test, id=f"{test.id}#block{i + 1}", record=rec))
    return out


def heldout_units(level_tests) -> list[tuple[list, object]]:
    """[(training tests, held-out test)]: leave one test out, or blocks of a single test."""
    units = list(level_tests) if len(level_tests) >= 2 else blocks(level_tests[0])
    return [(units[:k] + units[k + 1:], units[k]) for k in range(len(units))]


def _score_model(args) -> dict:
    """One model's held-out scoring (a task of workers.Workers.map): the MAP on all held-out units
    together (F.joint_fit), each fold's training MAP warm-started from it (F.refit), and the
    Laplace evidences of both (predictive.log_evidence)."""
    lp_all, th_all, recs, trains = args
    t0 = time.perf_counter()
    lp_joint, th_joint = F.joint_fit(lp_all, th_all, recs)
    fits = []
    for train in trains:
        lp_tr = LogPosterior(lp_all.space, [recs[i] for i in train])
        th_k = F.refit(lp_tr, th_joint)
        fits.append((th_k, F.log_prob(lp_tr, th_k), log_evidence(lp_tr, th_k)))
    return {"th_joint": th_joint, "log_z": log_evidence(lp_joint, th_joint), "folds": fits,
            "seconds": time.perf_counter() - t0}


def screen_level(level_tests, cfg: FitConfig, seed: int, effects=None, log=None,
                 base_effects=(), base_start: dict | None = None, workers=None) -> dict:
    """Held-out log-likelihoods of the baseline and every candidate on one level.

    base_effects: effects the baseline already has (a later round of discover: the effects
    named before); each candidate is then the baseline plus one more. base_start: {name: value}
    of the baseline's MAP found before (the previous round's MAP of the model now taken as the
    baseline), polished instead of a new multi-start search. workers: a workers.Workers whose
    processes run the candidates' fits side by side (default: one after the other, here); the
    results are the same."""
    log = log or (lambda m: None)
    pool = workers or Workers(1)
    base_effects = tuple(base_effects)
    effects = [e for e in (effects if effects is not None else candidates(level_tests))
               if e not in base_effects]
    folds = heldout_units(level_tests)
    out = {"tests": [t.id for t in level_tests], "units": [h.id for _, h in folds], "models": {}}
    fold_fits = {}        # model -> [(training log-posterior, theta, its log-posterior)] per fold
    full_fits = {}        # model -> (log-posterior on all tests, MAP, held-out units' records)
    fitted = {}           # model -> [log-posterior on all tests, MAP, its log-posterior, seconds]
    t0 = time.perf_counter()      # the MAP on all units: the baseline's first
    lp_all, scales = F.logpost_for(level_tests, base_effects, cfg)
    start = None if base_start is None else lp_all.space.to_theta(
        {n: base_start[n] for n in lp_all.space.names})
    th_all, lpmap, info = find_map(lp_all, scales,
                                   np.random.default_rng([seed, 17, len(base_effects)]),
                                   n_random=1, n_prior=1, start=start)
    base_theta = {"space": lp_all.space, "all": th_all, "log_prob": lpmap,
                  "global_points": info.get("global_points", [])}
    fitted["baseline"] = [lp_all, th_all, lpmap, time.perf_counter() - t0]
    # each candidate from the baseline's MAP (its effect at the default and at prior draws), the
    # heuristic starts and a global search (candidate.candidate_map), side by side in the workers
    lps = {name: F.logpost_for(level_tests, base_effects + (name,), cfg) for name in effects}
    res = pool.map(fit_candidate, [(lps[n][0], base_theta, seed, len(base_effects) + 1, lps[n][1])
                                    for n in effects])
    for name, (th_c, lp_c, secs) in zip(effects, res):
        fitted[name] = [lps[name][0], th_c, lp_c, secs]
    changed, moved = cross_refit(fitted, log, pool.map)
    raised = peer_refit(fitted, _stage1_min_gain, log, pool.map)
    for name, m in raised.items():
        moved[name] += m
    # the baseline from the raised contenders' new MAPs too: no side keeps a poorer optimum
    changed += baseline_from(fitted, [n for n, m in raised.items() if m], log, pool.map)
    lp_base = fitted["baseline"][2]
    scored = []
    for key, (lp_all, th_all, lpmap, secs) in fitted.items():
        if key != "baseline" and lpmap - lp_base <= _stage1_min_gain(key):
            # stage 1 of the screen: no better in-sample fit, no held-out scoring (rule (e))
            full_fits[key] = (lp_all, th_all, None)
            out["models"][key] = {"log_prob_map": lpmap, "map": F.values(lp_all.space, th_all),
                                  "rmse_map": F.rmse(lp_all, th_all), "screened_out": True,
                                  "seconds": secs}
            log(f"screen {key}: MAP {lpmap - lp_base:+.1f} nats over the baseline's "
                f"on all units (<= {_stage1_min_gain(key):.3g}): not scored held out, MAP RMSE "
                f"{out['models'][key]['rmse_map']:.4g} N ({secs:.1f} s)")
            continue
        scored.append(key)
    recs = {key: F.unit_records(fitted[key][0], folds, cfg) for key in scored}
    trains = [[t.id for t in train] for train, _ in folds]
    res = pool.map(_score_model, [(fitted[k][0], fitted[k][1], recs[k], trains) for k in scored])
    for key, r in zip(scored, res):
        lp_all, th_all, lpmap, secs = fitted[key]
        fold_fits[key] = [(LogPosterior(lp_all.space, [recs[key][i] for i in train]), th_k, lp_k)
                          for train, (th_k, lp_k, _) in zip(trains, r["folds"])]
        full_fits[key] = (lp_all, th_all, recs[key])
        out["models"][key] = {"log_prob_map": lpmap, "map": F.values(lp_all.space, th_all),
                              "rmse_map": F.rmse(lp_all, th_all),
                              "fold_log_evidence": [z for _, _, z in r["folds"]]}
        set_evidence(out["models"][key], r["log_z"])
        out["models"][key]["seconds"] = secs + r["seconds"]
        ll = out["models"][key]["heldout_loglik"]
        log(f"screen {key}: held-out log-likelihood {sum(ll):.1f} nats over {len(ll)} unit(s), "
            f"MAP RMSE {out['models'][key]['rmse_map']:.4g} N ({secs + r['seconds']:.1f} s)")
    nested_recheck(out, full_fits, fold_fits, folds, log, changed, moved, MIN_UNIT_GAIN)
    return out
