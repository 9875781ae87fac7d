"""The software and machine that made an output: recorded beside the package version in every
result file (fit.json, summary.json, discrepancy.json, law.json, comparison, validation,
predictions, mechanical advantage, simulate's metadata, a pipeline run's run.json).

Why: the same seed and inputs give the same numbers on one machine (checked: two `discover` runs
on the real 25 and 70 lb records of dataset 1, 2026-11-29, identical to the last digit), but not
always across machines or dependency versions: numba compiles the kernel for the host CPU
(`numba_cpu`, LLVM's name for it: AVX-512 or not changes the rounding of sums), and the
dependencies are not pinned. On real records, where two candidate effects explain a similar part
of the gap, that rounding can move a multi-start optimiser to another optimum and change a
second-round name (docs/log-discrepancy.md, 2026-11-29). With this block two outputs that differ
say whether they came from the same software on the same kind of CPU.
"""
from __future__ import annotations

import os
import platform
from functools import lru_cache
from importlib import metadata

#: the distributions whose versions can change a result (numerics, sampler, posterior summaries)
#: or the files that hold it (arviz-base writes the netCDF through h5netcdf / h5py; matplotlib
#: the figures)
PACKAGES = ("numpy", "scipy", "numba", "llvmlite", "emcee", "arviz", "arviz-base", "arviz-stats",
            "arviz-plots", "pandas", "xarray", "h5py", "h5netcdf", "matplotlib")


def timestamp() -> str:
    """Now, as every output writes a time: ISO 8601 to the second, local time with its UTC
    offset ("2026-12-05T12:36:29+00:00")."""
    import datetime as _dt
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def _version(dist: str) -> str | None:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return None


def _cpu_model() -> str:
    """The CPU's model name (Linux /proc/cpuinfo), else platform.processor(), else ""."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or ""


def _numba_cpu() -> str | None:
    """LLVM's name of the CPU numba compiles for (numba's NUMBA_CPU_NAME if set to a CPU, else
    the host's)."""
    name = os.environ.get("NUMBA_CPU_NAME")
    if name and name != "host":
        return name
    try:
        import llvmlite.binding as ll
        return str(ll.get_host_cpu_name())
    except Exception:       # noqa: BLE001 - provenance must never stop a run
        return None


@lru_cache(maxsize=1)
def _static() -> dict:
    return {"python": platform.python_version(),
            "platform": platform.platform(),
            "cpu": _cpu_model(),
            "numba_cpu": _numba_cpu(),
            "cores": os.cpu_count(),
            "packages": {p: _version(p) for p in PACKAGES}}


def environment() -> dict:
    """{"python", "platform", "cpu", "numba_cpu", "cores", "numba_threads", "blas_threads",
    "packages": {name: version or None}} of this process (JSON-ready; a fresh dict each call)."""
    env = dict(_static(), packages=dict(_static()["packages"]))
    env["numba_threads"] = _numba_threads()
    env["blas_threads"] = _blas_threads()
    return env


def _blas_threads() -> int | None:
    """The most threads any loaded BLAS may use (frictionuq holds them to one unless the user
    set OPENBLAS_NUM_THREADS: with more, the MAP search's SVDs are not reproducible bit for
    bit); None when no BLAS is loaded yet."""
    try:
        from threadpoolctl import threadpool_info
        n = [int(i["num_threads"]) for i in threadpool_info() if i.get("user_api") == "blas"]
        return max(n) if n else None
    except Exception:       # noqa: BLE001 - provenance must never stop a run
        return None


def _numba_threads() -> int | None:
    try:
        import numba
        return int(numba.get_num_threads())
    except Exception:       # noqa: BLE001
        return None


def png_metadata() -> dict:
    """PNG text chunks of a figure frictionuq writes: the package version beside matplotlib's
    (a figure saved next to its JSON names the version that drew it)."""
    from . import __version__
    return {"Software": f"frictionuq {__version__} with matplotlib {_version('matplotlib')}"}
