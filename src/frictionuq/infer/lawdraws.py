"""Draws from a fitted force-dependence law (infer.law, `law.json`): a parameter's law at any
applied force (law_values), and whole parameter draws at an applied force that was never tested
(draws_at), what `predict` and the mechanical-advantage table use away from the fitted levels."""
from __future__ import annotations

import math

import numpy as np

from .. import params as P
from ..errors import InputError
from .law import _mean_fn, level_draws, load_law


def law_values(law: dict, name: str, applied_si, with_scatter: bool, rng) -> np.ndarray:
    """Draws (S, len(applied)) of parameter `name` from the law at applied forces (SI)."""
    L = law["laws"][name]
    beta = np.asarray(L["beta_draws"], float)
    tau = np.asarray(L["tau_draws"], float)
    a = np.atleast_1d(np.asarray(applied_si, float))
    mu = _mean_fn(L["family"], beta, a, L["log_space"])
    if with_scatter:
        mu = mu + tau[:, None] * rng.standard_normal(mu.shape)
    if L["log_space"]:
        return np.exp(mu)
    return mu


def scatter_normals(law: dict, levels: list[dict], names: list[str], n: int, rng) -> np.ndarray:
    """(n, len(names)) standard normals for the laws' between-level scatter terms, correlated
    as the fitted levels' departures from their laws: per level and parameter, the level's
    posterior mean (in the law's space) minus the law's centre at that level's force (posterior
    mean of the law's coefficients); their sample correlation over the levels (eigenvalues
    clipped at 0: with fewer levels than parameters it is singular, and is sampled as such).
    Fewer than three levels with finite departures: independent normals."""
    m = len(names)
    eps = rng.standard_normal((n, m))
    applied = [Lv["applied"] for Lv in levels]
    res = np.empty((len(levels), m))
    for j, name in enumerate(names):
        L = law["laws"][name]
        beta = np.mean(np.asarray(L["beta_draws"], float), axis=0)[None, :]
        centre = _mean_fn(L["family"], beta, applied, L["log_space"])[0]
        for i, Lv in enumerate(levels):
            v = Lv["draws"][name]
            res[i, j] = float(np.mean(np.log(v) if L["log_space"] else v)) - centre[i]
    res = res[np.all(np.isfinite(res), axis=1)]
    if res.shape[0] < 3 or m < 2:
        return eps
    sd = res.std(axis=0)
    C = np.eye(m)
    ok = sd > 0
    if ok.sum() >= 2:
        C[np.ix_(ok, ok)] = np.corrcoef(res[:, ok].T)
    w, V = np.linalg.eigh(C)
    return eps @ (V * np.sqrt(np.clip(w, 0.0, None))).T


def draws_at(fit_dir, applied_si: float, n: int, rng):
    """Parameter draws (name -> (n,) array, SI) at an applied force that need not have been
    tested, with the fit's model and effects: (draws, model, effects).

    Each draw starts from a joint posterior draw of the nearest fitted level (nearest in log
    force), which keeps the within-level correlations between parameters, and moves its
    parameters to the law: in the law's space (log or linear),
        p_new = p_draw - mean_near + law_s(a_new) + tau_s z,
    i.e. the law's centre at the new force (a law posterior draw s), its between-level scatter,
    and the nearest level's within-level spread. At a fitted level this is close to, but wider
    than, that level's own posterior (the scatter term); predict uses the posterior there. The
    scatter's normals z are correlated across parameters as the fitted levels' departures from
    their laws are (scatter_normals), and each draw takes the law draws (s, tau) at one shared
    rank of tau for every parameter: a level whose friction lies above the law has all its
    friction forces above it, and independent z and tau gave implausible combinations
    (fs_fwd / fc_fwd from 0.92 to 1.40 where every level had 1.20)."""

    law = load_law(fit_dir)
    levels, _ = level_draws(fit_dir)
    levels = [L for L in levels if L["applied"] > 0]
    a = float(applied_si)
    if not np.isfinite(a) or a <= 0:
        raise InputError(f"applied force must be > 0, got {applied_si!r}")
    near = min(levels, key=lambda L: abs(math.log(L["applied"]) - math.log(a)))
    S = next(iter(near["draws"].values())).size
    idx = rng.choice(S, size=n, replace=S < n)
    names = [name for name in law["laws"] if name in near["draws"]]
    Z = dict(zip(names, scatter_normals(law, levels, names, n, rng).T))
    U = rng.random(n)       # one rank of the scatter's size per draw, shared by the parameters
    out = {}
    for name in names:
        L = law["laws"][name]
        d = near["draws"][name][idx]
        tr = np.log(d) if L["log_space"] else d
        mean_near = float(np.mean(np.log(near["draws"][name]) if L["log_space"] else near["draws"][name]))
        order = np.argsort(np.asarray(L["tau_draws"], float), kind="stable")
        k = order[np.minimum((U * order.size).astype(int), order.size - 1)]
        beta = np.asarray(L["beta_draws"], float)[k]
        centre = _mean_fn(L["family"], beta, [a], L["log_space"])[:, 0]
        new = tr - mean_near + centre + np.asarray(L["tau_draws"])[k] * Z[name]
        v = np.exp(new) if L["log_space"] else new
        # the scatter term can carry a draw past the prior box (or the physical bounds): clip
        lo, hi = near["bounds"].get(name, (-np.inf, np.inf))
        if name in P.PARAMS:
            lo, hi = max(lo, P.PARAMS[name].lower), min(hi, P.PARAMS[name].upper)
        v = np.clip(np.where(np.isfinite(v), v, lo), lo, hi)
        out[name] = v
    for name, v in near["fixed"].items():
        out.setdefault(name, np.full(n, float(v)))
    return out, law["model"], tuple(law["effects"])
