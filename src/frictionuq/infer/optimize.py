"""MAP search: multi-start nonlinear least squares, then a polish of the full log-posterior.

The force records are long and precise, so the posterior is sharp and a random start rarely
lands near it. The search therefore works in three steps:

1. starting points: a heuristic start read off the records (friction plateaus, the distance
   after a reversal over which the force recovers, a stiff pre-sliding), random perturbations of
   it, the best of a batch of prior draws, and the best point of a differential-evolution search
   over the whole prior box on the coarsened records (`global_start`: least squares from a
   start near the answer can still end in a wrong basin, see there), run until two runs agree
   (`_global_searches`);
2. from each local start, least squares on coarsened copies of the records (every k-th sample,
   <= 800 per record, the model run on the coarse displacement: cheap); all starts ranked on
   copies that run the model on the kept samples and compare every k-th output
   (`coarsened(simulate="kept")`, on which the global search runs too),
   then for the two best local starts and the best global one again on the full records,
   trust-region least squares (scipy.optimize.least_squares, bounded by the prior box) on the
   concatenated residuals of all records, for the model parameters and the force offset; the
   Jacobian is a forward difference evaluated as ONE batch of D+1 simulations (simulate_batch,
   all cores), each start competing with its refinements on the full log-posterior;
3. the best result is polished with Powell's method on the full log-posterior (priors and the
   integrated per-record noise included).

The local fits themselves (least squares, whitening, the noise parameters in turn) and the
Gauss-Newton covariance at the optimum (the walkers' initial ball) are in localfit.py.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import differential_evolution, minimize

from .likelihood import LogPosterior
from .localfit import (alternate_noise, clip_in, least_squares_fit, set_noise_shape,
                       whitening)
from .noisefit import noise_indices
from .priors import RecordScales



def heuristic_values(space, records, scales: RecordScales) -> dict[str, float]:
    """A physically sensible start read off the records (SI values)."""
    F, A = scales.f_scale, scales.amp
    fwd, bwd, recover = [], [], []
    for r in records:
        v = r.drive.v
        vm = np.max(np.abs(v)) or 1.0
        fwd.append(r.y[v > 0.3 * vm])
        bwd.append(r.y[v < -0.3 * vm])
        recover.extend(_recovery_lengths(r.x, r.y, r.eps))
    up = float(np.median(np.concatenate(fwd))) if fwd else F
    lo = float(np.median(np.concatenate(bwd))) if bwd else -F
    off = 0.0
    fcf, fcb = max(up - off, 0.05 * F), max(off - lo, 0.05 * F)
    total = float(np.median(recover)) if recover else 0.05 * A
    total = float(np.clip(total, 1e-3 * A, 0.5 * A))
    vals = {
        "fc_fwd": fcf, "fc_bwd": fcb, "fs_fwd": 1.05 * fcf, "fs_bwd": 1.05 * fcb,
        "v_s": 0.02 * scales.v_max, "sigma0": F / (0.01 * total + 1e-4 * A),
        "sigma1": 0.01 * F / max(scales.v_max, 1e-9), "sigma2": 0.01 * F / max(scales.v_max, 1e-9),
        "d2": 0.6 * total, "d3": 0.3 * total, "w": 0.05 * total,
        "force_offset": off,
    }
    vals["k2"] = 0.3 * F / vals["d2"]
    vals["k3"] = 0.5 * F / vals["d3"]
    for eff_param in ("p2", "kappa", "e_fade", "a_hump", "l_hump", "eps_ecc", "l_ecc", "psi_ecc",
                      "beta_rate", "v_ref", "beta_app", "a_ch"):
        p = space.priors.get(eff_param)
        if p is not None:   # start effects near off (neutral) when the prior allows it
            from .. import params as P
            neu = P.PARAMS[eff_param].neutral
            vals[eff_param] = neu if neu is not None and p.lower <= neu <= p.upper else \
                (np.sqrt(p.lower * p.upper) if p.log else 0.5 * (p.lower + p.upper))
    return vals


def _recovery_lengths(x, y, eps):
    """Distance after each reversal over which the force covers 90 % of its swing, on the
    half-cycles that travel at least 40 % as far as the record's longest (a sine's first, from
    rest, travels half as far): a short one (an earthquake replay's small reversals) ends before
    the backlash is taken up. Counted, they made the median: on a short MFD campaign (two sines,
    the Kobe replay, a hidden reversal_hump, seed 18) 0.39 mm against 13.9 mm on the sines'
    (d2 + d3 = 17.8 mm), so the heuristic starts had d2 0.5 mm and d3 0.2 mm and their searches
    ended 2,700 nats below the fit from the generating values (docs/log-discrepancy.md,
    2026-12-05, evening)."""
    from ..noise import reversal_indices
    idx = reversal_indices(np.asarray(x, float), float(eps))
    out = []
    bounds = list(idx) + [x.size]
    segs = [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b - a >= 5]
    travel = [abs(x[b - 1] - x[a - 1]) for a, b in segs]
    longest = max(travel, default=0.0)
    for (a, b), t in zip(segs, travel):
        if t < 0.4 * longest:
            continue
        seg_x, seg_y = x[a - 1:b], y[a - 1:b]
        d = np.sign(seg_x[-1] - seg_x[0]) or 1.0
        swing = d * (seg_y - seg_y[0])
        full = np.max(swing)
        if full <= 0:
            continue
        k = np.argmax(swing >= 0.9 * full)
        out.append(abs(seg_x[k] - seg_x[0]))
    return out


def coarsened(logpost: LogPosterior, max_samples: int = 800,
              simulate: str = "coarse") -> LogPosterior:
    """The same log-posterior on every k-th sample of each record (for cheap searches).
    simulate="coarse": the model runs on the coarse displacement itself (sim_drive dropped; the
    cheapest, but with steps k times longer it is a different discrete-time model); "kept": it
    runs on the record's kept samples, unfiltered, and every k-th output is compared; "full": as
    the fit simulates it (raw rate where the record has one), every k-th output compared. A record
    short enough to keep is kept as it is in every mode.

    find_map ranks its starts and runs its global search on "kept", and runs the local starts'
    least squares on "coarse", which costs less on long records (MFD hidden thermal_fade
    campaign: find_map 20.5 s all "coarse", 26.5 s all "kept", 23.2 s so). Measured on the BRFD
    twin (four harmonics 0.05-0.5 Hz per level, 400 samples per cycle, with the global starts):
    at 53 N the "coarse" copies ranked the MAP found
    (-62,234 on the full records) 700 above the fit from the published values (-60,213), and the
    search ended there; with "kept" it ended at -60,213.8 (15 s), with "full" at -60,213.9 (58 s).
    At 267 N "coarse" ended at -115,284, "kept" at -115,194.8 (the fit from the published values:
    -115,194.8); at 35 N both at that fit."""
    from dataclasses import replace as dc_replace
    from .. import model as M
    if simulate not in ("coarse", "kept", "full"):
        raise ValueError(f"simulate must be 'coarse', 'kept' or 'full', got {simulate!r}")
    recs = []
    for r in logpost.records:
        k = max(1, int(np.ceil(r.n / max_samples)))
        if k == 1:
            recs.append(r)
            continue
        a = None if r.applied is None else r.applied[::k]
        common = dict(t=r.t[::k], x=r.x[::k], y=r.y[::k], applied=a)
        if simulate == "coarse":
            recs.append(dc_replace(r, **common, drive=M.prepare(r.t[::k], r.x[::k], a),
                                   sim_drive=None))
        elif simulate == "kept":
            recs.append(dc_replace(r, **common, sim_drive=None, stride=k))
        else:       # "full"
            recs.append(dc_replace(r, **common, stride=k))
    return LogPosterior(logpost.space, recs, logpost.parallel)


def _log_prob_batched(logpost: LogPosterior, X: np.ndarray, batch: int = 256) -> np.ndarray:
    return np.concatenate([logpost.log_prob(X[i:i + batch]) for i in range(0, len(X), batch)])


#: global_start's largest population. scipy's Sobol initialisation rounds popsize x D up to a
#: power of 2, so popsize 8 gave 256 members from 17 parameters on (a candidate effect with 3 or
#: more parameters, every second-round candidate), twice the 14-parameter baseline's 128; the
#: multiplier is lowered there instead (7 for 17 parameters, 6 for 20). Measured 2026-12-04
#: (docs/log-discrepancy.md): the slowest CI case (two rounds, overshoot + chatter) 302 s
#: against 380 s side by side (the whole suite 29 min 15 s against 30 min 20 s; item 6 3 % faster);
#: the hidden eccentricity and stage2_nonlinear campaigns and clean ones of seeds 11-13, 16, 17
#: and 31-34 and the real 22, 25, 35 and 80 lb levels were named as with 256.
DE_MAX_POPULATION = 128


def global_start(coarse: LogPosterior, theta0: np.ndarray | None, rng: np.random.Generator,
                 popsize: int = 8, maxiter: int = 300) -> tuple[np.ndarray, int]:
    """Best point of a differential-evolution search (scipy, vectorised: each generation is one
    batch of simulations) of the coarsened log-posterior over the prior box, seeded with theta0
    (None: a Sobol population alone). Returns (theta, number of generations run).

    Why: the take-up parameters make the least-squares landscape rugged. On a clean short BRFD
    campaign (hidden-brfd-7) least squares from the generating values with only d3 changed from
    0.5 to 0.73 mm, or w from 0.2 to 0.12 mm, ended in a basin 400 nats lower (d3 ~ 7 mm,
    sigma1 at its upper bound, v_s at a bound), and so did every heuristic and prior start; this
    search (128 members, 100-170 generations to convergence, 3-4 s on one core) reached the
    generating values' basin on the clean hidden BRFD campaigns of seeds 1, 2, 5 and 7 (400-420
    nats gained; MFD seeds 4 and 7 were already there); on the real 36 lb sines of quick.toml it
    gained 39 nats. It is not certain: on a short 66 N record 8 of 10 seeds reached the mode
    (best1bin; rand1bin, best2bin 0, currenttobest1bin 4, no x0 or Latin hypercube 7, popsize
    16 8), so find_map runs it more than once (_global_searches)."""
    def nlp(X):
        v = _log_prob_batched(coarse, np.atleast_2d(X.T))
        return np.where(np.isfinite(v), -v, 1e300)
    sp = coarse.space
    popsize = max(1, min(popsize, DE_MAX_POPULATION // sp.ndim))
    r = differential_evolution(nlp, list(zip(sp.lo, sp.hi)), popsize=popsize, maxiter=maxiter,
                               vectorized=True, updating="deferred", polish=False, rng=rng,
                               x0=None if theta0 is None else clip_in(sp, theta0), init="sobol",
                               tol=0.0, atol=0.5,
                               mutation=(0.5, 1.0), recombination=0.9)
    return clip_in(sp, r.x), int(r.nit)


#: find_map's differential-evolution searches (_global_searches): with n_global >= 2, more runs
#: (GLOBAL_MAX_RUNS in all at most) while the best two results differ by more than GLOBAL_AGREE
#: nats on the ranking copies
GLOBAL_AGREE = 2.0
GLOBAL_MAX_RUNS = 5


def _global_searches(ranked: LogPosterior, th_h: np.ndarray, rng: np.random.Generator,
                     n_global: int) -> list[tuple[float, np.ndarray, int]]:
    """find_map's differential-evolution searches: (log-posterior on `ranked`, point,
    generations) of each run. The first run is seeded with the heuristic start th_h, the others
    start from their Sobol population alone; with n_global >= 2, runs are added (up to
    GLOBAL_MAX_RUNS) until the best two agree within GLOBAL_AGREE nats: a basin reached by two
    independent runs.

    Why (2026-11-28): on the short 66 N BRFD record of tests/test_stat_recovery.py two runs,
    both seeded with the heuristic start, both ended in wrong basins for rng seeds 2 and 9 of
    1-10 (the better 558 nats below the truth, with sigma0 and k3 at the top of their prior).
    With the later runs unseeded, 19 of 20 seeds reached the mode with two runs; with the agreement rule
    20 of 20 (2.9 runs on average), and the 35, 53, 133 and 267 N records 40 of 40 (2.0-2.8
    runs). On the real ARTS levels tried (arts-d2 0 and 36 lb, arts-d1 35 and 70 lb) the first
    two runs agree (within 0.1-1.9 nats): no extra run."""
    out = []

    def disagree() -> bool:
        top = sorted((z[0] for z in out), reverse=True)
        return top[0] - top[1] > GLOBAL_AGREE

    while len(out) < n_global or (n_global >= 2 and len(out) < GLOBAL_MAX_RUNS and disagree()):
        th_g, gens = global_start(ranked, None if out else th_h, rng)
        out.append((float(ranked.log_prob(th_g[None, :])[0]), th_g, gens))
    return out


def find_map(logpost: LogPosterior, scales: RecordScales, rng: np.random.Generator,
             n_random: int = 6, n_prior: int = 4, n_draws: int = 1024, log=None,
             n_global: int = 2, start: np.ndarray | None = None):
    """Multi-start MAP search. Returns (theta_map, log_prob_map, info). With `start` (a point
    found by another search on the same log-posterior, e.g. the discrepancy screening's) the
    multi-start search is skipped and only the polish runs from there."""
    log = log or (lambda m: None)
    sp = logpost.space
    if start is not None:
        best = clip_in(sp, np.asarray(start, float))
        best_lp = float(logpost.log_prob(best[None, :])[0])
        if not np.isfinite(best_lp):
            raise ValueError("find_map: the given start has a log-posterior that is not finite")
        log(f"MAP polished from the given start (log-posterior {best_lp:.6g}); no multi-start search")
        info = {"start": "given", "start_log_prob": best_lp}
    else:
        best, best_lp, info = _multi_start(logpost, scales, rng, n_random, n_prior, n_draws, log,
                                           n_global)
    if noise_indices(sp):        # a noise effect: its parameters and the weighted fit, in turn
        best, best_lp = alternate_noise(logpost, best, best_lp)
        log(f"noise effect fitted in turn with the model (log-posterior {best_lp:.6g})")
    th_map, lp_map = polish(logpost, best, best_lp)
    if sp.likelihood == "arma":      # the records' MA coefficients at the MAP, then re-polished
        for rnd in range(2):
            thetas = set_noise_shape(logpost, th_map)
            th_map, lp_map = polish(logpost, th_map, float(logpost.log_prob(th_map[None, :])[0]))
        info["noise_theta"] = thetas
        log(f"ARMA(1,1) noise, MA coefficient per record at the MAP: "
            f"{[round(t, 3) for t in thetas]}; MAP log-posterior {lp_map:.6g} nats")
    return th_map, lp_map, info


def heuristic_starts(sp, h0: dict) -> list[np.ndarray]:
    """The heuristic start (heuristic_values; a parameter it does not set at the middle of its
    prior box) and its deterministic variants along the directions in which wrong local optima
    were found on short BRFD records (v_s at its upper bound with an extreme sigma0 and a long
    take-up d3): a small Stribeck velocity, a short take-up, a stiffer or softer bristle. The
    first starts of find_map, and starts of the discrepancy screening's candidate fits.
    h0: heuristic_values of the space and its records."""

    def point(h):
        return clip_in(sp, sp.to_theta({n: h.get(n, float(np.exp(0.5 * (sp.lo[i] + sp.hi[i])))
                                                  if sp.log[i] else 0.5 * (sp.lo[i] + sp.hi[i]))
                                         for i, n in enumerate(sp.names)}))
    starts = [point(h0)]
    for change in ({"v_s": 0.1}, {"d3": 0.2}, {"sigma0": 10.0}, {"sigma0": 0.1},
                   {"v_s": 0.1, "d3": 0.2}):
        if all(n in sp.names for n in change):
            starts.append(point({**h0, **{n: h0[n] * f for n, f in change.items()}}))
    return starts


def _multi_start(logpost, scales, rng, n_random, n_prior, n_draws, log, n_global):
    """find_map's search (module docstring, steps 1-2): (best point, its log-posterior, info)."""
    sp = logpost.space
    coarse = coarsened(logpost)              # cheap: the local starts' least squares
    ranked = coarsened(logpost, simulate="kept")   # faithful: ranking and the global search
    h0 = heuristic_values(sp, logpost.records, scales)
    starts = heuristic_starts(sp, h0)
    th_h = starts[0]
    width = sp.hi - sp.lo
    for _ in range(n_random):
        starts.append(clip_in(sp, th_h + rng.normal(0, 0.08, sp.ndim) * width))
    draws = sp.sample_prior(n_draws, rng)
    lp = _log_prob_batched(coarse, draws)
    for k in np.argsort(-lp)[:n_prior]:
        starts.append(draws[k])
    results = []     # (log-posterior on `ranked`, theta, is a global start)
    for s in starts:     # raw least squares can lower the log-posterior: then the start is kept
        th, _ = least_squares_fit(coarse, s, max_nfev=100)
        lp_th, lp_s = ranked.log_prob(np.vstack([th, s]))
        results.append((float(lp_th), th, False) if lp_th >= lp_s else (float(lp_s), s, False))
    searches = _global_searches(ranked, th_h, rng, n_global)
    results += [(lp_g, th_g, True) for lp_g, th_g, _ in searches]
    generations = [gens for _, _, gens in searches]
    results.sort(key=lambda z: -z[0])
    ranked_lps = [z[0] for z in results]
    start_lps = []      # the refined starts' log-posteriors on the full records
    if ranked is not logpost:
        # refined on the full records: the two best local starts and the best global one (even
        # the ranking copies can rank them wrongly: on the BRFD twin's 53 N level the global start
        # ranked first on the coarse copies and ended 2,500 nats lower on the full records)
        chosen = [z for z in results if not z[2]][:2] + [z for z in results if z[2]][:1]
        # each start competes with its refinements: the first, raw least squares can lose
        # log-posterior on AR(1) noise (BRFD hidden takeup_overshoot campaign of seed 13, records
        # kept at 50 Hz or more: the best global start, -26,819.5 on the full records, refined to
        # -27,422.5 at best, and find_map returned that, 603 nats below its own start)
        start_lps = logpost.log_prob(np.array([z[1] for z in chosen]))
        fine = [(float(v), z[1], None) for v, z in zip(start_lps, chosen)]
        for _, th0, _ in chosen:
            th, r = least_squares_fit(logpost, th0, max_nfev=60)
            fine.append((float(logpost.log_prob(th[None, :])[0]), th, r))
            for _ in range(3):     # iteratively reweighted: AR(1)-whitened, per-record scales
                th, r = least_squares_fit(logpost, th, max_nfev=40, white=whitening(logpost, th))
                fine.append((float(logpost.log_prob(th[None, :])[0]), th, r))
        results = sorted(fine, key=lambda z: -z[0])
    best_lp, best = results[0][:2]
    log(f"least squares from {len(starts)} starts and {len(searches)} global searches (log-posteriors "
        f"in nats on the ranking copies, best first: "
        f"{[round(v, 1) for v in ranked_lps[:4]]}); refined best {best_lp:.6g} nats")
    return best, best_lp, {"start": "search", "starts_log_prob_ranked": ranked_lps,
                           "refined_starts_log_prob": [float(v) for v in start_lps],
                           "heuristic": h0, "global_generations": generations,
                           "global_points": [th_g for _, th_g, _ in searches]}


def polish(logpost: LogPosterior, theta: np.ndarray, lp: float,
           passes: int = 3, max_evals: int | None = None) -> tuple[np.ndarray, float]:
    """Powell's method on the full log-posterior from theta (log-posterior lp): the best point it
    evaluated (never below theta), and again from there while a pass gains more than 0.1 (at most
    `passes` passes). Why the best point evaluated and not Powell's answer: scipy's bounded Powell
    line search can end at a point worse than where it started, and the whole search then wanders
    off (scipy issue 22978). Seen on a BRFD campaign with a hidden takeup_overshoot (seed 13,
    records kept at 50 Hz or more, the plain 3-stage model's MAP search): Powell returned
    -28,965.1 from a start at -26,819.5 after visiting -26,750.3 (the old polish then kept the
    start: no gain). `max_evals`: a cap on the log-posterior evaluations of each pass (None:
    Powell's own stopping rules only)."""
    sp = logpost.space
    best = {"x": np.asarray(theta, float), "f": -lp}
    opts = {"maxiter": 4000, "xtol": 1e-8, "ftol": 1e-12}
    if max_evals is not None:
        opts["maxfev"] = int(max_evals)

    def nlp(x):
        v = logpost.log_prob(x[None, :])[0]
        f = -v if np.isfinite(v) else 1e300
        if f < best["f"]:
            best["x"], best["f"] = np.array(x, float), f
        return f
    for _ in range(passes):
        f0 = best["f"]
        minimize(nlp, best["x"], method="Powell", bounds=list(zip(sp.lo, sp.hi)), options=opts)
        if f0 - best["f"] <= 0.1:
            break
    return best["x"], (-float(best["f"]) if best["f"] < 1e300 else -np.inf)
