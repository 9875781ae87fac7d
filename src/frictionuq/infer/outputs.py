"""From a sampler result to the fit's outputs: named posterior draws (with each record's noise
parameters drawn from their conditional posterior), the posterior predictive, the ArviZ DataTree
and the summary entry (statistics, convergence, RMSE, identifiability)."""
from __future__ import annotations

import numpy as np

from .. import azadapter, params as P
from . import between, noisemodel

WEAK_CONTRACTION = 0.5       # posterior sd / prior sd above this: "close to the prior" ...
#: ... if its draws are also spread like the prior's: the Kolmogorov-Smirnov distance between
#: them and the prior (sampling coordinates) at most PRIOR_LIKE_KS. The sd alone called a
#: posterior split between a mode cut by a bound and one far from it "close to the prior" (the
#: real 70 lb level of arts-d1, 2026-12-06: v_s's sd ratio 0.93 with 73 % of the draws in the top
#: 2.4 % of its box, so its pile at the bound went unreported)
PRIOR_LIKE_KS = 0.2
STRONG_CORRELATION = 0.9     # |rho| above this: a strongly correlated pair
#: "pressed against a prior bound": more than AT_BOUND_MASS of the draws lie within
#: AT_BOUND_SLAB x the posterior's 95 % interval width of the bound (sampling coordinates), i.e.
#: the density at the bound is at least half the interval's average density: the prior cuts the
#: posterior off. A posterior merely near a bound (density falling to ~0 before it) is not flagged
AT_BOUND_SLAB = 0.05
AT_BOUND_MASS = 0.025


def posterior_draws(logpost, res, rng) -> dict:
    """Posterior draws as arrays shaped (walker, draw[, record])."""
    sp = logpost.space
    th = np.transpose(res.chain, (1, 0, 2))          # (W, D, ndim)
    W, D, _ = th.shape
    flat = th.reshape(-1, sp.ndim)
    vals = sp.to_values(flat).reshape(W, D, sp.ndim)
    out = {"theta": th, "values": {n: vals[:, :, i] for i, n in enumerate(sp.names)},
           "fixed": dict(sp.fixed)}
    sig = np.empty((W * D, len(logpost.records)))
    phi = np.empty_like(sig)
    # the residuals' sufficient statistics at every draw, stored by the sampler (D, W, R, S)
    stats = np.transpose(res.noise_stats, (1, 0, 2, 3)).reshape(W * D, len(logpost.records), -1)
    ns = len(noisemodel.STATS)
    for j, rec in enumerate(logpost.records):
        s_g, phi[:, j] = noisemodel.draw_noise_stats(stats[:, j, :ns].T, rec.n, rng=rng,
                                                     **_draw_args(logpost))
        sig[:, j] = noisemodel.marginal_sd(s_g, phi[:, j], rec.noise_theta)
    out["sigma_noise"] = sig.reshape(W, D, -1)
    out["noise_phi"] = phi.reshape(W, D, -1)
    if sp.per_test_offset:
        offs = draw_test_offsets(logpost, stats[:, :, ns], sig, phi, rng)
        out["force_offset"] = offs.reshape(W, D, -1)
    out["log_prob"] = res.log_prob.T
    out["loglik_records"] = np.transpose(res.blobs, (1, 0, 2))
    return out


#: a test's zero whose 95 % interval reaches this fraction of the box's width from an edge
EDGE = 0.01


def per_test_offsets(logpost, post) -> dict:
    """The per-test offsets' prior box and the tests whose zero presses against it (the box, not
    the data, then bounds it: widen it with force_offset=uniform:LOWER:UPPER)."""
    lo, hi = logpost.space.offset_box
    c = np.asarray(post["force_offset"], float).reshape(-1, len(logpost.records))
    q = np.quantile(c, [0.025, 0.975], axis=0)
    slab = EDGE * (hi - lo)
    edge = [r.id for j, r in enumerate(logpost.records) if q[0, j] < lo + slab or q[1, j] > hi - slab]
    return {"box_N": [lo, hi], "at_box_edge": edge,
            "rule": f"a test's 95 % interval within {EDGE:.0%} of the box's width from an edge"}


def draw_test_offsets(logpost, c_opt, sigma, phi, rng) -> np.ndarray:
    """(draws, records) each test's own force offset (per-test offsets), given the model draw
    and the record's noise draw: Gaussian about the stored conditional optimum c_opt (at the
    most probable phi of the draw's model, an approximation: across the phi posterior it moves
    by well under its sd) with sd s / sqrt(A), s the innovation sd and A = (1 - phi^2) + (N - 1)
    (1 - phi)^2 (offsetnoise; sigma given, the Student-t there is this Gaussian), truncated to
    the prior box."""
    from scipy.stats import truncnorm
    n = np.array([r.n for r in logpost.records], float)[None, :]
    A = (1 - phi**2) + (n - 1) * (1 - phi) ** 2
    sd = sigma * np.sqrt(1 - phi**2) / np.sqrt(A)
    lo, hi = logpost.space.offset_box
    c = np.clip(c_opt, lo, hi)
    return truncnorm.rvs((lo - c) / sd, (hi - c) / sd, loc=c, scale=sd, random_state=rng)


def _draw_args(logpost) -> dict:
    n = dict(logpost.noise)
    n.pop("sigma_bounds")
    return n


def ar1_noise(sigma, phi, n, rng, theta: float = 0.0) -> np.ndarray:
    """Stationary noise paths (S, n) with marginal sd sigma (S,), AR coefficient phi (S,) and
    ARMA(1,1) MA coefficient theta: AR(1) plus white noise (noisemodel.split_ar1_white; theta =
    0: AR(1) alone)."""
    sd_ar, sd_white = noisemodel.split_ar1_white(sigma, phi, theta)
    return noisemodel.noise_paths(sd_ar, phi, sd_white, n, rng)


def predictive(logpost, post, n_draws: int, rng) -> dict:
    """Posterior predictive of every record: noise-free model force (offset included) and with
    the record's measurement noise. Lists over records of (S, N) arrays."""
    th = post["theta"].reshape(-1, post["theta"].shape[-1])
    S = min(n_draws, th.shape[0])
    idx = rng.choice(th.shape[0], size=S, replace=False)
    sel = th[idx]
    R = len(logpost.records)
    off = (post["force_offset"].reshape(-1, R)[idx] if logpost.space.per_test_offset
           else np.repeat(logpost.space.offset(sel)[:, None], R, axis=1))
    sig = post["sigma_noise"].reshape(-1, len(logpost.records))[idx]
    phi = post["noise_phi"].reshape(-1, len(logpost.records))[idx]
    model, rep = [], []
    for j, rec in enumerate(logpost.records):
        F = logpost.simulate(sel, rec) + off[:, j, None]
        model.append(F)
        noise = ar1_noise(sig[:, j], phi[:, j], rec.n, rng, rec.noise_theta)
        g = logpost.noise_gain(sel, j)      # the `chatter` noise effect, if the fit has it
        rep.append(F + (noise if g is None else g * noise))
    return {"index": idx, "model": model, "rep": rep}


def datatree(logpost, post, pred, attrs: dict):
    """The fit's ArviZ DataTree. Observed force lives on the "obs" dim (all records
    concatenated; constant_data says which test and time each sample belongs to); the
    log-likelihood's unit is the whole test (dim "test"), the held-out unit of model comparison."""
    recs = logpost.records
    posterior = dict(post["values"])
    posterior["sigma_noise"] = post["sigma_noise"]
    posterior["noise_phi"] = post["noise_phi"]
    if "force_offset" in post:              # per-test offsets: one per test
        posterior["force_offset"] = post["force_offset"]
    observed = {"force": np.concatenate([r.y for r in recs])}
    const = {"time": np.concatenate([r.t for r in recs]),
             "displacement": np.concatenate([r.x for r in recs]),
             "test_of_obs": np.concatenate([[r.id] * r.n for r in recs])}
    pp = {"force": np.concatenate(pred["rep"], axis=1)[None],
          "force_model": np.concatenate(pred["model"], axis=1)[None]}
    attrs = dict(attrs)
    attrs.update(units="SI: force N, displacement m, time s; parameters in their SI units",
                 log_likelihood="per test: log marginal likelihood of the whole record, noise "
                                "parameters integrated out (tests are the held-out units)")
    dt = azadapter.build(
        posterior,
        sample_stats={"lp": post["log_prob"]},
        log_likelihood={"force_per_test": post["loglik_records"]},
        observed_data=observed, constant_data=const, posterior_predictive=pp,
        dims={"sigma_noise": ["test"], "noise_phi": ["test"], "force_per_test": ["test"],
              **({"force_offset": ["test"]} if "force_offset" in post else {}),
              "force": ["obs"], "force_model": ["obs"], "time": ["obs"], "displacement": ["obs"],
              "test_of_obs": ["obs"]},
        coords={"test": [r.id for r in recs], "obs": np.arange(observed["force"].size)},
        attrs=attrs)
    # each variable's own unit (CF's "units" attribute), for a reader who opens one variable
    for name in posterior:
        base = name.split("[", 1)[0]
        if base in P.PARAMS:
            dt["posterior"][name].attrs["units"] = P.PARAMS[base].unit
            dt["posterior"][name].attrs["long_name"] = P.PARAMS[base].description
    for group, var, unit in (("observed_data", "force", "N"), ("posterior_predictive", "force", "N"),
                             ("posterior_predictive", "force_model", "N"),
                             ("constant_data", "time", "s"), ("constant_data", "displacement", "m"),
                             ("log_likelihood", "force_per_test", "nat"),
                             ("sample_stats", "lp", "nat")):
        dt[group][var].attrs["units"] = unit
    return dt


def rmse(logpost, pred) -> tuple[float, dict]:
    """RMSE (N) of the posterior median of the noise-free prediction, pooled and per test."""
    per, sq, n = {}, 0.0, 0
    for rec, F in zip(logpost.records, pred["model"]):
        r = rec.y - np.median(F, axis=0)
        per[rec.id] = float(np.sqrt(np.mean(r**2)))
        sq += float(np.sum(r**2))
        n += r.size
    return float(np.sqrt(sq / n)), per


def _prior_cdf(space, i: int, x: np.ndarray) -> np.ndarray:
    """The prior's CDF of sampling coordinate i at x: uniform on the box (log-uniform priors are
    uniform in their log coordinate), or the normal prior truncated to the box."""
    lo, hi = space.lo[i], space.hi[i]
    p = space.priors[space.names[i]]
    if p.dist != "normal":
        return np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    from scipy.stats import truncnorm
    return truncnorm.cdf(x, (lo - p.mu) / p.sd, (hi - p.mu) / p.sd, loc=p.mu, scale=p.sd)


def ks_to_prior(space, i: int, x: np.ndarray) -> float:
    """Kolmogorov-Smirnov distance between the draws x of sampling coordinate i and its prior: a
    distance, not a test (thousands of autocorrelated draws would reject any prior)."""
    x = np.sort(np.asarray(x, float))
    F = _prior_cdf(space, i, x)
    n = x.size
    return float(max(np.max(np.arange(1, n + 1) / n - F), np.max(F - np.arange(n) / n)))


def identifiability(space, post) -> dict:
    """Parameters close to their prior (posterior sd / prior sd > 0.5, in sampling coordinates,
    and draws spread like the prior's: ks_to_prior <= PRIOR_LIKE_KS), strongly correlated pairs
    (|rho| > 0.9) and posteriors pressed against a prior bound."""
    th = post["theta"].reshape(-1, space.ndim)
    sd_post = th.std(axis=0)
    weak, contraction, ks = [], {}, {}
    for i, n in enumerate(space.names):
        p = space.priors[n]
        if p.dist == "normal":
            sd_prior = min(p.sd, (space.hi[i] - space.lo[i]) / np.sqrt(12))
        else:
            sd_prior = (space.hi[i] - space.lo[i]) / np.sqrt(12)
        contraction[n] = float(sd_post[i] / sd_prior) if sd_prior > 0 else float("nan")
        if contraction[n] > WEAK_CONTRACTION:
            ks[n] = ks_to_prior(space, i, th[:, i])
            if ks[n] <= PRIOR_LIKE_KS:
                weak.append(n)
    C = np.corrcoef(th.T) if space.ndim > 1 else np.ones((1, 1))
    pairs = [[space.names[i], space.names[j], float(C[i, j])]
             for i in range(space.ndim) for j in range(i + 1, space.ndim)
             if abs(C[i, j]) > STRONG_CORRELATION]
    # posteriors pressed against a prior bound (AT_BOUND_SLAB, AT_BOUND_MASS). Either the data
    # want a value beyond the prior (v_s above 30 % of the peak velocity on the ARTS records) or
    # the bound is physical (a take-up length d3 -> 0 means no take-up stage). A parameter close
    # to its prior reaches the bounds trivially and is listed under close_to_prior instead; one
    # as wide as its prior but not spread like it (ks_to_prior) is checked here.
    lo_q, hi_q = np.quantile(th, [0.025, 0.975], axis=0)
    slab = AT_BOUND_SLAB * (hi_q - lo_q)
    at_bound = {}
    for i, n in enumerate(space.names):
        if n in weak or not slab[i] > 0:
            continue
        lower = float(np.mean(th[:, i] - space.lo[i] <= slab[i]))
        upper = float(np.mean(space.hi[i] - th[:, i] <= slab[i]))
        if max(lower, upper) > AT_BOUND_MASS:
            at_bound[n] = "lower" if lower >= upper else "upper"
    return {"posterior_over_prior_sd": contraction, "ks_to_prior": ks, "close_to_prior": weak,
            "strongly_correlated": pairs, "at_prior_bound": at_bound,
            "rule": f"close to prior: sd ratio > {WEAK_CONTRACTION} and Kolmogorov-Smirnov "
                    f"distance to the prior <= {PRIOR_LIKE_KS} (ks_to_prior, given where the sd "
                    f"ratio is above {WEAK_CONTRACTION}); correlated: |rho| > "
                    f"{STRONG_CORRELATION}; at a prior bound: more than {AT_BOUND_MASS:.1%} of the draws "
                    f"within {AT_BOUND_SLAB:.0%} of the 95 % interval's width from the bound "
                    "(sampling coordinates; the density there at least half the interval's "
                    "average), among the parameters not close to the prior"}


def summary_entry(spec, logpost, res, dt, post, pred) -> dict:
    from .fit import CONVERGENCE
    sp = logpost.space
    # noise_phi is 0 in every draw under the iid likelihood (or fixed by an override): fixed,
    # not a parameter whose R-hat (NaN for constant draws) could hold back convergence
    fixed_noise = {}
    for per_test in ("noise_phi",):
        vals = np.asarray(post[per_test], float).reshape(-1, len(logpost.records))
        if np.all(vals == vals[:1]):
            fixed_noise.update({f"{per_test}[{r.id}]": float(vals[0, j])
                                for j, r in enumerate(logpost.records)})
    names = list(sp.names) + ["sigma_noise"] + ([] if fixed_noise else ["noise_phi"]) \
        + (["force_offset"] if sp.per_test_offset else [])
    tab = azadapter.summary(dt, var_names=names)
    params = {}
    for name, row in tab.iterrows():
        params[str(name)] = {k: float(row[k]) for k in tab.columns}
    for n, v in {**sp.fixed, **fixed_noise}.items():
        params[n] = {"fixed": float(v)}
    free = [n for n in params if "fixed" not in params[n]]
    bad = [n for n in free if not (params[n]["r_hat"] <= CONVERGENCE["r_hat_max"]
                                   and params[n]["ess_bulk"] >= CONVERGENCE["ess_min"]
                                   and params[n]["ess_tail"] >= CONVERGENCE["ess_min"])]
    total, per = rmse(logpost, pred)
    return {"id": spec.id, "tests": [t.id for t in spec.tests], "applied": spec.applied,
            "model": sp.model, "effects": list(sp.effects), "likelihood": sp.likelihood,
            "parameters": params, "converged": not bad and bool(res.converged_tau),
            "not_converged_parameters": bad, "sampler_criteria_met": bool(res.converged_tau),
            "convergence_rule": f"r_hat <= {CONVERGENCE['r_hat_max']} and ess_bulk, ess_tail >= "
                                f"{CONVERGENCE['ess_min']} for every free parameter on the stored "
                                "draws, and the sampler's own stopping rule met on the whole kept "
                                "chain (R-hat, ESS, > 50 tau) before the step cap",
            "rmse": total, "rmse_per_test": per, "identifiability": identifiability(sp, post),
            "between_tests": between.check_fit(logpost, post, pred),
            **({"per_test_offsets": per_test_offsets(logpost, post)} if sp.per_test_offset else {}),
            "sampler_steps": res.n_steps, "tau_max": float(np.max(res.tau)),
            "model_evaluations": res.n_evals,
            **({"noise_theta": {r.id: r.noise_theta for r in logpost.records}}
               if sp.likelihood == "arma" else {})}
