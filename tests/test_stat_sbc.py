"""Simulation-based calibration (Talts, Betancourt, Simpson, Vehtari & Gelman 2018) of the
inference layer on a reduced 3-stage model.

What is checked: if the data are generated from the prior the fit uses and from the likelihood
the fit assumes, the rank of the true value among L independent posterior draws is discrete
uniform on 0..L. That holds only when the whole chain is right: the prior box and its
log-uniform / truncated-normal densities (Space.log_prior, sample_prior), the relative prior of
fs_fwd (sampled as the ratio fs_fwd / fc_fwd), the unbounded logit coordinates and their
Jacobian (UnboundedPosterior, Space.log_jac_u), the simulator and the AR(1) noise model with
sigma_noise and noise_phi integrated out (noisemodel.log_marginal).

Set-up. BRFD 267 N published parameters (spec section 6) with four free parameters: fc_fwd,
fs_fwd (relative prior), sigma2 and force_offset, every other model parameter fixed at its
published value; default priors from the record scales of the noise-free nominal record (fixed
once, not data-dependent), except the noise prior, narrowed to innovation sd s log-uniform on
[0.3 %, 3 %] of the friction scale (what noisemodel integrates: p(s) ~ 1/s, s = sigma_noise
sqrt(1 - phi^2)), and noise_phi uniform on [0, 0.999] (noisemodel's grid prior). Record: 25.4 mm,
0.2 Hz sine, 3 cycles at 20 Hz (300 samples). Each of N_REP = 100 replicates draws theta, s and
phi from these priors, simulates force + offset + stationary AR(1) noise, and samples the
posterior with frictionuq.infer.quickfit (least-squares start, 32 walkers, emcee DE/snooker in
the unbounded coordinates): 250 steps of burn-in, then the states of all walkers at steps 250,
325 and 400, of which L = 95 are kept at random. At stationarity the walkers of an ensemble are
independent draws; the autocorrelation times are 10-35 steps (sigma2 the slowest, measured on
6000-step runs, whose posterior quantiles agree with those of the 400-step runs), so the kept
ensembles are 2-7 tau apart and the burn-in is 7 tau or more.

Test. Per parameter the ranks (0..95, 96 values) are put in 8 bins of 12 values: under the null
each bin has probability exactly 1/8, so the bin counts are multinomial(100, 1/8) and Pearson's
chi-square has a known null distribution, evaluated here by Monte Carlo (200 000 multinomial
draws, seeded). The test fails when any parameter's p-value is below 0.01 / 4 (Bonferroni over
the 4 parameters).

False-alarm rate (probability the test fails on correct code, i.e. over random seeds): at most 4
x 0.0025 = 1 % (each p-value is super-uniform under the null; Bonferroni holds for dependent
parameters), up to the approximation that 250 burn-in steps and 75-step gaps give stationary,
independent draws. Power (measured with a prototype of this test): fitting the same AR(1) data
with the `iid` likelihood makes three of the four rank histograms U-shaped (chi-square p-values
4e-4 or smaller, below the 0.0025 threshold). Results: p-values 0.21 (fc_fwd), 0.84 (fs_fwd),
0.03 (sigma2), 0.10 (force_offset); an offline run of 300 replicates with another seed gave
0.17, 0.49, 0.31, 0.14. Deterministic (seeded); about 75 s of CPU (2 min wall on a loaded
2-core machine): marked slow."""
from __future__ import annotations

import numpy as np
import pytest

from frictionuq import published
from frictionuq.infer.likelihood import LogPosterior, prepare_record
from frictionuq.infer.noisemodel import PHI_MAX
from frictionuq.infer.priors import apply_overrides, default_priors, record_scales
from frictionuq.infer.quickfit import quick_sample
from frictionuq.infer.space import Space
from frictionuq.model import simulate, simulate_batch
from frictionuq.noise import ar1_from_normals

FREE = ("fc_fwd", "fs_fwd", "sigma2", "force_offset")
N_REP = 100            # replicates
WALKERS = 32
BURN, GAP = 250, 75    # steps before the first kept ensemble, steps between kept ensembles
L = 95                 # posterior draws per replicate (3 x 32 ensemble states, one dropped)
BINS = 8               # (L + 1) / BINS = 12 rank values per bin
FAMILY_ALPHA = 0.01
SEED = 2018


def _drive():
    t = np.arange(300) / 20.0                       # 3 cycles of 0.2 Hz at 20 Hz
    return t, 0.0254 * np.sin(2 * np.pi * 0.2 * t)


def _space():
    truth = published.brfd_params(267.0)
    t, x = _drive()

    class Rec:     # record scales of the noise-free nominal record: a fixed, data-free prior
        pass
    rec = Rec()
    rec.t, rec.x, rec.force = t, x, simulate(t, x, truth)
    scales = record_scales([rec])
    F = scales.f_scale
    over = {n: v for n, v in truth.items() if n not in FREE}
    over["sigma_noise"] = {"dist": "loguniform", "lower": 0.003 * F, "upper": 0.03 * F}
    pri, fixed = apply_overrides(default_priors(scales, "three_stage", (), "ar1"), over)
    return Space("three_stage", (), "ar1", pri, fixed)


def _replicate(space: Space, rep: int) -> np.ndarray:
    """Ranks (ndim,) of the true values among L posterior draws of one replicate."""
    rng = np.random.default_rng([SEED, rep])
    t, x = _drive()
    theta = space.sample_prior(1, rng)[0]
    a, b = space.noise_config()["sigma_bounds"]
    s = np.exp(rng.uniform(np.log(a), np.log(b)))           # innovation sd, p(s) ~ 1/s
    phi = rng.uniform(0.0, PHI_MAX)
    force = simulate_batch(t, x, space.kernel_matrix(theta), check=False)[0] + space.offset(theta)[0]
    y = force + ar1_from_normals(rng.standard_normal(t.size), phi, s / np.sqrt(1.0 - phi**2))
    logpost = LogPosterior(space, [prepare_record("sbc", t, x, y, q=1, eps=0.0)], parallel=False)
    qs = quick_sample(logpost, [SEED, rep, 1], steps=BURN + 2 * GAP, nwalkers=WALKERS)
    draws = np.concatenate([qs.chain[BURN - 1 + k * GAP] for k in range(3)])
    draws = draws[rng.permutation(draws.shape[0])[:L]]
    return np.sum(draws < theta[None, :], axis=0)


def _chi2(counts: np.ndarray) -> np.ndarray:
    e = counts.sum(axis=-1, keepdims=True) / counts.shape[-1]
    return np.sum((counts - e) ** 2 / e, axis=-1)


def _p_values(ranks: np.ndarray) -> np.ndarray:
    """Monte Carlo p-value of the binned-rank chi-square of each column of ranks (n, ndim)."""
    per_bin = (L + 1) // BINS
    counts = np.stack([np.bincount(r // per_bin, minlength=BINS) for r in ranks.T])
    null = _chi2(np.random.default_rng([SEED, 99]).multinomial(ranks.shape[0], np.full(BINS, 1 / BINS),
                                                                size=200_000))
    stat = _chi2(counts)
    return np.array([(1 + np.sum(null >= s)) / (1 + null.size) for s in stat]), counts


@pytest.mark.slow
def test_sbc_rank_uniformity_reduced_three_stage():
    assert (L + 1) % BINS == 0 and L < 3 * WALKERS
    space = _space()
    assert space.names == list(FREE)
    ranks = np.array([_replicate(space, rep) for rep in range(N_REP)])
    assert ranks.shape == (N_REP, len(FREE)) and ranks.min() >= 0 and ranks.max() <= L
    p, counts = _p_values(ranks)
    report = {n: (float(pv), c.tolist()) for n, pv, c in zip(FREE, p, counts)}
    print("SBC p-values and rank histograms:", report)
    alpha = FAMILY_ALPHA / len(FREE)
    assert np.all(p >= alpha), f"rank histogram not uniform (p < {alpha:g}): {report}"
