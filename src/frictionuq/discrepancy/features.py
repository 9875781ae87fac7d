"""Per-sample features of a record: the axes against which the residual diagnostics look for
structure (frictionuq.discrepancy.diagnostics).

Every feature is a plain numpy array with one value per sample, in SI (see `FEATURE_UNITS`):

* `displacement` (m): x itself.
* `velocity` (m/s): `np.gradient(x, t)` (central differences inside, one-sided at both ends:
  the spec's sample velocity on a uniform record).
* `time` (s): t itself.
* `cycle` (1): the number of complete cycles before the sample: reversals seen so far by the
  kernel's detector with dead-band eps (frictionuq.noise.reversal_indices, spec section 4),
  integer-divided by 2. A 5-cycle sine that starts at x = 0 ends at cycle 5.
* `since_reversal` (m): travel since the last reversal, the spec's
  `s = max(0, d*(x[k] - x_r))` with `x_r = x[r-1]` at a reversal detected at sample r and
  `x_r = x[0]` before the first one (the `s` of `reversal_hump` and of the backlash line).
* `energy` (J): energy dissipated before the sample, the spec's E of `thermal_fade`:
  `E[k] = sum over j<k of abs(F[j]*(x[j+1]-x[j]))`, with F the model force (E[0] = 0).
  Omitted when no model force is given.
* `applied` (N, or Pa for a pressure-driven device): the record's measured applied-force channel,
  when given.
* `direction` (+1/-1): the detector's direction of motion d. Not a view of its own: the
  diagnostics bin every view separately per direction, because every friction effect of the
  library changes the force by d times something (friction opposes motion).
"""
from __future__ import annotations

import numpy as np

from ..noise import reversal_state, since_reversal_from

FEATURE_UNITS: dict[str, str] = {
    "displacement": "m",
    "velocity": "m/s",
    "time": "s",
    "cycle": "1",
    "since_reversal": "m",
    "energy": "J",
    "applied": "N",
    "direction": "1",
}


def dissipated_energy(x, force) -> np.ndarray:
    """E[k] = sum over j<k of |F[j] (x[j+1]-x[j])| (J): the spec's thermal_fade energy."""
    x = np.asarray(x, dtype=float)
    f = np.asarray(force, dtype=float)
    if f.shape != x.shape:
        raise ValueError(f"force_model and x differ in length ({f.size} vs {x.size})")
    return np.concatenate(([0.0], np.cumsum(np.abs(f[:-1] * np.diff(x)))))


def features(t, x, force_model, eps: float = 0.0, applied=None) -> dict[str, np.ndarray]:
    """The per-sample features of a record (SI, see the module docstring).

    t, x: times (s) and displacement (m); force_model: the model force (N) along the record
    (e.g. the posterior predictive median), used for `energy` (None: no `energy` feature);
    eps: the reversal dead-band (m) of the fit; applied: the measured applied-force channel."""
    t = np.asarray(t, dtype=float)
    x = np.asarray(x, dtype=float)
    if t.ndim != 1 or t.shape != x.shape:
        raise ValueError(f"t and x must be 1-D arrays of one length, got {t.shape} and {x.shape}")
    if t.size < 3:
        raise ValueError(f"need at least 3 samples, got {t.size}")
    if not np.all(np.diff(t) > 0):
        raise ValueError("time is not strictly increasing")
    d, x_r, n_rev = reversal_state(x, eps)
    out = {
        "displacement": x.copy(),
        "velocity": np.gradient(x, t),
        "time": t.copy(),
        "cycle": (n_rev // 2).astype(float),
        "since_reversal": since_reversal_from(x, d, x_r),
    }
    if force_model is not None:
        out["energy"] = dissipated_energy(x, force_model)
    if applied is not None:
        a = np.asarray(applied, dtype=float)
        if a.shape != x.shape:
            raise ValueError(f"applied and x differ in length ({a.size} vs {x.size})")
        out["applied"] = a.copy()
    out["direction"] = d
    return out
