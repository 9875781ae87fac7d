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
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

try:
    __version__ = _version("frictionuq")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"

from .model import simulate, simulate_batch, pack_batch, prepare  # noqa: E402


def load_campaign(path):
    """Read a campaign folder (campaign.toml + tests) or an ingested SI folder (manifest.json)."""
    from .campaign import load_campaign as _load
    return _load(path)


__all__ = ["__version__", "simulate", "simulate_batch", "pack_batch", "prepare", "load_campaign"]
