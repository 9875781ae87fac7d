"""frictionuq: honest error bars for semi-active friction dampers.

Data flows one way:
    campaign (ingest, units) -> model (kernel, effects) -> infer (priors, likelihood, sampler)
        -> predict (bands, mechanical advantage) -> discrepancy -> report -> pipeline/cli
"""
from importlib.metadata import PackageNotFoundError, version as _version

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
