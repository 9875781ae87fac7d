"""Do the tests of a joint fit share one force zero? A check of the fit's own noise model.

A joint fit carries one `force_offset` (load-cell zero) for all its tests. If the zero moved
between tests (re-zeroed, drifted, re-mounted), every test's residual keeps a constant part
that no friction parameter can take up: each plateau of a test sits above or below the model
by the same amount in both directions. On the ARTS dataset 2 36 lb sines (2026-12-02,
docs/log-calibration.md) the per-test mean residuals ran from -1.9 to +1.2 kN, ordered by the
sines' amplitude, where the fit's own noise model allows about 0.25 kN.

Statistic. Test j's mean residual m_j = mean(y - median noise-free prediction) over its n_j
kept samples. Under the fit's noise model (marginal sd sigma_j, lag-1 correlation phi_j, MA
coefficient theta_j of `arma`; their posterior medians) the mean of n_j samples of that
stationary process has variance LRV_j / n_j for long records, with the long-run variance

    LRV = sigma^2 (1 - phi^2) (1 + theta)^2 / ((1 + 2 phi theta + theta^2) (1 - phi)^2)

(sigma^2 (1 + phi) / (1 - phi) for AR(1)); under the `chatter` noise effect sigma is scaled by
the record's rms noise gain. With se_j = sqrt(LRV_j / n_j) and the precision-weighted mean
m_w, X^2 = sum_j ((m_j - m_w) / se_j)^2 is chi-square with K - 1 degrees of freedom if the
tests share their zero and the noise model holds (one degree goes to the shared offset, which
the fit adjusts). Significant at ALPHA: the zero (or something else constant per test) differs
between tests beyond the noise, and a shared-offset fit's bands for a new test are too narrow by
about the spread of the m_j. False alarms: ALPHA when the noise model holds (checked by
simulation in tests/test_infer_between.py); a noise model that understates the long-run
variance (a misfit slower than the AR(1)'s correlation) raises it, so the spread of the m_j in
newtons is reported beside the p-value. A single-test fit, or one with per-test offsets
(FitConfig.force_offset = "per_test"), has nothing to compare (None).
"""
from __future__ import annotations

import numpy as np
from scipy import stats

ALPHA = 0.01
METHOD = ("per-test mean residual against the fit's noise model: chi-square with K - 1 degrees "
          "of freedom of (m_j - precision-weighted mean) / se_j, se_j from the noise's long-run "
          "variance")


def long_run_variance(sigma, phi, theta=0.0) -> np.ndarray:
    """Long-run variance (N^2) of a stationary ARMA(1,1) with marginal sd sigma (module docstring)."""
    sigma, phi, theta = (np.asarray(v, float) for v in (sigma, phi, theta))
    return sigma**2 * (1 - phi**2) * (1 + theta) ** 2 / ((1 + 2 * phi * theta + theta**2) * (1 - phi) ** 2)


def offset_check(tests: list[str], means, n, sigma, phi, theta=None, alpha: float = ALPHA) -> dict | None:
    """The check of the module docstring from per-test mean residuals `means` (N), sample counts
    `n` and noise parameters; None for fewer than two tests. JSON-ready."""
    K = len(tests)
    if K < 2:
        return None
    m, n = np.asarray(means, float), np.asarray(n, float)
    theta = np.zeros(K) if theta is None else np.asarray(theta, float)
    se = np.sqrt(long_run_variance(sigma, phi, theta) / n)
    w = 1.0 / se**2
    mw = float(np.sum(w * m) / np.sum(w))
    x2 = float(np.sum(((m - mw) / se) ** 2))
    p = float(stats.chi2.sf(x2, K - 1))
    return {"mean_residual_N": dict(zip(tests, map(float, m))),
            "se_N": dict(zip(tests, map(float, se))),
            "spread_N": float(np.std(m, ddof=1)), "chi2": x2, "df": K - 1, "p_value": p,
            "alpha": float(alpha), "significant": bool(p <= alpha), "method": METHOD}


def check_fit(logpost, post, pred) -> dict | None:
    """offset_check of a fit: its records' residuals against the posterior median noise-free
    prediction (outputs.predictive) and the posterior medians of each record's noise parameters."""
    recs = logpost.records
    R = len(recs)
    if R < 2 or logpost.space.per_test_offset:     # each test has its own zero: nothing to check
        return None
    sig = np.median(np.asarray(post["sigma_noise"], float).reshape(-1, R), axis=0)
    phi = np.median(np.asarray(post["noise_phi"], float).reshape(-1, R), axis=0)
    gain = np.ones(R)
    th = post["theta"].reshape(-1, post["theta"].shape[-1])
    centre = np.median(th, axis=0)[None, :]
    for j in range(R):
        g = logpost.noise_gain(centre, j)
        if g is not None:
            gain[j] = float(np.sqrt(np.mean(g**2)))
    means = [float(np.mean(rec.y - np.median(F, axis=0))) for rec, F in zip(recs, pred["model"])]
    return offset_check([r.id for r in recs], means, [r.n for r in recs], sig * gain, phi,
                        [r.noise_theta for r in recs])
