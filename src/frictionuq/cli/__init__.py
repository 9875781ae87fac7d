"""The command line: parse, call the library, print. Every command is a library function first.

Bad input (frictionuq.errors.InputError, or a ValueError raised by validation) prints one line
`frictionuq: error: ...` on stderr and exits with code 2, without a traceback.
"""
from __future__ import annotations

import sys

from ..errors import EXIT_BAD_INPUT
from .options import build_parser


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

