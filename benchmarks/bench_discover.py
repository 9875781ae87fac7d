"""Benchmark of the discrepancy workflow (issue 5, items 4 and 6): hidden-effect campaigns of both
paper devices, one per effect of the library plus campaigns with nothing hidden, each named by
`discover`; prints per campaign the hidden and named effect, the gain of the named one and the
wall time, then the hit rate and false-alarm count, in one run.

    .venv/bin/python benchmarks/bench_discover.py [--full] [--refit] [--seeds 1 2] [--devices brfd mfd]
        [--effects none eccentricity ...] [--extra-effects takeup_overshoot] [--simulate-at raw|kept]
        [--also chatter --max-effects 2] [--chatter-form bursts] [--jobs 2]
        [--samples-per-cycle 400] [--max-steps 3000] [--sampler chains|ensemble|both] [--verbose]
        [--rows ROWS.jsonl] [--score-all] [--truth-fit]

--full: full-length records (two harmonics of ~5,000 samples and a Kobe replay, the issue's speed
case) under the CLI's own configuration (`frictionuq discover CAMPAIGN --out DIR`: 400 samples
per cycle, the refit run until it converges); default: the short CI campaigns under the CI
tests' (100 samples per cycle, the refit capped at 3,000 stored steps). --refit: also the MCMC
refit with the named effect (parameters inside their 95 % intervals, rmse_after / noise scale,
whether it converged). --sampler: the refit's
stored run as the default (16 independent chains) or as the default before 2026-12-01 (the
burn-in's ensemble: bench_fit.py's SAMPLERS), or both side by side on the same campaigns (the
screening runs again for each). Not a test: figures only.

Side by side, give each run one numba thread (NUMBA_NUM_THREADS=1): with --jobs 1 the
simulations of a batch run on every core, and three or four such runs on 2 cores took 350-600 s
per clean short campaign, against 100-200 s for three with one thread each (2026-12-03).
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path
from unittest import mock

from frictionuq import atomic
from frictionuq import params as P
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy import rule, screen
from frictionuq.discrepancy.discover import discover
from frictionuq.discrepancy.hidden import hidden_campaign
from frictionuq.discrepancy.truthfit import truth_fit_gain
from frictionuq.errors import InputError
from frictionuq.infer.fit import FitConfig, plan
from frictionuq.infer.sampler import SamplerConfig

from bench_fit import SAMPLERS


#: the refit's cap on stored steps and the fits' decimation of the short campaigns: those of the
#: CI's end-to-end cases (tests/discover_check.py)
SHORT_MAX_STEPS = 3000
SHORT_SAMPLES_PER_CYCLE = 100.0


def bench_config(full: bool, samples_per_cycle: float | None, max_steps: int | None,
                 simulate_at: str, sampler: dict) -> FitConfig:
    """The discover configuration of a run: the CI tests' on the short campaigns; on the full
    ones (the issue's speed case) what `frictionuq discover CAMPAIGN --out DIR` runs, FitConfig's
    and SamplerConfig's defaults, so that the figure is the one a user gets. Until 2026-12-04
    --full ran the short campaigns' 100 samples per cycle and a 3,000-step cap too, where the
    refit mostly stopped unconverged (docs/log-discrepancy.md)."""
    spc = samples_per_cycle if samples_per_cycle is not None else (
        FitConfig().samples_per_cycle if full else SHORT_SAMPLES_PER_CYCLE)
    steps = max_steps if max_steps is not None else (
        SamplerConfig().max_steps if full else SHORT_MAX_STEPS)
    return FitConfig(samples_per_cycle=spc, simulate_at=simulate_at,
                     sampler=SamplerConfig(max_steps=steps, progress=False, **sampler))


def campaign_row(device: str, seed: int, ans: dict, doc: dict, secs: float, refit: bool) -> dict:
    """One campaign's figures from the generator's answer (ans) and discover's discrepancy.json
    (doc): hidden and named effects, RMSE, time, and with --refit whether the refit converged and
    how many of the hidden parameters fall inside their 95 % intervals; "candidates" holds every
    candidate's in-sample (MAP) and held-out gains and "hidden_parameters" the generator's draw,
    for --rows (benchmarks/gain_table.py reads them)."""
    hidden = sorted(ans["effects"])
    row = {"device": device, "seed": seed, "hidden": "+".join(hidden) or "none",
           "named": "+".join(doc["named_effects"]) or "none",
           "right": sorted(doc["named_effects"]) == hidden,
           "seconds": secs, "rmse_before": doc["rmse_before"],
           "rmse_after": doc["rmse_after"], "noise": ans["noise_sd_N"],
           # with a noise effect (chatter) the rms of the generator's sd over the records
           "noise_rms": ans.get("noise_rms_N", ans["noise_sd_N"])}
    if refit and hidden and row["right"]:
        ok = [doc["effect_parameters"][n]["q2.5"] <= v <= doc["effect_parameters"][n]["q97.5"]
              for q in ans["effects"].values() for n, v in q.items()
              if n in doc["effect_parameters"]]
        row["params_inside"] = f"{sum(ok)}/{len(ok)}"
    if "refit" in doc:      # did every level's MCMC refit converge?
        row["refit_converged"] = all(e["converged"] for e in doc["refit"])
    best = doc["candidates"][0] if doc["candidates"] else {}
    g = best.get("elpd_gain")
    row["best"] = f"{best.get('effect')} " + (f"{g:+.1f}" if g is not None else
                                             f"MAP {best.get('map_gain', 0):+.1f}")
    row["per_unit"] = {c["effect"]: [round(g, 1) for g in c["gain_per_unit"]]
                       for c in doc["candidates"][:2]}
    row["map_gain"] = {c["effect"]: round(c["map_gain"], 1) for c in doc["candidates"][:2]}
    row["candidates"] = [{k: c[k] for k in ("effect", "n_params", "map_gain", "elpd_gain",
                                            "gain_per_unit", "screened_out")}
                         for c in doc["candidates"]]
    row["hidden_parameters"] = {e: dict(q) for e, q in ans["effects"].items()}
    # what made it: the package, discover's configuration and seed, the machine
    row["made_by"] = {k: doc.get(k) for k in ("package_version", "config", "seed", "environment")}
    return row


def truth_fit_fields(campaign_dir: Path, ans: dict, doc: dict, cfg: FitConfig) -> dict:
    """--truth-fit: the in-sample evidence the campaign carries for its hidden effect(s)
    (discrepancy.truthfit: the baseline plus the hidden effects fitted from the generating values,
    its gain over the screening's baseline MAP), and the evidence a search could have used: the
    larger of that and the hidden candidate's own in-sample gain (one hidden effect only).
    "no_evidence": that evidence is under the rule's threshold for the effect (rule.min_gain), so
    no search could name it at the rule's false-alarm rate; a miss with evidence over it is the
    search's or the held-out scoring's."""
    level = doc["levels"][0]["models"]["baseline"]
    # the records the baseline's MAP was scored on: with a noise effect among the candidates
    # discover keeps every model's records at NOISE_EFFECT_MIN_KEPT_HZ or more (its document's
    # config), and a truth fit on the config's own decimation would score fewer samples (seen
    # 2026-12-05: +3,631 nats for a hidden speed_weakening whose candidate gained +165)
    cfg = replace(cfg, min_kept_hz=doc["config"].get("min_kept_hz"))
    tests = plan(load_campaign(campaign_dir), "applied", cfg)[0].tests
    o = truth_fit_gain(tests, cfg, ans, level["map"], level["log_prob_map"])
    out = {"truth_fit_gain": o["gain"]}
    if len(ans["effects"]) == 1:
        (eff,) = ans["effects"]
        own = next((c["map_gain"] for c in doc["candidates"] if c["effect"] == eff), -math.inf)
        out["evidence"] = max(o["gain"], own)
        out["min_gain"] = rule.min_gain(eff)
        out["no_evidence"] = out["evidence"] < out["min_gain"]
    return out


def refuse_bad_rows(ap: argparse.ArgumentParser, rows: Path | None) -> None:
    """--rows refused before any campaign runs (a folder, a parent that cannot be written): the
    parser's one-line usage error, exit code 2."""
    if rows is not None:
        if rows.is_dir():
            ap.error(f"--rows {rows}: a folder; give a file path")
        try:
            atomic.writable_parent(rows, create=False)
        except InputError as e:
            ap.error(f"--rows: {e}")


class RowLog(list):
    """The rows so far; with a path, all of them rewritten there as JSON lines after each
    campaign (atomically: an interrupted run leaves the rows of its finished campaigns)."""

    def __init__(self, path: Path | None):
        super().__init__()
        self.path = path

    def append(self, row: dict) -> None:
        super().append(row)
        if self.path is not None:
            atomic.write_text(self.path, "".join(json.dumps(r, default=float) + "\n" for r in self))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--full", action="store_true")
    ap.add_argument("--refit", action="store_true")
    ap.add_argument("--jobs", type=int, default=1, help="discover's processes for the screening's "
                    "fits (the CLI's default is every core; 1 here, to run campaigns side by side)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[11])
    ap.add_argument("--devices", nargs="+", default=["brfd", "mfd"])
    ap.add_argument("--effects", nargs="+",
                    default=[None] + [e for e in P.EFFECTS if e not in P.BEYOND_SPEC],
                    help="hidden effects (none: nothing hidden); default: none and the spec's library")
    ap.add_argument("--extra-effects", nargs="*", default=[],
                    help="effects beyond the spec to screen as candidates too "
                         f"({', '.join(sorted(P.BEYOND_SPEC))})")
    ap.add_argument("--simulate-at", choices=["raw", "kept"], default="raw",
                    help="decimated records simulated at the raw rate (default, as the fits) or on "
                    "the kept samples (the rule's first calibration)")
    ap.add_argument("--ramp", action="store_true", help="a fourth test in each campaign: a sine "
                    "of geometrically growing amplitude (hidden.ramp_drive)")
    ap.add_argument("--ramp-start", type=float, default=None, help="with --ramp: the first "
                    "cycle's amplitude as a fraction of the full one (default hidden.RAMP_START; "
                    "1: a constant-amplitude control)")
    ap.add_argument("--also", default=None, metavar="EFFECT", help="a second effect hidden in "
                    "every campaign with the first (hidden_campaign(also=)); use with --max-effects 2")
    ap.add_argument("--max-effects", type=int, default=1, help="discover's max_effects: effects "
                    "named one per round (default 1); a campaign counts as right when the named "
                    "set is the hidden set")
    ap.add_argument("--chatter-form", choices=["window", "bursts"], default="window",
                    help="how a hidden chatter is generated: the model's own noise window "
                    "(default) or decaying oscillations from each slip onset "
                    "(hidden.stick_slip_bursts; its parameters are not the model's, so --refit "
                    "checks none of them)")
    ap.add_argument("--samples-per-cycle", type=float, default=None, help="the fits' decimation "
                    "(FitConfig.samples_per_cycle): default 100 on the short campaigns, the CI "
                    "tests' setting; with --full the CLI's default (400, which keeps every sample "
                    "of these 100 Hz campaigns but halves the 0.1 Hz sine's)")
    ap.add_argument("--max-steps", type=int, default=None, help="the refit's cap on stored steps: "
                    f"default {SHORT_MAX_STEPS} on the short campaigns (the CI tests'); with --full "
                    "the CLI's default (none in effect: the refit runs until it converges)")
    ap.add_argument("--sampler", choices=["chains", "ensemble", "both"], default="chains")
    ap.add_argument("--verbose", action="store_true", help="also the top two candidates' gain per "
                    "held-out unit and the decision's reason")
    ap.add_argument("--score-all", action="store_true", help="score every candidate held out, "
                    "whatever its in-sample gain (screen.STAGE1_MIN_GAIN, a cap on each effect's "
                    "stage-1 threshold, lowered to -inf; the "
                    "decision rule unchanged, rule (e) included): the held-out gains of "
                    "candidates stage 1 would not score, e.g. on clean campaigns; slower")
    ap.add_argument("--rows", type=Path, default=None, metavar="PATH", help="also write every "
                    "campaign's row (every candidate's in-sample and held-out gains, the hidden "
                    "parameters) to PATH as JSON lines, after each campaign; "
                    "benchmarks/gain_table.py tabulates them")
    ap.add_argument("--truth-fit", action="store_true", help="also, on each hidden-effect campaign, "
                    "the gain over the baseline's MAP of the baseline plus the hidden effect "
                    "fitted from the generating values (discrepancy.truthfit), so that a miss is "
                    "told apart: too little evidence in the records for the rule's threshold, or "
                    "a search or scoring that fell short (about 1 s a campaign)")
    a = ap.parse_args(argv)
    refuse_bad_rows(ap, a.rows)
    samplers = ["ensemble", "chains"] if a.sampler == "both" else [a.sampler]
    cfgs = {sm: bench_config(a.full, a.samples_per_cycle, a.max_steps, a.simulate_at, SAMPLERS[sm])
            for sm in samplers}
    rows = RowLog(a.rows)
    # --score-all: every candidate scored held out (the rule unchanged); restored after the runs
    with mock.patch.object(screen, "STAGE1_MIN_GAIN", -math.inf if a.score_all else
                           screen.STAGE1_MIN_GAIN), tempfile.TemporaryDirectory() as tmp:
        for dev in a.devices:
            for eff in a.effects:
                eff = None if eff in (None, "none") else eff
                for seed in a.seeds:
                    d = Path(tmp) / f"{dev}-{eff}-{seed}"
                    ans = hidden_campaign(d / "c", dev, eff, seed=seed, short=not a.full,
                                          ramp=a.ramp, also=a.also if eff else None,
                                          chatter_form=a.chatter_form, **({} if a.ramp_start is None else
                                                           {"ramp_start": a.ramp_start}))
                    for sm in samplers:
                        t0 = time.perf_counter()
                        doc = discover(d / "c", d / f"out-{sm}", cfgs[sm], seed=1, refit=a.refit,
                                       extra_effects=tuple(a.extra_effects), max_effects=a.max_effects,
                                       jobs=a.jobs)
                        secs = time.perf_counter() - t0
                        row = campaign_row(dev, seed, ans, doc, secs, a.refit)
                        row["score_all"] = a.score_all
                        if a.truth_fit and ans["effects"] and a.chatter_form != "bursts":
                            row.update(truth_fit_fields(d / "c", ans, doc, cfgs[sm]))
                        rows.append(row)
                        print(f"{dev + ('/' + sm if len(samplers) > 1 else ''):<5} hidden {row['hidden']:<19} named {row['named']:<19} "
                              f"best {row['best']:<28} RMSE {row['rmse_before']:8.1f} -> "
                              f"{row['rmse_after']:8.1f} N (noise {row['noise']:.1f} N"
                              + (f", rms {row['noise_rms']:.1f} N"
                                 if abs(row['noise_rms'] - row['noise']) > 1e-9 * row['noise'] else "")
                              + f"; x{row['rmse_after'] / row['noise_rms']:.2f}) "
                              f"{row.get('params_inside', ''):>5} {secs:6.1f} s"
                              + {True: ", refit converged", False: ", refit NOT converged",
                                 None: ""}[row.get("refit_converged")]
                              + (f", truth fit {row['truth_fit_gain']:+.1f} nats (evidence "
                                 f"{row['evidence']:+.1f}, needs {row['min_gain']:.3g})"
                                 if "evidence" in row else ""), flush=True)
                        if a.verbose:
                            st = doc["seconds_by_stage"]
                            print("      " + ", ".join(f"{k} {v:.1f} s" for k, v in st.items()), flush=True)
                            print(f"      gain per held-out unit (nats): {row['per_unit']}; MAP gain on "
                                  f"all units: {row['map_gain']}; {doc['reason']}", flush=True)
                            for r in doc["rounds"][1:]:
                                c = r["candidates"][0] if r["candidates"] else {}
                                print(f"      round {r['round']}: named {r['named_effect']}; best "
                                      f"{c.get('effect')} per unit {[round(g, 1) for g in c.get('gain_per_unit', [])]}"
                                      f" MAP {c.get('map_gain', 0):+.1f}; {r['reason']}", flush=True)
    hits = sum(r["right"] for r in rows if r["hidden"] != "none")
    n_eff = sum(r["hidden"] != "none" for r in rows)
    fa = sum(r["named"] != "none" for r in rows if r["hidden"] == "none")
    n_none = sum(r["hidden"] == "none" for r in rows)
    print(f"hidden effects named correctly: {hits}/{n_eff}; false alarms on clean campaigns: "
          f"{fa}/{n_none}; mean time per campaign {sum(r['seconds'] for r in rows) / len(rows):.1f} s "
          f"({'full' if a.full else 'short'} records{', with refit' if a.refit else ''})")
    missed = [r for r in rows if r["hidden"] != "none" and not r["right"] and "no_evidence" in r]
    if a.truth_fit:
        print(f"misses whose records carry less in-sample evidence than the rule's threshold "
              f"(truth fit): {sum(r['no_evidence'] for r in missed)}/{len(missed)}; hidden campaigns "
              f"with evidence over it: {sum(not r['no_evidence'] for r in rows if 'no_evidence' in r)}"
              f"/{sum('no_evidence' in r for r in rows)}, named: "
              f"{sum(r['right'] for r in rows if r.get('no_evidence') is False)}")
    refits = [r["refit_converged"] for r in rows if "refit_converged" in r]
    if refits:
        c = next(iter(cfgs.values()))
        print(f"refits converged: {sum(refits)}/{len(refits)} (cap {c.sampler.max_steps} stored "
              f"steps; {c.samples_per_cycle:g} samples per cycle)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
