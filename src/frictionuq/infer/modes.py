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
(the log-posteriors are the ones the burn-in computed; no new evaluation; the refinement below
costs REFINE_ROUNDS x REFINE_DRAWS evaluations per component found). The reference is the
last round's second half, the states the proposal was fitted to. A kept state is flagged when
  * lw exceeds the reference's 99 % point by more than `MARGIN` nats (e^3: a proposal back from
    there is accepted at most about 5 % as often as from the bulk's top per cent), the 99 % point
    read robustly, as the median plus 2.326 standard deviations estimated from the median
    absolute deviation (`top`): the last round's walkers may still over-sample a mode they
    started in (a 5 % mode, 10-14 % of the reference, on the tests' 3-D target), and the raw
    99 % point then lies inside that mode's own weights, so none of its states was flagged
    (2026-12-07, stop 84: 3 of 10 seeds found that mode; with the robust point 30 of 30, at
    three distances; on Gaussian, skewed and heavy-tailed 14-D posteriors that the t covers,
    none added at 15 seeds either way), and
  * its log-posterior is no more than `max(10, 3 sqrt(D/2))` below the reference's median (the
    burn-in's own threshold for a stuck walker: a transient state of a walker still climbing
    from its start is not a region of the posterior).
With at least `MIN_STATES` distinct flagged states (and 2 D + 2), a t is fitted to them and
refined (Shape, below), and added as a component; the flagged states are then
weighed again under the mixture, and a further component is fitted to those still flagged, up
to `MAX_MODES`. The components share the weight `mode_weight` (SamplerConfig; 0.1, the weight
that made the dataset-2 fit converge).

Shape: the flagged states are where the walkers passed, not draws of the region they mark (on
dataset 2, the start ball around the MAP, whose d3 width was a fifth of the second mode's:
compared with a t fitted to another run's states there). The component starts as the flagged
states' own t (`component`: each coordinate's width raised to at least half the main t's,
WIDEN, their correlations kept) and is then refined by adaptive importance sampling (`refine`):
REFINE_ROUNDS rounds of REFINE_DRAWS draws from it, weighed by the posterior over the mixture
it would join, tempered to an effective sample size of REFINE_ESS of the draws, and refitted to
their weighted mean and covariance. On dataset 2 (measured offline on two seeds' burn-ins,
docs/log-calibration.md, 2026-12-07, morning) the second mode's median log weight fell from
+3.0 and +2.3 (the widened start) to +1.6 and +0.2 (two components each; on the CLI's own
burn-ins +0.6 and +0.3; an oracle component fitted to a tempered run's draws of the mode: -2.2),
at 5,000 evaluations a component. The fits reached R-hat 1.005 and 1.019 at 6,000 steps.
Until 2026-12-07 (stop 84) each round drew from the t refitted to the last one's weighted
moments with the t's own inflation (scale^2 df / (df - 2) = 2.6 times the covariance) on top,
and under tempered weights that compounds: on a 14-D two-mode target (tests/test_infer_modes.py)
the search made three components, two of them pulled 2-4 widths towards the main mode and 1.1
times its width, the third on the mode at 2.0-2.4 times its sd; with the inflation divided out of
the rounds' draws, one component on the mode, centre within 0.04, sd 0.18-0.21 against 0.2.
Tried first and dropped: an ensemble started at the flagged states that explored the region for
two burn-in rounds (16,000 evaluations; its walkers left the region at one seed, and offline it
scored +2.1 to +3.2, no better than the widened start), that ensemble confined to the flagged
region (+2.6 and +3.1: the region where the main t is weakest is a slice of the mode),
untempered importance weights (effective sample size 1-23 of 1,000; the component collapsed).
A refit of the components on a further burn-in round run with the mixture was tried and not
kept (2026-12-06, night).

Exactness: the mixture is fixed before the stored run and its density is exact (MixtureMove), so
the stored run's target is the posterior whatever the components are; a poor component only
costs rejected proposals (with weight 0.1 at most a tenth of the independence move's). On a
posterior that the t already covers no state is flagged and the stored run is the same, step for
step, as without the search (tested).

Default (since 2026-12-07, stop 87; opt-in before): on wherever the independence move runs
(SamplerConfig.searches_modes; `--no-mode-search` or `mode_search = false` turns it off). Where the
t covers the posterior it costs nothing: the BRFD twin level's fit is the same with and without
it (74,052 evaluations, 3,000 stored steps, the same ESS and R-hat; `benchmarks/bench_fit.py
--case twin --mode-search both`). Where it adds components it helped every real fit measured:
dataset 2's 36 lb fit (R-hat 1.10-1.13 at 4,600 steps without it; with it converged at some
seeds, R-hat 1.005-1.021 at the others) and arts-d1's 70 lb level (R-hat at 12,000 steps
1.357 -> 1.271 on stop 83's code, 1.567 -> 1.186 on stop 86's); at 80 lb (stop 83) its burn-in
never entered the missed region, no component, the same chain (docs/log-calibration.md).

Limitations: the search sees only what the burn-in visited; a mode it never entered stays
unseen (tempering, infer.tempering, is the tool that explores). A region that a stored chain
enters later and sticks in gets its component from the stored run's own search (infer.stuck,
since 2026-12-08), which reuses find_modes on the stored states. Flagged states from two separate
regions make one broad component first; the next round of the search then fits what it missed.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .proposal import IndependenceMove, Proposal

#: every this many steps of a burn-in round is kept for the search
MEMORY_STRIDE = 5
#: nats above the reference's (robust) 99 % point of the log importance weight
MARGIN = 3.0
#: distinct flagged states needed for a component (at least, and 2 D + 2)
MIN_STATES = 50
#: components at most
MAX_MODES = 3
#: a component's width in each coordinate at least this fraction of the main t's
WIDEN = 0.5
#: rounds of the component's refinement (refine), draws from the component in each
REFINE_ROUNDS = 5
REFINE_DRAWS = 1000
#: the weights of a refinement round are tempered until their effective sample size is at least
#: this fraction of the draws
REFINE_ESS = 0.25


def keep(chain: np.ndarray, log_prob: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A burn-in round's kept states: every MEMORY_STRIDE-th step, flattened ((n, D), (n,))."""
    c, lp = chain[::MEMORY_STRIDE], log_prob[::MEMORY_STRIDE]
    return c.reshape(-1, c.shape[-1]), lp.reshape(-1)


def flagged(states, log_prob, ref_states, ref_log_prob, logq) -> np.ndarray:
    """Mask of the states where the posterior outweighs the proposal (module docstring); `logq`:
    the proposal's log density (any constant)."""
    lw = log_prob - logq(states)
    d = states.shape[1]
    floor = np.median(ref_log_prob) - max(10.0, 3.0 * np.sqrt(d / 2.0))
    above = lw > top(ref_log_prob - logq(ref_states)) + MARGIN
    return np.isfinite(lw) & above & (log_prob >= floor)


def top(lw: np.ndarray) -> float:
    """The 99 % point of the reference's log weights, read robustly: median + 2.326 x 1.4826 x
    the median absolute deviation (a Gaussian's 99 % point; a minority of states from a mode
    the proposal misses does not move it, module docstring)."""
    lw = lw[np.isfinite(lw)]
    med = float(np.median(lw))
    return med + 2.326 * 1.4826 * float(np.median(np.abs(lw - med)))


def find_modes(proposal: Proposal, states, log_prob, ref_states, ref_log_prob,
               weight: float, names=None, log=None, density=None, seed=0,
               min_states: int | None = None, min_kept: int = 0,
               source: str = "burn-in") -> Proposal:
    """`proposal` with the components the search finds (module docstring), or unchanged.
    `states`, `log_prob`: the burn-in's kept states; `ref_*`: the last round's second half.
    `density(states)`: the log-posterior of a batch ((n, D) -> (n,)), with which each component
    is refined (`refine`, seeded by `seed` and its number); None: the component is the flagged
    states' (`component`). A component needs `min_states` distinct flagged states (default
    max(MIN_STATES, 2 D + 2)) and `min_kept` flagged states counted with repeats (the stored
    run's search, infer.stuck, where a stuck chain repeats its states); `source`: what the
    states are, for the log."""
    log = log or (lambda msg: None)
    states, log_prob = np.asarray(states, float), np.asarray(log_prob, float)
    d = states.shape[1]
    need = max(MIN_STATES, 2 * d + 2) if min_states is None else int(min_states)
    current = proposal
    for _ in range(MAX_MODES):
        mask = flagged(states, log_prob, ref_states, ref_log_prob, current.move().logq)
        pool = np.unique(states[mask], axis=0)
        if len(pool) < need or mask.sum() < min_kept:
            if current is proposal:
                log(f"mode search: {len(pool)} distinct {source} states ({mask.sum()} with "
                    f"repeats) where the posterior outweighs the proposal by more than "
                    f"e^{MARGIN:g} (a component needs {need}"
                    + (f" and {min_kept}" if min_kept else "") + "): none added")
            break
        k = len(current.modes) + 1
        comp, how = component(pool, proposal), f"fitted to {len(pool)} distinct {source} states"
        if density is not None:
            comp, alphas = refine(comp, _with_modes(proposal, current.modes, weight), density,
                                  np.random.default_rng([seed % (2**32), 1000 + k]))
            how += (f", refined by {len(alphas)} rounds of {REFINE_DRAWS} draws weighted by "
                    f"posterior over mixture (weights tempered by "
                    + "/".join(f"{a:.2f}" for a in alphas) + ")" if alphas else
                    f", unrefined (fewer than {2 * d + 2} of {REFINE_DRAWS} draws from it were "
                    f"its own with a finite posterior)")
        current = _with_modes(proposal, (*current.modes, comp), weight)
        log(f"mode search: component {k} {how} ({mask.mean():.1%} of the {len(states)} kept "
            f"flagged: the posterior outweighs the proposal by more than e^{MARGIN:g}); "
            + _where(proposal, comp, names))
    return current


def log_density(target, intr=None):
    """The log-posterior of a batch ((n, D) -> (n,)) from the vectorized emcee target (its first
    column; the others are blobs), for `refine`; with `intr`, a Ctrl-C stops the refinement
    between two of its rounds."""
    def density(x):
        if intr is not None:
            intr.check()
        out = np.asarray(target(x), float)
        return out[:, 0] if out.ndim == 2 else out
    return density


def refine(comp: Proposal, current: Proposal, density, rng) -> tuple[Proposal, list[float]]:
    """`comp` refined by adaptive importance sampling (population Monte Carlo; Cappe et al.
    2008): each of REFINE_ROUNDS rounds draws REFINE_DRAWS states from the component, weighs
    them by p / q, q the mixture of `current` (the main t and the components found before) and
    this component (its weight divided among them as in the stored run), and refits the
    component (a t on the sampler's coordinates) to the weighted mean and covariance of the
    draws it is the most likely source of. Drawn from the component alone, p / q_mix is its
    responsibility for p over its own density (r = w_c c / q_mix, so p r / c = w_c p / q_mix):
    the update is EM's for this component of the mixture, with hard assignments (soft ones pull
    a component whose weight exceeds its mode's mass onto the main mode; tested). In 14
    dimensions the raw weights are degenerate (effective sample size 1-23 of 1,000 on dataset
    2), so they are tempered, w^alpha with the largest alpha in [0, 1] that
    keeps their effective sample size at REFINE_ESS of the draws. Tempered moments lie between
    the draws' spread and the mode's, so each round draws with the estimate's own spread (the
    t's inflation divided out, below) and the rounds close in on the mode; the returned
    component carries the usual inflation. Returns the component and each round's alpha.
    A round with fewer than 2 D + 2 finite weights ends the refinement."""
    d = comp.mean.size
    alphas = []
    # each round draws from a t whose spread is the current estimate itself: the component's t
    # inflates its covariance by scale^2 df / (df - 2) (2.6), and the tempered weights' moments
    # lie between the draws' and the mode's, so refitting to them as the component's own
    # covariance widened it round after round to a fixed point well beyond the mode (twice
    # its sd on the 14-D test target; dataset 2's d3: 0.6-0.8 of the main t's width against
    # the mode's 0.33). The returned component is the last estimate with the usual inflation,
    # as the main t is to its round's states.
    df, scale = comp.df, comp.scale
    infl = scale ** 2 * df / (df - 2.0)
    mean, cov = comp.mean, comp.cov
    for _ in range(REFINE_ROUNDS):
        draw = Proposal.gaussian(mean, cov / infl, df=df, scale=scale)
        x = IndependenceMove(draw).draw(REFINE_DRAWS, rng)
        mix = _with_modes(current, (*current.modes, draw), current.mode_weight).move()
        terms = mix.terms(x)        # each part's; their log-sum-exp is mix.logq(x)
        lw = np.asarray(density(x), float) - np.logaddexp.reduce(terms, axis=0)
        # the draws this component is the most likely source of (hard EM): with its weight fixed
        # above the mode's mass, soft responsibilities pull it onto the main mode
        ok = np.isfinite(lw) & (np.argmax(terms, axis=0) == len(mix.parts) - 1)
        if ok.sum() < 2 * d + 2:
            break
        w, alpha = tempered_weights(lw[ok], REFINE_ESS)
        xo = x[ok]
        mean = w @ xo
        cov = (xo - mean).T @ ((xo - mean) * w[:, None])
        alphas.append(alpha)
    return (Proposal.gaussian(mean, cov, df=df, scale=scale) if alphas else comp), alphas


def tempered_weights(lw: np.ndarray, frac: float) -> tuple[np.ndarray, float]:
    """Normalised weights exp(alpha lw) with the largest alpha in [0, 1] whose effective sample
    size (1 / sum w^2) is at least `frac` of len(lw) (bisection; alpha = 0 gives equal weights)."""
    lw = lw - lw.max()

    def weights(a):
        w = np.exp(a * lw)
        return w / w.sum()

    def enough(a):
        return 1.0 / np.sum(weights(a) ** 2) >= frac * lw.size
    if enough(1.0):
        return weights(1.0), 1.0
    lo, hi = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if enough(mid) else (lo, mid)
    return weights(lo), lo


def component(pool: np.ndarray, main: Proposal) -> Proposal:
    """The t of a component: the flagged states' mean and correlations (none from fewer than
    2 D + 2 states), each coordinate's width their sd or half the main t's, whichever is larger
    (WIDEN). The flagged states are where the walkers passed (on dataset 2, the start ball
    around the MAP), narrower than the region they mark: d3's width among them was a fifth of
    the second mode's."""
    sd = pool.std(axis=0)
    main_sd = np.sqrt(np.diag(main.x_cov)) if main.x_cov is not None else main.x_width
    s = np.maximum(sd, WIDEN * main_sd)
    # a few states (a stuck chain's, infer.stuck) give no correlations worth keeping
    enough = np.all(sd > 0) and len(pool) >= 2 * pool.shape[1] + 2
    r = np.corrcoef(pool.T) if enough else np.eye(pool.shape[1])
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
