"""Atomic file and folder writes: write to a temporary sibling, then rename. A crash, Ctrl-C or
a validation error never leaves a half-written output behind, and an existing output is only
replaced once the new one is complete."""
from __future__ import annotations

import contextlib
import json
import os
import shutil
import tempfile
from pathlib import Path


def _umask() -> int:
    old = os.umask(0)
    os.umask(old)
    return old


@contextlib.contextmanager
def replacing(path):
    """Yield a temporary sibling path to write; on success it replaces `path` (rename), on any
    exception it is removed and `path` is left as it was."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        os.chmod(tmp, 0o666 & ~_umask())     # mkstemp makes 0600; give the usual mode
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_bytes(path, data: bytes) -> Path:
    with replacing(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)


def write_text(path, text: str) -> Path:
    return write_bytes(path, text.encode("utf-8"))


def write_json(path, obj, **kw) -> Path:
    kw.setdefault("indent", 2)
    return write_text(path, json.dumps(obj, **kw) + "\n")


@contextlib.contextmanager
def output_dir(path):
    """Yield a fresh temporary folder; on success it replaces `path` as a whole.

    On any exception the temporary folder is removed and `path` is left exactly as it was.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    os.chmod(tmp, 0o777 & ~_umask())          # mkdtemp makes 0700
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    old = None
    if path.exists():
        old = path.with_name(f".{path.name}.old-{os.getpid()}")
        os.replace(path, old)
    os.replace(tmp, path)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def check_replaceable(source: Path, out: Path, marker: str, source_what: str, out_what: str) -> None:
    """Refuse an output folder that `output_dir` must not replace: the source folder itself, a
    file, or a non-empty folder that is not a previous output (recognised by its `marker` file)."""
    from .errors import InputError
    source, out = Path(source), Path(out)
    if out.resolve() == source.resolve():
        raise InputError(f"--out {out}: must differ from the {source_what} folder")
    if out.exists():
        if not out.is_dir():
            raise InputError(f"--out {out}: exists and is not a folder")
        if any(out.iterdir()) and not (out / marker).is_file():
            raise InputError(f"--out {out}: exists, is not empty and is not {out_what}; "
                             "choose a new folder (it would be replaced)")
