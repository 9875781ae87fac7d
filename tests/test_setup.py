"""The set-up behind the README's two commands: tools/find-python locates a Python >= 3.12
(PATH first, then pyenv's installed versions, or a PYTHON= override) and says what to install
when none exists."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FIND = ROOT / "tools" / "find-python"


def run(env_extra, path_dirs):
    env = {"PATH": os.pathsep.join(map(str, path_dirs)), "HOME": env_extra.pop("HOME", "/nonexistent")}
    env.update(env_extra)
    return subprocess.run(["/bin/bash", str(FIND)], capture_output=True, text=True, env=env)


def fake_python(folder: Path, name: str, version: str) -> Path:
    """A stand-in interpreter that reports `version` to find-python's check."""
    folder.mkdir(parents=True, exist_ok=True)
    major, minor = version.split(".")[:2]
    p = folder / name
    p.write_text(f"#!/bin/sh\n[ \"$1\" = -c ] && exec {sys.executable} -c "
                 f"'import sys; sys.exit(0 if ({major}, {minor}) >= (3, 12) else 1)'\n")
    p.chmod(0o755)
    return p


def test_skips_old_python_on_path_and_finds_pyenv(tmp_path):
    bindir = tmp_path / "bin"
    fake_python(bindir, "python3", "3.11.7")           # the default python3 is too old
    root = tmp_path / "pyenv"
    want = fake_python(root / "versions" / "3.12.1" / "bin", "python3", "3.12.1")
    fake_python(root / "versions" / "3.10.13" / "bin", "python3", "3.10.13")
    r = run({"PYENV_ROOT": str(root)}, [bindir, "/usr/bin", "/bin"])
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == str(want)


def test_path_first(tmp_path):
    bindir = tmp_path / "bin"
    want = fake_python(bindir, "python3.12", "3.12.4")
    root = tmp_path / "pyenv"
    fake_python(root / "versions" / "3.13.0" / "bin", "python3", "3.13.0")
    r = run({"PYENV_ROOT": str(root)}, [bindir, "/usr/bin", "/bin"])
    assert r.stdout.strip() == str(want)


def test_override_and_refusal(tmp_path):
    old = fake_python(tmp_path / "o", "python3", "3.11.7")
    r = run({"PYTHON": str(old)}, ["/usr/bin", "/bin"])
    assert r.returncode == 1 and "not a Python >= 3.12" in r.stderr
    new = fake_python(tmp_path / "n", "python3", "3.12.1")
    r = run({"PYTHON": str(new)}, ["/usr/bin", "/bin"])
    assert r.returncode == 0 and r.stdout.strip() == str(new)


@pytest.mark.skipif(any(Path(p).exists() for p in ("/usr/bin/python3.12", "/usr/bin/python3.13",
                                                    "/usr/local/bin/python3.12", "/usr/local/bin/python3.13")),
                    reason="this machine has a system Python >= 3.12")
def test_none_found_says_what_to_install(tmp_path):
    bindir = tmp_path / "bin"
    fake_python(bindir, "python3", "3.11.7")
    r = run({"PYENV_ROOT": str(tmp_path / "empty")}, [bindir, "/usr/bin", "/bin"])
    assert r.returncode == 1
    assert "no Python >= 3.12 found" in r.stderr and "pyenv install 3.12" in r.stderr
    assert "PYTHON=" in r.stderr
