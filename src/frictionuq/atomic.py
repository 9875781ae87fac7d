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


def _cannot_write(path, e: OSError, where):
    """The one-line refusal of an OSError met while making `path` (InputError)."""
    from .errors import InputError
    return InputError(f"cannot write {path}: {e.strerror or e} ({e.filename or where})")


def writable_parent(path, create: bool = True) -> Path:
    """Make the folder `path` is to be written in, or refuse with one line naming `path`: a
    parent that is a file, or one that cannot be created (InputError, not an OSError with the
    temporary sibling's name). create=False only checks the nearest existing ancestor (before
    any work: nothing is made)."""
    from .errors import InputError
    path = Path(path)
    for up in path.parents:          # the nearest existing ancestor must be a folder
        if up.exists():
            if not up.is_dir():
                raise InputError(f"cannot write {path}: {up} is a file, not a folder")
            break
    if not create:
        return path.parent
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise _cannot_write(path, e, path.parent) from None
    return path.parent


@contextlib.contextmanager
def replacing(path):
    """Yield a temporary sibling path to write; on success it replaces `path` (rename), on any
    exception it is removed and `path` is left as it was."""
    from .errors import InputError
    path = Path(path)
    if path.is_dir():
        raise InputError(f"cannot write the file {path}: it is a folder")
    if path.exists() and not path.is_file():     # the rename would replace a device or FIFO
        raise InputError(f"cannot write the file {path}: it exists and is not a regular file "
                         "(a device, FIFO or socket); choose another path")
    writable_parent(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as e:
        raise _cannot_write(path, e, path.parent) from None
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
    from .errors import InputError
    path = Path(path).absolute()
    cwd = Path.cwd()
    if path.exists() and (path.resolve() == cwd.resolve() or path.resolve() in cwd.resolve().parents):
        raise InputError(f"cannot replace {path}: it is the current folder or holds it; "
                         "choose a new folder")
    if path.exists() and not path.is_dir():
        raise InputError(f"cannot replace {path} by a folder: it is a file")
    made = [up for up in path.parents if not up.exists()]     # the parents this call makes
    writable_parent(path)
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent))
    except OSError as e:
        raise _cannot_write(path, e, path.parent) from None
    os.chmod(tmp, 0o777 & ~_umask())          # mkdtemp makes 0700
    try:
        yield tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        for up in made:                       # innermost first; only if still empty
            try:
                up.rmdir()
            except OSError:
                break
        raise
    old = None
    try:
        if path.exists():
            old = path.with_name(f".{path.name}.old-{os.getpid()}")
            os.replace(path, old)
        os.replace(tmp, path)
    except OSError as e:      # the folder cannot be moved aside (immutable, a mount point ...)
        shutil.rmtree(tmp, ignore_errors=True)
        if old is not None and old.exists() and not path.exists():
            os.replace(old, path)                   # the previous output, back in its place
        raise _cannot_write(path, e, path) from None
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def check_replaceable(source: Path | None, out: Path, marker: str, source_what: str, out_what: str,
                      is_previous=None, owned=None) -> None:
    """Refuse an output folder that `output_dir` must not replace: the source folder itself (or
    one holding it), a file, or a non-empty folder that is not a previous output (recognised by
    its `marker` file, and `is_previous(folder)` when given); with `owned` (name patterns of
    what the command writes there), also a previous output holding anything else (a file the
    user added would be lost with the folder)."""
    from .errors import InputError
    out = Path(out)
    if source is not None:
        src = Path(source).resolve()
        if out.resolve() == src or out.resolve() in src.parents:
            raise InputError(f"--out {out}: must differ from the {source_what} folder and not hold it")
    if out.exists():
        if not out.is_dir():
            raise InputError(f"--out {out}: exists and is not a folder")
        previous = (out / marker).is_file() and (is_previous is None or is_previous(out))
        if any(out.iterdir()) and not previous:
            raise InputError(f"--out {out}: exists, is not empty and is not {out_what}; "
                             "choose a new folder (it would be replaced)")
        if previous and owned:
            from fnmatch import fnmatch
            foreign = sorted(p.name for p in out.iterdir()
                             if not any(fnmatch(p.name, pat) for pat in owned))
            if foreign:
                raise InputError(f"--out {out}: {out_what} that also holds {', '.join(foreign[:3])}"
                                 f"{' ...' if len(foreign) > 3 else ''}, which frictionuq did not "
                                 "write and would delete with the folder: move it out or choose "
                                 "a new folder")
