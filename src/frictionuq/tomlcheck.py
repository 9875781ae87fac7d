"""Typed getters over a parsed TOML document that name the file and the key in every error
(InputError: one line, exit code 2 in the CLI). Used by workflow files (frictionuq.workflow);
nothing here knows what a workflow is."""
from __future__ import annotations

import math
from pathlib import Path

from .errors import InputError, unknown


class Checker:
    """Typed getters that name the file and the key in every error."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, key: str, problem: str):
        raise InputError(f"{self.path}: {key}: {problem}")

    def table(self, doc: dict, key: str) -> dict:
        v = doc.get(key, {})
        if not isinstance(v, dict):
            self.fail(f"[{key}]", f"must be a table, got {type(v).__name__}")
        return v

    def unknown(self, table: dict, allowed, where: str) -> None:
        extra = sorted(set(table) - set(allowed))
        if extra:
            self.fail(f"{where}.{extra[0]}" if where else extra[0],
                      unknown("key", extra[0], sorted(allowed)))

    def str_(self, t, key, where, default=None, choices=None, required=False):
        if key not in t:
            if required:
                self.fail(f"{where}.{key}", "missing (required)")
            return default
        v = t[key]
        if not isinstance(v, str) or not v:
            self.fail(f"{where}.{key}", f"must be a non-empty string, got {v!r}")
        if choices and v not in choices:
            self.fail(f"{where}.{key}", f"must be one of {', '.join(choices)}, got {v!r}")
        return v

    def bool_(self, t, key, where, default):
        v = t.get(key, default)
        if not isinstance(v, bool):
            self.fail(f"{where}.{key}", f"must be true or false, got {v!r}")
        return v

    def num(self, t, key, where, default=None, integer=False, minimum=None, positive=False,
            required=False, maximum=None):
        if key not in t:
            if required:
                self.fail(f"{where}.{key}", "missing (required)")
            return default
        v = t[key]
        ok = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok or not math.isfinite(v):
            self.fail(f"{where}.{key}", f"must be {'an integer' if integer else 'a number'}, got {v!r}")
        if positive and not v > 0:
            self.fail(f"{where}.{key}", f"must be > 0, got {v!r}")
        if minimum is not None and v < minimum:
            self.fail(f"{where}.{key}", f"must be >= {minimum}, got {v!r}")
        if maximum is not None and v > maximum:
            self.fail(f"{where}.{key}", f"must be <= {maximum}, got {v!r}")
        return v

    def integers(self, t, key, where, minimum=0):
        v = t.get(key, [])
        if not isinstance(v, list) or not all(isinstance(i, int) and not isinstance(i, bool)
                                              for i in v):
            self.fail(f"{where}.{key}", f"must be a list of integers, got {v!r}")
        if any(i < minimum for i in v):
            self.fail(f"{where}.{key}", f"entries must be >= {minimum}, got {v!r}")
        if len(set(v)) != len(v):
            self.fail(f"{where}.{key}", "lists an entry twice")
        return list(v)

    def strings(self, t, key, where, choices=None):
        v = t.get(key, [])
        if not isinstance(v, list) or not all(isinstance(s, str) and s for s in v):
            self.fail(f"{where}.{key}", f"must be a list of strings, got {v!r}")
        for s in v:
            if choices and s not in choices:
                self.fail(f"{where}.{key}", f"{s!r} is not one of {', '.join(choices)}")
        if len(set(v)) != len(v):
            self.fail(f"{where}.{key}", "lists an entry twice")
        return list(v)
