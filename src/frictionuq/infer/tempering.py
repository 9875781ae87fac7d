"""Parallel tempering for the stored run's independent chains (SamplerConfig.temperatures).

Why: a posterior with separated modes, where a chain seldom crosses from one to the other.
It was built for the real arts-d1 70 lb level, whose Stribeck velocity v_s looked bimodal (R-hat
1.47 after 6,000 steps, whatever the move); measured there it did not help (R-hat 1.22 after
2,000 steps with 4 levels): the upper "mode" is a tail toward v_s's prior bound, which the moves
cross slowly at any temperature (docs/log-calibration.md, 2026-12-02 afternoon). Opt-in, not
the default. Tempered copies of each chain, at inverse temperatures
beta_l = ratio^l (l = 0 .. L-1) of the likelihood, cross between the modes where the cold chain
cannot, and swaps of adjacent levels carry the crossings down to beta = 1 (Geyer 1991; Earl and
Deem 2005; ptemcee, Vousden et al. 2016, whose swap rule this is).

Layout: the stored run has C x L walkers, walker l * C + c is chain c's copy at level l; level 0
(beta = 1) is the posterior, and only its C walkers are the fit's chains (`cold`). Each level l
targets p(theta) L(theta)^beta_l, which needs the log-likelihood apart from the rest of the
log-density: it is the sum of the per-record log-likelihoods the target returns as emcee blobs
(the first `n_records` blob columns), so the backend keeps the untempered log-posterior of
every walker and nothing is evaluated twice.

A step (TemperedMove.propose): every walker proposes from the wrapped move (the independence
move, or the random walk with its covariance widened by 1 / beta_l at level l, the tempered
posterior's width), accepted by the tempered Metropolis-Hastings ratio; then for each chain and
each pair of adjacent levels (l, l + 1), from the hottest pair down, the two states swap with
probability min(1, exp((beta_l - beta_{l+1}) (ll_{l+1} - ll_l))), which keeps every level's
target invariant. The ladder's ratio: a swap is accepted about as often as
(beta_l - beta_{l+1}) times the spread of the log-likelihood at level l, about sqrt(D/2) / beta_l,
is of order one: ratio 1 - 1 / sqrt(D/2) keeps that product at one whatever the level (0.59 at
D = 12), the default `temper_ratio` None.

Every level uses the stored run's moves and weights; the independence proposal is the one
fitted to the untempered burn-in, so the hotter levels accept it less and move mostly by the
(widened) random walk. The swap counts (TemperedMove.swaps, the history's swap_acceptance) are
those of the current session: a resumed run counts afresh.
"""
from __future__ import annotations

import emcee
import numpy as np
from emcee.state import State


def ladder(levels: int, ratio: float) -> np.ndarray:
    """Inverse temperatures ratio^l, l = 0 .. levels - 1 (1 first)."""
    return float(ratio) ** np.arange(int(levels))


def default_ratio(ndim: int) -> float:
    """The ladder ratio that keeps adjacent levels' swaps accepted at a rate of order one
    (module docstring), at least 0.3."""
    return float(max(0.3, 1.0 - 1.0 / np.sqrt(max(ndim, 2) / 2.0)))


class TemperedMove(emcee.moves.Move):
    """One tempered Metropolis-Hastings step of every walker, then the swaps of adjacent levels
    (module docstring). `base`: an emcee MHMove whose `get_proposal(coords, random)` gives the
    proposals and log Hastings factors; `widen`: scale each level's proposal displacement by
    1 / sqrt(beta_l) (a symmetric random walk only; each walker must draw its own: emcee's
    GaussianMove with a covariance matrix moves all walkers by one displacement). `chains`: C, walkers per level;
    `n_records`: the blob columns that hold the records' log-likelihoods. Counts of proposed
    and accepted swaps per level pair are kept in `swaps` (2, L - 1)."""

    def __init__(self, base: emcee.moves.MHMove, betas, chains: int, n_records: int,
                 widen: bool = False, swaps: np.ndarray | None = None):
        self.base = base
        self.betas = np.asarray(betas, float)
        self.C = int(chains)
        self.R = int(n_records)
        self.widen = widen
        L = self.betas.size
        self.beta_w = np.repeat(self.betas, self.C)           # each walker's beta
        # shared between the moves of one run, so that the counts add up
        self.swaps = np.zeros((2, max(L - 1, 0))) if swaps is None else swaps

    def loglik(self, state: State) -> np.ndarray:
        b = np.asarray(state.blobs)            # emcee squeezes a single blob column away
        return np.sum(b.reshape(b.shape[0], -1)[:, : self.R], axis=1)

    def _tempered(self, log_prob, ll):
        with np.errstate(invalid="ignore"):
            t = log_prob - (1.0 - self.beta_w) * ll
        return np.where(np.isfinite(log_prob), t, -np.inf)

    def propose(self, model, state):
        x0 = state.coords
        q, factors = self.base.get_proposal(x0, model.random)
        if self.widen:
            q = x0 + (q - x0) / np.sqrt(self.beta_w)[:, None]
        lp, blobs = model.compute_log_prob_fn(q)
        new = State(q, log_prob=lp, blobs=blobs)
        diff = self._tempered(lp, self.loglik(new)) - self._tempered(state.log_prob,
                                                                     self.loglik(state)) + factors
        accepted = np.log(model.random.rand(x0.shape[0])) < diff
        state = self.update(state, new, accepted)
        self._swap(state, model.random)
        return state, accepted

    def _swap(self, state: State, random):
        """Swap adjacent levels' states per chain, hottest pair first, in place."""
        L, C = self.betas.size, self.C
        for l in range(L - 2, -1, -1):
            ll = self.loglik(state)
            i, j = l * C + np.arange(C), (l + 1) * C + np.arange(C)
            a = (self.betas[l] - self.betas[l + 1]) * (ll[j] - ll[i])
            ok = np.isfinite(a) & (np.log(random.rand(C)) < a)
            self.swaps[0, l] += C
            self.swaps[1, l] += ok.sum()
            if ok.any():
                a_, b_ = i[ok], j[ok]
                for arr in (state.coords, state.log_prob, state.blobs):
                    arr[a_], arr[b_] = arr[b_].copy(), arr[a_].copy()


def tempered_moves(moves, betas, chains: int, n_records: int):
    """The stored run's (move, weight) list with every move wrapped in a TemperedMove sharing
    one swap count; the random walk (proposal.RandomWalkMove) widened per level."""
    from .proposal import RandomWalkMove
    swaps = np.zeros((2, max(len(betas) - 1, 0)))
    return [(TemperedMove(m, betas, chains, n_records, widen=isinstance(m, RandomWalkMove),
                          swaps=swaps), w) for m, w in moves]


def swap_rates(moves) -> np.ndarray | None:
    """Fraction of swaps accepted per adjacent level pair so far, or None without tempering."""
    for m, _ in moves:
        if isinstance(m, TemperedMove) and m.swaps.size:
            return m.swaps[1] / np.maximum(m.swaps[0], 1)
    return None
