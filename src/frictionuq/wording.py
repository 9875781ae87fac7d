"""Small helpers for the words of messages, logs and the report."""
from __future__ import annotations


def count(n, noun: str, plural: str | None = None) -> str:
    """'1 test', '3 tests', '1 degree of freedom' (count(1, 'degree', 'degrees') + ...): the
    noun in the number's form; plural defaults to noun + 's'."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"
