"""The burn-in's mode search (SamplerConfig.mode_search): regions the posterior holds that the
independence proposal misses, found among the states the burn-in visited, and given proposal
components of their own (proposal.MixtureMove) for the stored run.

Why: the stored run moves each chain mostly by the independence move, whose t is fitted to the
last burn-in round. A region of the posterior that round did not cover, where p(x) / q(x) is
e^k times its value in the bulk, is entered rarely and left only by proposals accepted about
e^-k of the time; a chain that gets there stays, and R-hat sees it. Measured on the real
dataset-2 fit of item 9 (docs/log-calibration.md, 2026-12-06, evening): d3's second mode near
13 mm (4-6 % of the mass) had log importance weights +6 at its median against +1.5 at the bulk's
95 % point; one chain spent 63 % of 4,600 steps there and R-hat stayed at 1.10-1.13. With a
proposal component on that mode (fitted to an earlier run's states) the fit converged after
3,500 steps.

How: every `MEMORY_STRIDE`-th step of every burn-in round is kept (the burn-in starts at the
MAP, so its first rounds pass through regions the later ones leave). After the last round, the
log importance weight lw = log p(x) - log q(x) under its proposal is computed for the kept states
(the log-posteriors are the ones the burn-in computed; no new evaluation; the exploration below
costs EXPLORE_ROUNDS burn-in rounds per component found). The reference is the
last round's second half, the states the proposal was fitted to. A kept state is flagged when
  * lw exceeds the reference's 99 % point by more than `MARGIN` nats (e^3: a proposal back from
    there is accepted at most about 5 % as often as from the bulk's top per cent), and
  * its log-posterior is no more than `max(10, 3 sqrt(D/2))` below the reference's median (the
    burn-in's own threshold for a stuck walker: a transient state of a walker still climbing
    from its start is not a region of the posterior).
With at least `MIN_STATES` distinct flagged states (and 2 D + 2), a t is fitted to them, after
exploring their region (Shape, below), and added as a component; the flagged states are then
weighed again under the mixture, and a further component is fitted to those still flagged, up
to `MAX_MODES`. The components share the weight `mode_weight` (SamplerConfig; 0.1, the weight
that made the dataset-2 fit converge).

Shape: the flagged states are where the walkers passed, not draws of the region they mark (on
dataset 2, the start ball around the MAP, whose d3 width was a fifth of the second mode's:
compared with a t fitted to another run's states there). So the region is explored first
(burnin.explore): an ensemble started at distinct flagged states runs EXPLORE_ROUNDS rounds of
the burn-in's length with the first round's moves (differential evolution only), each round
after the first started at distinct states of the previous round's second half that are still
flagged (walkers that left the region for the main mode are dropped, as the burn-in drops stuck
walkers), and the component is `Proposal.fit` (the main t's construction) to the flagged states
of the rounds' second halves. When fewer than MIN_STATES (and 2 D + 2) remain, the component
falls back to the flagged states themselves (`component`: each coordinate's width raised to at
least half the main t's, WIDEN, their correlations kept). A refit of the components on a
further burn-in round run with the mixture was tried and not kept (docs/log-calibration.md,
2026-12-06, night).

Exactness: the mixture is fixed before the stored run and its density is exact (MixtureMove), so
the stored run's target is the posterior whatever the components are; a poor component only
costs rejected proposals (with weight 0.1 at most a tenth of the independence move's). On a
posterior that the t already covers no state is flagged and the stored run is the same, step for
step, as without the search (tested).

Limitations: the search sees only what the burn-in visited; a mode it never entered stays
unseen (tempering, infer.tempering, is the tool that explores). Flagged states from two separate
regions make one broad component first; the next round of the search then fits what it missed.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .proposal import Proposal

#: every this many steps of a burn-in round is kept for the search
MEMORY_STRIDE = 5
#: nats above the reference's 99 % point of the log importance weight
MARGIN = 3.0
#: distinct flagged states needed for a component (at least, and 2 D + 2)
MIN_STATES = 50
#: components at most
MAX_MODES = 3
#: a component's width in each coordinate at least this fraction of the main t's
WIDEN = 0.5
#: the exploring ensemble runs this many burn-in rounds' worth of steps (burnin.explore)
EXPLORE_ROUNDS = 2


def keep(chain: np.ndarray, log_prob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A burn-in round's kept states: every MEMORY_STRIDE-th step, flattened ((n, D), (n,))."""
    c, lp = chain[::MEMORY_STRIDE], log_prob[::MEMORY_STRIDE]
    return c.reshape(-1, c.shape[-1]), lp.reshape(-1)


def flagged(states, log_prob, ref_states, ref_log_prob, logq) -> np.ndarray:
    """Mask of the states where the posterior outweighs the proposal (module docstring); `logq`:
    the proposal's log density (any constant)."""
    ref_lw = ref_log_prob - logq(ref_states)
    lw = log_prob - logq(states)
    d = states.shape[1]
    floor = np.median(ref_log_prob) - max(10.0, 3.0 * np.sqrt(d / 2.0))
    return np.isfinite(lw) & (lw > np.percentile(ref_lw, 99) + MARGIN) & (log_prob >= floor)


def find_modes(proposal: Proposal, states, log_prob, ref_states, ref_log_prob,
               weight: float, names=None, log=None, explore=None) -> Proposal:
    """`proposal` with the components the search finds (module docstring), or unchanged.
    `states`, `log_prob`: the burn-in's kept states; `ref_*`: the last round's second half.
    `explore(pool, k, inside)`: draws of the region the flagged `pool` marks ((n, D) states and
    their log-posteriors; burnin.explore, an ensemble run started there; `inside(states,
    log_prob)` the mask of the flagged ones), or None: the component is then fitted to the pool
    itself (`component`)."""
    log = log or (lambda msg: None)
    states, log_prob = np.asarray(states, float), np.asarray(log_prob, float)
    d = states.shape[1]
    current = proposal
    for _ in range(MAX_MODES):
        mask = flagged(states, log_prob, ref_states, ref_log_prob, current.move().logq)
        pool = np.unique(states[mask], axis=0)
        if len(pool) < max(MIN_STATES, 2 * d + 2):
            if current is proposal:
                log(f"mode search: {len(pool)} distinct burn-in states where the posterior "
                    f"outweighs the proposal by more than e^{MARGIN:g} (a component needs "
                    f"{max(MIN_STATES, 2 * d + 2)}): none added")
            break
        k = len(current.modes) + 1
        comp, how = None, f"fitted to {len(pool)} distinct burn-in states"
        if explore is not None:
            def inside(xs, xl, logq=current.move().logq):
                return flagged(xs, xl, ref_states, ref_log_prob, logq)
            xs, xl = explore(pool, k, inside)
            region = np.unique(xs[inside(xs, xl)], axis=0)
            if len(region) >= max(MIN_STATES, 2 * d + 2):
                comp = Proposal.fit(region)
                how = (f"fitted to {len(region)} distinct states of {len(xs)} drawn by an "
                       f"ensemble started at {len(pool)} flagged burn-in states")
            else:
                how += (f" (the ensemble started there kept only {len(region)} distinct states "
                        f"in the region)")
        comp = comp if comp is not None else component(pool, proposal)
        current = _with_modes(proposal, (*current.modes, comp), weight)
        log(f"mode search: component {k} {how} ({mask.mean():.1%} of the {len(states)} kept "
            f"flagged: the posterior outweighs the proposal by more than e^{MARGIN:g}); "
            + _where(proposal, comp, names))
    return current


def component(pool: np.ndarray, main: Proposal) -> Proposal:
    """The t of a component: the flagged states' mean and correlations, each coordinate's width
    their sd or half the main t's, whichever is larger (WIDEN). The flagged states are where the
    walkers passed (on dataset 2, the start ball around the MAP), narrower than the region they
    mark: d3's width among them was a fifth of the second mode's."""
    sd = pool.std(axis=0)
    main_sd = np.sqrt(np.diag(main.x_cov)) if main.x_cov is not None else main.x_width
    s = np.maximum(sd, WIDEN * main_sd)
    r = np.corrcoef(pool.T) if np.all(sd > 0) else np.eye(pool.shape[1])
    return Proposal.gaussian(pool.mean(axis=0), r * np.outer(s, s))


def _with_modes(p: Proposal, modes, weight: float) -> Proposal:
    return replace(p, modes=tuple(modes), mode_weight=float(weight))


def _where(main: Proposal, comp: Proposal, names=None) -> str:
    """The coordinates where the component's centre lies farthest from the main one's, in the
    main one's widths (the sampler's unbounded coordinates)."""
    shift = (comp.x_centre - main.x_centre) / np.where(main.x_width > 0, main.x_width, 1.0)
    order = np.argsort(-np.abs(shift))[:3]
    names = names or [f"x{i}" for i in range(shift.size)]
    return "centre off the main one's by " + ", ".join(
        f"{names[i]} {shift[i]:+.1f}" for i in order) + " widths (unbounded coordinates)"
