"""The one error type for bad input. Its message is a single line that names the file, the row
or key, and what is wrong; the CLI prints it and exits with code 2 (no traceback)."""
from __future__ import annotations

EXIT_BAD_INPUT = 2


class InputError(ValueError):
    """Bad input from a user: a file, a row, a key or a parameter. One line, says what to do."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))   # always one line


def where(path, row: int | None = None, key: str | None = None) -> str:
    """'file.csv', 'file.csv, row 12', 'campaign.toml, key tests[3].applied' ..."""
    s = str(path)
    if row is not None:
        s += f", row {row}"
    if key is not None:
        s += f", key {key}"
    return s
