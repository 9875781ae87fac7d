"""The commands: each calls one library function and prints what it wrote (units shown)."""
from __future__ import annotations

import sys

from ..wording import count


def _cmd_ingest(a):
    from ..ingest import ingest
    m = ingest(a.campaign, a.out)
    print(f"ingested {count(len(m['tests']), 'test')} of campaign {m['name']!r} into {a.out} (SI units)")


def _cmd_simulate(a):
    from ..simulate_io import simulate_files
    n = simulate_files(a.params, a.input, a.out, model=a.model, eps=a.eps, reversal=a.reversal)
    print(f"wrote {a.out}: {n} samples (time s, displacement m, force N)")


def _cmd_twin(a):
    from ..twins import write_twin
    m = write_twin(a.device, a.out, seed=a.seed)
    print(f"wrote the {a.device.upper()} twin campaign to {a.out}: {count(len(m['tests']), 'test')}, seed {a.seed}")


def _cmd_fit(a):
    from ..infer.fit import FitConfig, fit_campaign
    from ..infer.priors import prior_options
    samp = _sampler_config(a)
    cfg = FitConfig(model=a.model, effects=tuple(a.effect or ()), likelihood=a.likelihood,
                    seed=a.seed, priors=prior_options(a.prior), sampler=samp,
                    tests=tuple(a.test) if a.test else None,
                    kinds=tuple(a.kind) if a.kind else None, simulate_at=a.simulate_at,
                    drive_lowpass=a.drive_lowpass, reversal=a.reversal,
                    force_offset=a.force_offset)
    from ..infer.fit import unused_parameters
    unused = unused_parameters(cfg, cfg.priors)
    if unused:
        print(f"note: --prior {', '.join(unused)}: not a parameter of the {cfg.model} model"
              + (f" with {', '.join(cfg.effects)}" if cfg.effects else "") + ": ignored",
              file=sys.stderr)
    s = fit_campaign(a.campaign, a.out, by=a.by, config=cfg, log=lambda m: print(m, file=sys.stderr),
                     jobs=a.jobs)
    bad = [f["id"] for f in s["fits"] if not f["converged"]]
    print(f"wrote {len(s['fits'])} fit(s) of campaign {s['campaign']!r} to {a.out} (summary.json, "
          f"<fit>/posterior.nc, <fit>/fit.json; SI units)")
    for f in s["fits"]:
        print(f"  {f['id']}: {'converged' if f['converged'] else 'NOT converged'}, "
              f"RMSE {f['rmse']:.4g} N")
        pinned = (f.get("identifiability") or {}).get("at_prior_bound") or {}
        if pinned:
            print(f"  note: {f['id']}: posterior pressed against a prior bound: "
                  + ", ".join(f"{n} ({side})" for n, side in pinned.items())
                  + ": there the prior, not the data, sets the interval (widen it with --prior "
                    "if the bound is not physical)")
    if bad:
        print(f"not converged (R-hat > 1.01 or ESS < 400 for some parameter): {', '.join(bad)}")
        return 1


def _cmd_law(a):
    from ..infer.law import fit_law
    doc = fit_law(a.fit_dir, family=a.family, seed=a.seed, log=lambda m: print(m, file=sys.stderr))
    print(f"wrote {a.fit_dir}/law.json: family {doc['family']} for {', '.join(doc['force_dependent'])} "
          f"(other parameters shared), {len(doc['levels'])} applied forces")
    for fam, c in doc["comparison"].items():
        print(f"  {fam:<11} held-out ELPD {c['elpd']:9.2f} nats (SE {c['se']:.2f})")
    if len(doc["levels"]) < 3:
        print("  note: with fewer than 3 levels the between-level scatter is set by its prior, so "
              "the law's intervals between and beyond the levels are wide")
    if not doc["comparison"]:
        print(f"  families not compared: leave-one-level-out needs 3 or more levels, here "
              f"{len(doc['levels'])}")


def _cmd_validate(a):
    from ..validate import validate
    doc = validate(a.fit_dir, a.campaign, a.test, a.out, n_draws=a.draws, seed=a.seed,
                   log=lambda m: print(m, file=sys.stderr))
    print(f"wrote {a.out}/validation.json (and per test <id>.bands.csv, <id>.png)")
    print(f"{'test':<34}{'cover95':>8}{'cover50':>8}{'RMSE N':>10}{'NRMSE':>8}  draws from")
    for r in doc["tests"]:      # the draws' source last, whole (it names the fit or the law)
        print(f"{r['test']:<34}{r['coverage95']:8.3f}{r['coverage50']:8.3f}"
              f"{r['rmse_N']:10.4g}{r['nrmse']:8.4f}  {r['draws_source']}"
              + ("" if r["held_out"] else "  (NOT held out: the fit saw this test)"))
    print("cover95/cover50: fraction of measured samples inside the 95 %/50 % band; NRMSE: RMSE of "
          "the median / the measured force's peak to peak")
    from ..extrapolation import notes
    from ..validate import calibration_notes
    for r in doc["tests"]:
        for line in calibration_notes(r) + notes(r):
            print(f"note: {r['test']}: {line}")
    _note_not_converged(doc["not_converged_fits"], "the predictions are drawn")


def _cmd_table(a):
    from ..quicklook import campaign_table
    print(campaign_table(a.campaign, published=a.published, eps=a.eps))


def _harmonic_arg(text: str) -> tuple[float, float]:
    from ..errors import InputError
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"--harmonic {text!r}: expected AMP_M,FREQ_HZ (two numbers, e.g. 0.0254,0.2)") from None


def _cmd_predict(a):
    from ..predict import write_prediction
    m = write_prediction(a.fit_dir, a.out, input_csv=a.input,
                         harmonic=_harmonic_arg(a.harmonic) if a.harmonic else None,
                         applied=a.applied, n_draws=a.draws, seed=a.seed,
                         include_offset=a.include_offset, clean_input=a.clean_input)
    ap = m["applied"]
    print(f"wrote {a.out}: bands.csv, cycles.csv, prediction.json at applied {ap['value']:g} "
          f"{ap['unit']} ({m['draws_source']}, {m['n_draws']} draws; time s, displacement m, "
          "force N, energy J)")
    _note_not_converged(m["not_converged_fits"], "the bands are drawn")
    from ..extrapolation import notes
    for i, n in enumerate(notes(m)):
        # the input CSV is in SI: an amplitude far beyond the records may be millimetres as metres
        tail = (" (predict's input CSV is in SI: metres)"
                if i == 0 and m["fitted_range"]["beyond"] and a.input else "")
        print(f"note: {n}{tail}", file=sys.stderr)


def _cmd_advantage(a):
    from ..advantage import format_table, write_advantage
    df = write_advantage(a.fit_dir, a.out)
    print(format_table(df))
    print(f"wrote {a.out or a.fit_dir}/advantage.csv and advantage.json")
    from ..advantage import fits_behind
    from ..fitdir import load_summary, not_converged
    summary = load_summary(a.fit_dir)
    _note_not_converged(not_converged(summary, fits_behind(df, summary)), "C and mu are drawn")
    from ..advantage import zero_force_fits
    zero = zero_force_fits(summary)
    if zero:
        print(f"note: no row for {', '.join(zero)}: at zero applied force C = fc / applied is "
              "undefined", file=sys.stderr)


def _cmd_compare(a):
    from ..errors import InputError
    from ..infer.compare import compare_campaign, format_table
    from ..infer.fit import FitConfig
    samp = _sampler_config(a)
    models = a.model or ["three_stage", "lugre"]
    if len(set(models)) != len(models):
        raise InputError(f"--model {next(m for i, m in enumerate(models) if m in models[:i])}: "
                         "given twice; give each model once")
    from ..infer.priors import prior_options
    pri = prior_options(a.prior)
    cfgs = {m: FitConfig(model=m, likelihood=a.likelihood, seed=a.seed, sampler=samp, priors=pri,
                         drive_lowpass=a.drive_lowpass, reversal=a.reversal,
                         force_offset=a.force_offset)
            for m in models}        # an unknown model is refused here
    if len(models) < 2:
        raise InputError(f"--model {models[0]}: compare needs two models (e.g. --model three_stage "
                         "--model lugre); one model's posterior is `frictionuq fit`")
    r = compare_campaign(a.campaign, a.out, cfgs, kinds=a.kind, tests=a.test, seed=a.seed,
                         offset=a.offset, log=lambda m: print(m, file=sys.stderr), jobs=a.jobs)
    print(format_table(r))
    print(f"wrote {a.out}/compare.json and compare.csv (RMSE in N, ELPD in nats of whole held-out tests)")
    if not all(m["converged"] for lv in r["levels"] for m in lv["models"].values()):
        print("not converged: some fits stopped at --max-steps; their ELPD and RMSE are less reliable")
        return 1


def discover_config(a):
    """The FitConfig `frictionuq discover` runs with the parsed options a (the speed benchmark,
    benchmarks/bench_discover.py --full, measures this configuration)."""
    from ..infer.fit import FitConfig
    from ..infer.priors import prior_options
    return FitConfig(likelihood=a.likelihood, sampler=_sampler_config(a),
                     priors=prior_options(a.prior), tests=tuple(a.test) if a.test else None,
                     kinds=tuple(a.kind) if a.kind else None, drive_lowpass=a.drive_lowpass,
                     reversal=a.reversal, force_offset=a.force_offset)


def _discover_notes(a, cfg) -> list[str]:
    """What of the options will do nothing: a prior of an effect no candidate screens, sampler
    options with --no-refit."""
    from .. import params as P
    screened = [e for e in P.EFFECTS if e not in P.BEYOND_SPEC or e in (a.extra_effect or ())]
    out = [f"--prior {n}: its effect {P.PARAMS[n].effect} is not screened "
           + (f"(--extra-effect {P.PARAMS[n].effect} screens it)" if P.PARAMS[n].effect in P.BEYOND_SPEC
              else "") + "; the prior does nothing"
           for n in cfg.priors if P.PARAMS[n].effect is not None and P.PARAMS[n].effect not in screened]
    if a.no_refit:
        given = [o for o, v in (("--max-steps", a.max_steps), ("--stored-run", a.stored_run),
                                ("--temperatures", a.temperatures),
                                ("--mode-search" if a.mode_search else "--no-mode-search",
                                 a.mode_search)) if v is not None]
        if given:
            out.append(f"{', '.join(given)}: {'settings' if len(given) > 1 else 'a setting'} of "
                       "the refit's sampler, and --no-refit runs no refit: ignored")
    return out


def _cmd_discover(a):
    from ..discrepancy.discover import discover
    cfg = discover_config(a)
    for n in _discover_notes(a, cfg):
        print(f"note: {n}", file=sys.stderr)
    d = discover(a.campaign, a.out, cfg, seed=a.seed, refit=not a.no_refit,
                 extra_effects=tuple(a.extra_effect or ()), max_effects=a.max_effects,
                 jobs=a.jobs, check_seeds=tuple(a.check_seed or ()),
                 log=lambda m: print(m, file=sys.stderr))
    print(f"{'candidate':<20}{'ELPD gain (nats)':>18}{'SE':>10}{'MAP gain (nats)':>17}"
          f"{'needs (nats)':>14}{'RMSE after (N)':>16}")
    for c in d["candidates"]:
        if c["screened_out"]:      # stage 1: no better in-sample fit, not scored held out
            gain, se = f"{'not scored':>18}", f"{'':>10}"
        else:
            gain, se = f"{c['elpd_gain']:18.1f}", f"{c['elpd_gain_se']:10.1f}"
        print(f"{c['effect']:<20}{gain}{se}{c['map_gain']:17.1f}{c['min_gain']:14.1f}"
              f"{c['rmse_after']:16.4g}")
    from ..discrepancy.rule import shown_reason
    print(f"named effect: {d['named_effect']} ({shown_reason(d['named_effect'], d['reason'])})")
    for r in d["rounds"][1:]:
        print(f"round {r['round']} (against 3-stage + {' + '.join(r['baseline_effects'])}): "
              f"named {r['named_effect']} ({shown_reason(r['named_effect'], r['reason'])})")
    if d.get("seed_check"):
        from ..discrepancy.seedcheck import sentence
        print(sentence(d["seed_check"]))
    from ..discrepancy.gap import worse_sentence
    if d.get("named_effect", "none") != "none" and (w := worse_sentence(d)):
        print(f"note: {w}")
    print(f"RMSE before {d['rmse_before']:.4g} N, after {d['rmse_after']:.4g} N"
          + (f", noise scale {d['noise_scale']:.4g} N" if d["noise_scale"] else ""))
    def unit(u):                        # a dimensionless value shows no unit
        return "" if u == "1" else f" {u}"
    for n, st in d["effect_parameters"].items():
        print(f"  {n} = {st['mean']:.4g}{unit(st['unit'])} [{st['q2.5']:.4g}, {st['q97.5']:.4g}]")
    for lid, vals in (d.get("effect_parameters_map") or {}).items():
        print(f"  at its MAP ({lid}; no refit, so no intervals): "
              + ", ".join(f"{n} = {v['value']:.4g}{unit(v['unit'])}" for n, v in vals.items()))
    from ..report import render_discrepancy_page
    page = render_discrepancy_page(a.out)
    st = d["seconds_by_stage"]
    print(f"time: {d['seconds']:.0f} s (screening {st['screening']:.0f} s, refit {st['refit']:.0f} s, "
          f"diagnostics {st['diagnostics']:.0f} s)")
    print(f"wrote {a.out}/discrepancy.json and {page}")
    bad = [r["id"] for r in d.get("refit") or [] if not r["converged"]]
    if bad:
        print(f"not converged (R-hat > 1.01 or ESS < 400 for some parameter): the refit of "
              f"{', '.join(bad)}; its intervals are indicative only (--max-steps runs it longer)")
        return 1


def _cmd_run(a):
    from ..pipeline import plan_status, run
    from ..workflow import load_workflow
    wf = load_workflow(a.workflow)
    targets = a.targets or ["all"]
    if a.jobs < 1:
        raise ValueError(f"-j/--jobs must be >= 1, got {a.jobs}")
    if a.dry_run:
        rows = plan_status(wf, targets, a.force)
        for name, runs, why in rows:
            print(f"{'run ' if runs else 'skip'}  {name:<40} {why}")
        n = sum(r[1] for r in rows)
        print(f"dry run: {n} of {len(rows)} task(s) would run; run folder {wf.out}")
        return
    r = run(wf, targets, jobs=a.jobs, scheduler=a.scheduler, force=a.force)
    if r.failed or r.skipped:
        for n, why in {**r.failed, **r.skipped}.items():
            print(f"not done: {n}: {why}")
        print(f"{len(r.failed)} task(s) failed, {len(r.skipped)} skipped; run the same command "
              "again to retry only those (finished tasks are cached)")
        return 1
    if not r.ran:
        print(f"nothing to do: {wf.name} is up to date ({len(r.cached)} task(s) cached)")
    else:
        print(f"{wf.name}: {len(r.ran)} task(s) ran, {len(r.cached)} up to date, "
              f"{r.seconds:.0f} s")
    rep = wf.report_dir / "index.html"
    if rep.is_file():
        print(f"report: {rep}")


def _cmd_status(a):
    from ..pipeline import plan_status
    from ..workflow import load_workflow
    wf = load_workflow(a.workflow)
    rows = plan_status(wf, ["all"])
    for name, runs, why in rows:
        print(f"{'stale' if runs else 'ok   '}  {name:<40} {why}")
    stale = sum(r[1] for r in rows)
    print(f"{wf.name}: {len(rows) - stale} up to date, {stale} stale; run folder {wf.out}")


def _cmd_clean(a):
    from ..pipeline import clean
    from ..workflow import load_workflow
    wf = load_workflow(a.workflow)
    gone = clean(wf)
    print(f"removed {', '.join(map(str, gone))}" if gone else f"nothing to remove for {wf.name}")


def _note_not_converged(ids, what: str) -> None:
    """One line on stderr when results come from fits marked not converged."""
    if ids:
        print(f"note: {what} from fit(s) not converged (R-hat > 1.01 or ESS < 400 for some "
              f"parameter): {', '.join(ids)}; indicative only", file=sys.stderr)


def _sampler_config(a):
    """The SamplerConfig of the options --max-steps, --stored-run, --temperatures and
    --mode-search (the rest: defaults)."""
    from ..infer.sampler import SamplerConfig
    kw = {"max_steps": a.max_steps, "stored_run": a.stored_run,
          "temperatures": getattr(a, "temperatures", None),
          "mode_search": getattr(a, "mode_search", None)}
    return SamplerConfig(**{k: v for k, v in kw.items() if v is not None})
