"""Per-cycle figures of a predicted force (predict.py): peak |F| and dissipated energy, median and
95 % interval over the posterior draws.

* Cycles: the harmonic is generated as whole periods starting at x = 0 moving up, so its cycles
  are the periods; for a record, a cycle runs from one turning point to the next turning point
  in the same direction, the turning points being the extremes the kernel's detector finds with
  a dead band of CYCLE_DEAD_BAND (5 %) of the record's amplitude (largest |x - median x|), or eps
  if larger: wiggles smaller than that (micrometres on a ground motion's history) do not cut a
  cycle. A record with fewer than 3 such turning points has no complete cycle (empty table).
* Energy per cycle is the loop integral of F dx (trapezoid rule) of the noise-free model force.
  For a periodic drive the loop closes and this is the energy dissipated; for an irregular
  record (a ground motion) a "cycle" need not return to its starting displacement, and the
  integral is the net work done on the device over it, which also contains the change of the
  energy stored in the backlash and bristles (a short cycle can then come out slightly
  negative).
"""
from __future__ import annotations

import numpy as np
import pandas as pd

#: a record's cycles turn where the motion reverses by more than this fraction of its amplitude
CYCLE_DEAD_BAND = 0.05
CYCLE_COLUMNS = ["cycle", "t_start", "t_end", "peak_force_median", "peak_force_q2.5",
                 "peak_force_q97.5", "energy_median", "energy_q2.5", "energy_q97.5"]


def cycle_bounds(x, eps: float = 0.0, samples_per_cycle: int | None = None) -> list[tuple[int, int]]:
    """Sample index pairs (start, end) of the complete cycles: whole periods of a generated
    harmonic (samples_per_cycle given), else turning point to the next turning point in the same
    direction, the turning points being the extremes of reversals larger than CYCLE_DEAD_BAND
    times the record's amplitude (or eps, if larger)."""
    x = np.asarray(x, float)
    if samples_per_cycle:
        n = (x.size - 1) // samples_per_cycle
        return [(c * samples_per_cycle, (c + 1) * samples_per_cycle) for c in range(n)]
    if x.size < 3:
        return []
    from .noise import amplitude, reversal_flags
    band = max(float(eps), CYCLE_DEAD_BAND * amplitude(x))
    turn = np.flatnonzero(reversal_flags(x, band)) - 1      # the flag sits after the extreme
    return [(int(turn[i]), int(turn[i + 2])) for i in range(0, turn.size - 2, 2)]


def cycle_table(t, x, F_model: np.ndarray, bounds) -> pd.DataFrame:
    """Per cycle: peak |F| (N) and dissipated energy (J, trapezoid loop integral of F dx) of the
    noise-free model force, median and 2.5/97.5 % over draws."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    rows = []
    for c, (i0, i1) in enumerate(bounds, start=1):
        F = F_model[:, i0:i1 + 1]
        peak = np.max(np.abs(F), axis=1)
        energy = np.sum(0.5 * (F[:, 1:] + F[:, :-1]) * np.diff(x[i0:i1 + 1])[None, :], axis=1)
        pq = np.percentile(peak, (50, 2.5, 97.5))
        eq = np.percentile(energy, (50, 2.5, 97.5))
        rows.append([c, t[i0], t[i1], *pq, *eq])
    return pd.DataFrame(rows, columns=CYCLE_COLUMNS).astype({"cycle": int})
