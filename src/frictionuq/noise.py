"""The reversal dead-band of measured records: a displacement-noise estimator and the default
`eps` derived from it.

Estimator. For a record sampled finely relative to its motion, the k-th order difference of the
displacement is dominated by the noise: the signal's k-th difference scales as
A (2 pi f dt)^k (for a 1 Hz, 25 mm sine at 1024 Hz and k = 4: 3e-11 m), while white noise of
standard deviation sigma gives a k-th difference of variance C(2k, k) sigma^2. We take k = 4 and
a robust scale (1.4826 x the median absolute deviation, insensitive to the few samples where
the motion itself is rough):

    sigma_x = 1.4826 * MAD(diff(x, 4)) / sqrt(C(8, 4))          (C(8, 4) = 70)

On the ARTS Lab records (1024 Hz, quantised displacement) this gives 1.3-1.6 um on every test,
consistent across orders k = 3..5 and with the standard deviation of the quiescent segments.
Where the record is coarsely sampled relative to its content (k-th differences of the signal no
longer negligible), the estimate is biased high and the dead-band is conservative.

Default dead-band. eps = 8 sigma_x. Counting the reversals the kernel's detector sees on all 29
real ARTS records (see tests/test_noise.py and docs/model-choices.md): at 0 x sigma every noise
wiggle is a reversal (55-2300 per test instead of 14-19), at 4 sigma up to 5 x too many remain,
from 8 sigma on the count equals that of the heavily smoothed record on every sine test and is
stable up to 40 sigma. 8 sigma (about 10-13 um there) is negligible against the backlash
lengths (mm), so detecting a reversal eps late costs nothing measurable.
Clean simulated inputs have sigma_x ~ 0 and keep eps ~ 0.
"""
from __future__ import annotations

from math import comb, sqrt

import numpy as np
from numba import njit
from scipy.signal import lfilter

ORDER = 4
EPS_MULTIPLIER = 8.0


def amplitude(x) -> float:
    """A displacement record's amplitude (m): the largest |x - median x| (half the stroke of a
    centred sine; 0 for an empty record). The priors' length scale, the extrapolation check's
    reach, the cycles' dead band and the input plausibility check all read it."""
    x = np.asarray(x, float)
    return float(np.max(np.abs(x - np.median(x)))) if x.size else 0.0


def displacement_noise_sd(x, where: str | None = None) -> float:
    """Robust estimate (m) of the standard deviation of the noise on displacement record x.
    where: what the record is ("test h1"), named in the error of a record too short for it."""
    x = np.asarray(x, dtype=float)
    if x.size < ORDER + 10:
        from .errors import InputError
        raise InputError(f"{where + ': ' if where else ''}need at least {ORDER + 10} samples to "
                         f"estimate displacement noise, got {x.size}")
    d = np.diff(x, ORDER)
    mad = np.median(np.abs(d - np.median(d)))
    return float(1.4826 * mad / sqrt(comb(2 * ORDER, ORDER)))


def default_eps(x, multiplier: float = EPS_MULTIPLIER, where: str | None = None) -> float:
    """Default reversal dead-band (m) for a measured record: `multiplier` x the noise sd."""
    return multiplier * displacement_noise_sd(x, where)


@njit(cache=True)
def first_direction(x):
    """The direction of the first motion of x (+1 or -1; +1 for a constant record), as the
    kernel starts its detector."""
    for j in range(1, x.shape[0]):
        if x[j] != x[0]:
            return 1.0 if x[j] > x[0] else -1.0
    return 1.0


@njit(cache=True)
def reversal_indices(x, eps):
    """Sample indices at which the kernel's detector (spec section 4) sees a reversal of x with
    dead-band eps."""
    out = np.empty(x.shape[0], dtype=np.int64)
    d = first_direction(x)
    x_ext = x[0]
    n = 0
    for k in range(1, x.shape[0]):
        if d * (x[k] - x_ext) > 0.0:
            x_ext = x[k]
        elif d * (x_ext - x[k]) > eps:
            d = -d
            x_ext = x[k]
            out[n] = k
            n += 1
    return out[:n]


def initial_direction(x: np.ndarray) -> float:
    """The spec's initial d: sign of the first nonzero x[j] - x[0] (+1 if none)."""
    moved = np.flatnonzero(x != x[0])
    return 1.0 if moved.size == 0 or x[moved[0]] > x[0] else -1.0


def reversal_state(x, eps: float = 0.0):
    """(direction d, reversal point x_r, number of reversals so far) at every sample, as the
    kernel's detector (spec section 4) sees them with dead-band eps."""
    x = np.ascontiguousarray(np.asarray(x, dtype=float))
    rev = reversal_indices(x, float(eps))
    k = np.arange(x.size)
    n_rev = np.searchsorted(rev, k, side="right")          # reversals at or before sample k
    d = initial_direction(x) * np.where(n_rev % 2 == 0, 1.0, -1.0)
    x_r = np.concatenate(([x[0]], x[rev - 1]))[n_rev]
    return d, x_r, n_rev


def since_reversal_from(x, d, x_r) -> np.ndarray:
    """The spec's s (>= 0) from reversal_state's direction d and reversal point x_r."""
    return np.maximum(0.0, d * (np.asarray(x, dtype=float) - x_r))


def since_reversal(x, eps: float = 0.0) -> np.ndarray:
    """Travel since the last reversal (m) at every sample, the spec's s (>= 0)."""
    d, x_r, _ = reversal_state(x, eps)
    return since_reversal_from(x, d, x_r)


def chatter_gain(s, a, s0, w, b=0.0) -> np.ndarray:
    """The `chatter` noise effect's sd multiplier g(s) = sqrt(1 + a h(s)) for rows of
    parameters a, s0, w, b (W,) at travels s (N,): (W, N). The window h is the bump
    exp(-(s - s0)^2 / (2 w^2)) up to its centre s0 and b + (1 - b) times the bump after it:
    with b = 0 a bump, with b > 0 a rise that keeps the fraction b of its peak until the next
    reversal (the real ARTS chatter rises at the end of the take-up and stays up:
    docs/model-choices.md, "chatter"). h is continuous with a continuous slope at s0."""
    a, s0, w, b = (np.asarray(v, dtype=float).reshape(-1, 1) for v in (a, s0, w, b))
    s = np.asarray(s, dtype=float)[None, :]
    z = (s - s0) / w
    bump = np.exp(-0.5 * z * z)
    h = np.where(s > s0, b + (1.0 - b) * bump, bump)
    return np.sqrt(1.0 + a * h)


def count_reversals(x, eps) -> int:
    """Number of reversals the kernel's detector sees in x with dead-band eps."""
    return int(reversal_indices(np.asarray(x, dtype=float), float(eps)).size)


def ar1_from_normals(z, phi, sd) -> np.ndarray:
    """Stationary AR(1) paths along the last axis of standard normals `z` (..., n): marginal sd
    `sd`, lag-1 correlation `phi` (scalars, or one per path: shape z.shape[:-1]).
    y[0] = sd z[0], y[k] = phi y[k-1] + sd sqrt(1 - phi^2) z[k]. The caller draws `z`, so its
    random stream (and draw order) stays its own."""
    z = np.array(z, dtype=float)
    phi_a, sd_a = np.broadcast_to(phi, z.shape[:-1]), np.broadcast_to(sd, z.shape[:-1])
    out = np.empty_like(z)
    for idx in np.ndindex(z.shape[:-1]):
        ph, s = float(phi_a[idx]), float(sd_a[idx])
        c = s * np.sqrt(1.0 - ph * ph)
        e = z[idx].copy()
        e[0] /= np.sqrt(1.0 - ph * ph)
        out[idx] = lfilter([c], [1.0, -ph], e)
    return out


@njit(cache=True)
def reversal_flags(x, eps):
    """uint8 flags (length of x) of the reversals of the kernel's detector with dead band eps,
    each placed at the sample after its extreme instead of where the detector sees it (eps of
    travel later): the kernel's `rev` for the "extreme" reversal rule. With eps = 0 the two
    places coincide. On a recorded (offline) record the extreme is known once the detector has
    fired, so the backlash can start where the motion turned; the causal rule starts it eps
    late, after the model has run LuGre pre-sliding backwards over the dead band
    (docs/model-choices.md, "Reversals at the extreme")."""
    n = x.shape[0]
    out = np.zeros(n, dtype=np.uint8)
    d = first_direction(x)
    x_ext = x[0]
    j_ext = 0                      # the last sample at the extreme (the detector keeps the first
    for k in range(1, n):          # sample strictly beyond; equal values extend the plateau)
        if d * (x[k] - x_ext) > 0.0:
            x_ext = x[k]
            j_ext = k
        elif x[k] == x_ext:
            j_ext = k
        elif d * (x_ext - x[k]) > eps:
            out[j_ext + 1] = 1
            d = -d
            x_ext = x[k]
            j_ext = k
    return out

