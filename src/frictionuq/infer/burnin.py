"""The burn-in phase and the moves of every phase of the sampler (infer.sampler runs them).

* Burn-in (not stored, always discarded): at least `burn_rounds` rounds of `burn_steps` steps,
  more (up to `burn_max_rounds`) while the median walker's log-posterior still rises by more
  than sqrt(D/2) per round, walkers are stuck, or the ensemble is still spreading: the proposal
  fitted to the round (below) has a parameter width (half its 15.9-84.1 % range) more than
  `burn_stable` times (or less than 1 / `burn_stable` times) the previous round's, or a median
  moved by more than `burn_shift` widths (function burn_in; the BRFD twin's 267 N level needed
  five rounds of 500 steps, and with the old two its independence move was accepted 0.9 % of the
  time and tau was 149 steps). Rounds of 250 steps rather than 500: the proposal, inflated by
  1.25x, is refitted twice as often, so a start ball too narrow widens in fewer steps (twin 267 N:
  seven rounds, 1,750 steps, against five rounds, 2,500 steps; 109 s against 140 s in all). After each round
  the walkers are re-initialised by drawing states from the second half of that round, pooled
  over the walkers that are not stuck (a walker whose mean log-posterior lies more than
  max(10, 3 sqrt(D/2)) below the median walker's is stuck). The Gauss-Newton ball is far too
  narrow for the weakly identified parameters and the MAP need not be the mode; the pooled
  re-initialisation spreads the ensemble over the posterior and drops stuck walkers (a standard
  emcee practice; it only affects the discarded burn-in).
* Moves of the burn-in: differential evolution (70 %), DE with gamma = 1 (10 %: the
  "mode-jumping" step of ter Braak 2006) and DE snooker (20 %) (ter Braak & Vrugt 2008; emcee
  docs) in the first round. From the second round on, half of the steps are an independence
  Metropolis-Hastings move (proposal.IndependenceMove: a multivariate t, 5 degrees of freedom,
  on Johnson SU-Gaussianised marginals, fitted to the previous burn-in round with its covariance
  inflated by 1.25^2; the last round's proposal is fixed for the whole stored run and kept in
  the HDF5 file) and the rest DE (35 %), DE gamma = 1 (5 %) and snooker (10 %). DE needs more
  than 2 x ndim walkers; the burn-in has max(32, 2 ndim + 4).
* Mode search (cfg.mode_search; on by default since 2026-12-07, stop 87, wherever the
  independence move runs: SamplerConfig.searches_modes; infer.modes): every fifth step of
  every round is kept, and after the last round the states where the posterior outweighs the
  last proposal by more than e^3 beyond the round's own top per cent get proposal components of
  their own, each refined by importance sampling (modes.refine). After a restart
  (infer.restart) the search runs whatever cfg.mode_search says, over every state kept since
  the fit began: the first burn-in's, the discarded stored run's and the new rounds'
  (`memory`).
* The stored run's moves (moves_for(..., stored=True)): with stored_run "chains" the
  independence move and a random walk per walker (proposal.RandomWalkMove), each walker a
  Markov chain of its own; with "ensemble" the independence move beside the DE moves above.

`cfg` is an infer.sampler.SamplerConfig (only its fields are read here).
"""
from __future__ import annotations

import os
import sys

import emcee
import numpy as np

from ..interrupts import Interrupts
from . import modes
from .proposal import Proposal, proposal_change
from .walkers import pooled_states, reinitialise


def progress_bar(cfg) -> bool:
    """Whether emcee shows its progress bar: the config's setting, else on a terminal."""
    if cfg.progress is not None:
        return cfg.progress
    return sys.stderr.isatty() and os.environ.get("FRICTIONUQ_PROGRESS", "1") != "0"


def fit_proposal(chain: np.ndarray, log_prob: np.ndarray) -> Proposal:
    """The independence proposal fitted to a burn-in round's `pooled_states`."""
    return Proposal.fit(pooled_states(chain, log_prob)[0])


def independent(cfg) -> bool:
    """Whether the stored run moves each walker on its own (module docstring)."""
    return cfg.stored_run == "chains" and cfg.independence


def moves_for(cfg, proposal=None, stored: bool = False):
    """The burn-in rounds' moves (stored=False) or the stored run's."""
    de = emcee.moves.DEMove() if cfg.de_gamma is None else emcee.moves.DEMove(gamma0=cfg.de_gamma)
    if proposal is None or not cfg.independence:
        return [(de, 0.7), (emcee.moves.DEMove(gamma0=1.0), 0.1), (emcee.moves.DESnookerMove(), 0.2)]
    w = cfg.independence_weight if stored else 0.5
    if stored and independent(cfg):
        moves = [(proposal.move(), w), (proposal.random_walk(), 1.0 - w)]
        return [m for m in moves if m[1] > 0]
    rest = 1.0 - w
    moves = [(proposal.move(), w), (de, 0.7 * rest),
             (emcee.moves.DEMove(gamma0=1.0), 0.1 * rest), (emcee.moves.DESnookerMove(), 0.2 * rest)]
    return [m for m in moves if m[1] > 0]


def burn_in(target, state: np.ndarray, cfg, seed: int, rng, log=None,
            n_out: int | None = None, intr: Interrupts | None = None, names=None,
            memory: list | None = None, search: bool | None = None):
    """The burn-in phase (module docstring) from walker positions `state` (walkers, ndim) of
    the vectorized emcee target. Rounds of cfg.burn_steps steps, at least cfg.burn_rounds, more
    (up to cfg.burn_max_rounds) while the walkers still climb, some are stuck, or the proposal
    fitted to the round still differs from the previous round's (proposal_change above
    cfg.burn_stable or cfg.burn_shift): a Gauss-Newton start ball can be far narrower than the
    posterior along a parameter (BRFD twin 267 N: d3 at 0.009 of its posterior sd), and a
    proposal fitted before the ensemble has spread is rejected almost always (measured: 0.9 %
    acceptance, tau 149 steps, against 20 % and tau 36 with this rule).
    Returns (positions, proposal.Proposal, steps run); `n_out` positions (default: as many as
    walkers), drawn like the next round's. With cfg.mode_search the proposal gets the
    components infer.modes finds among the rounds' states (`names`: the coordinates', for the
    log), each refined with draws of its own (modes.refine: posterior evaluations, no steps).
    `memory`: a list of (states, log-posteriors) pairs of the same target, to which each round's
    kept states are appended (the caller keeps them: infer.restart) and over which the search
    runs, earlier runs' included; `search`: run the mode search (None: cfg.searches_modes; it needs
    the independence move)."""
    log = log or (lambda msg: None)
    nw, ndim = state.shape
    n_draw = max(nw, n_out or nw)
    proposal, prev, steps = None, -np.inf, 0
    search = cfg.searches_modes if search is None else cfg.independence and search
    keeping = search or memory is not None
    memory = [] if memory is None else memory    # (states, log-posteriors) kept, for the search
    for rnd in range(max(cfg.burn_rounds, cfg.burn_max_rounds)):
        bs = _round(target, state[:nw], cfg, proposal, [seed % (2**32), rnd], intr)
        lpc = bs.get_log_prob()
        if keeping:
            memory.append(modes.keep(bs.get_chain(), lpc))
        new = fit_proposal(bs.get_chain(), lpc)
        ratio, shift = proposal_change(proposal.spread if proposal else None, new.spread)
        proposal = new
        state, stuck = reinitialise(bs.get_chain(), lpc, n_draw, rng)
        steps += cfg.burn_steps
        level = float(np.median(lpc[cfg.burn_steps // 2:]))
        log(f"burn-in round {rnd + 1}: acceptance {np.mean(bs.acceptance_fraction):.2f}, "
            f"median log-posterior {level:.6g} nats in the sampler's unbounded coordinates "
            f"(best {np.max(lpc):.6g}), "
            f"{stuck} stuck walkers dropped, "
            + (f"proposal width ratio {ratio:.2f}, median shift {shift:.2f} widths"
               if np.isfinite(ratio) else "first proposal fitted (no earlier one to compare)"))
        # still climbing (the median walker gained more than the posterior's own spread of the
        # log density, sqrt(D/2)), walkers stuck, or the ensemble still spreading: another round
        settled = stuck == 0 and level - prev < np.sqrt(ndim / 2.0) and \
            ratio <= cfg.burn_stable and shift <= cfg.burn_shift
        prev = level
        if rnd + 1 >= cfg.burn_rounds and settled:
            break
    if search:
        density = modes.log_density(target, intr)
        half = bs.get_chain()[cfg.burn_steps // 2:]
        proposal = modes.find_modes(proposal, np.concatenate([m[0] for m in memory]),
                                    np.concatenate([m[1] for m in memory]),
                                    half.reshape(-1, ndim), lpc[cfg.burn_steps // 2:].reshape(-1),
                                    cfg.mode_weight, names, log, density=density, seed=seed)
    return state, proposal, steps


def _round(target, state, cfg, proposal, key, intr=None):
    """One round of cfg.burn_steps steps from `state` with the moves of `proposal` (None: the
    first round's), its random state seeded by `key`."""
    nw, ndim = state.shape
    bs = emcee.EnsembleSampler(nw, ndim, target, vectorize=True, moves=moves_for(cfg, proposal))
    bs.random_state = np.random.RandomState(key).get_state()
    run_steps(bs, state, cfg.burn_steps, progress=progress_bar(cfg), intr=intr)
    return bs


def run_steps(sampler, state, n: int, progress=False, intr: Interrupts | None = None):
    """sampler.run_mcmc(state, n) (state None: from the last stored step); with `intr`, a Ctrl-C
    stops it between two steps (KeyboardInterrupt), every finished step in the backend."""
    if state is None:
        state = sampler.get_last_sample()
    intr = intr or Interrupts()
    intr.check()
    before, intr.defer = intr.defer, True
    try:
        for state in sampler.sample(state, iterations=n, progress=progress,
                                    skip_initial_state_check=True):
            if intr.hit:
                break
    finally:
        intr.defer = before
    intr.check()
    return state
