"""Held-out scoring (nats): the log predictive density of a held-out test from a training fit's
posterior draws, and totals and paired differences over held-out tests with their standard
errors. Used by compare.py (leave-one-test-out ELPD per applied force) and by the discrepancy
screening (held-out gains of candidate effects).

For each test k of a level, the model is fitted on the other tests only and the held-out test
is predicted:
    elpd_k = log( (1/S) sum_s p(y_k | theta_s) ),   theta_s ~ p(theta | y_-k),
computed as logsumexp - log S, where p(y_k | theta) is the record's likelihood with its own
noise parameters (sigma_noise, and noise_phi for `ar1`) integrated out exactly as in the fit
(frictionuq.infer.noisemodel, the held-out record's noise priors being the training fit's).
Whole tests are the held-out units: the residuals of a friction model are strongly
autocorrelated within a test, so pointwise LOO over samples would predict a sample from its
neighbours and say little about a new test. Then (Vehtari, Gelman & Gabry 2017, Stat. Comput.
27, 1413, eq. 23-24)
    ELPD = sum_k elpd_k,   SE = sqrt(K * V_k(elpd_k)),
and for two models A, B with paired per-test differences d_k = elpd_k(A) - elpd_k(B)
    dELPD = sum_k d_k,   SE(dELPD) = sqrt(K * V_k(d_k)),
V being the sample variance with divisor K - 1 (the paper's definition; ArviZ divides by K).
With few tests (K = 2 to 5) these SEs are themselves uncertain: |dELPD| > 2 SE is a screen, not
a calibrated test. A level with a single test cannot be cross-validated by test and is
reported as such (elpd None), never with invented numbers.
`n_eff_weights` per test is (sum w)^2 / sum w^2 of the weights w_s = p(y_k | theta_s): when it
is a handful of draws the log-mean is carried by few (autocorrelated) draws and is noisy.

**The held-out test's force offset.** The fits carry one `force_offset` (load-cell zero) shared
by the tests of the fit. Nothing in the other tests tells the zero of a new test: a load cell is
re-zeroed, drifts or is re-mounted between tests. By default (`offset="marginal"`) the held-out
test gets its own offset c, integrated out under a uniform prior on the training fit's
`force_offset` prior box [lo, hi] (density 1/(hi - lo); the fit's own prior there is a normal
truncated to that box, centred on 0 with the records' force asymmetry as sd). Given theta, the
residual e = y - F(theta) - c of the AR(1) noise model has the quadratic form
      Q(c, phi) = (1 - phi^2)(e_0 - c)^2 + sum_{k>=1} ((e_k - phi e_{k-1}) - c (1 - phi))^2
                = Q_min(phi) + A(phi) (c - c_hat(phi))^2,
      A = (1 - phi^2) + (N - 1)(1 - phi)^2,
so c integrates in closed form together with sigma (log-uniform prior on [a, b], integrated over
(0, inf) as noisemodel does) before phi (grid, as in noisemodel); `iid` is phi = 0 (A = N,
Q_min = sum (e - mean e)^2):
      p(e | phi) = pi^(-(N-1)/2) Gamma((N-1)/2) (1 - phi^2)^(1/2) A^(-1/2) Q_min^(-(N-1)/2)
                   / (2 ln(b/a) (hi - lo)) * [T_(N-1)(t_hi) - T_(N-1)(t_lo)],
      t = (c - c_hat) sqrt(A (N-1) / Q_min) at c = lo, hi
(T_nu the Student-t CDF: with sigma integrated out, c given phi is Student-t). With sigma fixed:
(2 pi s^2)^(-(N-1)/2) (1 - phi^2)^(1/2) A^(-1/2) exp(-Q_min / (2 s^2)) / (hi - lo) times the
normal probability of the box, s^2 = sigma^2 (1 - phi^2). The box factor matters only for a
model that needs an offset beyond the prior (e.g. LuGre absorbing backlash misfit into a shifted
zero); sd(c) = s / sqrt(A) is at most the noise sd. The median c_hat of each held-out test is
reported (`heldout_offset`, flagged when outside the box). The box derives from the training
records, not from the model, so 1/(hi - lo) is the same for all models of a fold and cancels in
dELPD. A model is thus judged on the shape of the force it predicts for a new test, not on a
zero it cannot know.
`offset="shared"` instead treats the held-out test's offset as the training posterior's shared
offset (plain LogPosterior.loglik_records on the held-out record), the right choice when the
tests of a level were recorded in one session without re-zeroing. A fixed `force_offset`
(config priors {"force_offset": value}) is known and used as such in either mode.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import logsumexp

from ..errors import InputError
from .likelihood import LogPosterior
from .offsetnoise import log_marginal_offset

OFFSET_MODES = ("marginal", "shared")
BATCH = 512


# ------------------------------------------------------------------ ELPD arithmetic
def log_mean_exp(a) -> float:
    """log((1/S) sum_s exp(a_s)), stably (logsumexp - log S); -inf terms are allowed."""
    a = np.asarray(a, dtype=float).ravel()
    if a.size == 0:
        raise ValueError("log_mean_exp of an empty array")
    return float(logsumexp(a) - math.log(a.size))


def weights_n_eff(a) -> float:
    """(sum w)^2 / sum w^2 of w = exp(a): how many draws carry the log-mean."""
    a = np.asarray(a, dtype=float).ravel()
    if not np.isfinite(np.max(a)):
        return 0.0
    return float(math.exp(2.0 * logsumexp(a) - logsumexp(2.0 * a)))


def elpd_total(elpd_k) -> dict:
    """ELPD = sum of the per-test values and SE = sqrt(K * sample variance), divisor K - 1
    (Vehtari, Gelman & Gabry 2017, eq. 23). Needs K >= 2."""
    e = np.asarray(elpd_k, dtype=float).ravel()
    if e.size < 2:
        raise ValueError("ELPD by held-out tests needs at least 2 tests")
    return {"elpd": float(np.sum(e)), "se": float(math.sqrt(e.size * np.var(e, ddof=1))),
            "n_tests": int(e.size)}


def elpd_difference(elpd_a, elpd_b) -> dict:
    """dELPD = sum_k (a_k - b_k) and its SE from the paired differences (eq. 24)."""
    a = np.asarray(elpd_a, dtype=float).ravel()
    b = np.asarray(elpd_b, dtype=float).ravel()
    if a.shape != b.shape:
        raise ValueError("paired ELPD differences need the same tests for both models")
    t = elpd_total(a - b)
    return {"delta_elpd": t["elpd"], "se": t["se"], "n_tests": t["n_tests"]}


# ------------------------------------------------------------------ held-out likelihood
def heldout_loglik(logpost: LogPosterior, theta: np.ndarray, offset: str = "marginal",
                   offset_box: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """log p(y_held-out | theta_s) for draws theta (S, ndim) of a training fit, on the records of
    `logpost` (built on the held-out record(s) with the training Space). Returns
    (log-likelihood (S, n_records), c_hat (S, n_records); NaN where the offset is not
    marginalised)."""
    theta = np.atleast_2d(theta)
    sp = logpost.space
    S, R = theta.shape[0], len(logpost.records)
    ll = np.empty((S, R))
    ch = np.full((S, R), np.nan)
    if offset not in OFFSET_MODES:
        raise InputError(f"held-out offset must be one of {OFFSET_MODES}, got {offset!r}")
    # a fit with per-test offsets has no shared one to carry over: the held-out test's own
    # zero is integrated out whatever `offset` says
    marginal = sp.per_test_offset or (offset == "marginal" and "force_offset" in sp.priors)
    for i in range(0, S, BATCH):
        th = theta[i:i + BATCH]
        if not marginal:
            ll[i:i + BATCH] = logpost.loglik_records(th)
            continue
        lo, hi = offset_box or sp.offset_box or (sp.priors["force_offset"].lower,
                                                 sp.priors["force_offset"].upper)
        for j, rec in enumerate(logpost.records):
            e = rec.y[None, :] - logpost.simulate(th, rec)
            ll[i:i + BATCH, j], ch[i:i + BATCH, j] = log_marginal_offset(
                e, offset_box=(lo, hi), **logpost.noise)
    ll = np.where(np.isnan(ll), -np.inf, ll)
    return ll, ch
