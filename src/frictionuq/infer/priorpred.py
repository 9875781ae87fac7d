"""Prior predictive check: do the priors put the measured force within what they allow?

For S parameter vectors drawn from the fit's prior (Space.sample_prior), every record is
simulated (noise-free, plus the offset) and three figures of each simulation are compared with
the measured record's: the peak force max F, the trough min F and the energy dissipated over the
record (the loop integral of F dx, J). A prior is reasonable when each measured figure lies inside
the central 98 % of its prior predictive distribution (neither so narrow that the data are
excluded nor so wide that the priors are meaningless: the check also reports the ratio of the
prior predictive 98 % width to the measured value). It also counts the draws whose simulation is
not finite (there should be none: the kernel is stable over the whole prior box).
"""
from __future__ import annotations

import numpy as np


def _figures(F: np.ndarray, x: np.ndarray) -> dict:
    """(S, N) simulated or (N,) measured force -> peak, trough, dissipated energy (each (S,))."""
    F = np.atleast_2d(F)
    dx = np.diff(x)
    energy = np.sum(0.5 * (F[:, 1:] + F[:, :-1]) * dx[None, :], axis=1)
    return {"peak_N": F.max(axis=1), "trough_N": F.min(axis=1), "energy_J": energy}


def prior_predictive(logpost, n: int = 200, seed: int = 0) -> dict:
    """The check on every record of a LogPosterior; JSON-ready."""
    rng = np.random.default_rng(seed)
    sp = logpost.space
    theta = sp.sample_prior(n, rng)
    off = sp.offset(theta)
    if sp.per_test_offset:                  # each test's own zero, from its uniform prior
        off = rng.uniform(*sp.offset_box, size=n)
    out = {"draws": int(n), "seed": seed, "rule": "measured figure inside the central 98 % of the "
           "prior predictive; figures: peak force, trough force (N), energy dissipated over the "
           "record (J)", "records": {}}
    ok_all = True
    for rec in logpost.records:
        F = logpost.simulate(theta, rec) + off[:, None]
        finite = np.all(np.isfinite(F), axis=1)
        sim = _figures(F[finite], rec.x)
        obs = _figures(rec.y, rec.x)
        r = {"non_finite_draws": int((~finite).sum())}
        for k in sim:
            lo, hi = np.quantile(sim[k], [0.01, 0.99])
            o = float(obs[k][0])
            inside = bool(lo <= o <= hi)
            ok_all &= inside
            r[k] = {"measured": o, "q1": float(lo), "q99": float(hi), "inside": inside,
                    "quantile_of_measured": float(np.mean(sim[k] <= o))}
        out["records"][rec.id] = r
        ok_all &= r["non_finite_draws"] == 0
    out["passed"] = bool(ok_all)
    return out


def outside(check: dict) -> list[str]:
    """The figures of a check that failed, as phrases: 'test t: peak 16.1 kN above the prior
    predictive's q99 14.5 kN', and draws whose simulation was not finite."""
    out = []
    for rid, r in check["records"].items():
        if r["non_finite_draws"]:
            out.append(f"test {rid}: {r['non_finite_draws']} draws not finite")
        for k, what, unit, scale in (("peak_N", "peak", "kN", 1e-3), ("trough_N", "trough", "kN", 1e-3),
                                     ("energy_J", "energy", "J", 1.0)):
            f = r[k]
            if not f["inside"]:
                side, q = ("above", "q99") if f["measured"] > f["q99"] else ("below", "q1")
                out.append(f"test {rid}: {what} {f['measured'] * scale:.4g} {unit} {side} the prior "
                           f"predictive's {q} {f[q] * scale:.4g} {unit}")
    return out
