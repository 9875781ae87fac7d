"""The forward model, in named parameters: `simulate` (one parameter set) and `simulate_batch`
(many parameter vectors on one record, for a vectorized MCMC log-probability).

This is the layer above the numba kernel: it validates the inputs (names, bounds, shapes,
effects that need a signal the record lacks) and converts mappings to the kernel's vector.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from . import kernel, params as P

_MODEL_CODE = {"three_stage": kernel.THREE_STAGE, "lugre": kernel.LUGRE}


@dataclass(frozen=True)
class Drive:
    """A displacement record prepared for repeated simulation (velocities computed once)."""
    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    u: np.ndarray
    dt: np.ndarray
    applied: np.ndarray   # measured applied-force signal, or empty
    a_med: float

    @property
    def n(self) -> int:
        return self.x.shape[0]


def _as_1d(name: str, a) -> np.ndarray:
    arr = np.ascontiguousarray(np.asarray(a, dtype=float))
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {arr.shape}")
    return arr


def prepare(t, x, applied=None) -> Drive:
    """Validate a drive record (SI) and precompute its velocities."""
    t = _as_1d("t", t)
    x = _as_1d("x", x)
    if t.shape != x.shape:
        raise ValueError(f"t and x differ in length ({t.size} vs {x.size})")
    if t.size < 2:
        raise ValueError(f"a record needs at least 2 samples, got {t.size}")
    k, kind = kernel.check_record(t, x)
    if kind == 1:
        raise ValueError(f"t holds NaN or inf (first at index {k})")
    if kind == 2:
        raise ValueError(f"x holds NaN or inf (first at index {k})")
    if kind == 3:
        raise ValueError(f"time is not strictly increasing at index {k}")
    if applied is None:
        a = np.empty(0)
        a_med = 1.0
    else:
        a = _as_1d("applied", applied)
        if a.shape != x.shape:
            raise ValueError(f"applied and x differ in length ({a.size} vs {x.size})")
        if not np.all(np.isfinite(a)):
            raise ValueError("applied holds NaN or inf")
        a_med = float(np.median(a))
        if not a_med > 0:
            raise ValueError(f"the median of the applied-force signal is {a_med:g}; "
                             "applied_tracking needs a positive median")
    v, u, dt = kernel.prepare(t, x)
    return Drive(t, x, v, u, dt, a, a_med)


def _check_needs(effects: Mapping | None, drive: Drive) -> None:
    for eff in effects or {}:
        if eff in P.NEEDS_APPLIED and drive.applied.size == 0:
            raise ValueError(f"effect {eff!r} needs the record's measured applied-force signal "
                             "(pass applied=..., or a campaign column `applied`)")


def _model_code(model: str) -> int:
    try:
        return _MODEL_CODE[model]
    except KeyError:
        raise ValueError(f"unknown model {model!r}; use one of: {', '.join(_MODEL_CODE)}") from None


def _check_eps(eps) -> float:
    try:
        e = float(eps)
    except (TypeError, ValueError):     # e.g. "auto": the record's estimator is noise.default_eps
        raise ValueError(f"eps (reversal dead-band) must be a number of m >= 0, got {eps!r} "
                         "(frictionuq.noise.default_eps(x) estimates one from a record)") from None
    if not (np.isfinite(e) and e >= 0):
        raise ValueError(f"eps (reversal dead-band) must be finite and >= 0 m, got {eps!r}")
    return e


#: where a reversal starts the backlash: "detection" (the spec's causal rule: where the motion
#: has come back eps from its extreme) or "extreme" (at the sample after the extreme; the same
#: with eps = 0; docs/model-choices.md, "Reversals at the extreme")
REVERSAL_RULES = ("detection", "extreme")
_NO_FLAGS = np.zeros(0, dtype=np.uint8)


def _reversal_flags(drive, eps: float, reversal: str) -> np.ndarray:
    if reversal not in REVERSAL_RULES:
        raise ValueError(f"reversal must be one of {', '.join(REVERSAL_RULES)}, got {reversal!r}")
    if reversal == "detection" or eps == 0.0:
        return _NO_FLAGS
    from .noise import reversal_flags
    return reversal_flags(drive.x, eps)


def simulate(t, x, params: Mapping[str, float], effects: Mapping[str, Mapping[str, float]] | None = None,
             model: str = "three_stage", eps: float = 0.0, applied=None,
             reversal: str = "detection") -> np.ndarray:
    """Force (N) of the damper driven by displacement `x` (m) at times `t` (s).

    params: the spec's SI names -> values (likelihood-only names are ignored);
    effects: {effect name: {parameter: value}} from the effect library (missing parameters take
    their defaults); model: "three_stage" (default) or "lugre"; eps: reversal dead-band (m);
    applied: the measured applied-force signal (SI), needed by `applied_tracking`; reversal:
    REVERSAL_RULES.
    """
    code = _model_code(model)
    vec = P.pack(params, effects, model)
    drive = t if isinstance(t, Drive) else prepare(t, x, applied)
    _check_needs(effects, drive)
    e = _check_eps(eps)
    return kernel.simulate_one(drive.x, drive.v, drive.u, drive.dt, _fx(drive, vec[None, :]),
                               drive.a_med, vec, code, e, _reversal_flags(drive, e, reversal))


_NEUTRAL = P.neutral_vector()
_EFFECT_IS_SET = np.array([P.PARAMS[n].neutral is not None for n in P.EFFECT_PARAM_NAMES])


def _fx(drive: Drive, M: np.ndarray):
    """None when no row turns an effect on (the kernel's fast specialisation), else the
    applied-force signal (possibly empty)."""
    eff = M[:, len(P.BASE_NAMES):][:, _EFFECT_IS_SET]
    if np.all(eff == _NEUTRAL[_EFFECT_IS_SET]):
        return None
    return drive.applied


def pack_batch(param_sets, effects=None, model: str = "three_stage") -> np.ndarray:
    """A list of parameter mappings (or a mapping of arrays) -> kernel matrix (m, NPARAM)."""
    if isinstance(param_sets, Mapping):
        sizes = {np.size(v) for v in param_sets.values()}
        if len(sizes) != 1:
            raise ValueError("all parameter arrays must have the same length")
        m = sizes.pop()
        param_sets = [{k: np.ravel(v)[i] for k, v in param_sets.items()} for i in range(m)]
    return np.array([P.pack(p, effects, model) for p in param_sets]).reshape(-1, kernel.NPARAM)


# below this many samples x vectors, threads cost more than they save (measured 2026-11-23:
# 16 vectors x 2,000-5,000 samples run 1.2-1.3x faster on 2 threads)
_PARALLEL_MIN_WORK = 30_000
#: read once: os.cpu_count() cost 74 us a call here, 0.6 % of a discover run's profile
_MULTICORE = (os.cpu_count() or 1) > 1


def simulate_batch(t, x, matrix, model: str = "three_stage", eps: float = 0.0, applied=None,
                   parallel: bool | None = None, check: bool = True,
                   reversal: str = "detection") -> np.ndarray:
    """Forces (m, N) for m parameter vectors on one record, in one call.

    matrix: (m, len(params.VECTOR_NAMES)) array laid out as params.VECTOR_NAMES (build it with
    `pack_batch`), or a list of parameter mappings. Rows run in parallel on all cores (numba
    prange) when the work is large enough. check=False skips the bound check of every row (the
    caller, e.g. a log-prior, has done it).
    """
    code = _model_code(model)
    if not isinstance(matrix, np.ndarray):
        matrix = pack_batch(matrix, model=model)
    M = np.ascontiguousarray(matrix, dtype=float)
    if M.ndim != 2 or M.shape[1] != kernel.NPARAM:
        raise ValueError(f"parameter matrix must have shape (m, {kernel.NPARAM}), got {M.shape}")
    if check:
        for j, name in enumerate(P.VECTOR_NAMES):
            col = M[:, j]
            p = P.PARAMS[name]
            bad = ~(np.isfinite(col) & (col >= p.lower) & (col <= p.upper))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                P.check_value(name, col[i])   # raises with the message
    drive = t if isinstance(t, Drive) else prepare(t, x, applied)
    # always checked (one column): the kernel would otherwise silently turn the effect off
    if drive.applied.size == 0 and np.any(M[:, P.INDEX["beta_app"]] != 0):
        raise ValueError("effect 'applied_tracking' needs the record's measured applied-force signal")
    if parallel is None:
        parallel = M.shape[0] > 1 and M.shape[0] * drive.n >= _PARALLEL_MIN_WORK and _MULTICORE
    fn = kernel.simulate_many if parallel else kernel.simulate_many_serial
    e = _check_eps(eps)
    return fn(drive.x, drive.v, drive.u, drive.dt, _fx(drive, M), drive.a_med, M, code, e,
              _reversal_flags(drive, e, reversal))
