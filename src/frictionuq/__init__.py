"""frictionuq: honest error bars for semi-active friction dampers.

Data flows one way:
    campaign (ingest, units) -> model (kernel, effects) -> infer (priors, likelihood, sampler)
        -> predict (bands, mechanical advantage) -> discrepancy -> report -> pipeline/cli
"""
import os as _os
from importlib.metadata import PackageNotFoundError, version as _version

# One OpenBLAS thread, set before numpy loads it (inherited by spawned workers). The least-squares
# searches do an SVD of a small Jacobian (a few thousand x ~16) per step; with OpenBLAS's default
# threads competing with numba's on 2 cores each SVD took 44 ms instead of ~3, and the discrepancy
# screening of a short campaign 72 s instead of 13 s (measured with another job running).
# A user's explicit setting wins.
_USER_BLAS_THREADS = "OPENBLAS_NUM_THREADS" in _os.environ
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

try:
    __version__ = _version("frictionuq")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

from .model import simulate, simulate_batch, pack_batch, prepare  # noqa: E402


def _one_blas_thread():
    """Hold every loaded BLAS to one thread, also when numpy was imported before frictionuq.

    The variable above only reaches a BLAS loaded after it. A script that imports numpy first
    got OpenBLAS's default of one thread per core, and with two threads the SVDs of the MAP
    search differ in their last bits from run to run, so the same seed gave another start
    ball and another chain (stop 81, docs/log-calibration.md). A BLAS loaded later reads the
    variable. Skipped when the user set OPENBLAS_NUM_THREADS.
    """
    if _USER_BLAS_THREADS:
        return
    from threadpoolctl import threadpool_limits
    threadpool_limits(limits=1, user_api="blas")


_one_blas_thread()


def load_campaign(path):
    """Read a campaign folder (campaign.toml + tests) or an ingested SI folder (manifest.json)."""
    from .campaign import load_campaign as _load
    return _load(path)


__all__ = ["__version__", "simulate", "simulate_batch", "pack_batch", "prepare", "load_campaign"]
