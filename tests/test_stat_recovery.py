"""Recovery of the published parameters of both devices from twin-like synthetic records, with
the real fit path (frictionuq.infer.fit.prepare + frictionuq.infer.sampler.sample: default
data-derived priors, multi-start MAP, adaptive burn-in with emcee's DE/snooker moves, then the
default stored run, 16 independent chains moved by the independence move fitted to the burn-in
and a random walk, in the unbounded coordinates, per-record AR(1) noise integrated out).

Cases: BRFD at 35, 53, 66, 133 and 267 N (0.5 Hz) and 267 N (0.2 Hz), i.e. every published BRFD
level; MFD at 500, 800, 1200 and 1500 psi (0.5 Hz): published sets of spec section 6, all 13 model
parameters and force_offset free (14 per fit, 140 (parameter, fit) pairs); nothing is fixed.
Records kept small: one sine of the paper's amplitude (BRFD 25.4 mm, MFD 1 in), 3 cycles sampled
directly at 100 samples per cycle (300 samples, decimation factor 1), so that the noise is
exactly of the class the likelihood assumes: force = simulated (published parameters) + offset
0.5 % of Fc + stationary AR(1) noise, phi 0.8, marginal sd 1 % of Fc (Fc = (fc_fwd + fc_bwd) /
2). A fixed sampler budget instead of the convergence loop: 2 to 4 burn-in rounds of 500 steps,
then 2000 stored steps (measured with the ensemble stored run, the default until 2026-12-01:
max R-hat 1.04-1.17 and min ESS 130-450 per fit, MFD 500 psi R-hat 1.30 and ESS 50: enough for
95 % intervals, not for the project's convergence rule).

Assertion: the true value lies inside the equal-tailed 95 % posterior interval for at least
90 % of the 140 pairs (at most 14 misses). Measured (2026-12-01, SEED 7, the 16 chains): 3
misses, 137/140 = 97.9 % covered (BRFD 267 N 0.2 Hz force_offset, MFD 500 psi fc_bwd, BRFD 35 N
fc_bwd); with the ensemble stored run (2026-11-26) 5 misses, 135/140 (the same three, and BRFD
35 N k2 and k3). The seed study below was made with the ensemble.
Over the noise seeds 1-7 (SEED changed, everything else as here) the miss count was 2-12 of
140, mean 6.4, sd 3.7. The two low-force levels added on 2026-11-26 (35 and 53 N), over the 37
seeds 1-37: 6.0 % (35 N) and 5.2 % (53 N) of their pairs missed, as calibrated as the nominal
5 %. Their misses come in groups of the take-up parameters (k2, d2, k3, d3 together), and not
from short chains: 35 N with SEED 5 and 2 run to 10,000 stored steps (max R-hat 1.002-1.003)
missed the same parameters as with 2,000.

False-alarm rate (probability of failing on correct code, over noise seeds): 0.5 % if the 140
interval misses were independent Bernoulli(0.05) (P(Binomial(140, 0.05) >= 15)). Misses within
a fit are correlated (posterior correlations up to 0.99 for the MFD), which widens the spread
of the miss count: simulating z ~ N(0, R_fit) with each fit's measured posterior correlation
matrix (SEED 7's ten fits) and counting |z| > 1.96 gives 1.3 % (mean 7.0 misses; measured
above: 6.4). These rates assume the sampler reaches the posterior's main mode; a fit stuck in a
wrong mode fails the test, rightly. Until 2026-11-28 the MAP search alone missed the mode on
this test's 66 N record for 2 of 10 rng seeds (the MAP test below; its chain covered all 14
true values, the burn-in recovering the mode). Before 2026-11-26 the 35 and 53 N sets were left out because the MAP search missed their
mode (the chain settled 250 log-posterior units below the truth at 35 N); the search reaches it
since the heuristic's variants and the differential-evolution starts.
Deterministic (seeded); about 60 s on 2 cores (63 s measured alone): marked slow."""
from __future__ import annotations

import warnings
from types import SimpleNamespace as NS

import numpy as np
import pytest

from frictionuq import published
from frictionuq.infer.fit import FitConfig, FitSpec, prepare
from frictionuq.infer.optimize import find_map
from frictionuq.infer.sampler import SamplerConfig, sample
from frictionuq.model import simulate
from frictionuq.noise import ar1_from_normals
from frictionuq.units import PSI

#: (device, level: N for the BRFD, psi for the MFD, frequency Hz); the index is the noise seed
CASES = (("brfd", 267.0, 0.2), ("brfd", 66.0, 0.5), ("brfd", 133.0, 0.5), ("brfd", 267.0, 0.5),
         ("mfd", 500.0, 0.5), ("mfd", 800.0, 0.5), ("mfd", 1200.0, 0.5), ("mfd", 1500.0, 0.5),
         ("brfd", 35.0, 0.5), ("brfd", 53.0, 0.5))
SAMPLES_PER_CYCLE, CYCLES = 100, 3
PHI, NOISE_SD, OFFSET = 0.8, 0.01, 0.005       # noise and offset as fractions of Fc
MIN_COVERED = 0.90
SEED = 7
SAMPLER = SamplerConfig(chunk=2000, min_steps=2000, max_steps=2000, burn_rounds=2,
                        burn_max_rounds=4, burn_steps=500, n_random_starts=2, n_prior_starts=2,
                        progress=False)


def twin_like(device: str, level: float, freq: float, k: int, sampler=SAMPLER):
    """A short twin-like record of `device` at `level`, prepared for the fit. Returns (records,
    scales, space, log-posterior, true values in sampling coordinates)."""
    if device == "brfd":
        truth, applied, amp = published.brfd_params(level), level, published.BRFD_AMPLITUDE_M
    else:
        truth, applied, amp = published.mfd_params(level), level * PSI, published.MFD_AMPLITUDE_M
    rate = SAMPLES_PER_CYCLE * freq
    t = np.arange(CYCLES * SAMPLES_PER_CYCLE) / rate
    x = amp * np.sin(2 * np.pi * freq * t)
    fc = 0.5 * (truth["fc_fwd"] + truth["fc_bwd"])
    rng = np.random.default_rng([SEED, k])
    y = (simulate(t, x, truth) + OFFSET * fc
         + ar1_from_normals(rng.standard_normal(t.size), PHI, NOISE_SD * fc))
    test = NS(id=f"{device}-{level:g}-{freq:g}Hz", record=NS(t=t, x=x, force=y, applied=None),
              applied=applied, kind="harmonic", frequency_hz=freq)
    cfg = FitConfig(seed=k + 1, samples_per_cycle=SAMPLES_PER_CYCLE, sampler=sampler)
    records, scales, space, logpost = prepare(FitSpec(test.id, [test], applied, cfg))
    assert records[0].q == 1 and records[0].n == t.size
    return records, scales, space, logpost, space.to_theta({**truth, "force_offset": OFFSET * fc})


def fit_case(k: int):
    """Fit case k. Returns (space, posterior draws (n, ndim) in sampling coordinates, true
    values in sampling coordinates)."""
    _, scales, space, logpost, true_theta = twin_like(*CASES[k], k)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # emcee's "chain shorter than 50 tau" warnings
        res = sample(logpost, scales, k + 1, None, SAMPLER)
    return space, res.chain.reshape(-1, space.ndim), true_theta


@pytest.mark.slow
def test_published_parameters_recovered_for_both_devices():
    misses, pairs = [], 0
    for k, (device, level, freq) in enumerate(CASES):
        space, draws, true_theta = fit_case(k)
        assert space.ndim == 14
        lo, hi = np.quantile(draws, [0.025, 0.975], axis=0)   # monotone maps: same as in SI
        for i, name in enumerate(space.names):
            pairs += 1
            if not lo[i] <= true_theta[i] <= hi[i]:
                v = space.to_values(np.vstack([true_theta, lo, hi]))[:, i]
                misses.append(f"{device} {level:g} {freq:g} Hz: {name} true {v[0]:.4g} "
                              f"not in [{v[1]:.4g}, {v[2]:.4g}]")
    covered = 1 - len(misses) / pairs
    print(f"coverage of the 95 % intervals: {pairs - len(misses)}/{pairs} = {covered:.3f}; "
          f"misses: {misses}")
    assert pairs == len(CASES) * 14
    assert covered >= MIN_COVERED, f"only {covered:.1%} of {pairs} intervals cover the truth: {misses}"


@pytest.mark.parametrize("level, k, rng_seed", [
    (35.0, 1, 2), (53.0, 3, 4), (267.0, 4, 5), (133.0, 2, 3),
    # the 66 N record with the two rng seeds of 1-10 for which both differential-evolution runs,
    # each seeded with the heuristic start, ended in wrong basins (570 below the truth; a strict
    # xfail until 2026-11-28): fixed by optimize._global_searches
    (66.0, 1, 2), (66.0, 1, 9)])
def test_map_search_reaches_the_true_mode_on_brfd(level, k, rng_seed):
    """The multi-start MAP search (default starts) ends at least as high as the true
    parameters' log-posterior (minus 5, for the optimiser's tolerance). Before the heuristic's
    variants (small v_s, short d3, stiffer/softer bristles) were added to the starts it ended 244
    (35 N) and 47 (53 N) below it; the differential-evolution starts (optimize.global_start)
    took 66 N to the mode for 8 of 10 rng seeds until their later runs were unseeded and run
    until two agree (optimize._global_searches: 20 of 20 rng seeds at 66 N, 40 of 40 at 35, 53,
    133 and 267 N, measured 2026-11-28). Deterministic (no sampling)."""
    _, scales, _, logpost, true_theta = twin_like("brfd", level, 0.5, k, sampler=SamplerConfig())
    lp_true = float(logpost.log_prob(true_theta[None])[0])
    _, lp_map, info = find_map(logpost, scales, np.random.default_rng(rng_seed))
    assert 2 <= len(info["global_generations"]) <= 5
    assert lp_map >= lp_true - 5.0, f"MAP log-posterior {lp_map:.1f}, at the truth {lp_true:.1f}"
