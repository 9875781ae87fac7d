"""The suite's own scheduling (tests/conftest.py): the slow files it runs first all exist, so a
renamed file cannot silently fall back to the alphabet's place, and xdist keeps that order."""
from __future__ import annotations

import tomllib
from pathlib import Path

from conftest import SLOW_FIRST

TESTS = Path(__file__).resolve().parent


def test_slow_first_names_existing_files_once():
    assert len(set(SLOW_FIRST)) == len(SLOW_FIRST)
    missing = [name for name in SLOW_FIRST if not (TESTS / name).is_file()]
    assert not missing, f"tests/conftest.py SLOW_FIRST names files that do not exist: {missing}"


def test_xdist_keeps_the_collection_order():
    opts = tomllib.loads((TESTS.parent / "pyproject.toml").read_text())["tool"]["pytest"]["ini_options"]["addopts"]
    assert "--dist loadfile" in opts and "--no-loadscope-reorder" in opts
