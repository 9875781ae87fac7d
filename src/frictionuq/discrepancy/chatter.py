"""High-frequency bursts in the residual: where along the travel since a reversal does the
residual carry oscillation that the model, and the residual's own repeatable shape, do not?

Stick-slip chatter (the real ARTS loops; "chattering in the device" at the higher frequencies in
both papers' model validations) is a fast oscillation of the force after the take-up whose phase
changes from cycle to cycle. A deterministic model cannot follow it, and the residual views of
frictionuq.discrepancy.diagnostics average it away (a bin mean of an oscillation with a random
phase is about 0). What it leaves is *power*: the residual's high-frequency power is larger at
some travels since the reversal than at others.

The burst signal of a record:

1. the residual minus its per-direction means is high-passed (Butterworth, order 4, forward and
   backward) at HF_FACTOR x the drive frequency f_drive (the frequency below which 99 % of the
   velocity power lies): the loop's own shape lives below it, chatter above (the measured force
   of the ARTS 0.5-1 Hz sines has its largest power above 10 Hz at 10.5-15 Hz);
2. its repeatable part is removed: the mean of the high-passed residual in each of LOCK_BINS
   quantile bins of the travel since the reversal, per direction (`power`). A misfit that
   recurs at the same travel after every reversal (a take-up corner one sample off) is the
   residual views' business; what is left changes from cycle to cycle;
3. h = its square, the local high-frequency power (N^2).

The statistic is the partial correlation ratio of h over the since_reversal bins of the views
(per direction, direction means removed, as diagnostics' T), and its null the same random-cut
block permutations that the views use, applied to the high-passed residual (step 1 runs once),
with steps 2 and 3 repeated on each permuted copy: under the null (the residual a stationary
short-memory process) the power does not depend on the travel since the reversal. Reported:
the statistic and p-value (in the views' Holm family), the band, the bin of the largest power
(its travel range and its rms against the record's), and the bin profile for the figure.
`None` when the record is too coarse for the band (HF_FACTOR x f_drive above 0.4 x the
sampling rate) or has no reversal.

Only for records whose half-cycles repeat (sines, ramped sines): step 2 removes a misfit that
is a function of the travel only because the filtered misfit is one too when every half-cycle
traverses the same travels. On a ground-motion replay with many small reversals a misfit that
switches sign at every reversal (a hidden reversal_hump's, on the Kobe replay of a hidden
campaign) becomes high-frequency power near s = 0 that step 2 cannot remove: flagged at p =
0.001. Removing the repeated part before the filter as well fixes that but, done once on the
observed residual, breaks the null (13.5 % of p <= 0.05 on AR(1) noise). So discover skips
the test on earthquake records (diagnose(bursts=False)).
"""
from __future__ import annotations

import numpy as np

from .nullperm import row_bincount

HF_FACTOR = 8.0
LOCK_BINS = 64
MAX_BAND = 0.4          # of the sampling rate


def drive_frequency(t, x) -> float:
    """The frequency (Hz) below which 99 % of the velocity power of x lies."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    dt = float(np.median(np.diff(t)))
    v = np.gradient(x, t)
    P = np.abs(np.fft.rfft(v - v.mean())) ** 2
    f = np.fft.rfftfreq(v.size, dt)
    c = np.cumsum(P)
    if c[-1] <= 0:
        return float("nan")
    return float(f[min(int(np.searchsorted(c, 0.99 * c[-1])), f.size - 1)])


def highpass(t, x, rc):
    """(high-passed residual, f_cut in Hz) of the module docstring's step 1, or None when the
    band does not fit the record. rc: the residual minus its per-direction means."""
    from scipy.signal import butter, sosfiltfilt
    t = np.asarray(t, float)
    if t.size < 64:
        return None
    fs = 1.0 / float(np.median(np.diff(t)))
    f_cut = HF_FACTOR * drive_frequency(t, x)
    if not np.isfinite(f_cut) or f_cut <= 0 or f_cut >= MAX_BAND * fs:
        return None
    return sosfiltfilt(butter(4, f_cut, "highpass", fs=fs, output="sos"), np.asarray(rc, float)), f_cut


def lock_cells(up, s) -> tuple[np.ndarray, np.ndarray]:
    """(cell of each sample, samples per cell): LOCK_BINS quantile bins of the travel since the
    reversal s, per direction (up: 1 forward, 0 backward), for step 2."""
    s = np.asarray(s, float)
    cell = np.zeros(s.size, np.int64)
    for direction in (0, 1):
        m = up == direction
        if not m.any():
            continue
        edges = np.unique(np.quantile(s[m], np.linspace(0.0, 1.0, LOCK_BINS + 1)))
        cell[m] = np.searchsorted(edges[1:-1], s[m], side="right") + direction * LOCK_BINS
    return cell, np.bincount(cell, minlength=2 * LOCK_BINS).astype(float)


def power(hp, cell, count) -> np.ndarray:
    """Step 3: the square of hp minus its mean in each lock cell (hp 1-D, or one copy per row). The null applies it to each
    block-permuted hp in turn (removing the cell means of the observed hp only, and permuting the
    result, gave 14.5 % of p-values <= 0.05 on AR(1) noise, phi = 0.9; computed per permutation,
    the test is calibrated: chatter tests in tests/test_discrepancy_diagnostics.py)."""
    hp = np.asarray(hp, float)
    if hp.ndim == 2:            # one permuted copy per row (nullperm: the same sums per row)
        means = row_bincount(cell, hp, count.size) / np.maximum(count, 1.0)
        u = hp - means[:, cell]
    else:
        means = np.bincount(cell, weights=hp, minlength=count.size) / np.maximum(count, 1.0)
        u = hp - means[cell]
    return u * u


def result(h_obs_stat, h_null, null_rms_q95, h, f_cut, s_bin, n_bins_used, s_feature, up) -> dict:
    """The JSON-ready part of diagnose's output for the bursts (before the Holm correction);
    null_rms_q95: per since_reversal bin, the 95 % quantile of the permuted copies' rms (N)."""
    n_perm = h_null.size
    with np.errstate(invalid="ignore", divide="ignore"):
        n_b = np.bincount(s_bin, minlength=n_bins_used).astype(float)
        mean_b = np.bincount(s_bin, weights=h, minlength=n_bins_used) / n_b
        centre = np.bincount(s_bin, weights=s_feature, minlength=n_bins_used) / n_b
        per_dir = {}
        for name, direction in (("rms_fwd", 1), ("rms_bwd", 0)):
            m = up == direction
            nb = np.bincount(s_bin[m], minlength=n_bins_used).astype(float)
            per_dir[name] = np.where(nb >= 10, np.sqrt(np.bincount(s_bin[m], weights=h[m],
                                                                   minlength=n_bins_used) / nb), np.nan)
    k = int(np.nanargmax(mean_b))
    lo = float(np.min(s_feature[s_bin == k]))
    hi = float(np.max(s_feature[s_bin == k]))
    fl = lambda a: [None if not np.isfinite(v) else float(v) for v in np.asarray(a, float)]
    return {"feature": "since_reversal", "statistic": float(h_obs_stat),
            "null_median": float(np.median(h_null)),
            "p_value": float((1.0 + np.sum(h_null >= h_obs_stat)) / (1.0 + n_perm)),
            "highpass_hz": float(f_cut), "hf_rms_n": float(np.sqrt(np.mean(h))),
            "peak_since_reversal_m": [lo, hi], "peak_rms_n": float(np.sqrt(mean_b[k])),
            "peak_ratio": float(mean_b[k] / np.mean(h)) if np.mean(h) > 0 else None,
            "bins": {"centre": fl(centre), "rms": fl(np.sqrt(mean_b)), "count": [int(c) for c in n_b],
                     **{k2: fl(v) for k2, v in per_dir.items()}, "null_rms_q95": fl(null_rms_q95)}}
