"""The sampler controller: a multi-start MAP search, a burn-in phase, then emcee run in chunks
until the chain passes the convergence criteria.

* MAP: frictionuq.infer.optimize (multi-start least squares with batched Jacobians, then a
  polish of the full log-posterior).
* Coordinates: the walkers move in the unbounded coordinates u = logit of the position in the
  prior box (Space.to_u, with the Jacobian in the density: likelihood.UnboundedPosterior). The
  posteriors of real records press against prior bounds (a take-up length d3 near 0, v_s at its
  upper bound, sigma2 at its lower one); in box coordinates about half of all proposals fell
  outside the box and were rejected, and the walkers piled up at the walls.
* Start: walkers around the MAP, each parameter's half-width below and above it from a
  one-dimensional profile (`start_profile`, the default: walkers.profile_sides; one batch of
  about 20 ndim evaluations), with the Gauss-Newton correlation (AR(1)-inflated, prior box as a
  weak regulariser), kept 0.1 % of the box away from its walls; with start_profile off,
  N(MAP, Sigma/4) with Sigma the Gauss-Newton covariance. BRFD twin 267 N: the burn-in settled
  after 3 rounds instead of 7-8 (d3, whose Gauss-Newton sd is 40 times too small on one side,
  no longer has to spread round by round).
* Burn-in (not stored, always discarded) and the moves of every phase: infer/burnin.py
  (rounds until the walkers have settled and the independence proposal stops changing;
  DE, DE gamma = 1 and snooker moves, plus the independence move from the second round).
* The stored run (`stored_run`): R-hat treats each walker as a chain, so it needs every
  walker's own chain to hold about a hundred effective draws whatever the walker count, and the
  stored run's cost is proportional to its walkers (with DE alone tau is 60-80 steps on a twin
  force level, R-hat still 1.014 after 12,000 steps; the independence move decorrelates a
  walker in a few steps wherever the posterior is close to the t).
  - "chains" (the default since 2026-12-01): `run_walkers` (16) of the burn-in's final
    positions, each moved on its own: the independence move (weight `independence_weight`,
    0.8) and a Gaussian random walk with the last burn-in round's covariance scaled by
    2.38^2 / D. No ensemble move, so the walkers are independent Markov chains, the setting
    R-hat was made for. The random walk is proposal.RandomWalkMove, a displacement per walker
    (emcee's GaussianMove with a covariance matrix moves every walker by one shared vector).
    With `temperatures` L > 1 each chain has L - 1 tempered copies (infer.tempering; opt-in).
    With `mode_search` (on by default since 2026-12-07) the independence move proposes from a
    mixture when the search finds a region: the burn-in's t
    and components on regions the burn-in visited that the t misses (infer.modes), weight
    `mode_weight` (0.1) in all; each component costs 5,000 posterior evaluations that refine
    it by importance sampling (infer.modes).
  - "ensemble": the burn-in's walkers with the independence move (the same weight) and the DE
    moves for the rest (70/10/20 as above).
  Measured (docs/log-calibration.md): BRFD twin 267 N, one shared burn-in, 16 chains met R-hat
  <= 1.01 after 2,000 stored steps (32,016 evaluations) against 2,500 steps (80,032) for the
  ensemble; whole fits (`benchmarks/bench_fit.py --sampler both`) twin 267 N 2.1-2.5 times
  fewer evaluations, real arts-d1 35 lb 1.74 times, the same posteriors within Monte Carlo
  error. At the real 70 lb level (heavy d3 and fs_fwd tails, the slowest to mix) the chains
  were worse on the code of 2026-11-28 (R-hat 1.259 against 1.176 after 6,000 stored steps) and
  are better on the code of 2026-12-01 (R-hat 1.045 against 1.088 after 6,000 steps, in 187 s
  against 180 s), which made them the default.
* Stopping: every `chunk` steps of the stored run, on its part after the first
  `discard_fraction` (the burn-in phase is already discarded): the integrated autocorrelation
  time tau of every parameter (emcee.autocorr) and ArviZ's rank-normalised R-hat and bulk/tail
  ESS (walkers as chains) on the draws the fit reports (thinned, as parameter values: check).
  The rule holds when the kept chain is longer than `tau_factor` x max tau, max tau has not
  grown by `tau_rtol` or more since the previous check (a fall passes: convergence.rule_met),
  and every parameter has R-hat <= `r_hat_max`
  and ESS >= `ess_min`. The run stops when it has held at `confirm_checks` (2) checks in a row,
  or at `max_steps` (then the fit is reported as not converged). The confirming check (since
  2026-12-05): chains that start near the MAP and have not yet reached a slow direction's tail
  show a short tau and no disagreement, and nothing in one window tells. The real dataset-2
  fit of item 9 met the rule at 3,000 steps (tau 15, R-hat 1.008) and failed it at 3,500 (ESS
  155, R-hat 1.024); its chain at 12,000 steps has tau 95 and d3's 97.5 % quantile 11.8 mm
  instead of 2.9 (docs/log-calibration.md). One check more cannot rule such a stop out, only
  make it less likely; it costs a converging fit one `chunk` of steps or more.
* The MAP's check (`n_map_restarts`, default 1; infer.restart): at every chunk of the stored run,
  a cold chain's state more than 3 nats above the MAP proves that the multi-start search missed
  a higher region, which the burn-in (started at the MAP) never entered. The MAP is polished from
  that state, the stored steps are discarded (counted with the burn-in phase), and the burn-in
  runs again from the new MAP, its mode search given every state kept since the fit began (the
  first burn-in's and the discarded chains'), so that the regions they covered get proposal
  components. As a region's typical states lie below its peak, the highest new state that the
  stored run's proposal underweights is also polished (at most 10 times a run), and a polish
  that ends 3 nats above the MAP restarts the same way. Real arts-d1 80 lb level (2026-12-07,
  stops 85 and 86): every seed's search had missed a region holding about 88 % of the mass;
  R-hat grew to 1.833 in 100,000 steps; with the check, seed 2 restarted after 1,500 steps and
  converged after 5,500 (355 s), its chains 82-93 % in that region; seed 1's chains entered it
  only from step 7,500 on, 2 nats below the MAP, and the polish restarted from there.
* The stored run's mode search (`n_stored_searches`, default 2, with the mode search;
  infer.stuck): at every chunk, when the cold chains' kept states of the chunk hold 50 or more
  where the stored run's proposal underweights the posterior by e^3 beyond its bulk (a chain
  stuck there 250 steps), the search of infer.modes runs over the stored run's states; if it
  adds a component, the stored steps are discarded (counted with the burn-in phase) and the
  stored run starts again from the chains' positions with the new mixture. Real arts-d1
  (2026-12-08, stop 88): chains of the 25, 35 and 80 lb levels sat for hundreds to thousands
  of steps in regions the burn-in never visited (80 lb, seed 3: the corner where k2 sits at
  its lower bound, 7,000 steps, R-hat 1.110 at the cap).
* Storage (storage.py): emcee's HDF5 backend (in u coordinates), written every step: an
  interrupted run resumes from its last step (random state included) with `resume=True`, and
  replays the stored chain's checks first (convergence.replay), so that it checks on the same
  steps and stops where the uninterrupted run would.
* Reproducibility: emcee copies NumPy's global random state at construction, so the sampler's
  own state is seeded explicitly from `seed`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import emcee
import numpy as np

from ..interrupts import Interrupts, interrupts
from .burnin import burn_in, independent, moves_for
from .convergence import autocorr_time, thinning
from .likelihood import LogPosterior, UnboundedPosterior
from .localfit import gauss_newton_cov
from .optimize import find_map, polish
from .proposal import Proposal
from .restart import MapCheck, burn_in_map, carried, load_map, load_polishes, store_map
from .stuck import StuckCheck, load_searches, store_searches
from .storedrun import cold_walkers, run_chunks
from .tempering import default_ratio, ladder, tempered_moves
from .storage import load_account, load_proposal, open_backend, store_account, store_proposal
from .priors import RecordScales
from .samplerconfig import STORED_RUNS, SamplerConfig  # noqa: F401 (the package's import path)
from .walkers import initial_ball, profile_sides


@dataclass
class SampleResult:
    chain: np.ndarray            # (draws, walkers, ndim) after burn-in and thinning, box coordinates
    log_prob: np.ndarray         # (draws, walkers) log-posterior in box coordinates
    blobs: np.ndarray            # (draws, walkers, n_records) per-record log-likelihood
    tau: np.ndarray              # (ndim,) integrated autocorrelation time, steps
    n_steps: int                 # stored steps (after the burn-in phase)
    burn: int                    # stored steps discarded
    thin: int
    acceptance: float
    converged_tau: bool
    theta_map: np.ndarray
    log_prob_map: float
    n_evals: int
    seconds: float
    burn_in_steps: int = 0       # steps of the (unstored) burn-in phase
    history: list = field(default_factory=list)
    map_start: str = "search"    # "search" (find_map's multi-start) or "given" (polished from a start)
    resumed_from: list = field(default_factory=list)   # stored step each resumed session began at
    earlier_seconds: float = 0.0  # sampler seconds of the sessions before a resumed one
    # (draws, walkers, n_records, N_STATS): each record's residual sufficient statistics at
    # every kept draw (emcee blobs; outputs draws the noise parameters from them)
    noise_stats: np.ndarray | None = None
    mode_components: int = 0     # components the mode search added to the independence move
    map_restarts: int = 0        # burn-in restarts from a higher MAP the chains found (infer.restart)
    stored_searches: int = 0     # stored runs started again with new components (infer.stuck)


def _nwalkers(cfg: SamplerConfig, ndim: int) -> int:
    w = cfg.nwalkers or max(32, 2 * ndim + 4)
    if w <= 2 * ndim:
        raise ValueError(f"differential evolution needs more than 2 x ndim = {2 * ndim} walkers, got {w}")
    return int(w + (w % 2))


def sample(logpost: LogPosterior, scales: RecordScales, seed: int,
           backend_path: str | Path | None = None,
           cfg: SamplerConfig | None = None, resume: bool = True, log=None,
           start: np.ndarray | None = None, run_key: str | None = None) -> SampleResult:
    """Run the full sampler; see the module docstring. `start`: a MAP estimate found elsewhere on
    the same log-posterior (theta): the multi-start search is skipped, the polish runs from it.
    `run_key`: what a stored chain must have been made by to be resumed (storage.open_backend).
    Ctrl-C stops it between two steps (frictionuq.interrupts), every finished step stored."""
    with interrupts() as intr:
        return _sample(logpost, scales, seed, backend_path, cfg, resume, log, start, run_key, intr)


def _sample(logpost, scales, seed, backend_path, cfg, resume, log, start, run_key, intr):
    cfg = cfg or SamplerConfig()
    log = log or (lambda msg: None)
    sp = logpost.space
    ndim = sp.ndim
    nw = _nwalkers(cfg, ndim)
    # the stored run's walkers: the burn-in's ensemble, or run_walkers independent chains
    nrun = cfg.run_walkers * cfg.temperatures if independent(cfg) else nw
    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    target = UnboundedPosterior(logpost, stats=True)
    backend, resumed = open_backend(backend_path, nrun, ndim, resume, log, key=run_key)

    theta_map, lp_map, map_info = find_map(logpost, scales, rng, cfg.n_random_starts,
                                           cfg.n_prior_starts, log=log, n_global=cfg.n_global_starts,
                                           start=start)
    restarts = 0
    stored_map = load_map(backend) if resumed else None
    if stored_map is not None:   # polished after the burn-in, or a restart (infer.restart)
        theta_map, lp_map, restarts = stored_map
        log(f"MAP kept with the stored chain (restarts before it: {restarts}; infer.restart)")
    log(f"MAP log-posterior {lp_map:.6g} nats")
    # from here on a Ctrl-C is only noted and raised at the next step or chunk (run_steps): one
    # raised between chunks could land in a finaliser, where Python prints it and goes on
    intr.defer = True
    account = load_account(backend) if resumed else {"burn_in_steps": 0, "evaluations": 0,
                                                     "seconds": 0.0, "resumed_from": []}
    if resumed:
        account["resumed_from"].append(int(resumed))
        log(f"resuming from stored step {resumed}")
    # the states kept since the fit began (every fifth step): a restart's mode search reads them
    memory = [] if cfg.independence and cfg.n_map_restarts > 0 else None
    searches = load_searches(backend) if resumed else 0
    carry = None     # (positions, proposal) of a stored run started again (infer.stuck)
    while True:
        state = proposal = None
        if carry is not None:
            (state, proposal), carry = carry, None
        elif not resumed:
            state, proposal, steps = _burn_in(logpost, target, theta_map, lp_map, cfg, seed, rng,
                                              log, intr, nw, nrun, memory, restarts > 0)
            account["burn_in_steps"] += steps
            if memory:       # its walkers rose above the MAP: the stored run checks against theirs
                theta_map, lp_up, moved = burn_in_map(logpost, memory[-1], theta_map, lp_map)
                if moved:
                    log(f"the burn-in's last round rose more than 3 nats above the MAP: MAP "
                        f"polished from its highest state, {lp_map:.6g} -> {lp_up:.6g} nats")
                    lp_map = lp_up
                    store_map(backend, theta_map, lp_map, restarts)
        if resumed:      # the stored run's proposal is kept in the backend's attributes
            proposal = load_proposal(backend)
        else:
            store_proposal(backend, proposal)
        sampler, moves = _stored_sampler(target, backend, proposal, cfg, seed, nrun, ndim, resumed,
                                         log, searches)
        history = []
        before = dict(account)
        if backend is not None:
            backend.keep_open()
        map_check = None
        if restarts < cfg.n_map_restarts:
            map_check = MapCheck(logpost, lp_map, proposal.move().logq if cfg.independence else None,
                                 load_polishes(backend) if resumed else 0, backend, log)
        stuck_check = None
        if cfg.searches_modes and searches < cfg.n_stored_searches:
            stuck_check = StuckCheck(proposal, target, cfg.mode_weight, searches,
                                     cfg.n_stored_searches, seed, sp.names, log, intr)
        try:
            n_done, converged, found = run_chunks(sampler, state, cfg, sp, resumed, history, log, intr,
                                            moves, map_check, stuck_check)
        finally:
            if backend is not None:
                backend.close()
            # written even when interrupted, so that the next session adds to it
            from .. import __version__
            store_account(backend, {**before, "evaluations": before["evaluations"] + logpost.n_evals,
                                    "seconds": before["seconds"] + time.perf_counter() - t0},
                          __version__, seed)
        if found is None:
            break
        if memory is not None:
            memory.append(carried(sampler, cold_walkers(cfg, nrun)))
        account["burn_in_steps"] += n_done
        if isinstance(found, Proposal):
            # chains stuck where the proposal underweights: the stored run again, with the new
            # components, from the chains' positions (infer.stuck)
            searches += 1
            log(f"step {n_done}: {len(found.modes) - len(proposal.modes)} proposal component(s) "
                f"added (stored-run mode search {searches} of {cfg.n_stored_searches}; "
                f"infer.stuck); the {n_done} stored steps are discarded (counted with the "
                f"burn-in phase) and the stored run starts again from its chains' positions")
            carry = (np.array(sampler.get_last_sample().coords), found)
            backend, resumed = open_backend(backend_path, nrun, ndim, False, log, key=run_key)
            store_map(backend, theta_map, lp_map, restarts)
            store_searches(backend, searches)
            continue
        # a point above the MAP: the burn-in again from there (infer.restart)
        theta_best, lp_best, how = found
        theta_new, lp_new = polish(logpost, theta_best, lp_best)
        restarts += 1
        log(f"restart {restarts}: {how} log-posterior {lp_best:.6g} nats, "
            f"{lp_best - lp_map:.1f} above the MAP: the multi-start search missed a higher region "
            f"that the burn-in never entered. MAP now {lp_new:.6g} nats (polished from there); the "
            f"{n_done} stored steps are discarded (counted with the burn-in phase) and the burn-in "
            f"starts again at the new MAP, its mode search given every state kept so far")
        theta_map, lp_map = theta_new, lp_new
        backend, resumed = open_backend(backend_path, nrun, ndim, False, log, key=run_key)
        store_map(backend, theta_map, lp_map, restarts)
        store_searches(backend, searches)
    intr.check()              # one noted after the last chunk: the chain is stored, resumable
    res = _result(sampler, cfg, sp, n_done, converged, theta_map, lp_map, logpost, t0,
                  account["burn_in_steps"], history, map_info["start"])
    res.n_evals += before["evaluations"]
    res.seconds += before["seconds"]
    res.earlier_seconds = before["seconds"]
    res.resumed_from = list(account["resumed_from"])
    res.mode_components = len(proposal.modes) if proposal is not None else 0
    res.map_restarts = restarts
    res.stored_searches = searches
    return res


def _burn_in(logpost, target, theta_map, lp_map, cfg, seed, rng, log, intr, nw, nrun, memory,
             restarted):
    """The start ball around the MAP and the burn-in phase (infer.burnin): (the stored run's
    positions, its proposal, burn-in steps). After a restart the mode search runs over `memory`
    (every state kept since the fit began) whatever cfg.mode_search says."""
    sp = logpost.space
    cov = gauss_newton_cov(logpost, theta_map)
    sides = (profile_sides(logpost.log_prob, theta_map, lp_map, cov, sp)
             if cfg.start_profile else None)
    if sides is not None:
        log("start ball from profiles: half-widths (Gauss-Newton sds) below / above the MAP "
            + ", ".join(f"{n} {lo:g}/{hi:g}" for n, (lo, hi) in zip(sp.names, sides)))
    state = sp.to_u(initial_ball(theta_map, cov, nw, rng, sp, sides))
    state, proposal, steps = burn_in(target, state, cfg, seed, rng, log, intr=intr,
                                     n_out=nrun if nrun != nw else None, names=sp.names,
                                     memory=memory, search=True if restarted else None)
    return state[:nrun], proposal, steps


def _stored_sampler(target, backend, proposal, cfg, seed, nrun, ndim, resumed, log, searches=0):
    """The stored run's emcee sampler on `backend` and its moves (with tempering, wrapped); its
    random state seeded by `seed` (and, after stored-run searches, their count: infer.stuck)."""
    moves = moves_for(cfg, proposal, stored=True)
    if cfg.temperatures > 1:
        betas = ladder(cfg.temperatures, cfg.temper_ratio or default_ratio(ndim))
        log("tempered chains: inverse temperatures " + ", ".join(f"{b:.3g}" for b in betas))
        moves = tempered_moves(moves, betas, cfg.run_walkers, len(target.logpost.records))
    sampler = emcee.EnsembleSampler(nrun, ndim, target, vectorize=True, moves=moves,
                                    backend=backend)
    if not resumed:
        key = seed % (2**32) if not searches else [seed % (2**32), searches]
        sampler.random_state = np.random.RandomState(key).get_state()
    return sampler, moves


def _result(sampler, cfg, sp, n_done, converged, theta_map, lp_map, logpost, t0, burn_in_steps,
            history, map_start: str = "search") -> SampleResult:
    ndim = sp.ndim
    cold = cold_walkers(cfg, sampler.nwalkers)
    burn = int(n_done * cfg.discard_fraction)
    tau = autocorr_time(sampler.get_chain(discard=burn)[:, cold])
    thin = thinning(cfg, tau)
    u = sampler.get_chain(discard=burn, thin=thin)[:, cold]
    theta = sp.from_u(u)
    lp_u = sampler.get_log_prob(discard=burn, thin=thin)[:, cold]
    lp_theta = lp_u - sp.log_jac_u(u.reshape(-1, ndim)).reshape(lp_u.shape)
    blobs = sampler.get_blobs(discard=burn, thin=thin)[:, cold]
    R = len(logpost.records)
    return SampleResult(
        chain=theta, log_prob=lp_theta, blobs=blobs[..., :R],
        noise_stats=blobs[..., R:].reshape(blobs.shape[:2] + (R, logpost.n_stats)),
        tau=np.asarray(tau, float), n_steps=n_done, burn=burn, thin=thin,
        acceptance=float(np.mean(sampler.acceptance_fraction[cold])), converged_tau=converged,
        theta_map=theta_map, log_prob_map=lp_map, n_evals=int(logpost.n_evals),
        seconds=time.perf_counter() - t0, burn_in_steps=burn_in_steps, history=history,
        map_start=map_start)
