"""Optional low-pass of a measured displacement before the model runs on it (`drive_lowpass`).

Why: the kernel takes the sample velocity v[k] from central differences of the displacement, so
the displacement sensor's noise reaches the model amplified (sd ~ 0.7 sd_x / dt) and enters it
nonlinearly: through the Stribeck curve g(v) and through the backlash force d*Fb/sigma0 that
sets the bristle state until the hand-over at s = d2 + d3 + 5 w. Sliding relaxes z only over
g/sigma0 of travel (several mm on the BRFD), so z keeps the noise of the last sample before the
hand-over, and which sample that is depends on d2, d3 and w: the log-posterior is then rough
along those parameters (on the real arts-d1 20 lb level, second differences of up to 2.8 nats
along d3, against 0.1-0.2 along the friction forces; docs/log-calibration.md, "What the real
posteriors look like" and "Where the steps come from").

What: a zero-phase Butterworth low-pass (order 4, run forward and backward) at `multiple` x the
frequency below which 99 % of the record's velocity power lies (likelihood.dominant_frequency,
the same figure the decimation rule uses), after removing the line through the end points (as
decimate does), with an odd extension six cutoff periods long at each end so that the edges
carry no transient. The measured force and the reversal dead band eps (estimated on the raw
displacement) are unchanged.

Default "auto": on at AUTO_MULTIPLE (20) for a record whose reversal dead band eps is > 0 (a
record treated as measured: eps "auto" is 8 x its estimated displacement-noise sd, which is
> 0 for any record read from a file, a clean drive rounded in its CSV included), off only at
eps = 0 (a drive generated in memory, a harmonic, or a fit with eps = 0). With the "extreme"
reversal rule it removes the bias the displacement noise of the ARTS records puts into sigma0
(docs/log-calibration.md, 2026-12-01 evening; benchmarks/bench_reversal.py); on a clean drive the filter at 20 x the 99 % frequency
changes the force by far less than the records' noise (tests/test_infer_drivefilter.py). "off"
(None) runs the model on the recorded samples, as the spec's simulator does.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, sosfiltfilt

ORDER = 4
#: the highest cutoff worth filtering at, as a fraction of the Nyquist frequency
MAX_FRACTION = 0.9
#: edge padding, in periods of the cutoff frequency
PAD_PERIODS = 6.0


#: the multiple "auto" uses on a record with eps > 0
AUTO_MULTIPLE = 20.0


def check_multiple(value, where: str = "drive_lowpass") -> float | str | None:
    """None (off; also "off"), "auto", or a finite multiple > 0; anything else raises ValueError
    naming `where`."""
    if value is None or (isinstance(value, str) and value == "off"):
        return None
    if isinstance(value, str) and value == "auto":
        return "auto"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not (
            math.isfinite(value) and value > 0):
        raise ValueError(f"{where} must be 'auto', 'off' or a finite number > 0 (a multiple of "
                         f"the record's 99 % velocity-power frequency), got {value!r}")
    return float(value)


def resolve(value, eps: float) -> float | None:
    """The multiple a record with reversal dead band eps (m) is filtered at: "auto" gives
    AUTO_MULTIPLE when eps > 0 and None (off) at eps = 0; a number is itself; None/"off" None."""
    v = check_multiple(value)
    if v == "auto":
        return AUTO_MULTIPLE if float(eps) > 0.0 else None
    return v


def cutoff_hz(fs_hz: float, f99_hz: float, multiple: float | None) -> float | None:
    """The cutoff (Hz) for a record sampled at fs_hz, or None when there is nothing to filter
    (off, or the cutoff at or above MAX_FRACTION of Nyquist)."""
    if multiple is None:
        return None
    c = float(multiple) * float(f99_hz)
    return c if 0.0 < c < MAX_FRACTION * 0.5 * fs_hz else None


def lowpass(x, fs_hz: float, cutoff: float | None) -> np.ndarray:
    """x low-passed at `cutoff` Hz (zero phase), or a copy of x when cutoff is None."""
    x = np.asarray(x, float)
    if cutoff is None or x.size < 3 * (2 * ORDER + 1):
        return x.copy()
    ramp = np.linspace(0.0, 1.0, x.size)
    trend = x[0] + (x[-1] - x[0]) * ramp
    sos = butter(ORDER, cutoff, fs=fs_hz, output="sos")
    # odd extension over PAD_PERIODS periods of the cutoff: scipy's default (15 samples) is far
    # shorter than the filter's memory and leaves edge transients of mm on a 0.5 Hz, 25 mm sine
    pad = min(x.size - 1, int(math.ceil(PAD_PERIODS * fs_hz / cutoff)))
    return sosfiltfilt(sos, x - trend, padtype="odd", padlen=pad) + trend
