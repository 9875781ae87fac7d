"""The stored run's check of the MAP (SamplerConfig.n_map_restarts; infer.sampler runs it).

Why: the burn-in starts at the MAP that the multi-start search (infer.optimize) returns, and its
walkers and proposal cover the region around it. If the search missed a region that holds more
posterior density, the burn-in may never enter it, and the stored run's independence proposal
then weighs it so little that a chain which wanders in stays. Measured on the real arts-d1
80 lb level (docs/log-calibration.md, 2026-12-07, stop 85): every seed's search ended at the
same point (sigma0 6.9e7 N/m, take-up d3 9.2 mm; log-posterior -63,176.8 nats), while a second
region (sigma0 at its lower bound, d3 at 0: the bristle's compliance doing the take-up's work)
peaks 7.7-9.1 nats higher and holds about 88 % of the posterior mass (importance-sampling
evidence of each region from a t fitted to it: log Z -63,202.6 against -63,204.6). Its states
weighed 14-18 nats more than the bulk's under the proposal, so the chains that entered it never
came back, and R-hat grew with the run (1.833 after 100,000 steps, stop 83). A burn-in started
there sampled that region alone (its chains never left it), so the remedy needs both regions.

What: at every check of the stored run, the cold chains' states since the last check are read
for a log-posterior (in the prior box's coordinates, the MAP's) more than ABOVE_MAP nats above
the MAP's. Such a state proves the search missed a higher region: the MAP is polished from it,
the stored steps so far are discarded (counted with the burn-in phase), and the burn-in runs
again from the new MAP, its mode search (infer.modes) given every state kept since the fit
began (every MEMORY_STRIDE-th step): the first burn-in's, the discarded chains' and its own
rounds'. The region the chains had covered (around the old MAP) is then where the new proposal
is weak, and gets components of its own, as does any region the first burn-in passed through
(the dataset-2 fit's first rounds sit in d3's second mode: with the discarded chains' states
alone, 500 steps that had left it, the search after the restart found too few states there and
added none, where the first burn-in's search had added one); the stored run proposes from the
mixture. At most `n_map_restarts` times per fit (default 1).

A chain need not climb above the MAP by itself: a region's typical states lie several nats below
its peak (about D / 2 in D dimensions), so a region that peaks a few nats above the MAP can hold
chains for thousands of steps none of whose states passes the MAP. At arts-d1's 80 lb level, seed
1 (2026-12-07, stop 86): from step 8,000 on, chains sat for up to 1,700 steps at states of the
corner region 2.5-5 nats BELOW the MAP, R-hat rose from 1.006 to 1.036, and no restart came;
Powell from the highest of those states reached 4.1 nats above the MAP in 3 s (1,299
evaluations). So at every check the stored run's proposal is also read: the highest cold state
of the new steps that the proposal underweights (modes.flagged: its log importance weight more
than modes.MARGIN above the robust 99 % point of all stored states', every MEMORY_STRIDE-th) is
polished if it lies no deeper than D / 2 below ABOVE_MAP above the MAP (where the typical states
of a region that peaks ABOVE_MAP above it lie; at 80 lb, seed 1, polishes from two flagged states
7.5 and 8.8 nats below the MAP went back to it, at 26,011 and 31,624 evaluations, a seventh of the
fit's each), and a polish that ends more than ABOVE_MAP above the MAP restarts the burn-in as a
chain above it would. At most MAX_POLISHES polishes per stored run (a posterior the proposal covers
flags a state now and then), each one pass of Powell's method of at most POLISH_EVALS
evaluations per free parameter (2,800 for the 3-stage model): the polish that found 80 lb's
region took 1,267, and on the real 35 lb level one from a flagged state 3.3 nats below the MAP
went back to it after 97,313 evaluations in three passes, a fifth of that converged fit's; the
restart itself polishes fully. The polishes are counted in the chain's file so that a resumed
fit polishes where the uninterrupted one would.

The check compares with the MAP the burn-in ended at, not the search's: when the last burn-in
round's walkers stand more than ABOVE_MAP above the search's MAP, the MAP is polished from their
highest state first (burn_in_map). The burn-in covered that region, and its proposal was fitted
there; checked against the search's MAP, the stored chains would restart a burn-in for nothing
(the BRFD twin's 267 N level: the search 14.3 nats short, one restart; with the polish after the
burn-in, no restart, 74,052 evaluations to convergence against 114,392).

Exactness: the stored run that is kept starts after the last restart with a fixed proposal; the
states that shaped it are discarded, as every burn-in's are. ABOVE_MAP: the MAP is polished to
well under a nat (a chain cannot exceed the posterior's maximum, only an imperfect estimate of
it); 3 nats keeps a polish's last fraction of a nat near prior bounds from triggering a restart.
"""
from __future__ import annotations

import numpy as np

from .modes import flagged, keep
from .optimize import polish
from .storage import load_count, store_count

#: nats above the MAP's log-posterior that a stored state must reach to restart the burn-in
ABOVE_MAP = 3.0
#: polishes from underweighted stored states per stored run (module docstring)
MAX_POLISHES = 10
#: log-posterior evaluations per such polish, per free parameter (module docstring)
POLISH_EVALS = 200


class MapCheck:
    """The check run at every chunk of the stored run (module docstring): `(sampler, cold,
    start) -> (theta, log-posterior, how it was found)` of a point more than ABOVE_MAP nats above
    the MAP (a stored state, or the polish of an underweighted one) from which to restart, or
    None.
    `logq`: the stored run's independence proposal's log density in the sampler's coordinates
    (None: no independence move, only the plain check); `polishes`: those already spent (a
    resumed fit's, load_polishes); `backend`: where each polish is counted."""

    def __init__(self, logpost, lp_map: float, logq=None, polishes: int = 0, backend=None,
                 log=None):
        self.logpost, self.lp_map, self.logq = logpost, float(lp_map), logq
        self.polishes, self.backend = int(polishes), backend
        self.log = log or (lambda msg: None)

    def __call__(self, sampler, cold: slice, start: int):
        sp = self.logpost.space
        u, lp_u = _new_states(sampler, cold, start)
        if u.size == 0:
            return None
        k, lp = _highest(sp, u, lp_u)
        if lp > self.lp_map + ABOVE_MAP:
            return sp.from_u(u[k]), lp, "a chain reached"
        if self.logq is None or self.polishes >= MAX_POLISHES:
            return None
        ref_u, ref_lp = keep(sampler.get_chain()[:, cold], sampler.get_log_prob()[:, cold])
        mask = flagged(u, lp_u, ref_u, ref_lp, self.logq)
        if not mask.any():
            return None
        k, lp = _highest(sp, u, lp_u, mask)     # the highest state the proposal underweights
        # a region that peaks ABOVE_MAP above the MAP has its typical states about D / 2 below
        # that: a flagged state deeper than this lies in a region no higher than the MAP's
        if lp < self.lp_map + ABOVE_MAP - 0.5 * sp.ndim:
            return None
        self.polishes += 1
        store_polishes(self.backend, self.polishes)
        n0 = self.logpost.n_evals
        theta, best = polish(self.logpost, sp.from_u(u[k]), lp, passes=1,
                             max_evals=POLISH_EVALS * sp.ndim)
        self.log(f"step {sampler.iteration}: polished from a stored state the proposal "
                 f"underweights (log-posterior {lp:.6g} nats, {lp - self.lp_map:+.1f} against "
                 f"the MAP) to {best:.6g} ({best - self.lp_map:+.1f}; "
                 f"{self.logpost.n_evals - n0} evaluations; polish {self.polishes} of "
                 f"{MAX_POLISHES})")
        return (theta, best, "a polish from such a state reached") \
            if best > self.lp_map + ABOVE_MAP else None


def burn_in_map(logpost, kept, theta_map: np.ndarray, lp_map: float):
    """(theta, log-posterior, moved): the MAP polished from the highest of the last burn-in
    round's kept states `kept` ((u, log-posterior in the sampler's coordinates), as modes.keep
    gives them) when that lies more than ABOVE_MAP above `lp_map`; else the MAP unchanged. The
    burn-in's walkers, started around a MAP the search left short of its optimum, climb to it, and
    the stored run's proposal is fitted to them there: without this the stored run's check would
    find its chains above the old MAP and restart a burn-in that had covered the region (the BRFD
    twin's 267 N level, 2026-12-07, stop 86: the search's MAP 14.3 nats short, one needless
    restart, 114,392 evaluations to convergence)."""
    sp = logpost.space
    u, lp_u = kept
    k, lp = _highest(sp, u, lp_u)
    if not lp > lp_map + ABOVE_MAP:
        return theta_map, lp_map, False
    theta, best = polish(logpost, sp.from_u(u[k]), lp)
    return theta, best, True


def above_map(sampler, cold: slice, start: int, sp, lp_map: float):
    """(state u, its log-posterior in box coordinates) of the cold chains' highest state among
    the stored steps from `start` on, if it lies more than ABOVE_MAP nats above `lp_map`; else
    None."""
    u, lp_u = _new_states(sampler, cold, start)
    if u.size == 0:
        return None
    k, lp = _highest(sp, u, lp_u)
    return (u[k].copy(), lp) if lp > lp_map + ABOVE_MAP else None


def _new_states(sampler, cold: slice, start: int) -> tuple[np.ndarray, np.ndarray]:
    """The cold chains' stored states from step `start` on, flattened ((n, D), (n,)), with their
    log-posteriors in the sampler's coordinates."""
    u = sampler.get_chain(discard=start)[:, cold]
    return u.reshape(-1, u.shape[-1]), sampler.get_log_prob(discard=start)[:, cold].reshape(-1)


def _highest(sp, u: np.ndarray, lp_u: np.ndarray, mask=None) -> tuple[int, float]:
    """(index, log-posterior in box coordinates) of the highest of the states `u` (sampler's
    coordinates, log-posteriors `lp_u` there; among `mask` if given)."""
    lp = lp_u - sp.log_jac_u(u)
    ok = np.isfinite(lp) if mask is None else np.isfinite(lp) & mask
    lp = np.where(ok, lp, -np.inf)
    k = int(np.argmax(lp))
    return k, float(lp[k])


def carried(sampler, cold: slice) -> tuple[np.ndarray, np.ndarray]:
    """The discarded stored run's states for the next burn-in's mode search: every
    MEMORY_STRIDE-th step of the cold chains, with their log-posteriors (u coordinates)."""
    return keep(sampler.get_chain()[:, cold], sampler.get_log_prob()[:, cold])


def store_map(backend, theta: np.ndarray, lp: float, restarts: int) -> None:
    """Keep the restarted run's MAP in the chain's file: a resumed fit starts from it, not from
    the search's (which would see the stored chains above it and restart again)."""
    if backend is None:
        return
    with backend.open("a") as f:
        a = f[backend.name].attrs
        a["map_theta"] = np.asarray(theta, float)
        a["map_log_prob"] = float(lp)
        a["map_restarts"] = int(restarts)


def load_map(backend):
    """(theta, log-posterior, restarts) stored by store_map, or None."""
    if backend is None:
        return None
    with backend.open() as f:
        a = f[backend.name].attrs
        if "map_theta" not in a:
            return None
        return np.asarray(a["map_theta"], float), float(a["map_log_prob"]), int(a["map_restarts"])


def store_polishes(backend, n: int) -> None:
    """Count MapCheck's polishes in the chain's file (a resumed fit goes on from the count)."""
    store_count(backend, "map_polishes", n)


def load_polishes(backend) -> int:
    return load_count(backend, "map_polishes")
