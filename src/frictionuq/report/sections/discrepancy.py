"""Section "discrepancy": what `frictionuq discover` (the workflow's discrepancy stage) found:
the named effect or none (and, with --max-effects, the later rounds), the candidates ranked by
held-out ELPD gain, RMSE before and after, the effects' parameters with intervals."""
from __future__ import annotations

import json

from .. import blocks as B
from ...params import NOISE_EFFECTS
from ...discrepancy import seedcheck
from ...discrepancy.gap import worse_sentence
from ...discrepancy.rule import shown_reason
from ... import units
from ..tables import num, scaled, table
from ...wording import count


def _capital(s: str) -> str:
    return s[:1].upper() + s[1:]


def build(ctx, folder=None) -> list[dict]:
    """Blocks of the section from `folder` (default: the run's discrepancy/ folder), the output
    folder of `frictionuq discover`."""
    folder = ctx.run_dir / "discrepancy" if folder is None else folder
    p = folder / "discrepancy.json"
    if not p.is_file() or ctx.disabled("discrepancy"):
        return [B.note("The discrepancy stage was not run in this workflow ([discrepancy] enabled = "
                       "false); `frictionuq discover CAMPAIGN --out DIR` runs it on its own.")]
    d = json.loads(p.read_text())
    named = d.get("named_effects", [] if d["named_effect"] == "none" else [d["named_effect"]])
    out = [B.para(f"Named effect: {d['named_effect']}. "
                  f"{_capital(shown_reason(d['named_effect'], d['reason']))}.")]
    for r in d.get("rounds", [])[1:]:       # forward selection (discover --max-effects)
        out.append(B.para(f"Round {r['round']}, against the 3-stage model with "
                          f"{' + '.join(r['baseline_effects'])}: named {r['named_effect']} "
                          f"({shown_reason(r['named_effect'], r['reason'])})."))
    if d.get("seed_check"):          # discover --check-seed
        out.append(B.para(seedcheck.sentence(d["seed_check"])))
    if d["named_effect"] != "none" and (w := worse_sentence(d)):
        out.append(B.warn(_capital(w) + "."))
    after = f" (with {' + '.join(named)})" if len(named) > 1 else ""
    out.append(B.para(f"RMSE before (baseline 3-stage, at its MAP): {num(d['rmse_before'])} N; "
                      f"after{after}: {num(d['rmse_after'])} N"
                      + (f"; estimated noise scale {num(d['noise_scale'])} N." if d.get("noise_scale") else ".")))
    for e in (e for e in named if e in NOISE_EFFECTS):
        out.append(B.para(
            f"{e} is a noise effect: it changes the measurement noise (more of it in "
            "a window after each reversal), not the force, so the loops and the RMSE barely move "
            "and the noise scale is the rms of the fitted noise sd over the records. The gap it "
            "closes is in the held-out log-likelihood (the candidates' table) and in the bands, "
            "which widen in the window; the residual diagnostics of the model with it use the "
            "residual divided by its noise gain."))
    for b in d.get("between_tests", []):
        out.append(B.para(
            f"Level {b['level']}: " + (
                f"the tests do not share one force zero: their mean residuals about the baseline's "
                f"zero spread by {num(b['spread_N'])} N where its noise allows "
                f"{num(min(b['se_N'].values()))}-{num(max(b['se_N'].values()))} N per test "
                f"(chi-square {num(b['chi2'])} on {count(b['df'], 'degree')} of freedom, p = "
                f"{b['p_value']:.2g} at {100 * b['alpha']:g} %). No effect of the library moves a "
                "test's zero; fitting with each test's own (--force-offset per_test, or a "
                "workflow's [fit] force_offset = \"per_test\") models it, and the per-test table "
                "below gives each test's mean residual."
                if b["significant"] else
                f"the tests share one force zero within the noise (between-tests check, p = "
                f"{b['p_value']:.2g}).")))
    out.append(_candidates(d["candidates"], "candidates, ranked" + (
        " (round 1, against the plain 3-stage model)" if len(d.get("rounds", [])) > 1 else "")))
    for r in d.get("rounds", [])[1:]:
        out.append(_candidates(r["candidates"], f"round {r['round']}: candidates against 3-stage + "
                               f"{' + '.join(r['baseline_effects'])}, ranked"))
    unconverged = [r["id"] for r in d.get("refit") or [] if not r.get("converged")]
    if unconverged:
        out.append(B.warn(f"The refit did NOT converge ({', '.join(unconverged)}: R-hat above "
                          "1.01 or ESS below 400 for some parameter at the step cap): the "
                          "intervals below, and the RMSE after, are indicative only; run it "
                          "longer (--max-steps)."))
    if d.get("effect_parameters"):
        rows = []
        for n, s in d["effect_parameters"].items():
            unit, fac = units.display(s["unit"])
            rows.append((n, *(scaled(s[k], fac) for k in ("mean", "q2.5", "q97.5")), unit))
        out.append(B.html(table(["parameter", "mean", "2.5 %", "97.5 %", "unit"], rows,
                                caption="the named effects' parameters (MCMC refit)" if len(named) > 1
                                else "the named effect's parameters (MCMC refit)")))
    elif d.get("effect_parameters_map"):
        rows = []
        for lid, vals in d["effect_parameters_map"].items():
            for n, v in vals.items():
                unit, fac = units.display(v["unit"])
                rows.append((lid, n, scaled(v["value"], fac), unit))
        out.append(B.html(table(["level", "parameter", "value at the MAP", "unit"], rows,
                                caption="the named effect's parameters at its MAP (run with "
                                        "--no-refit: no MCMC refit, so no intervals)")))
    out.extend(gap_blocks(folder, d))
    out.append(B.note("Decision rule: " + d.get("decision_rule", "")))
    return out


def _candidates(cands: list[dict], caption: str) -> dict:
    """The table of one round's candidates."""
    if cands and cands[0].get("rmse_before") is not None:     # the RMSE rule (f) compares with
        caption += f"; the baseline's RMSE at its MAP {num(cands[0]['rmse_before'])} N"
    rows = [(c["effect"], "not scored (MAP gain too small)" if c.get("screened_out") else num(c["elpd_gain"]),
             num(c["elpd_gain_se"]), ", ".join(num(g) for g in c["gain_per_unit"]) or num(None),
             num(c["map_gain"]) if "map_gain" in c else "-",
             num(c["min_gain"]) if c.get("min_gain") is not None else "-",
             num(c["rmse_after"]), c["n_params"])
            for c in cands]
    return B.html(table(["candidate effect", "held-out ELPD gain (nats)", "SE (nats)",
                         "gain per held-out unit (nats)", "MAP gain on all units (nats)",
                         "gain the rule asks, held out and at the MAP (nats)",
                         "RMSE at its MAP (N)", "parameters"], rows, caption=caption))


def gap_blocks(folder, d: dict) -> list[dict]:
    """The gap before (baseline) and after (with the named effect), per test: RMSE and the views
    with significant residual structure, the loops of both models over the data, the residual
    signatures."""
    out = []
    diags = d.get("diagnostics", [])
    rows = [(g["test"], g["model"], num(g["rmse"]) if "rmse" in g else "-",
             num(g["mean_residual"]) if "mean_residual" in g else "-",
             ", ".join(g["significant_views"]) or "none") for g in diags]
    if rows:
        out.append(B.html(table(["test", "model", "RMSE at its MAP (N)", "mean residual (N)",
                                 "views with significant structure (Holm, 1 %)"],
                                rows, caption="the gap before and after, per test")))
    comb = d.get("combined_diagnostics", [])
    rows = [(c["level"], c["model"], ", ".join(c["tests"]) or "-", ", ".join(c["excluded"]) or "-",
             ", ".join(c["significant"]) or "none") for c in comb]
    if rows:
        out.append(B.html(table(
            ["level", "model", "tests combined", "not combined (null blocks too short)",
             f"views with significant structure (Holm, {100 * comb[0]['alpha']:g} %, tests combined)"],
            rows, caption="the level's tests taken together: Fisher's combination of the tests' "
                          "p-values per view, Holm over the views (a structure each test shows "
                          "too weakly on its own)")))
    chat = sorted({g["test"] for g in diags if g["model"] == "baseline"
                   and any(v.startswith("chatter") for v in g["significant_views"])})
    if chat:
        out.append(B.para(
            f"High-frequency bursts after the reversals (stick-slip chatter) are significant in "
            f"{', '.join(chat)}: the residual above the band shown carries more power at some "
            "travels since the reversal than at others, and not as a shape repeated every cycle "
            "(that part is removed before the test). No deterministic effect of the library can "
            "close this part of the gap: a force model cannot follow an oscillation whose phase "
            "changes from cycle to cycle. The noise effect chatter describes it as more "
            "measurement noise in a window after each reversal, so that the bands widen there "
            "(frictionuq fit --effect chatter; discover screens it with --extra-effect chatter)."))
    seen = set()
    for g in diags:
        name = g.get("loop_figure")
        if name and name not in seen and (folder / name).is_file():
            seen.add(name)
            out.append(B.figure((folder / name).read_bytes(), f"loops {g['test']}",
                                f"{g['test']}: measured force (grey) against displacement with the "
                                "baseline and the model with the named effect, and their residuals "
                                "against time (RMSE in the legend)"))
    for g in diags:
        p = folder / g["figure"]
        if p.is_file():
            out.append(B.figure(p.read_bytes(), f"residuals {g['test']} {g['model']}",
                                f"{g['test']}, {g['model']}: binned residual means (N) per view, "
                                "significant views marked; position-locked spectrum; high-frequency "
                                "bursts against the travel since the reversal"))
    return out
