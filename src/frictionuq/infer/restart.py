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

Exactness: the stored run that is kept starts after the last restart with a fixed proposal; the
states that shaped it are discarded, as every burn-in's are. ABOVE_MAP: the MAP is polished to
well under a nat (a chain cannot exceed the posterior's maximum, only an imperfect estimate of
it); 3 nats keeps a polish's last fraction of a nat near prior bounds from triggering a restart.
"""
from __future__ import annotations

import numpy as np

from .modes import keep

#: nats above the MAP's log-posterior that a stored state must reach to restart the burn-in
ABOVE_MAP = 3.0


def above_map(sampler, cold: slice, start: int, sp, lp_map: float):
    """(state u, its log-posterior in box coordinates) of the cold chains' highest state among
    the stored steps from `start` on, if it lies more than ABOVE_MAP nats above `lp_map`; else
    None."""
    u = sampler.get_chain(discard=start)[:, cold]
    if u.size == 0:
        return None
    d = u.shape[-1]
    lp_u = sampler.get_log_prob(discard=start)[:, cold]
    lp = (lp_u - sp.log_jac_u(u.reshape(-1, d)).reshape(lp_u.shape)).reshape(-1)
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    k = int(np.argmax(lp))
    if not lp[k] > lp_map + ABOVE_MAP:
        return None
    return u.reshape(-1, d)[k].copy(), float(lp[k])


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
