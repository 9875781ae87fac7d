"""The parameter draws a prediction uses at an applied force F (SI), from a fit output folder
(`frictionuq fit`, see frictionuq.infer.fit).

If F is a fitted level (summary.json fits[i]["applied"]; the nearest level within a relative
REL_TOL, so that a level typed as `table` or a fit id shows it, to 4-6 digits, is that level), the joint
posterior draws of that fit (free parameters from posterior.nc, fixed ones from fit.json), with
its model and effects; several fits at the same level (`fit --by test`) are pooled with equal
weight. Otherwise the force-dependence law of the folder (frictionuq.infer.lawdraws.draws_at); without
a law the request is refused.
Each draw carries the measurement noise (sigma_noise, noise_phi, and the ARMA(1,1) MA
coefficient where the fit has one) of one of its fit's tests, picked at random, from the same
posterior draw; with the law, from the posterior of the fitted level nearest in log force (the
law describes the model parameters only). How predict.py converts that noise to the
prediction's step is explained there.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import params as P
from .errors import InputError
from .fitdir import FitPosterior, fitted_levels, load_posterior, load_summary

#: a requested force within this relative distance of a fitted level is that level: `table`
#: shows levels to 4 significant digits, fit ids to 6 (29.8996 lbf typed as 29.9 is 1.3e-5 away;
#: with 1e-6 it went to the force-dependence law, or was refused without one)
REL_TOL = 1e-3
LIKELIHOOD_ONLY = set(P.LIKELIHOOD_NAMES)


LAW_SOURCE = "force-dependence law"    # Draws.source of draws made by the law


@dataclass
class Draws:
    """S parameter draws for one prediction, with their measurement noise and offset."""
    params: dict[str, np.ndarray]      # model parameters (SI), (S,) each
    model: str
    effects: tuple[str, ...]
    offset: np.ndarray                 # (S,) force_offset (N)
    sigma: np.ndarray                  # (S,) noise marginal sd (N)
    phi: np.ndarray                    # (S,) noise lag-1 correlation at rate_hz
    rate_hz: np.ndarray                # (S,)
    source: str
    fits: list[str]
    theta: np.ndarray | None = None    # (S,) ARMA(1,1) MA coefficient at rate_hz (None: 0)

    @property
    def size(self) -> int:
        return self.offset.size

    def resting_on(self, summary: dict) -> list[str]:
        """The fits these draws rest on: their own, or every level for the force-dependence law
        (fitted on all of them)."""
        if self.source == LAW_SOURCE:
            return [f["id"] for f in summary["fits"]]
        return list(self.fits)


def _take(posts: list[FitPosterior], n: int, rng) -> dict:
    """n joint draws from a mixture (equal weights) of fits: named parameters (free + fixed),
    offset and one test's noise per draw. With per-test offsets (FitConfig.force_offset) the offset
    is that same test's own: a new test's zero is drawn from the fitted tests' zeros."""
    which = rng.integers(len(posts), size=n) if len(posts) > 1 else np.zeros(n, int)
    names = set().union(*(set(p.params) | set(p.fixed) for p in posts))
    if any(p.offsets is not None for p in posts):    # per-test offsets: the drawn test's own
        names.add("force_offset")
    out = {k: np.full(n, np.nan) for k in names | {"_sigma", "_phi", "_rate", "_theta"}}
    for k, p in enumerate(posts):
        sel = np.flatnonzero(which == k)
        if not sel.size:
            continue
        idx = rng.choice(p.size, size=sel.size, replace=p.size < sel.size)
        j = rng.integers(p.sigma.shape[1], size=sel.size)
        for nm in names:
            if nm in p.params:
                out[nm][sel] = p.params[nm][idx]
            elif nm in p.fixed:
                out[nm][sel] = p.fixed[nm]
        if p.offsets is not None:
            out["force_offset"][sel] = p.offsets[idx, j]
        out["_sigma"][sel] = p.sigma[idx, j]
        out["_phi"][sel] = p.phi[idx, j]
        out["_rate"][sel] = p.rate_hz[j]
        out["_theta"][sel] = p.theta[j] if p.theta is not None else 0.0
    return out


def _shown(values_si, summary: dict) -> str:
    """Applied forces (SI) as the user gave them: in the campaign's unit with the SI value beside
    it ("50 lb (222.4 N)"), or in SI alone when the campaign's unit is SI or unknown."""
    from .units import from_si, si_unit_of_applied
    unit = (summary.get("units") or {}).get("applied")
    try:
        si = si_unit_of_applied(unit)
    except (ValueError, TypeError):
        return ", ".join(f"{float(v):g} (SI)" for v in values_si) or "none"

    def one(v: float) -> str:
        return f"{v:g} {si}" if unit == si else \
            f"{from_si(v, 'applied', unit):g} {unit} ({v:.6g} {si})"
    return ", ".join(one(float(v)) for v in values_si) or "none"


def choose_draws(fit_dir, applied_si: float, n: int, rng, summary: dict | None = None) -> Draws:
    """n parameter draws at applied force `applied_si` (SI): the posterior of the fit(s) at that
    level, else the folder's force-dependence law (module docstring)."""
    summary = summary or load_summary(fit_dir)
    a = float(applied_si)
    at = [float(f["applied"]) for f in summary["fits"] if f.get("applied") is not None]
    near = [v for v in at if abs(v - a) <= REL_TOL * max(abs(v), 1e-300)]
    level = min(near, key=lambda v: abs(v - a)) if near else None     # the nearest one only
    match = [f for f in summary["fits"] if f.get("applied") is not None
             and float(f["applied"]) == level]
    if match:
        posts = [load_posterior(fit_dir, f["id"]) for f in match]
        kinds = {(p.model, p.effects) for p in posts}
        if len(kinds) > 1:
            raise InputError(f"{fit_dir}: the fits at applied {a:g} (SI) use different models/effects "
                             f"{sorted(kinds)}; predict from one of them")
        d = _take(posts, n, rng)
        ids = [p.id for p in posts]
        src = f"posterior of fit {ids[0]}" if len(ids) == 1 else \
            f"posterior of fits {', '.join(ids)} (equal-weight mixture)"
        if level != a:
            src += f", the fitted level {_shown([level], summary)} nearest the requested one"
        params = {k: v for k, v in d.items() if not k.startswith("_") and k not in LIKELIHOOD_ONLY}
        return Draws(params, posts[0].model, posts[0].effects, d.get("force_offset", np.zeros(n)),
                     d["_sigma"], d["_phi"], d["_rate"], src, ids, d["_theta"])
    levels = fitted_levels(summary)
    lv, shown = _shown(levels, summary), _shown([a], summary)
    try:
        from .infer.lawdraws import draws_at
    except ImportError:
        raise InputError(f"{fit_dir}: applied force {shown} is not a fitted level (fitted: {lv}) "
                         "and no force-dependence law is available in this version") from None
    try:
        params, model, effects = draws_at(fit_dir, a, n, rng)
    except InputError as e:
        raise InputError(f"no fitted level at applied force {shown} (fitted: {lv}) and no usable "
                         f"force-dependence law: {e}") from None     # e names the folder
    if not levels:
        raise InputError(f"{fit_dir}: no fit at a single applied force to take the noise from")
    near = min(levels, key=lambda v: abs(math.log(v) - math.log(a)) if v > 0 and a > 0 else abs(v - a))
    posts = [load_posterior(fit_dir, f["id"]) for f in summary["fits"]
             if f.get("applied") is not None and float(f["applied"]) == near]
    d = _take(posts, n, rng)
    off = np.asarray(params["force_offset"], float) if "force_offset" in params else \
        d.get("force_offset", np.zeros(n))
    params = {k: np.asarray(v, float) for k, v in params.items() if k not in LIKELIHOOD_ONLY}
    return Draws(params, model, tuple(effects), off, d["_sigma"], d["_phi"], d["_rate"],
                 LAW_SOURCE, [p.id for p in posts], d["_theta"])
