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
    from .infer.sampler import SamplerConfig
    samp = SamplerConfig(**({"max_steps": a.max_steps} if a.max_steps else {}))
    cfg = FitConfig(model=a.model, effects=tuple(a.effect or ()), likelihood=a.likelihood,
                    seed=a.seed, sampler=samp, tests=tuple(a.test) if a.test else None,
                    kinds=tuple(a.kind) if a.kind else None)
    s = fit_campaign(a.campaign, a.out, by=a.by, config=cfg, log=lambda m: print(m, file=sys.stderr))
    bad = [f["id"] for f in s["fits"] if not f["converged"]]
    print(f"wrote {len(s['fits'])} fit(s) of campaign {s['campaign']!r} to {a.out} (summary.json, "
          f"<fit>/posterior.nc, <fit>/fit.json; SI units)")
    for f in s["fits"]:
        print(f"  {f['id']}: {'converged' if f['converged'] else 'NOT converged'}, "
              f"RMSE {f['rmse']:.4g} N")
    if bad:
        print(f"not converged (R-hat > 1.01 or ESS < 400 for some parameter): {', '.join(bad)}")
        return 1


def _cmd_table(a):
    from .quicklook import campaign_table
    print(campaign_table(a.campaign, published=a.published, eps=a.eps))


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
    s.add_argument("--likelihood", choices=["iid", "ar1"], default="ar1")
    s.add_argument("--seed", type=int, default=1)
    s.add_argument("--test", action="append", metavar="ID", help="only this test (repeatable)")
    s.add_argument("--kind", action="append", choices=["harmonic", "earthquake", "other"],
                   help="only tests of this kind (repeatable)")
    s.add_argument("--max-steps", type=int, default=None, help="cap on stored sampler steps")
    s.set_defaults(func=_cmd_fit)

    s = sub.add_parser("table", help="per-test table of a campaign, with a published-parameter simulation")
    s.add_argument("campaign", help="campaign folder or ingested folder")
    s.add_argument("--published", choices=["brfd", "mfd", "none"], default="none",
                   help="simulate each test with the paper's parameters at the nearest applied level")
    s.add_argument("--eps", default="auto", help="reversal dead-band in m, or 'auto' (estimated)")
    s.set_defaults(func=_cmd_table)
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
