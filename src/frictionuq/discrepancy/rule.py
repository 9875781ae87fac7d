"""The decision rule of the discrepancy workflow: which screened candidate is named, or "none".

discrepancy.screen scores every candidate on each level (held-out log predictive densities and
the MAP on all units); rank() sums them over levels and decide() applies the rule.

Decision rule (guards against false positives): the best candidate by ELPD gain is named only if
  (a) it improves the held-out units by more than MIN_UNIT_GAIN = 5 nats each (a likelihood
      ratio of e^5 ~ 150 on data the candidate never saw), all of them when there are one or two
      units, all but one when there are three or more (an effect can be invisible in one test:
      a thermal fade in a short replay that dissipates little energy), and it loses no unit more
      than MAX_UNIT_LOSS = 5 nats (a spurious parameter fitted to noise in some tests loses
      density on the others);
  (b) its total gain exceeds its threshold, min_gain(effect), and, with 5 or more held-out
      units, 2 SE (with K < 5 units the SE has K - 1 degrees of freedom and says little; (a) is
      then the guard). The threshold is MIN_GAIN = 20 nats, except for an effect whose null is
      regular (params.REGULAR_NULL: stage2_nonlinear, applied_tracking), where it is half the
      1 - ALPHA_REGULAR = 99.9 % point of chi2 with its number of parameters (5.4 nats for one),
      and (a)'s gain on all units but one is not asked of it (its loss guard is). Why
      (2026-12-04, night): MIN_GAIN and (a)'s spread are the guards for effects with a parameter
      that is free when the effect is off (a period, a decay length): their best fit to noise
      searches a family of shapes and has no known law (clean campaigns' in-sample gains reached
      +9.1 nats for eccentricity). For a regular effect, Wilks's theorem bounds the in-sample
      gain on data without it: P(map_gain > min_gain) <= ALPHA_REGULAR per level, so (e) alone
      keeps its false alarms under 0.1 % per effect, and two regular effects under 0.2 % per
      campaign. A hidden stage-2 curvature shows mostly in one test (in the BRFD the replay,
      whose reversals put more of its travel in stage 2): held out +8.1 to +15.1 nats on 6 of 7
      hidden campaigns scored, e.g. -1.0 / 6.8 / 9.3, which (a)'s spread and MIN_GAIN refused
      (named on 4 of 26 hidden campaigns), while on 32 clean ones its in-sample gain never
      passed +1.4 (held out, +0.4 at most on 12);
  (c) it is the candidate with the largest gain: when the best explanation fails (a), (b), (e)
      or (f), a weaker one that passes is not named (seen with a hidden thermal_fade: fade +225
      nats but one replay made worse by 22, reversal_hump +29 passing: a wrong name);
  (d) with 5 or more held-out units, among candidates passing (a)-(b) whose gain is within 2 SE
      of the best (paired), the one with the fewest parameters is named (with 3 units the paired
      SE is so loose that applied_tracking, +129 nats, counted as "within 2 SE" of +1147).
  (e) fitted to all the units of each level, it beats the baseline's maximum log-posterior by
      more than min_gain(effect) nats on every level (stage 1) and in total (map_gain). The MAP heights
      come from optimisation alone; the held-out scores also rest on each fit's curvature
      (Laplace), which is only local. A real effect that predicts held-out units better by tens
      of nats fits the units it sees better by at least as much; a held-out gain the in-sample
      fit does not show comes from the approximation. Seen on the clean BRFD campaign of seed
      12: eccentricity gained +10.2 / +23.6 / -2.2 held out (passing (a)-(b)) with a MAP only
      3.6 nats above the baseline's, because the baseline's fold fit sat on a wide ridge
      (1/2 log det Sigma -42.4) and the candidate's 2.7 nats higher where the ridge is narrow
      (-61.7); and on the real 80 lb records of dataset 1, rate_strengthening +25.2 held out
      with +4.2 in-sample. (c) and (d) apply to the candidates scored held out.
  (f) a force effect (not a noise effect, params.NOISE_EFFECTS) lowers the RMSE of the force at
      its MAP on all units (mean over levels) below the baseline's. The gap the workflow closes
      is the force the model fails to simulate; under the AR(1) likelihood, whose phi is near 1
      on records sampled at 100-1000 Hz, a candidate can gain by making the residual smoother
      (its innovations smaller) while moving the force further from the data. Seen on the real
      36 lb sines of dataset 2 at 2 and 1 Hz: applied_tracking gained +200.9 nats held out
      (+161.7 / +39.2) and +367.7 in-sample while its MAP's RMSE rose from 3,172 to 3,661 N
      (eccentricity, second: +166 held out, RMSE 2,766 N); speed_weakening on dataset 1 the
      same way (+45 to +87 nats in-sample, RMSE higher at five of six levels, no gain with
      independent errors). Such a best candidate fails the rule, and by (c) no weaker one is
      named in its place.
Otherwise the answer is "none". The other candidates that pass the whole rule are listed with
the name (`alternatives`: their gains and how far behind), and a name with one of them within
MIN_GAIN nats is marked not decisive: on real records two effects can explain much the same part
of the gap, and which of them the searches put ahead can turn on the kernel's rounding
(alternatives() says where this was seen).
Calibration on clean campaigns (benchmarks/bench_discover.py --effects none, short records):
with the plug-in score, screened on the kept samples, the best candidate's gains reached 67.7
nats on one held-out test but never two tests above 5 nats; screened at the raw rate, BRFD seed
5 was a false alarm (discrepancy.screen's docstring). Figures with the evidence ratio: README, issue 5, and
docs/log-discrepancy.md.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from .. import params as P
from ..infer.elpd import elpd_total

MIN_GAIN = 20.0
MIN_UNIT_GAIN = 5.0
MAX_UNIT_LOSS = 5.0
MIN_UNITS_FOR_SE = 5
#: the false-alarm rate, per level, of a regular effect's in-sample condition (min_gain)
ALPHA_REGULAR = 1e-3


def min_gain(effect: str) -> float:
    """The gain (nats) that rules (b) and (e) ask of `effect`, held out in total and in its MAP on
    all units (on each level in stage 1): MIN_GAIN, or for an effect whose null is regular
    (params.REGULAR_NULL) half the 1 - ALPHA_REGULAR point of chi2 with its number of parameters
    (the module docstring, rule (b), says why)."""
    if effect in P.REGULAR_NULL:
        return float(chi2.ppf(1.0 - ALPHA_REGULAR, len(P.EFFECTS[effect])) / 2.0)
    return MIN_GAIN


def thresholds(effects) -> str:
    """The thresholds of rules (b) and (e) for these effects, in words: "20 nats (stage2_nonlinear:
    5.4)"."""
    low = [f"{e}: {min_gain(e):.1f}" for e in effects if min_gain(e) != MIN_GAIN]
    return f"{MIN_GAIN:g} nats" + (f" ({', '.join(low)})" if low else "")


#: the decision rule in one line (recorded in discrepancy.json; the module docstring says why)
RULE = (f"rule.py: held-out scores are log predictive densities log Z(all units) - log Z(the "
        f"others), Laplace evidences at each fit's maximum; the candidate with the largest held-out ELPD "
        f"gain is named if it improves the "
        f"held-out units by > {MIN_UNIT_GAIN:g} nats (all of 1-2, all but one of 3+), makes none "
        f"worse by > {MAX_UNIT_LOSS:g} nats and gains > {MIN_GAIN:g} nats in total (and > 2 SE with "
        f"{MIN_UNITS_FOR_SE}+ units), its MAP on all units is > {MIN_GAIN:g} nats above the "
        f"baseline's (for an effect whose null is regular, {', '.join(sorted(P.REGULAR_NULL))}: "
        f"> half the {100 * (1 - ALPHA_REGULAR):g} % point of chi2 with its number of parameters, "
        "held out and in its MAP, and the per-unit gains not asked) and, for a force effect, has "
        f"a lower RMSE than the baseline's; with "
        f"{MIN_UNITS_FOR_SE}+ units an effect with fewer parameters within 2 SE is preferred; "
        f"otherwise none; the other candidates passing are listed, and one within {MIN_GAIN:g} "
        "nats of the named makes the name not decisive")


def rank(levels: list[dict]) -> list[dict]:
    """Candidates ranked by held-out ELPD gain over the baseline, summed over levels; then those
    not scored held out on some level (stage 1, rule (e)), by their in-sample MAP gain, with
    elpd_gain None."""
    names = [n for n in levels[0]["models"] if n != "baseline"]
    rmse_base = float(np.mean([lv["models"]["baseline"]["rmse_map"] for lv in levels]))
    rows, out = [], []
    for n in names:
        map_gain = sum(lv["models"][n]["log_prob_map"] - lv["models"]["baseline"]["log_prob_map"]
                       for lv in levels)
        row = {"effect": n, "map_gain": float(map_gain), "n_params": len(P.EFFECTS[n]),
               "rmse_map": float(np.mean([lv["models"][n]["rmse_map"] for lv in levels])),
               "rmse_baseline": rmse_base}
        if any(lv["models"][n].get("screened_out") for lv in levels):
            out.append({**row, "elpd_gain": None, "elpd_gain_se": None, "gain_per_unit": [],
                        "min_unit_gain": None, "screened_out": True})
            continue
        g = np.concatenate([np.subtract(lv["models"][n]["heldout_loglik"],
                                        lv["models"]["baseline"]["heldout_loglik"]) for lv in levels])
        tot = elpd_total(g)
        rows.append({**row, "elpd_gain": tot["elpd"], "elpd_gain_se": tot["se"],
                     "gain_per_unit": g.tolist(), "min_unit_gain": float(g.min()),
                     "screened_out": False})
    rows.sort(key=lambda r: -r["elpd_gain"])
    out.sort(key=lambda r: -r["map_gain"])
    return rows + out


def _raises_rmse(r) -> bool:
    """Rule (f): a force effect whose MAP does not lower the RMSE below the baseline's."""
    return r["effect"] not in P.NOISE_EFFECTS and not r["rmse_map"] < r["rmse_baseline"]


def _passes_likelihood(r) -> bool:
    """Rules (a), (b) and (e): the held-out and in-sample gains."""
    g = np.asarray(r["gain_per_unit"], float)
    k = g.size
    need = k if k <= 2 else k - 1
    spread = r["effect"] in P.REGULAR_NULL or int(np.sum(g > MIN_UNIT_GAIN)) >= need
    se_ok = k < MIN_UNITS_FOR_SE or r["elpd_gain"] > 2 * r["elpd_gain_se"]
    c = min_gain(r["effect"])
    return (spread and float(g.min()) > -MAX_UNIT_LOSS and r["elpd_gain"] > c and se_ok
            and r["map_gain"] > c)


def _passes(r) -> bool:
    return _passes_likelihood(r) and not _raises_rmse(r)


def _rmse_note(r, sep: str = "; ") -> str:
    """The clause of a reason that says a candidate fails rule (f) (after sep), or ""."""
    if not _raises_rmse(r):
        return ""
    return (f"{sep}its MAP does not lower the RMSE ({r['rmse_baseline']:.4g} N, the baseline's, -> "
            f"{r['rmse_map']:.4g} N): the likelihood gain is a smoother residual, not a closer force")


def decide(ranked: list[dict], levels: list[dict] | None = None) -> tuple[str, str]:
    """(named effect or "none", the reason) by the module's decision rule."""
    if not ranked:
        return "none", "no candidate effect could be screened"
    scored = [r for r in ranked if not r.get("screened_out")]
    if not scored:
        b = max(ranked, key=lambda r: r["map_gain"])
        return "none", (f"no candidate fits all units better than the baseline by > "
                        f"{thresholds(r['effect'] for r in ranked)} at its MAP (best: "
                        f"{b['effect']}, {b['map_gain']:+.1f}), so none was scored held out")
    ranked = scored
    ok = [r for r in ranked if _passes(r)]
    if ok and ok[0] is not ranked[0]:
        b, w = ranked[0], ok[0]
        return "none", (f"the best candidate, {b['effect']} (gain {b['elpd_gain']:.1f} nats, per unit "
                        + ", ".join(f"{v:.1f}" for v in b["gain_per_unit"]) + "), does not pass the "
                        f"rule{_rmse_note(b)}; {w['effect']} passes with a smaller gain "
                        f"({w['elpd_gain']:.1f}) but naming a weaker explanation than the best one "
                        "would be a guess")
    if not ok:
        b = ranked[0]
        g = ", ".join(f"{v:.1f}" for v in b["gain_per_unit"])
        if _passes_likelihood(b):        # only rule (f) fails
            return "none", (f"the best candidate, {b['effect']} (gain {b['elpd_gain']:.1f} +- "
                            f"{b['elpd_gain_se']:.1f} nats held out, per unit {g}; MAP "
                            f"{b['map_gain']:+.1f}), passes the likelihood conditions, but"
                            + _rmse_note(b, sep=" "))
        return "none", (f"no candidate improves the held-out units by > {MIN_UNIT_GAIN:g} nats (all "
                        f"but one of 3 or more), loses none by > {MAX_UNIT_LOSS:g} and gains > "
                        f"{thresholds(r['effect'] for r in ranked)} in total, held out and in its "
                        f"MAP on all units (best: "
                        f"{b['effect']}, gain {b['elpd_gain']:.1f} +- {b['elpd_gain_se']:.1f}, per "
                        f"unit {g}; MAP {b['map_gain']:+.1f}){_rmse_note(b)}")
    best = ok[0]
    close = []
    for r in (ok[1:] if len(best["gain_per_unit"]) >= MIN_UNITS_FOR_SE else []):
        d = np.subtract(best["gain_per_unit"], r["gain_per_unit"])
        se = math.sqrt(d.size * np.var(d, ddof=1)) if d.size > 1 else float("inf")
        if d.sum() <= 2 * se:
            close.append(r)
    simpler = min([best] + close, key=lambda r: (r["n_params"], -r["elpd_gain"]))
    why = (f"{simpler['effect']}: held-out gain {simpler['elpd_gain']:.1f} +- "
           f"{simpler['elpd_gain_se']:.1f} nats (per held-out unit: "
           + ", ".join(f"{v:.1f}" for v in simpler["gain_per_unit"]) + ")")
    if simpler is not best:
        why += f" (within 2 SE of {best['effect']}, fewer parameters)"
    return simpler["effect"], why + _alternatives_note(alternatives(ranked, simpler["effect"]))


def alternatives(ranked: list[dict], named: str) -> list[dict]:
    """The other candidates that pass the whole rule, by held-out gain: [{"effect", "elpd_gain",
    "behind"}] (behind: nats of held-out gain fewer than the named effect's; negative for a
    stronger one that rule (d) passed over for having more parameters). Empty for "none".

    Why they are reported (2026-11-29): on the real 70 lb records of dataset 1, round 2 (against
    3-stage + chatter), takeup_overshoot, thermal_fade and eccentricity all passed the rule, the
    overshoot named 37 nats ahead of the fade; the same run with numba compiling the kernel for a
    generic x86-64 CPU instead of the host's (NUMBA_CPU_NAME=generic: only the rounding differs)
    named thermal_fade, 12 nats ahead of the overshoot. Each candidate's multi-start search ends
    in optima that move by tens of nats with such rounding, so a name chosen over another that
    also passes by a margin of that size rests on the search, not on the data. (Since then the
    contenders are refitted from each other's MAPs, recheck.peer_refit, and both codes name the
    overshoot; the gains still move, 202.5 against 250.5 nats.)"""
    if named == "none":
        return []
    by = {r["effect"]: r for r in ranked if not r.get("screened_out")}
    if named not in by:
        return []
    top = by[named]["elpd_gain"]
    return [{"effect": r["effect"], "elpd_gain": r["elpd_gain"], "behind": top - r["elpd_gain"]}
            for r in ranked if not r.get("screened_out") and r["effect"] != named and _passes(r)]


def _alternatives_note(alts: list[dict]) -> str:
    """The clause of a naming reason that lists the other candidates passing the rule, and says
    the name is not decisive when one is within MIN_GAIN nats of it."""
    if not alts:
        return ""
    near = [a["effect"] for a in alts if a["behind"] <= MIN_GAIN]
    return ("; also passing the rule: " + ", ".join(
        f"{a['effect']} ({a['elpd_gain']:+.1f}, {a['behind']:.1f} nats behind)" for a in alts)
        + (f"; not decisive: {', '.join(near)} within {MIN_GAIN:g} nats" if near else ""))


def shown_reason(named: str, reason: str) -> str:
    """The reason without the named effect's name in front ("eccentricity: held-out gain ..."
    reads "held-out gain ..." after "named effect: eccentricity")."""
    return reason[len(named) + 2:] if reason.startswith(f"{named}: ") else reason
