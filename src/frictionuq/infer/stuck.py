"""The stored run's mode search (SamplerConfig.n_stored_searches; infer.sampler runs it): when
stored chains stick where their independence proposal underweights the posterior, the proposal
gets components there (infer.modes) and the stored run starts again from the chains' positions.

Why: the burn-in's mode search sees only the regions the burn-in visited. A chain of the stored
run that enters a region the proposal underweights by e^k is left only by proposals accepted
about e^-k times as often as from the bulk, and its random walk, scaled to the bulk, fails in a
region of another shape: the chain stays for thousands of steps and R-hat sees it. Measured on
the real arts-d1 records (docs/log-calibration.md, 2026-12-08, stop 88), reading the stored
chains of stop 87 under their own proposals:
  * 80 lb, seed 3: chain 2 entered the corner where k2 sits at its lower bound at step 3,000 and
    left it at 10,000; its log importance weights there were 3-7 nats above the bulk's robust
    99 % point, its states changed 3-20 times per 500 steps, and R-hat ended at 1.110;
  * 25 lb: chains 2, 1 and 12 in turn spent 300-400 steps each in such regions (steps 0-500,
    4,000-5,000, 7,000-8,000); 35 lb: chains 12, 5 and 0 (R-hat 1.026 at the cap for both);
  * the fits that converged (22 lb; 80 lb at seeds 1 and 4; dataset 2 at seeds 3 and 4) had no
    chunk with STUCK_STATES flagged states, except 80 lb seed 1's at step 8,500.

What: at every check of the stored run, the new chunk's kept states (every MEMORY_STRIDE-th step
of the cold chains) are weighed under the stored run's proposal against every kept stored
state (modes.flagged: more than e^3 above the robust 99 % point of the log importance weights).
When at least STUCK_STATES of them are flagged (250 chain steps), the search of infer.modes
runs over every kept stored state. A stuck chain rarely moves (3-20 distinct states per 500
steps at 80 lb; on a narrow toy mode, tests/test_infer_stuck.py, one state for 250 steps), so a
component needs only MIN_DISTINCT distinct flagged states (and STUCK_STATES with repeats): it
starts as a blob on them at least half the main t's width in every coordinate
(modes.component) and the refinement by importance sampling (modes.refine, 5,000 posterior
evaluations) gives it the region's shape. If a component is added, the stored steps
are discarded (counted with the burn-in phase) and the stored run starts again from the chains'
last positions with the new mixture (the MAP and its check carry over). At most
n_stored_searches components-adding searches per fit (default 2; 0: none); the count is kept in
the chain's file, so that a resumed fit searches where the uninterrupted one would.

Exactness: the stored run that is kept has one proposal from its first step; the steps that
shaped it are discarded, as a burn-in's are. Where no chunk has STUCK_STATES flagged states the
stored run is the same, step for step, as without this check.

Limitation (measured, 80 lb at seeds 1-4, stop 88): every seed now reports converged, but seed
3's fit is a false convergence. Its search came at step 500 (a chain in the k2 corner), and the
restarted chains never entered the region the multi-start MAP search misses (sigma0 at its lower
bound, d3 near 0, about 88 % of the mass: infer.restart), which on stop 87's code a chain of
the same seed had reached within 1,000 steps by chance; they sampled the other region alone (d3
mean 8.1 mm against 1.1 mm at seeds 1, 2 and 4). This check only changes which random path the
chains take; a region that no chain and no burn-in visits stays unseen, and the remedy for that
one is a MAP search that finds it.
"""
from __future__ import annotations

import numpy as np

from .modes import find_modes, flagged, keep, log_density
from .storage import load_count, store_count

#: flagged kept states in one chunk (of every cold chain) that start the search
STUCK_STATES = 50
#: distinct flagged states a component needs (a stuck chain repeats its states)
MIN_DISTINCT = 1


class StuckCheck:
    """The check run at every chunk of the stored run (module docstring): `(sampler, cold,
    start) -> Proposal` with the new components, or None. `proposal`: the stored run's; `target`:
    the vectorized emcee target (for the refinement); `weight`: SamplerConfig.mode_weight;
    `searches`: the searches that added components so far in this fit; `limit`:
    SamplerConfig.n_stored_searches."""

    def __init__(self, proposal, target, weight: float, searches: int, limit: int, seed: int,
                 names=None, log=None, intr=None):
        self.proposal, self.weight = proposal, float(weight)
        self.density = log_density(target, intr)
        self.searches, self.limit, self.seed = int(searches), int(limit), int(seed)
        self.names, self.log = names, log or (lambda msg: None)

    def __call__(self, sampler, cold: slice, start: int):
        if self.searches >= self.limit:
            return None
        chain, lp = sampler.get_chain()[:, cold], sampler.get_log_prob()[:, cold]
        ref_u, ref_lp = keep(chain, lp)
        if start >= len(chain):
            return None
        u, lpu = keep(chain[start:], lp[start:])        # the new chunk's kept states
        logq = self.proposal.move().logq
        mask = flagged(u, lpu, ref_u, ref_lp, logq)
        if mask.sum() < STUCK_STATES:
            return None
        per_chain = mask.reshape(-1, chain.shape[1]).sum(axis=0)
        self.log(f"step {sampler.iteration}: {mask.sum()} of this chunk's {mask.size} kept states "
                 f"lie where the proposal underweights the posterior (chain "
                 f"{int(np.argmax(per_chain))}: {per_chain.max()}): mode search over the stored "
                 f"run's {len(ref_u)} kept states")
        found = find_modes(self.proposal, ref_u, ref_lp, ref_u, ref_lp, self.weight, self.names,
                           self.log, density=self.density,
                           seed=self.seed + 7919 * (self.searches + 1),
                           min_states=MIN_DISTINCT, min_kept=STUCK_STATES, source="stored")
        if len(found.modes) == len(self.proposal.modes):
            return None
        self.searches += 1
        return found


def store_searches(backend, n: int) -> None:
    """Count the fit's stored-run searches that added components in the chain's file (a resumed
    fit goes on from the count)."""
    store_count(backend, "stored_searches", n)


def load_searches(backend) -> int:
    return load_count(backend, "stored_searches")
