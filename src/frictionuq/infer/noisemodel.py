"""The measurement-noise model of one record, with its nuisance parameters integrated out.

Residual e = y - F_model - force_offset of a record of N samples is Gaussian: independent with sd
sigma_noise (`iid`), or a stationary AR(1) process with marginal sd sigma_noise and lag-1
correlation noise_phi (`ar1`). Every record has its own sigma_noise and noise_phi (records are
decimated by different factors and carry different misfit), and both are *integrated out*
instead of sampled, which keeps the sampler's dimension at the model's:

* sigma: log-uniform prior (p(s) ~ 1/s on the innovation sd s = sigma sqrt(1 - phi^2)); the
  integral over s is closed-form,
      p(e | phi) = pi^(-N/2) Gamma(N/2) (1 - phi^2)^(1/2) Q(phi)^(-N/2) / (2 ln(b/a)),
  with Q(phi) = S0 - 2 phi S1 + phi^2 (S2 - e0^2), S0 = sum e_k^2, S1 = sum e_k e_(k-1),
  S2 = sum_(k<N-1) e_k^2. (The prior's bounds [a, b] enter only through the constant; the
  integral over (0, inf) equals the bounded one whenever the conditional posterior of sigma lies
  well inside them, which `draw_noise` lets the fit check.)
* phi: uniform prior on [0, phi_max]; integrated numerically on a grid that is uniform in
  u = -ln(1 - phi) (dense near 1, where the conditional posterior is narrow).
Either can instead be fixed by the configuration. After sampling, `draw_noise` draws sigma_noise
and noise_phi from their exact conditional posterior for every posterior draw.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln, logsumexp

PHI_MAX = 0.999
_U = np.linspace(0.0, -math.log(1.0 - PHI_MAX), 600)
PHI_GRID = 1.0 - np.exp(-_U)
# uniform prior on phi: weight of each grid point = d phi = (1 - phi) du, normalised by phi_max
_LOG_W = np.log((1.0 - PHI_GRID) * (_U[1] - _U[0]) / PHI_MAX)
_LOG_W[[0, -1]] += math.log(0.5)              # trapezoid end points


def suff_stats(e: np.ndarray):
    """Sufficient statistics of residuals e (W, N): S0, S1, S2, e0^2 (each (W,))."""
    S0 = np.einsum("ij,ij->i", e, e)
    S1 = np.einsum("ij,ij->i", e[:, 1:], e[:, :-1])
    e_last = e[:, -1] ** 2
    e0sq = e[:, 0] ** 2
    return S0, S1, S0 - e_last, e0sq


def _Q(S0, S1, S2, e0sq, phi):
    return S0 - 2 * phi * S1 + phi**2 * (S2 - e0sq)


def log_marginal(e: np.ndarray, kind: str, sigma_bounds: tuple[float, float],
                 sigma_fixed: float | None = None, phi_fixed: float | None = None) -> np.ndarray:
    """log p(e | model) with the record's noise parameters integrated out (or fixed). (W,)"""
    W, N = e.shape
    S0, S1, S2, e0sq = suff_stats(e)
    if kind == "iid":
        phi_fixed = 0.0
    if phi_fixed is not None:
        phis = np.array([phi_fixed])
        logw = np.array([0.0])
    else:
        phis, logw = PHI_GRID, _LOG_W
    Q = _Q(S0[:, None], S1[:, None], S2[:, None], e0sq[:, None], phis[None, :])
    Q = np.maximum(Q, 1e-300)
    if sigma_fixed is None:
        a, b = sigma_bounds
        const = -0.5 * N * math.log(math.pi) + gammaln(0.5 * N) - math.log(2 * math.log(b / a))
        lp = const + 0.5 * np.log1p(-phis[None, :] ** 2) - 0.5 * N * np.log(Q)
    else:
        s2 = sigma_fixed**2 * (1 - phis[None, :] ** 2)
        lp = (-0.5 * N * math.log(2 * math.pi) - 0.5 * N * np.log(s2)
              + 0.5 * np.log1p(-phis[None, :] ** 2) - Q / (2 * s2))
    return logsumexp(lp + logw[None, :], axis=1)


def draw_noise(e: np.ndarray, kind: str, rng: np.random.Generator,
               sigma_fixed: float | None = None, phi_fixed: float | None = None):
    """One draw of (sigma_noise, noise_phi) per row of residuals e (W, N) from their conditional
    posterior given the model parameters."""
    W, N = e.shape
    S0, S1, S2, e0sq = suff_stats(e)
    if kind == "iid":
        phi_fixed = 0.0
    if phi_fixed is not None:
        phi = np.full(W, float(phi_fixed))
    else:
        Q = np.maximum(_Q(S0[:, None], S1[:, None], S2[:, None], e0sq[:, None], PHI_GRID[None, :]), 1e-300)
        if sigma_fixed is None:
            lp = 0.5 * np.log1p(-PHI_GRID[None, :] ** 2) - 0.5 * N * np.log(Q)
        else:
            s2 = sigma_fixed**2 * (1 - PHI_GRID[None, :] ** 2)
            lp = -0.5 * N * np.log(s2) + 0.5 * np.log1p(-PHI_GRID[None, :] ** 2) - Q / (2 * s2)
        lp = lp + _LOG_W[None, :]
        p = np.exp(lp - lp.max(axis=1, keepdims=True))
        c = np.cumsum(p, axis=1)
        u = rng.random(W) * c[:, -1]
        k = np.array([np.searchsorted(c[i], u[i]) for i in range(W)])
        # jitter within the grid cell (uniform in u) for a continuous draw
        du = _U[1] - _U[0]
        uu = np.clip(_U[k] + (rng.random(W) - 0.5) * du, 0.0, _U[-1])
        phi = 1.0 - np.exp(-uu)
    if sigma_fixed is not None:
        return np.full(W, float(sigma_fixed)), phi
    Q = np.maximum(_Q(S0, S1, S2, e0sq, phi), 1e-300)
    # s^2 | phi ~ Inverse-Gamma(N/2, Q/2)
    s2 = (Q / 2) / rng.gamma(0.5 * N, 1.0, size=W)
    return np.sqrt(s2 / (1 - phi**2)), phi
