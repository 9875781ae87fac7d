"""The command line: parse, call the library, print. Every command is a library function first.

Bad input (frictionuq.errors.InputError, or a ValueError raised by validation) prints one line
`frictionuq: error: ...` on stderr and exits with code 2, without a traceback.
"""
from __future__ import annotations

import argparse
import sys

from .errors import EXIT_BAD_INPUT


def _cmd_ingest(a):
    from .ingest import ingest
    m = ingest(a.campaign, a.out)
    print(f"ingested {len(m['tests'])} tests of campaign {m['name']!r} into {a.out} (SI units)")


def _cmd_simulate(a):
    from .simulate_io import simulate_files
    n = simulate_files(a.params, a.input, a.out, model=a.model, eps=a.eps)
    print(f"wrote {a.out}: {n} samples (time s, displacement m, force N)")


def _cmd_twin(a):
    from .twins import write_twin
    m = write_twin(a.device, a.out, seed=a.seed)
    print(f"wrote the {a.device.upper()} twin campaign to {a.out}: {len(m['tests'])} tests, seed {a.seed}")


def _cmd_fit(a):
    from .infer.fit import FitConfig, fit_campaign
    samp = _sampler_config(a)
    cfg = FitConfig(model=a.model, effects=tuple(a.effect or ()), likelihood=a.likelihood,
                    seed=a.seed, sampler=samp, tests=tuple(a.test) if a.test else None,
                    kinds=tuple(a.kind) if a.kind else None, simulate_at=a.simulate_at,
                    drive_lowpass=a.drive_lowpass)
    s = fit_campaign(a.campaign, a.out, by=a.by, config=cfg, log=lambda m: print(m, file=sys.stderr),
                     jobs=a.jobs)
    bad = [f["id"] for f in s["fits"] if not f["converged"]]
    print(f"wrote {len(s['fits'])} fit(s) of campaign {s['campaign']!r} to {a.out} (summary.json, "
          f"<fit>/posterior.nc, <fit>/fit.json; SI units)")
    for f in s["fits"]:
        print(f"  {f['id']}: {'converged' if f['converged'] else 'NOT converged'}, "
              f"RMSE {f['rmse']:.4g} N")
    if bad:
        print(f"not converged (R-hat > 1.01 or ESS < 400 for some parameter): {', '.join(bad)}")
        return 1


def _cmd_law(a):
    from .infer.law import fit_law
    doc = fit_law(a.fit_dir, family=a.family, seed=a.seed, log=lambda m: print(m, file=sys.stderr))
    print(f"wrote {a.fit_dir}/law.json: family {doc['family']} for {', '.join(doc['force_dependent'])} "
          f"(other parameters shared), {len(doc['levels'])} applied forces")
    for fam, c in doc["comparison"].items():
        print(f"  {fam:<11} held-out ELPD {c['elpd']:9.2f} nats (SE {c['se']:.2f})")


def _cmd_validate(a):
    from .validate import validate
    doc = validate(a.fit_dir, a.campaign, a.test, a.out, n_draws=a.draws, seed=a.seed,
                   log=lambda m: print(m, file=sys.stderr))
    print(f"wrote {a.out}/validation.json (and per test <id>.bands.csv, <id>.png)")
    print(f"{'test':<34}{'source':<26}{'cover95':>8}{'cover50':>8}{'RMSE N':>10}{'NRMSE':>8}")
    for r in doc["tests"]:
        print(f"{r['test']:<34}{r['draws_source'][:25]:<26}{r['coverage95']:8.3f}{r['coverage50']:8.3f}"
              f"{r['rmse_N']:10.4g}{r['nrmse']:8.4f}")


def _cmd_table(a):
    from .quicklook import campaign_table
    print(campaign_table(a.campaign, published=a.published, eps=a.eps))


def _harmonic_arg(text: str) -> tuple[float, float]:
    from .errors import InputError
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise InputError(f"--harmonic {text!r}: expected AMP_M,FREQ_HZ (two numbers, e.g. 0.0254,0.2)") from None


def _cmd_predict(a):
    from .predict import write_prediction
    m = write_prediction(a.fit_dir, a.out, input_csv=a.input,
                         harmonic=_harmonic_arg(a.harmonic) if a.harmonic else None,
                         applied=a.applied, n_draws=a.draws, seed=a.seed,
                         include_offset=a.include_offset)
    ap = m["applied"]
    print(f"wrote {a.out}: bands.csv, cycles.csv, prediction.json at applied {ap['value']:g} "
          f"{ap['unit']} ({m['draws_source']}, {m['n_draws']} draws; time s, displacement m, "
          "force N, energy J)")


def _cmd_advantage(a):
    from .advantage import format_table, write_advantage
    df = write_advantage(a.fit_dir, a.out)
    print(format_table(df))
    print(f"wrote {a.out or a.fit_dir}/advantage.csv and advantage.json")


def _cmd_compare(a):
    from .infer.compare import compare_campaign, format_table
    from .infer.fit import FitConfig
    samp = _sampler_config(a)
    models = list(dict.fromkeys(a.model or ["three_stage", "lugre"]))
    cfgs = {m: FitConfig(model=m, likelihood=a.likelihood, seed=a.seed, sampler=samp) for m in models}
    r = compare_campaign(a.campaign, a.out, cfgs, kinds=a.kind, tests=a.test, seed=a.seed,
                         offset=a.offset, log=lambda m: print(m, file=sys.stderr), jobs=a.jobs)
    print(format_table(r))
    print(f"wrote {a.out}/compare.json and compare.csv (RMSE in N, ELPD in nats of whole held-out tests)")
    if not all(m["converged"] for lv in r["levels"] for m in lv["models"].values()):
        print("not converged: some fits stopped at --max-steps; their ELPD and RMSE are less reliable")
        return 1


def _cmd_discover(a):
    from .discrepancy.discover import discover
    from .infer.fit import FitConfig
    samp = _sampler_config(a)
    cfg = FitConfig(likelihood=a.likelihood, sampler=samp, tests=tuple(a.test) if a.test else None,
                    kinds=tuple(a.kind) if a.kind else None, drive_lowpass=a.drive_lowpass)
    d = discover(a.campaign, a.out, cfg, seed=a.seed, refit=not a.no_refit,
                 extra_effects=tuple(a.extra_effect or ()), max_effects=a.max_effects,
                 jobs=a.jobs, log=lambda m: print(m, file=sys.stderr))
    print(f"{'candidate':<20}{'ELPD gain (nats)':>18}{'SE':>10}{'MAP gain (nats)':>17}"
          f"{'RMSE after (N)':>16}")
    for c in d["candidates"]:
        if c["screened_out"]:      # stage 1: no better in-sample fit, not scored held out
            gain, se = f"{'not scored':>18}", f"{'':>10}"
        else:
            gain, se = f"{c['elpd_gain']:18.1f}", f"{c['elpd_gain_se']:10.1f}"
        print(f"{c['effect']:<20}{gain}{se}{c['map_gain']:17.1f}{c['rmse_after']:16.4g}")
    print(f"named effect: {d['named_effect']} ({d['reason']})")
    for r in d["rounds"][1:]:
        print(f"round {r['round']} (against 3-stage + {' + '.join(r['baseline_effects'])}): "
              f"named {r['named_effect']} ({r['reason']})")
    print(f"RMSE before {d['rmse_before']:.4g} N, after {d['rmse_after']:.4g} N"
          + (f", noise scale {d['noise_scale']:.4g} N" if d["noise_scale"] else ""))
    for n, st in d["effect_parameters"].items():
        print(f"  {n} = {st['mean']:.4g} {st['unit']} [{st['q2.5']:.4g}, {st['q97.5']:.4g}]")
    from .report import render_discrepancy_page
    page = render_discrepancy_page(a.out)
    print(f"wrote {a.out}/discrepancy.json and {page}")


def _cmd_run(a):
    from .pipeline import plan_status, run
    from .workflow import load_workflow
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
    from .pipeline import plan_status
    from .workflow import load_workflow
    wf = load_workflow(a.workflow)
    rows = plan_status(wf, ["all"])
    for name, runs, why in rows:
        print(f"{'stale' if runs else 'ok   '}  {name:<40} {why}")
    stale = sum(r[1] for r in rows)
    print(f"{wf.name}: {len(rows) - stale} up to date, {stale} stale; run folder {wf.out}")


def _cmd_clean(a):
    from .pipeline import clean
    from .workflow import load_workflow
    wf = load_workflow(a.workflow)
    gone = clean(wf)
    print(f"removed {', '.join(map(str, gone))}" if gone else f"nothing to remove for {wf.name}")


def _add_selection(s, max_steps_help: str) -> None:
    """Seed, test selection, step cap and the stored run's design, shared by the commands that
    run fits."""
    from .infer.sampler import STORED_RUNS
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--test", action="append", metavar="ID", help="only this test (repeatable)")
    s.add_argument("--kind", action="append", choices=["harmonic", "earthquake", "other"],
                   help="only tests of this kind (repeatable)")
    s.add_argument("--max-steps", type=int, default=None, help=max_steps_help)
    s.add_argument("--stored-run", choices=STORED_RUNS, default=None,
                   help="the sampler's stored run: 16 independent chains (default) or the burn-in's "
                        "ensemble of walkers with differential-evolution moves")


def _sampler_config(a):
    """The SamplerConfig of the options --max-steps and --stored-run (the rest: defaults)."""
    from .infer.sampler import SamplerConfig
    kw = {"max_steps": a.max_steps, "stored_run": a.stored_run}
    return SamplerConfig(**{k: v for k, v in kw.items() if v is not None})


def _add_drive_lowpass(s) -> None:
    s.add_argument("--drive-lowpass", type=float, default=None, metavar="MULT",
                   help="low-pass each measured displacement (zero phase) at MULT x its 99 %% "
                        "velocity-power frequency before the model runs on it (e.g. 20; default: "
                        "off); predict and validate then filter their measured inputs alike")


def build_parser() -> argparse.ArgumentParser:
    from . import __version__
    p = argparse.ArgumentParser(prog="frictionuq", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"frictionuq {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("ingest", help="validate a campaign and write it in SI units")
    s.add_argument("campaign", help="campaign folder (with campaign.toml)")
    s.add_argument("--out", required=True, help="output folder (replaced atomically)")
    s.set_defaults(func=_cmd_ingest)

    s = sub.add_parser("simulate", help="simulate the damper force for a displacement record")
    s.add_argument("--params", required=True, help="JSON: the spec's SI names, optional \"effects\"")
    s.add_argument("--input", required=True, help="CSV with columns time (s), displacement (m)")
    s.add_argument("--out", required=True, help="CSV to write: time, displacement, force (N)")
    s.add_argument("--model", default="three_stage", choices=["three_stage", "lugre"])
    s.add_argument("--eps", type=float, default=0.0, help="reversal dead-band (m), default 0")
    s.set_defaults(func=_cmd_simulate)

    s = sub.add_parser("twin", help="write a paper-twin campaign (published parameters)")
    s.add_argument("device", choices=["brfd", "mfd"])
    s.add_argument("--out", required=True)
    s.add_argument("--seed", type=int, default=2016)
    s.set_defaults(func=_cmd_twin)

    s = sub.add_parser("fit", help="Bayesian calibration (emcee): posteriors per applied force or per test")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--out", required=True, help="output folder: summary.json and one folder per fit")
    s.add_argument("--by", choices=["applied", "test"], default="applied",
                   help="one joint fit per applied force (default) or one per test")
    s.add_argument("--model", choices=["three_stage", "lugre"], default="three_stage")
    s.add_argument("--effect", action="append", metavar="NAME",
                   help="add an effect of the library (repeatable)")
    s.add_argument("--likelihood", choices=["iid", "ar1", "arma"], default="ar1",
                   help="measurement noise per test: iid, AR(1) (default) or ARMA(1,1) = AR(1) + white")
    s.add_argument("--simulate-at", choices=["raw", "kept"], default="raw",
                   help="decimated records: simulate at the raw rate and filter the model force like "
                        "the data (default), or simulate on the decimated displacement (faster)")
    _add_drive_lowpass(s)
    s.add_argument("--jobs", "-j", type=int, default=1, metavar="N",
                   help="fits side by side in N processes, one numba thread each (default 1: one "
                        "fit at a time on every core); the results do not depend on it")
    _add_selection(s, "cap on stored sampler steps")
    s.set_defaults(func=_cmd_fit)

    s = sub.add_parser("law", help="fit the force-dependence law on a `fit --by applied` folder")
    s.add_argument("fit_dir", help="output folder of `frictionuq fit --by applied`")
    s.add_argument("--family", default="auto", choices=["auto", "linear", "threshold", "saturating"],
                   help="law of the friction forces and sigma0 (auto: best held-out ELPD)")
    s.add_argument("--seed", type=int, default=1)
    s.set_defaults(func=_cmd_law)

    s = sub.add_parser("validate", help="predict held-out measured tests from a fit and score the bands")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    s.add_argument("campaign", help="campaign folder holding the held-out tests")
    s.add_argument("--test", action="append", required=True, metavar="ID",
                   help="held-out test id (repeatable)")
    s.add_argument("--out", required=True, help="output folder: validation.json, bands, figures")
    s.add_argument("--draws", type=int, default=400)
    s.add_argument("--seed", type=int, default=1)
    s.set_defaults(func=_cmd_validate)

    s = sub.add_parser("table", help="per-test table of a campaign, with a published-parameter simulation")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--published", choices=["brfd", "mfd", "none"], default="none",
                   help="simulate each test with the paper's parameters at the nearest applied level")
    s.add_argument("--eps", default="auto", help="reversal dead-band in m, or 'auto' (estimated)")
    s.set_defaults(func=_cmd_table)

    s = sub.add_parser("predict", help="posterior predictive force bands for a new drive at an applied force")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--input", metavar="X.csv", help="CSV with columns time (s), displacement (m)")
    g.add_argument("--harmonic", metavar="AMP_M,FREQ_HZ", help="clean sine: 3 cycles from x = 0")
    s.add_argument("--applied", required=True,
                   help="applied force (or pressure), in the fitted campaign's applied unit")
    s.add_argument("--out", required=True, help="output folder (replaced atomically)")
    s.add_argument("--draws", type=int, default=400, help="posterior draws (default 400)")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--include-offset", action="store_true",
                   help="add the fitted load-cell offset to the noisy bands (default: excluded)")
    s.set_defaults(func=_cmd_predict)

    s = sub.add_parser("advantage", help="mechanical advantage C and friction coefficient mu per applied force")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    s.add_argument("--out", default=None, help="folder for advantage.csv/.json (default FIT_DIR)")
    s.set_defaults(func=_cmd_advantage)

    s = sub.add_parser("compare", help="model comparison per applied force: RMSE and leave-one-test-out ELPD")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--out", required=True, help="output folder: compare.json, compare.csv")
    s.add_argument("--model", action="append", metavar="MODEL",
                   help="a model to compare (repeatable; default three_stage and lugre)")
    s.add_argument("--likelihood", choices=["iid", "ar1"], default="ar1")
    s.add_argument("--offset", choices=["marginal", "shared"], default="marginal",
                   help="held-out test's load-cell offset: integrated out (default) or the training fit's")
    s.add_argument("--jobs", "-j", type=int, default=1, metavar="N",
                   help="a level's fits (each model on all tests and without each test) side by "
                        "side in N processes, one numba thread each (default 1); the results do "
                        "not depend on it")
    _add_selection(s, "cap on stored sampler steps per fit")
    s.set_defaults(func=_cmd_compare)

    s = sub.add_parser("discover", help="name the effect the model misses (screen the effect library, refit)")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--out", required=True, help="output folder: discrepancy.json, report.html, figures, refit/")
    s.add_argument("--likelihood", choices=["iid", "ar1"], default="ar1")
    s.add_argument("--no-refit", action="store_true", help="screen and name only (no MCMC refit)")
    _add_drive_lowpass(s)
    from .params import BEYOND_SPEC
    s.add_argument("--extra-effect", action="append", metavar="EFFECT",
                   help="also screen this effect beyond the spec's library "
                        f"({', '.join(sorted(BEYOND_SPEC))})")
    s.add_argument("--max-effects", type=int, default=1, metavar="N",
                   help="name up to N effects, one per round, each screened against the model "
                        "with the ones named before (default 1)")
    from .workers import default_jobs
    s.add_argument("--jobs", "-j", type=int, default=default_jobs(), metavar="N",
                   help="processes for the screening's fits (default: every core, here "
                        f"{default_jobs()}); the results do not depend on it")
    _add_selection(s, "cap on stored sampler steps of the refit")
    s.set_defaults(func=_cmd_discover)

    s = sub.add_parser("run", help="run a workflow (make-like: only what is out of date)")
    s.add_argument("workflow", metavar="WORKFLOW", help="workflow file (TOML, e.g. workflows/quick.toml)")
    s.add_argument("targets", nargs="*", metavar="TARGET",
                   help="ingest, fit, predict, compare, report or all (default), or a task name")
    s.add_argument("-j", "--jobs", type=int, default=1, help="fits in parallel (local processes)")
    s.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="send fits to this Dask distributed scheduler (e.g. tcp://host:8786)")
    s.add_argument("--force", action="store_true", help="rerun the targets' tasks even if up to date")
    s.add_argument("--dry-run", action="store_true", help="print the plan: what would run and why")
    s.set_defaults(func=_cmd_run)

    s = sub.add_parser("status", help="which tasks of a workflow are up to date, which are stale and why")
    s.add_argument("workflow", metavar="WORKFLOW")
    s.set_defaults(func=_cmd_status)

    s = sub.add_parser("clean", help="remove a workflow's run folder and report")
    s.add_argument("workflow", metavar="WORKFLOW")
    s.set_defaults(func=_cmd_clean)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        code = args.func(args)
    except BrokenPipeError:           # output piped into `head` etc.: stop quietly
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        print("frictionuq: interrupted; finished outputs are kept", file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError,
            PermissionError) as e:
        msg = " ".join(str(e).split())
        print(f"frictionuq: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    return int(code or 0)


if __name__ == "__main__":
    sys.exit(main())
