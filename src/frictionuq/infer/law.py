"""The force-dependence law: model parameters as functions of the applied force, fitted as a
second stage on the per-force posteriors of a `fit --by applied` folder.

Why a second stage. The per-force fits use disjoint tests, so given the parameters their
likelihoods are independent, and their priors are broad (the per-level posterior is close to the
likelihood). The joint posterior of a law over all levels is then well approximated by treating
each level's posterior as a measurement of its parameters. In log space the per-level posteriors
of the friction forces are close to Gaussian, so each level contributes

    m_i ~ N(log f(a_i; beta), s_i^2 + tau^2)

with m_i, s_i the posterior mean and sd of log p at applied force a_i, f the law, and tau the
between-level scatter: the part of the level-to-level variation the law does not explain (real
records scatter far more than their posterior sds; without tau the law's intervals would be
overconfident). Parameters are treated one at a time (their cross-correlations within a level are
kept at prediction time, see `lawdraws.draws_at`).

Families, for the force-dependent parameters (friction forces and sigma0):
    linear       p = c a                       (through the origin: the MFD paper's Table 1)
    threshold    p = c (a - a0), a0 < min a_i  (a0 > 0: the band is slack below a0, as for the
                                                BRFD; a0 < 0: friction remains at zero force)
    saturating   p = p_max (1 - exp(-a / a_s))
Every other parameter is shared: constant, p = mu (with the same scatter tau).

Priors: log c, log p_max, mu flat on wide bounds; a0 uniform on (-2 max a, min a); a_s
log-uniform on (0.05 min a, 20 max a); tau half-normal with scale 1 (a factor e) in log space,
scale = 2 x the spread of the level means in linear space. Sampled with emcee (small: a few
parameters, microseconds per evaluation).

Comparison. Leave-one-level-out predictive density of each held-out level's posterior mean:
elpd_i = log mean_s N(m_i | log f(a_i; beta_s), s_i^2 + tau_s^2) with beta_s, tau_s from the fit
without level i; summed over levels and force-dependent parameters, with SE = sqrt(n var(elpd_i))
over levels (Vehtari et al. 2017). The family with the highest held-out ELPD is used for
predictions unless the caller names one.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

from .. import atomic
from ..environment import environment
from ..errors import InputError, check_seed

FORCE_DEPENDENT = ("fc_fwd", "fc_bwd", "fs_fwd", "fs_bwd", "sigma0")
FAMILIES = ("linear", "threshold", "saturating")
LAW_FILE = "law.json"
N_KEEP = 400                   # law posterior draws stored per parameter


# ---------------------------------------------------------------- per-level inputs

def level_draws(fit_dir) -> tuple[list[dict], dict]:
    """Per-level posterior draws of a `fit --by applied` folder: list of {"id", "applied" (SI),
    "draws": {name: (S,) array}, "fixed": {...}, "lo"/"hi": prior bounds}, and the summary."""
    from .. import azadapter
    from ..fitdir import load_summary, read_json
    fit_dir = Path(fit_dir)
    summary = load_summary(fit_dir)       # one line naming the file when it is not a fit's
    levels = []
    for f in summary["fits"]:
        if f.get("applied") is None:
            continue
        nc = fit_dir / f["id"] / "posterior.nc"
        fj = fit_dir / f["id"] / "fit.json"
        if not nc.is_file() or not fj.is_file():
            raise InputError(f"{fit_dir / f['id']}: posterior.nc or fit.json missing (incomplete fit)")
        rec = read_json(fj, f"record of fit {f['id']}")
        try:
            space = rec["space"]
            bounds = {n: (space["priors"][n]["lower"], space["priors"][n]["upper"])
                      for n in space["free"] if "ratio_of" not in space["priors"][n]}
            fixed, model, effects = dict(space["fixed"]), space["model"], tuple(space["effects"])
            applied = float(f["applied"])
        except (KeyError, TypeError, ValueError) as e:
            raise InputError(f"{fj}: not a frictionuq fit record (key {e})") from None
        try:
            post = azadapter.load(nc)["posterior"]
            draws = {n: np.asarray(post[n].values, float).ravel() for n in space["free"]}
        except (OSError, KeyError, ValueError) as e:
            raise InputError(f"{nc}: cannot read the posterior ({' '.join(str(e).split())})") from None
        levels.append({"id": f["id"], "applied": applied, "draws": draws,
                       "fixed": fixed, "model": model,
                       "effects": effects, "bounds": bounds,
                       "converged": bool(f.get("converged"))})
    levels.sort(key=lambda L: L["applied"])
    return levels, summary


def _stats(levels, name):
    """(a, m, s, log_space) of one parameter over the levels where it is free."""
    a, vals = [], []
    for L in levels:
        if name in L["draws"]:
            a.append(L["applied"])
            vals.append(L["draws"][name])
    if not vals:
        return None
    log_space = all(np.all(v > 0) for v in vals)
    tr = [np.log(v) if log_space else v for v in vals]
    return (np.array(a), np.array([np.mean(v) for v in tr]),
            np.array([max(np.std(v), 1e-12) for v in tr]), log_space)


# ---------------------------------------------------------------- law families

def _mean_fn(family, beta, a, log_space=True):
    """Law mean (in the parameter's transformed space) at forces a; beta (W, k)."""
    a = np.asarray(a, float)[None, :]
    if family == "constant":
        return np.broadcast_to(beta[:, :1], (beta.shape[0], a.shape[1]))
    if family == "linear":
        return beta[:, :1] + np.log(a)
    if family == "threshold":
        d = a - beta[:, 1:2]
        return np.where(d > 0, beta[:, :1] + np.log(np.maximum(d, 1e-300)), -np.inf)
    if family == "saturating":
        return beta[:, :1] + np.log(-np.expm1(-a / np.exp(beta[:, 1:2])))
    raise ValueError(f"unknown law family {family!r}; use one of {FAMILIES}")


def _box(family, a, m, log_space):
    """Prior bounds of (beta..., log tau)."""
    lo_a, hi_a = float(np.min(a)), float(np.max(a))
    spread = float(np.ptp(m)) if m.size > 1 else 1.0
    if family == "constant":
        w = 10.0 + 5 * spread if log_space else 10 * (abs(float(np.mean(m))) + spread) + 1e-12
        b = [(float(np.mean(m)) - w, float(np.mean(m)) + w)]
    elif family == "linear":
        c = float(np.mean(m - np.log(a)))
        b = [(c - 15, c + 15)]
    elif family == "threshold":
        c = float(np.mean(m - np.log(a)))
        b = [(c - 15, c + 15), (-2 * hi_a, lo_a * (1 - 1e-6))]
    elif family == "saturating":
        pmax = float(np.max(m))
        b = [(pmax - 15, pmax + 15), (math.log(0.05 * lo_a), math.log(20 * hi_a))]
    else:
        raise ValueError(f"unknown law family {family!r}")
    return np.array(b, float)


def _log_post(family, a, m, s, log_space, box, tau_scale):
    @np.errstate(over="ignore", invalid="ignore", divide="ignore")
    def f(th):
        th = np.atleast_2d(th)
        beta, ltau = th[:, :-1], th[:, -1]
        ok = np.all((beta >= box[:, 0]) & (beta <= box[:, 1]), axis=1) & (ltau < 5) & (ltau > -25)
        tau = np.exp(ltau)
        mu = _mean_fn(family, beta, a, log_space)
        var = s[None, :] ** 2 + tau[:, None] ** 2
        ll = -0.5 * np.sum((m[None, :] - mu) ** 2 / var + np.log(2 * np.pi * var), axis=1)
        # half-normal prior on tau (scale tau_scale), in log tau coordinates (+ Jacobian)
        lp = -0.5 * (tau / tau_scale) ** 2 + ltau
        out = np.where(ok & np.isfinite(ll), ll + lp, -np.inf)
        return out
    return f


def fit_family(family, a, m, s, log_space=True, seed=0, nwalkers=16, steps=2000):
    """Posterior draws (flat, k + 1 columns) of (beta..., log tau) of one parameter's law."""
    import emcee
    a, m, s = map(np.asarray, (a, m, s))
    box = _box(family, a, m, log_space)
    tau_scale = 1.0 if log_space else max(2 * float(np.ptp(m)), 1e-12) if m.size > 1 else abs(float(m[0])) + 1e-12
    lp = _log_post(family, a, m, s, log_space, box, tau_scale)
    rng = np.random.default_rng(seed)
    k = box.shape[0] + 1
    # start: the law's least-squares fit over a random grid of the box, jittered
    cand = np.column_stack([rng.uniform(box[:, 0], box[:, 1], (4000, box.shape[0])),
                            rng.uniform(math.log(tau_scale) - 6, math.log(tau_scale), 4000)])
    v = lp(cand)
    best = cand[np.argsort(-v)[:nwalkers]]
    p0 = best + 1e-4 * rng.standard_normal(best.shape) * np.r_[box[:, 1] - box[:, 0], 1.0]
    p0[:, :-1] = np.clip(p0[:, :-1], box[:, 0], box[:, 1])
    bad = ~np.isfinite(lp(p0))
    p0[bad] = best[bad]
    sm = emcee.EnsembleSampler(nwalkers, k, lp, vectorize=True,
                               moves=[(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)])
    sm.random_state = np.random.RandomState(seed % (2**32)).get_state()
    sm.run_mcmc(p0, steps, progress=False, skip_initial_state_check=True)
    ch = sm.get_chain(discard=steps // 3, thin=10, flat=True)
    return ch


def _heldout(family, a, m, s, log_space, seed):
    """Leave-one-level-out elpd_i of one parameter (levels,)."""
    out = np.empty(a.size)
    for i in range(a.size):
        keep = np.arange(a.size) != i
        ch = fit_family(family, a[keep], m[keep], s[keep], log_space, seed=seed + i, steps=1000)
        mu = _mean_fn(family, ch[:, :-1], a[i:i + 1], log_space)[:, 0]
        var = s[i] ** 2 + np.exp(ch[:, -1]) ** 2
        with np.errstate(invalid="ignore"):
            lpd = -0.5 * ((m[i] - mu) ** 2 / var + np.log(2 * np.pi * var))
        lpd = np.where(np.isfinite(lpd), lpd, -np.inf)
        out[i] = logsumexp(lpd) - math.log(lpd.size)
    return out


# ---------------------------------------------------------------- the law of a fit folder

def fit_law(fit_dir, family: str = "auto", seed: int = 1, compare: bool = True, log=None) -> dict:
    """Fit the force-dependence law on a `fit --by applied` folder and write FIT_DIR/law.json."""
    from .. import __version__
    log = log or (lambda m: None)
    check_seed(seed, "law")
    if family != "auto" and family not in FAMILIES:
        raise InputError(f"--family must be auto or one of {', '.join(FAMILIES)}, got {family!r}")
    levels, summary = level_draws(fit_dir)
    excluded = [L["id"] for L in levels if L["applied"] <= 0]
    levels = [L for L in levels if L["applied"] > 0]
    if excluded:
        log(f"law: levels at zero applied force left out ({', '.join(excluded)}): every family "
            "is a function of log force, and a level at zero force is outside its support")
    n_forces = len({L["applied"] for L in levels})     # a --by test folder: one fit per test
    if n_forces < 2 or n_forces < len(levels):
        raise InputError(f"{fit_dir}: a force-dependence law needs one fit per applied force at 2 "
                         f"or more forces > 0 (found {len(levels)} fit(s) at {n_forces} "
                         "force(s)); fit with --by applied on a campaign with several levels")
    models = {(L["model"], L["effects"]) for L in levels}
    if len(models) > 1:
        raise InputError(f"{fit_dir}: the fits use different models/effects {sorted(models)}")
    model, effects = models.pop()
    names = sorted({n for L in levels for n in L["draws"]})
    dep = [n for n in names if n in FORCE_DEPENDENT]
    stats = {n: _stats(levels, n) for n in names}
    comparison = {}
    if compare and len(levels) >= 3:
        for fam in FAMILIES:
            per = np.zeros(len(levels))
            for j, n in enumerate(dep):
                a, m, s, ls = stats[n]
                if a.size >= 3:
                    per[: a.size] += _heldout(fam, a, m, s, ls, seed + 101 * j)
            comparison[fam] = {"elpd": float(per.sum()),
                               "se": float(math.sqrt(per.size * np.var(per))),
                               "per_level": per.tolist()}
            log(f"law {fam}: held-out ELPD {per.sum():.2f} nats (SE {comparison[fam]['se']:.2f})")
    if family == "auto":
        finite = {f: c["elpd"] for f, c in comparison.items() if np.isfinite(c["elpd"])}
        chosen = max(finite, key=finite.get) if finite else "linear"
    else:
        chosen = family
    if not comparison:
        log(f"law: {len(levels)} levels: no held-out comparison of the families (leave one level "
            f"out needs 3 or more); {chosen} {'by default' if family == 'auto' else 'as asked'}")
    laws = {}
    for j, n in enumerate(names):
        a, m, s, ls = stats[n]
        fam = chosen if (n in dep and ls) else "constant"
        ch = fit_family(fam, a, m, s, ls, seed=seed + 7 * j)
        idx = np.random.default_rng([seed, j]).choice(ch.shape[0], size=min(N_KEEP, ch.shape[0]), replace=False)
        laws[n] = {"family": fam, "log_space": bool(ls), "levels_applied": a.tolist(),
                   "level_mean": m.tolist(), "level_sd": s.tolist(),
                   "beta_draws": ch[idx, :-1].tolist(), "tau_draws": np.exp(ch[idx, -1]).tolist(),
                   "tau_median": float(np.median(np.exp(ch[:, -1])))}
    doc = {"format": "frictionuq-law/1", "package_version": __version__, "environment": environment(),
           "campaign": summary.get("campaign"), "fit_dir": str(Path(fit_dir).resolve()), "seed": seed,
           "model": model, "effects": list(effects), "family": chosen,
           "family_requested": family, "force_dependent": dep,
           "levels": [{"id": L["id"], "applied": L["applied"], "converged": L["converged"]}
                      for L in levels],
           "excluded_levels": [{"id": i, "reason": "zero applied force (outside the laws' support)"}
                               for i in excluded],
           "comparison": comparison,
           "comparison_rule": "leave-one-level-out ELPD of the per-level posterior means of the "
                              "force-dependent parameters (log space), summed; SE over levels",
           "units": "applied in SI (N or Pa); parameters in SI; level_mean/sd in log space when "
                    "log_space", "laws": laws}
    atomic.write_json(Path(fit_dir) / LAW_FILE, doc)
    # the summary names the law now in the folder (after `law --family X` too)
    summary["law"] = law_entry(fit_dir)
    from .fit import jsonable
    atomic.write_json(Path(fit_dir) / "summary.json", jsonable(summary))
    return doc


def law_entry(fit_dir) -> dict | None:
    """{"file", "family", "sha256"} of the folder's law.json (None without one): what a
    prediction or a mechanical-advantage table drawn from the law records, so that results of
    two laws refitted into one folder can be told apart."""
    from ..campaign import sha256_file
    p = Path(fit_dir) / LAW_FILE
    if not p.is_file():
        return None
    doc = load_law(fit_dir)
    return {"file": LAW_FILE, "family": doc.get("family"), "sha256": sha256_file(p)}


def load_law(fit_dir) -> dict:
    p = Path(fit_dir) / LAW_FILE
    if not p.is_file():
        from ..fitdir import fitted_levels, load_summary
        try:
            positive = [a for a in fitted_levels(load_summary(fit_dir)) if a > 0]
        except InputError:
            positive = []
        if len(positive) >= 2:
            raise InputError(f"{fit_dir}: no force-dependence law ({LAW_FILE}); run `frictionuq "
                             f"law {fit_dir}`")
        raise InputError(f"{fit_dir}: no force-dependence law ({LAW_FILE}), and none can be "
                         f"fitted: it needs fits at 2 or more applied forces > 0, this folder "
                         f"has {len(positive)}; predict at a fitted level, or fit more levels")
    from ..fitdir import read_json
    return read_json(p, "force-dependence law")
