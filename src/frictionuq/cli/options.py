"""The command line's parser: commands, their options and the option types shared by several."""
from __future__ import annotations

import argparse

from . import commands as C

DESCRIPTION = ("frictionuq: honest error bars on semi-active friction dampers (LuGre friction "
               "and two backlash stages, calibrated with emcee)")


def _seed(text: str) -> int:
    """--seed: an integer the random generators take and the outputs can store."""
    from ..errors import InputError, check_seed
    try:
        return check_seed(int(text), "seed")
    except (ValueError, InputError):
        from ..errors import MAX_SEED
        raise argparse.ArgumentTypeError(f"takes an integer from 0 to {MAX_SEED}, got {text!r}") from None


def _at_least(minimum: int):
    """An integer option's type: refused by the parser, naming the option, below `minimum`."""
    def parse(text: str) -> int:
        try:
            v = int(text)
        except ValueError:
            v = None
        if v is None or v < minimum:
            raise argparse.ArgumentTypeError(f"takes an integer >= {minimum}, got {text!r}")
        return v
    parse.__name__ = f"integer >= {minimum}"
    return parse


def _add_selection(s, max_steps_help: str) -> None:
    """Seed, test selection, step cap and the stored run's design, shared by the commands that
    run fits."""
    from ..infer.sampler import STORED_RUNS
    s.add_argument("--seed", type=_seed, default=1,
                   help="seed of every random generator (default 1): the same seed and inputs "
                        "give the same numbers")
    s.add_argument("--test", action="append", metavar="ID", help="only this test (repeatable)")
    s.add_argument("--kind", action="append", choices=["harmonic", "earthquake", "other"],
                   help="only tests of this kind (repeatable)")
    s.add_argument("--max-steps", type=_at_least(1), default=None, help=max_steps_help)
    s.add_argument("--stored-run", choices=STORED_RUNS, default=None,
                   help="the sampler's stored run: 16 independent chains (default) or the burn-in's "
                        "ensemble of walkers with differential-evolution moves")
    s.add_argument("--temperatures", type=_at_least(1), default=None, metavar="L",
                   help="parallel tempering: L tempered copies of each of the stored run's chains "
                        "(default 1: none), for posteriors with separated modes; costs L times "
                        "the evaluations per step")
    s.add_argument("--mode-search", action=argparse.BooleanOptionalAction, default=None,
                   help="give the stored run's independence proposal components on regions the "
                        "burn-in visited and the proposal misses (a second mode a chain would "
                        "stick in); each region found costs 5,000 posterior evaluations that "
                        "shape its component (default: on; --no-mode-search turns it off)")


def _add_prior(s, whose: str) -> None:
    s.add_argument("--prior", action="append", metavar="NAME=SPEC",
                   help="override a parameter's prior, SI units (repeatable): NAME=VALUE fixes it; "
                        "NAME=uniform:LOWER:UPPER, NAME=loguniform:LOWER:UPPER or "
                        f"NAME=normal:MU:SD[:LOWER:UPPER] sets it; {whose}")


def _lowpass_value(text: str):
    if text in ("auto", "off"):
        return text
    try:
        v = float(text)
    except ValueError:
        v = float("nan")
    if not (v > 0 and v < float("inf")):
        raise argparse.ArgumentTypeError(f"takes 'auto', 'off' or a multiple > 0 (e.g. 20), "
                                         f"got {text!r}")
    return v


def _add_drive_lowpass(s) -> None:
    s.add_argument("--drive-lowpass", type=_lowpass_value, default="auto", metavar="auto|off|MULT",
                   help="low-pass each measured displacement (zero phase) at MULT x its 99 %% "
                        "velocity-power frequency before the model runs on it; 'auto' (default): "
                        "20 on every record with a reversal dead band eps > 0 (eps 'auto' gives "
                        "any record read from a file one), off only at eps = 0; 'off': the "
                        "recorded samples; predict and validate then filter their measured inputs "
                        "alike")
    s.add_argument("--reversal", choices=["detection", "extreme"], default="extreme",
                   help="where a reversal starts the backlash on a measured record: at the "
                        "motion's extreme (default) or where the dead band eps detects it (the "
                        "spec's causal rule); the same with eps = 0; with the drive low-pass the "
                        "extreme removes the bias displacement noise puts into sigma0 (README)")
    s.add_argument("--force-offset", choices=["shared", "per_test"], default="shared",
                   help="the load-cell zero of a joint fit's tests: one force_offset for all "
                        "(default), or each test's own, integrated out (per_test: for tests "
                        "re-zeroed or drifted between them, which fit's between-tests check "
                        "flags; iid and ar1 likelihoods only)")


class _Parser(argparse.ArgumentParser):
    """argparse's parser, its usage errors in the command line's one-line form (exit 2); the
    subcommands' parsers are of this class too (add_subparsers makes them so)."""

    def error(self, message):
        import sys
        msg = " ".join(str(message).split())
        print(f"frictionuq: error: {self.prog}: {msg} (see `{self.prog} --help`)", file=sys.stderr)
        raise SystemExit(2)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__
    p = _Parser(prog="frictionuq", description=DESCRIPTION)
    p.add_argument("--version", action="version", version=f"frictionuq {__version__}")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    s = sub.add_parser("ingest", help="validate a campaign and write it in SI units")
    s.add_argument("campaign", help="campaign folder (with campaign.toml)")
    s.add_argument("--out", required=True, help="output folder (replaced atomically)")
    s.set_defaults(func=C._cmd_ingest)

    s = sub.add_parser("simulate", help="simulate the damper force for a displacement record")
    s.add_argument("--params", required=True, help="JSON: the spec's SI names, optional \"effects\"")
    s.add_argument("--input", required=True, help="CSV with columns time (s), displacement (m)")
    s.add_argument("--out", required=True, help="CSV to write: time, displacement, force (N)")
    s.add_argument("--model", default="three_stage", choices=["three_stage", "lugre"])
    s.add_argument("--eps", type=float, default=0.0, help="reversal dead-band (m), default 0")
    s.add_argument("--reversal", default="detection", choices=["detection", "extreme"],
                   help="where a reversal starts the backlash when eps > 0: 'detection' (default, "
                        "the spec's causal rule) or 'extreme' (the sample after the extreme, the "
                        "rule `fit` uses by default on measured records: give it, with the fit's "
                        "eps, to re-simulate a fitted parameter set as the fit saw it)")
    s.set_defaults(func=C._cmd_simulate)

    s = sub.add_parser("twin", help="write a paper-twin campaign (published parameters)")
    s.add_argument("device", choices=["brfd", "mfd"])
    s.add_argument("--out", required=True)
    s.add_argument("--seed", type=_seed, default=2016)
    s.set_defaults(func=C._cmd_twin)

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
    _add_prior(s, "an effect's parameter applies only with --effect of that effect")
    s.add_argument("--jobs", "-j", type=_at_least(1), default=1, metavar="N",
                   help="fits side by side in N processes, one numba thread each (default 1: one "
                        "fit at a time on every core); the results do not depend on it")
    _add_selection(s, "cap on stored sampler steps (default 100000: until converged)")
    s.set_defaults(func=C._cmd_fit)

    s = sub.add_parser("law", help="fit the force-dependence law on a `fit --by applied` folder")
    s.add_argument("fit_dir", help="output folder of `frictionuq fit --by applied`")
    s.add_argument("--family", default="auto", choices=["auto", "linear", "threshold", "saturating"],
                   help="law of the friction forces and sigma0 (auto: best held-out ELPD)")
    s.add_argument("--seed", type=_seed, default=1)
    s.set_defaults(func=C._cmd_law)

    s = sub.add_parser("validate", help="predict held-out measured tests from a fit and score the bands")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    s.add_argument("campaign", help="campaign folder holding the held-out tests")
    s.add_argument("--test", action="append", required=True, metavar="ID",
                   help="held-out test id (repeatable)")
    s.add_argument("--out", required=True, help="output folder: validation.json, bands, figures")
    s.add_argument("--draws", type=_at_least(2), default=400)
    s.add_argument("--seed", type=_seed, default=1)
    s.set_defaults(func=C._cmd_validate)

    s = sub.add_parser("table", help="per-test table of a campaign, with a published-parameter simulation")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--published", choices=["brfd", "mfd", "none"], default="none",
                   help="simulate each test with the paper's parameters at the nearest applied level")
    s.add_argument("--eps", default="auto", help="reversal dead-band in m, or 'auto' (estimated)")
    s.set_defaults(func=C._cmd_table)

    s = sub.add_parser("predict", help="posterior predictive force bands for a new drive at an applied force")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    g = s.add_mutually_exclusive_group(required=True)
    g.add_argument("--input", metavar="X.csv", help="CSV with columns time (s), displacement (m)")
    g.add_argument("--harmonic", metavar="AMP_M,FREQ_HZ", help="clean sine: 3 cycles from x = 0")
    s.add_argument("--applied", required=True,
                   help="applied force (or pressure), in the fitted campaign's applied unit")
    s.add_argument("--out", required=True, help="output folder (replaced atomically)")
    s.add_argument("--draws", type=_at_least(2), default=400, help="posterior draws (default 400)")
    s.add_argument("--seed", type=_seed, default=1)
    s.add_argument("--include-offset", action="store_true",
                   help="add the fitted load-cell offset to the noisy bands (default: excluded)")
    s.add_argument("--clean-input", action="store_true",
                   help="the --input CSV is a clean generated drive (e.g. a ground motion's "
                        "displacement history): reversal dead band 0 and no drive filter, as for "
                        "--harmonic (default: a measured record, its dead band from its noise)")
    s.set_defaults(func=C._cmd_predict)

    s = sub.add_parser("advantage", help="mechanical advantage C and friction coefficient mu per applied force")
    s.add_argument("fit_dir", metavar="FIT_DIR", help="output folder of `frictionuq fit`")
    s.add_argument("--out", default=None, help="folder for advantage.csv/.json (default FIT_DIR)")
    s.set_defaults(func=C._cmd_advantage)

    s = sub.add_parser("compare", help="model comparison per applied force: RMSE and leave-one-test-out ELPD")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    _add_drive_lowpass(s)
    s.add_argument("--out", required=True, help="output folder: compare.json, compare.csv")
    s.add_argument("--model", action="append", metavar="MODEL",
                   help="a model to compare (repeatable; default three_stage and lugre)")
    s.add_argument("--likelihood", choices=["iid", "ar1"], default="ar1")
    s.add_argument("--offset", choices=["marginal", "shared"], default="marginal",
                   help="held-out test's load-cell offset: integrated out (default) or the training fit's")
    _add_prior(s, "applies to every model with the parameter (lugre has no backlash)")
    s.add_argument("--jobs", "-j", type=_at_least(1), default=1, metavar="N",
                   help="a level's fits (each model on all tests and without each test) side by "
                        "side in N processes, one numba thread each (default 1); the results do "
                        "not depend on it")
    _add_selection(s, "cap on stored sampler steps per fit (default 100000: until converged)")
    s.set_defaults(func=C._cmd_compare)

    s = sub.add_parser("discover", help="name the effect the model misses (screen the effect library, refit)")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--out", required=True, help="output folder: discrepancy.json, report.html, figures, refit/")
    s.add_argument("--likelihood", choices=["iid", "ar1"], default="ar1",
                   help="the residual's noise model: AR(1) (default; a friction model's residuals "
                        "on 100-1000 Hz records are strongly autocorrelated) or independent")
    s.add_argument("--no-refit", action="store_true", help="screen and name only (no MCMC refit)")
    _add_drive_lowpass(s)
    from ..params import BEYOND_SPEC
    s.add_argument("--extra-effect", action="append", metavar="EFFECT",
                   help="also screen this effect beyond the spec's library "
                        f"({', '.join(sorted(BEYOND_SPEC))})")
    _add_prior(s, "applies to the baseline and to every candidate with the parameter (e.g. "
                  "b_ch=uniform:0:1 frees chatter's tail)")
    s.add_argument("--max-effects", type=_at_least(1), default=1, metavar="N",
                   help="name up to N effects, one per round, each screened against the model "
                        "with the ones named before (default 1)")
    s.add_argument("--check-seed", action="append", type=_seed, metavar="N",
                   help="screen again with seed N (repeatable) and say whether every seed names "
                        "the same effects (one more screening each)")
    from ..workers import default_jobs
    s.add_argument("--jobs", "-j", type=_at_least(1), default=default_jobs(), metavar="N",
                   help="processes for the screening's fits (default: every core, here "
                        f"{default_jobs()}); the results do not depend on it")
    _add_selection(s, "cap on stored sampler steps of the refit (default 100000: until converged; "
                      "a real level can take over 10 minutes)")
    s.set_defaults(func=C._cmd_discover)

    s = sub.add_parser("run", help="run a workflow (make-like: only what is out of date)")
    s.add_argument("workflow", metavar="WORKFLOW", help="workflow file (TOML, e.g. workflows/quick.toml)")
    s.add_argument("targets", nargs="*", metavar="TARGET",
                   help="ingest, fit, predict, compare, discrepancy, report or all (default), "
                        "or a task name (`frictionuq status WORKFLOW` lists them)")
    s.add_argument("-j", "--jobs", type=_at_least(1), default=1, help="fits in parallel (local processes)")
    s.add_argument("--scheduler", metavar="ADDRESS", default=None,
                   help="send fits to this Dask distributed scheduler (e.g. tcp://host:8786)")
    s.add_argument("--force", action="store_true", help="rerun the targets' tasks even if up to date")
    s.add_argument("--dry-run", action="store_true", help="print the plan: what would run and why")
    s.set_defaults(func=C._cmd_run)

    s = sub.add_parser("status", help="which tasks of a workflow are up to date, which are stale and why")
    s.add_argument("workflow", metavar="WORKFLOW")
    s.set_defaults(func=C._cmd_status)

    s = sub.add_parser("clean", help="remove a workflow's run folder and report")
    s.add_argument("workflow", metavar="WORKFLOW")
    s.set_defaults(func=C._cmd_clean)
    return p
