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

ARMA(1,1) (`arma`): e_k - phi e_(k-1) = a_k + theta a_(k-1), the exact correlation structure of
an AR(1) process plus white noise (the usual make-up of a load cell's noise plus a slowly
wandering misfit; then -phi < theta <= 0). With theta given, the prefiltered residuals
g_k = e_k - theta g_(k-1) (`prefilter`, g_0 = e_0) are AR(1) in phi with innovations a_k, and
the transform has unit Jacobian, so everything above applies to g unchanged. theta is a
per-record noise-shape constant estimated once at the MAP (`estimate_theta`: it is determined to
about 1/sqrt(N), a few hundredths for records of thousands of samples, and integrating it out
would need an O(N) filter pass per grid point); the fit records it. sigma_noise is then reported
as the marginal sd of e (`marginal_sd`), and `split_ar1_white` turns (sigma_noise, phi, theta)
back into the AR(1) and white components for simulating the noise at another sample rate.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import lfilter
from scipy.special import gammaln

PHI_MAX = 0.999
_U = np.linspace(0.0, -math.log(1.0 - PHI_MAX), 600)
PHI_GRID = 1.0 - np.exp(-_U)
# uniform prior on phi: weight of each grid point = d phi = (1 - phi) du, normalised by phi_max
_LOG_W = np.log((1.0 - PHI_GRID) * (_U[1] - _U[0]) / PHI_MAX)
_LOG_W[[0, -1]] += math.log(0.5)              # trapezoid end points


#: range of the MA coefficient theta searched by estimate_theta: AR(1) plus white noise has
#: -phi < theta <= 0; -0.95 keeps the prefilter's memory (about 1/(1 - |theta|) samples) short
THETA_BOUNDS = (-0.95, 0.0)


def prefilter(e: np.ndarray, theta: float) -> np.ndarray:
    """g_k = e_k - theta g_(k-1) along the last axis (g_0 = e_0): ARMA(1,1) residuals with MA
    coefficient theta -> AR(1) residuals (module docstring). theta = 0 returns e itself."""
    if theta == 0.0:
        return e
    return lfilter([1.0], [1.0, float(theta)], e, axis=-1)


def estimate_theta(e: np.ndarray, sigma_bounds: tuple[float, float], sigma_fixed: float | None = None,
                   phi_fixed: float | None = None) -> float:
    """The MA coefficient theta in THETA_BOUNDS maximising the ARMA(1,1) marginal likelihood of
    residuals e (N,), sigma and phi integrated out (or fixed) as in log_marginal."""
    e = np.asarray(e, dtype=float)[None, :]

    def nll(th):
        v = log_marginal(prefilter(e, th), "ar1", sigma_bounds, sigma_fixed, phi_fixed)[0]
        return -v if np.isfinite(v) else 1e300
    r = minimize_scalar(nll, bounds=THETA_BOUNDS, method="bounded", options={"xatol": 1e-4})
    th = float(r.x)
    # the bounded search never evaluates the end points; the AR(1) end (theta = 0) is the
    # nested model and must win when it is at least as good
    return 0.0 if nll(0.0) <= r.fun else th


def marginal_sd(sigma_g, phi, theta):
    """Marginal sd of ARMA(1,1) noise e from the marginal sd sigma_g of its AR(1) prefiltered
    series g (innovation sd sigma_g sqrt(1 - phi^2)): var e = var g (1 + 2 phi theta + theta^2)."""
    return np.asarray(sigma_g) * np.sqrt(1.0 + 2.0 * np.asarray(phi) * theta + np.asarray(theta) ** 2)


def split_ar1_white(sigma, phi, theta):
    """(sd of the AR(1) component, sd of the white component) of ARMA(1,1) noise with marginal
    sd sigma, AR coefficient phi and MA coefficient theta, read as AR(1) + white noise: the
    innovation variance is s_a^2 = sigma^2 (1 - phi^2) / (1 + 2 phi theta + theta^2) and the
    white variance -theta s_a^2 / phi (clipped to [0, sigma^2]: outside -phi < theta <= 0 the
    process has no such decomposition). theta = 0 gives (sigma, 0)."""
    sigma, phi, theta = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (sigma, phi, theta)))
    s2 = sigma**2
    with np.errstate(divide="ignore", invalid="ignore"):
        sa2 = s2 * (1.0 - phi**2) / (1.0 + 2.0 * phi * theta + theta**2)
        w2 = np.where(theta < 0, -theta * sa2 / np.maximum(phi, 1e-12), 0.0)
    w2 = np.clip(np.nan_to_num(w2, nan=0.0, posinf=0.0), 0.0, s2)
    return np.sqrt(s2 - w2), np.sqrt(w2)


def noise_paths(sd_ar, phi, sd_white, n: int, rng: np.random.Generator) -> np.ndarray:
    """Noise paths (S, n): stationary AR(1) of marginal sd sd_ar (S,) and coefficient phi (S,),
    plus white noise of sd sd_white (S,) (drawn only when some is nonzero); the two components
    of split_ar1_white."""
    from ..noise import ar1_from_normals
    sd_white = np.asarray(sd_white, float)
    out = ar1_from_normals(rng.standard_normal((np.size(sd_ar), n)), phi, sd_ar)
    if np.any(sd_white > 0):
        out += sd_white[:, None] * rng.standard_normal(out.shape)
    return out


STATS = ("S0", "S1", "S2", "e0sq")      # suff_stats, in this order


def suff_stats(e: np.ndarray):
    """Sufficient statistics of residuals e (W, N): S0, S1, S2, e0^2 (each (W,))."""
    S0 = np.einsum("ij,ij->i", e, e)
    S1 = np.einsum("ij,ij->i", e[:, 1:], e[:, :-1])
    e_last = e[:, -1] ** 2
    e0sq = e[:, 0] ** 2
    return S0, S1, S0 - e_last, e0sq


def _Q(S0, S1, S2, e0sq, phi):
    return S0 - 2 * phi * S1 + phi**2 * (S2 - e0sq)


def _logsumexp_rows(a: np.ndarray) -> np.ndarray:
    """log sum exp over each row of a (W, K); -inf for a row of -inf. scipy.special.logsumexp
    does the same with array-API dispatch that cost 0.26 ms a call, 8 % of an MCMC step."""
    m = np.max(a, axis=1, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        return m[:, 0] + np.log(np.sum(np.exp(a - m), axis=1))


def log_marginal(e: np.ndarray, kind: str, sigma_bounds: tuple[float, float],
                 sigma_fixed: float | None = None, phi_fixed: float | None = None) -> np.ndarray:
    """log p(e | model) with the record's noise parameters integrated out (or fixed). (W,)"""
    return log_marginal_stats(suff_stats(e), e.shape[1], kind, sigma_bounds, sigma_fixed, phi_fixed)


def log_marginal_stats(stats, N: int, kind: str, sigma_bounds: tuple[float, float],
                       sigma_fixed: float | None = None, phi_fixed: float | None = None) -> np.ndarray:
    """log_marginal from the residuals' sufficient statistics (suff_stats) and their length N."""
    S0, S1, S2, e0sq = stats
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
    return _logsumexp_rows(lp + logw[None, :])


def draw_noise(e: np.ndarray, kind: str, rng: np.random.Generator,
               sigma_fixed: float | None = None, phi_fixed: float | None = None):
    """One draw of (sigma_noise, noise_phi) per row of residuals e (W, N) from their conditional
    posterior given the model parameters."""
    return draw_noise_stats(suff_stats(e), e.shape[1], kind, rng, sigma_fixed, phi_fixed)


def draw_noise_stats(stats, N: int, kind: str, rng: np.random.Generator,
                     sigma_fixed: float | None = None, phi_fixed: float | None = None):
    """draw_noise from the residuals' sufficient statistics (suff_stats, each (W,)) and length N:
    the sampler stores them with every step, so the draws need no second simulation."""
    S0, S1, S2, e0sq = (np.asarray(a, float) for a in stats)
    W = S0.shape[0]
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
