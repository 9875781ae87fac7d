"""The one error type for bad input. Its message is a single line that names the file, the row
or key, and what is wrong; the CLI prints it and exits with code 2 (no traceback)."""
from __future__ import annotations

from numbers import Integral
from pathlib import Path

EXIT_BAD_INPUT = 2


class InputError(ValueError):
    """Bad input from a user: a file, a row, a key or a parameter. One line, says what to do."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))   # always one line


class ResultWarning(UserWarning):
    """A result the library returns rests on something its user should know: fits that did not
    converge, or an input beyond the fitted records. The CLI prints its own one-line notes for
    these (and ignores the warning); a notebook sees the warning."""


def unknown(what: str, name, known) -> str:
    """The one wording of an unknown name (a key, a field, a parameter, an effect, a unit):
    "unknown key 'knd' (did you mean 'kind'?); known: id, file, kind". The closest known name is
    suggested when it is close enough, ignoring case (difflib, ratio >= 0.6: 'kn' -> 'kN')."""
    import difflib
    names = [str(k) for k in known]
    lower = {n.lower(): n for n in reversed(names)}        # the first of names equal but for case
    close = difflib.get_close_matches(str(name).lower(), list(lower), n=1, cutoff=0.6)
    hint = f" (did you mean {lower[close[0]]!r}?)" if close else ""
    return f"unknown {what} {name!r}{hint}; known: {', '.join(names)}"


def not_a_file(path) -> str | None:
    """Why `path` cannot be read as a file ("is a folder, not a file", "file not found", or not a
    regular file), or None when it is one."""
    p = Path(path)
    if p.is_file():
        return None
    if p.is_dir():
        return "is a folder, not a file"
    return "is not a regular file (a device, FIFO or socket)" if p.exists() else "file not found"


def bom_hint(raw: bytes) -> str:
    """The end of a "not valid TOML" message for a file starting with a UTF-8 byte-order mark
    (some Windows editors write one; TOML does not allow it)."""
    return ("; the file starts with a UTF-8 byte-order mark (BOM): save it as UTF-8 without BOM"
            if raw.startswith(b"\xef\xbb\xbf") else "")


def where(path, row: int | None = None, key: str | None = None) -> str:
    """'file.csv', 'file.csv, row 12', 'campaign.toml, key tests[3].applied' ..."""
    s = str(path)
    if row is not None:
        s += f", row {row}"
    if key is not None:
        s += f", key {key}"
    return s


#: the largest seed: outputs record it as a 64-bit integer (HDF5 and netCDF attributes)
MAX_SEED = 2**63 - 1


def check_seed(seed, who: str) -> int:
    """seed as an int, or an InputError naming `who`: the random generators (numpy's) take
    non-negative integers, the outputs store it in 64 bits, and a bad seed must be refused
    before any work starts."""
    if isinstance(seed, bool) or not isinstance(seed, Integral) or not 0 <= seed <= MAX_SEED:
        raise InputError(f"{who}: seed must be an integer from 0 to {MAX_SEED}, got {seed!r}")
    return int(seed)


def check_draws(n, who: str | None = None) -> int:
    """n as an int, or an InputError: a predictive band needs at least 2 posterior draws."""
    if isinstance(n, bool) or not isinstance(n, Integral) or n < 2:
        raise InputError(f"{who + ': ' if who else ''}number of draws must be an integer >= 2, "
                         f"got {n!r}")
    return int(n)
