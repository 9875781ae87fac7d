"""The command line: parse, call the library, print. Every command is a library function first.

Bad input (frictionuq.errors.InputError, or a ValueError raised by validation) prints one line
`frictionuq: error: ...` on stderr and exits with code 2, without a traceback.
"""
from __future__ import annotations

import sys

from ..errors import EXIT_BAD_INPUT
from .options import build_parser


#: options whose value may start with "-" without being a number argparse recognises
#: ("--harmonic -0.02,0.5" would read as a missing value; its own check then says what is wrong)
_DASH_VALUES = ("--harmonic",)


def _join_dash_values(argv: list[str]) -> list[str]:
    out, i = [], 0
    while i < len(argv):
        nxt = argv[i + 1] if i + 1 < len(argv) else ""
        if argv[i] in _DASH_VALUES and nxt[:1] == "-" and (nxt[1:2].isdigit() or nxt[1:2] == "."):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
            continue
        out.append(argv[i])
        i += 1
    return out


def main(argv=None) -> int:
    import warnings
    from ..errors import ResultWarning
    # the commands print their own one-line notes for what a library user gets as a warning
    warnings.filterwarnings("ignore", category=ResultWarning)
    parser = build_parser()
    args = parser.parse_args(_join_dash_values(list(sys.argv[1:] if argv is None else argv)))
    if getattr(args, "out", None) == "":
        print("frictionuq: error: --out is empty; give the output folder's path", file=sys.stderr)
        return EXIT_BAD_INPUT
    restore = _terminate_as_interrupt()
    try:
        code = args.func(args)
    except BrokenPipeError:           # output piped into `head` etc.: stop quietly
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        # fit and run keep a fit's stored steps; compare, discover and the others write their
        # output folder only once complete (nothing of the interrupted run is left)
        resumes = getattr(args, "command", None) in ("fit", "run")
        print("frictionuq: interrupted; finished outputs are kept, and the same command "
              + ("resumes a fit from its stored steps" if resumes else "starts it again"),
              file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError, IsADirectoryError, NotADirectoryError,
            PermissionError) as e:
        msg = " ".join(str(e).split())
        print(f"frictionuq: error: {msg}", file=sys.stderr)
        return EXIT_BAD_INPUT
    finally:
        restore()
    return int(code or 0)


def _terminate_as_interrupt():
    """SIGTERM (`kill`, `timeout`, a batch scheduler) stops a command as Ctrl-C does: the
    temporary output folders are removed and a fit keeps its stored steps (before, a terminated
    command left its `.NAME.*.tmp` folder behind). Returns the function restoring the old
    handler (main is also called from tests and notebooks, off the main thread too)."""
    import signal

    def handler(signum, frame):
        raise KeyboardInterrupt
    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:           # not the main thread: signals cannot be set here
        return lambda: None
    return lambda: signal.signal(signal.SIGTERM, old)

