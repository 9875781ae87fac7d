"""Reading a fit output folder (`frictionuq fit`, layout in frictionuq.infer.fit): its
summary, the campaign's `applied` unit, and one fit's posterior draws flattened over (chain,
draw) with the fit's model, effects, fixed parameters and per-test measurement noise. Used by
frictionuq.predict and frictionuq.advantage."""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

SUMMARY = "summary.json"


def read_json(path: Path, what: str) -> dict:
    """A JSON object from `path`, or one line naming the file and what is wrong."""
    if not path.is_file():
        raise InputError(f"{path}: missing ({what})")
    try:
        doc = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise InputError(f"{path}: not valid JSON ({' '.join(str(e).split())})") from None
    if not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object ({what})")
    return doc


def load_summary(fit_dir) -> dict:
    """summary.json of a fit output folder, checked to be one."""
    fit_dir = Path(fit_dir)
    if not fit_dir.is_dir():
        raise InputError(f"{fit_dir}: " + ("is a file, not a fit output folder (the folder `frictionuq "
                                           "fit --out` wrote)" if fit_dir.exists() else
                                           "no such fit output folder"))
    if not (fit_dir / SUMMARY).is_file():
        raise InputError(f"{fit_dir}: not a fit output folder (no {SUMMARY}); run `frictionuq fit` first")
    s = read_json(fit_dir / SUMMARY, "summary of a fit output folder")
    fits = s.get("fits")
    if not isinstance(fits, list) or not fits or not all(isinstance(f, dict) and "id" in f for f in fits):
        raise InputError(f"{fit_dir / SUMMARY}: key fits: expected a non-empty list of fits with ids "
                         "(not a `frictionuq fit` summary)")
    return s


def campaign_of(summary: dict):
    """The fitted campaign (frictionuq.campaign.Campaign, records not read) from summary.json
    campaign_path, or None when that folder is no longer readable."""
    cp = summary.get("campaign_path")
    if isinstance(cp, str) and Path(cp).is_dir():
        from .campaign import load_campaign
        try:
            return load_campaign(cp, read_records=False)
        except InputError:
            return None
    return None


def campaign_applied_unit(fit_dir, summary: dict) -> tuple[str, str]:
    """(the campaign's `applied` unit, where it was found). Looks in summary.json
    (`units`.applied, written by infer.fit.fit_campaign), then in the campaign folder recorded
    as summary.json campaign_path; falls back to SI (N)."""
    from . import units as U
    units = summary.get("units")
    if isinstance(units, dict) and isinstance(units.get("applied"), str):
        try:
            U.factor("applied", units["applied"])
        except ValueError as e:
            raise InputError(f"{Path(fit_dir) / SUMMARY}, key units.applied: {e}") from None
        return units["applied"], f"{Path(fit_dir) / SUMMARY}"
    camp = campaign_of(summary)
    if camp is not None:
        return camp.units["applied"], f"campaign {summary['campaign_path']}"
    return "N", "not recorded (campaign folder unavailable): SI assumed"


def not_converged(summary: dict, ids=None) -> list[str]:
    """The fits (of `ids`, or all) the summary marks "converged": false: results drawn from them
    are indicative only, which predict, validate and advantage record and say."""
    want = None if ids is None else set(ids)
    return [f["id"] for f in summary["fits"]
            if (want is None or f["id"] in want) and not f.get("converged", False)]


def fitted_levels(summary: dict) -> list[float]:
    return sorted({float(f["applied"]) for f in summary["fits"] if f.get("applied") is not None})


@dataclass
class FitPosterior:
    """One fit's posterior draws, flattened over (chain, draw)."""
    id: str
    applied: float | None
    model: str
    effects: tuple[str, ...]
    params: dict[str, np.ndarray]      # free parameters (M,)
    fixed: dict[str, float]
    sigma: np.ndarray                  # (M, T) noise marginal sd per test (N)
    phi: np.ndarray                    # (M, T) noise lag-1 correlation at rate_hz
    rate_hz: np.ndarray                # (T,) decimated sample rate of each test's record
    tests: list[str] = field(default_factory=list)
    theta: np.ndarray | None = None    # (T,) ARMA(1,1) MA coefficient (likelihood `arma`), else 0
    offsets: np.ndarray | None = None  # (M, T) each test's own force offset (per-test offsets)

    @property
    def size(self) -> int:
        return self.sigma.shape[0]


def load_posterior(fit_dir, fit_id: str) -> FitPosterior:
    """Posterior draws of fit `fit_id` (fit.json + posterior.nc under FIT_DIR/<fit_id>/)."""
    from . import azadapter
    fdir = Path(fit_dir) / fit_id
    rec = read_json(fdir / "fit.json", f"record of fit {fit_id}")
    nc = fdir / "posterior.nc"
    if not nc.is_file():
        raise InputError(f"{nc}: missing (posterior of fit {fit_id}; incomplete fit output)")
    try:
        space = rec["space"]
        free, fixed = list(space["free"]), {k: float(v) for k, v in space["fixed"].items()}
        model, effects = space["model"], tuple(space["effects"])
        rates = {r["id"]: float(r["rate_hz"]) for r in rec["records"]}
        thetas = {r["id"]: float(r.get("noise_theta", 0.0)) for r in rec["records"]}
    except (KeyError, TypeError, ValueError) as e:
        raise InputError(f"{fdir / 'fit.json'}: not a frictionuq fit record (key {e})") from None
    try:
        post = azadapter.load(nc)["posterior"]
        params = {n: np.asarray(post[n].values, float).ravel() for n in free}
        sig = np.asarray(post["sigma_noise"].values, float)
        tests = [str(v) for v in post["test"].values]
        phi = (np.asarray(post["noise_phi"].values, float) if "noise_phi" in post.data_vars
               else np.zeros_like(sig))
        per_test = "force_offset" in post.data_vars and "test" in post["force_offset"].dims
        offs = np.asarray(post["force_offset"].values, float) if per_test else None
    except (OSError, KeyError, ValueError) as e:
        raise InputError(f"{nc}: cannot read the posterior ({' '.join(str(e).split())})") from None
    missing = [t for t in tests if t not in rates]
    if missing:
        raise InputError(f"{fdir / 'fit.json'}: key records: no rate_hz for tests {missing}")
    T = len(tests)
    applied = (rec.get("summary") or {}).get("applied")
    return FitPosterior(fit_id, applied, model, effects, params, fixed,
                        sig.reshape(-1, T), phi.reshape(-1, T),
                        np.array([rates[t] for t in tests]), tests,
                        np.array([thetas[t] for t in tests]),
                        None if offs is None else offs.reshape(-1, T))
