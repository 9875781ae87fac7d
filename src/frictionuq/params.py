"""Parameter metadata in one place: names (the spec's SI names), units, physical bounds, and the
effect library's parameters with their neutral values.

The simulator kernel takes one flat float64 vector laid out as `VECTOR_NAMES` (13 base
parameters, then every effect parameter). `pack` turns named parameters into that vector and
is the only place where names are validated: unknown or missing names, non-finite or
out-of-bound values raise `ValueError` naming the parameter.

Bounds are *physical* limits (what the simulator accepts and a prior may never exceed), wide on
purpose; priors (frictionuq.infer.priors) are narrower and data-derived.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .errors import unknown


@dataclass(frozen=True)
class Param:
    name: str
    unit: str
    lower: float
    upper: float
    description: str
    kind: str = "base"          # base | likelihood | effect
    effect: str | None = None   # effect name for effect parameters
    neutral: float | None = None  # value at which the effect is off (None: any value is neutral)
    default: float | None = None  # value used when an effect is on and the parameter is not given
    log_scale: bool = False     # positive scale parameter: sampled in log space


_BASE = [
    Param("fc_fwd", "N", 1e-3, 1e7, "kinetic (Coulomb) friction force, forward (v>0)", log_scale=True),
    Param("fc_bwd", "N", 1e-3, 1e7, "kinetic (Coulomb) friction force, backward (v<0)", log_scale=True),
    Param("fs_fwd", "N", 1e-3, 1e7, "static friction force, forward", log_scale=True),
    Param("fs_bwd", "N", 1e-3, 1e7, "static friction force, backward", log_scale=True),
    Param("v_s", "m/s", 1e-7, 10.0, "Stribeck velocity", log_scale=True),
    Param("sigma0", "N/m", 1.0, 1e11, "LuGre aggregate bristle stiffness", log_scale=True),
    Param("sigma1", "N s/m", 0.0, 1e8, "LuGre micro-damping"),
    Param("sigma2", "N s/m", 0.0, 1e8, "viscous friction"),
    Param("k2", "N/m", 0.0, 1e11, "stage-2 (backlash) stiffness"),
    Param("d2", "m", 0.0, 0.2, "stage-2 (backlash) length"),
    Param("k3", "N/m", 0.0, 1e11, "stage-3 (take-up) stiffness"),
    Param("d3", "m", 0.0, 0.2, "stage-3 (take-up) length"),
    Param("w", "m", 1e-7, 0.05, "width of the smooth stage transitions", log_scale=True),
]

_LIKELIHOOD = [
    Param("sigma_noise", "N", 1e-6, 1e7, "measurement-noise scale", kind="likelihood", log_scale=True),
    Param("force_offset", "N", -1e7, 1e7, "constant zero offset of the measured force", kind="likelihood"),
    Param("noise_phi", "1", 0.0, 0.999, "lag-1 autocorrelation of AR(1) measurement noise "
          "(sigma_noise is then the marginal sd)", kind="likelihood"),
]

_EFFECT_PARAMS = [
    Param("p2", "1", 0.05, 20.0, "stage-2 stiffness exponent: k2*d2*(q/d2)^p2", "effect",
          "stage2_nonlinear", neutral=1.0, default=1.0, log_scale=True),
    Param("kappa", "1", 0.0, 0.999, "fraction of friction lost to heating", "effect",
          "thermal_fade", neutral=0.0, default=0.0),
    Param("e_fade", "J", 1e-3, 1e9, "energy scale of the fade", "effect", "thermal_fade",
          default=1e4, log_scale=True),
    Param("a_hump", "1", 0.0, 5.0, "hump amplitude after a reversal, relative to fc", "effect",
          "reversal_hump", neutral=0.0, default=0.0),
    Param("l_hump", "m", 1e-6, 0.2, "distance from the reversal to the hump's peak", "effect",
          "reversal_hump", default=2e-3, log_scale=True),
    Param("eps_ecc", "1", 0.0, 0.999, "relative amplitude of position-periodic friction", "effect",
          "eccentricity", neutral=0.0, default=0.0),
    Param("l_ecc", "m", 1e-4, 10.0, "period (in displacement) of the eccentricity", "effect",
          "eccentricity", default=0.1, log_scale=True),
    Param("psi_ecc", "rad", -math.pi, math.pi, "phase of the eccentricity", "effect",
          "eccentricity", default=0.0),
    Param("beta_rate", "1", 0.0, 10.0, "logarithmic rate strengthening of friction", "effect",
          "rate_strengthening", neutral=0.0, default=0.0),
    Param("v_ref", "m/s", 1e-7, 10.0, "reference velocity of rate strengthening", "effect",
          "rate_strengthening", default=1e-2, log_scale=True),
    Param("beta_app", "1", 0.0, 1.5, "how strongly friction follows the measured applied force",
          "effect", "applied_tracking", neutral=0.0, default=0.0),
    # not in the spec's library (docs/model-choices.md, "Effects beyond the spec"); appended
    # last so that the kernel vector's earlier slots keep their positions
    Param("a_to_fwd", "1", -0.95, 5.0, "friction overshoot (negative: undershoot) at the take-up "
          "of a forward half-cycle, relative to the friction level", "effect", "takeup_overshoot",
          neutral=0.0, default=0.0),
    Param("a_to_bwd", "1", -0.95, 5.0, "friction overshoot (negative: undershoot) at the take-up "
          "of a backward half-cycle, relative to the friction level", "effect", "takeup_overshoot",
          neutral=0.0, default=0.0),
    Param("l_to", "m", 1e-6, 0.2, "slip distance over which the take-up overshoot decays", "effect",
          "takeup_overshoot", default=3e-3, log_scale=True),
    Param("beta_sw", "1", 0.0, 0.95, "fraction of the friction level lost at sliding speeds well "
          "above v_sw", "effect", "speed_weakening", neutral=0.0, default=0.0),
    Param("v_sw", "m/s", 1e-7, 10.0, "velocity scale of the speed weakening", "effect",
          "speed_weakening", default=5e-2, log_scale=True),
]

#: effects on the measurement noise, not on the force (the kernel never sees them): the
#: likelihood scales the noise by g(s) = sqrt(1 + a_ch h(s)) at the travel s since the last
#: reversal, h the window exp(-(s - s_ch)^2 / (2 w_ch^2)) before its centre s_ch and b_ch + (1 -
#: b_ch) times it after (noise.chatter_gain; docs/model-choices.md, "chatter")
_NOISE_EFFECT_PARAMS = [
    Param("a_ch", "1", 0.0, 1e4, "extra measurement-noise variance at the centre of the chatter "
          "window, relative to the noise variance elsewhere (the variance there is 1 + a_ch times)",
          "noise_effect", "chatter", neutral=0.0, default=0.0),
    Param("s_ch", "m", 0.0, 10.0, "travel since the reversal at the centre of the chatter window",
          "noise_effect", "chatter", default=1e-2),
    Param("w_ch", "m", 1e-6, 10.0, "half-width (sd) of the chatter window, in travel",
          "noise_effect", "chatter", default=3e-3, log_scale=True),
    # appended last, so the first three keep their places (b_ch = 0: the one-bump window the
    # effect had before 2026-12-01)
    Param("b_ch", "1", 0.0, 1.0, "fraction of the window's extra noise variance that stays after "
          "its centre until the next reversal (0: a bump; 1: a step up)", "noise_effect",
          "chatter", default=0.0),
]

BASE_NAMES: tuple[str, ...] = tuple(p.name for p in _BASE)
LIKELIHOOD_NAMES: tuple[str, ...] = tuple(p.name for p in _LIKELIHOOD)
EFFECT_PARAM_NAMES: tuple[str, ...] = tuple(p.name for p in _EFFECT_PARAMS)
VECTOR_NAMES: tuple[str, ...] = BASE_NAMES + EFFECT_PARAM_NAMES
PARAMS: dict[str, Param] = {p.name: p for p in _BASE + _LIKELIHOOD + _EFFECT_PARAMS
                                + _NOISE_EFFECT_PARAMS}
INDEX: dict[str, int] = {n: i for i, n in enumerate(VECTOR_NAMES)}

#: effect name -> its parameter names, in vector order
EFFECTS: dict[str, tuple[str, ...]] = {}
for _p in _EFFECT_PARAMS + _NOISE_EFFECT_PARAMS:
    EFFECTS.setdefault(_p.effect, ())
    EFFECTS[_p.effect] = EFFECTS[_p.effect] + (_p.name,)

#: effects that need the record's measured applied-force signal
NEEDS_APPLIED = frozenset({"applied_tracking"})
#: effects beyond the spec's library (docs/model-choices.md): not screened by `discover` unless
#: asked for (takeup_overshoot mimics a reversal_hump on decimated BRFD records; speed_weakening
#: passes the in-sample stage on every real ARTS level through the AR(1) likelihood's preference
#: for a smooth residual, not through the data's level: docs/log-discrepancy.md, 2026-11-26)
BEYOND_SPEC = frozenset({"takeup_overshoot", "speed_weakening", "chatter"})
#: effects on the measurement noise only (the force model is unchanged)
NOISE_EFFECTS = frozenset(_p.effect for _p in _NOISE_EFFECT_PARAMS)
#: effects whose every parameter has a neutral value: with the effect off none of its parameters
#: is left free (unidentified), so on data without it the log-likelihood ratio of the effect's
#: best fit follows Wilks's chi2 with its number of parameters (half of that tail when a neutral
#: value lies on its bound, as beta_app's 0). An effect with a parameter that is free when it is
#: off (thermal_fade's e_fade, eccentricity's period and phase, ...) has no such law: it searches
#: a family of shapes for the noise to fit. discrepancy.rule.min_gain sets the decision rule's
#: threshold from this (docs/log-discrepancy.md, 2026-12-04, night)
REGULAR_NULL = frozenset(e for e, names in EFFECTS.items()
                         if all(PARAMS[n].neutral is not None for n in names))
#: effects that only make sense with the backlash stages
NEEDS_BACKLASH = frozenset({"stage2_nonlinear", "takeup_overshoot"})

MODELS = ("three_stage", "lugre")
#: the backlash parameters the pure LuGre model never reads (spec section 4: F = F1), with the
#: values pack gives them when a caller of model "lugre" leaves them out (no backlash)
LUGRE_UNUSED = {"k2": 0.0, "d2": 0.0, "k3": 0.0, "d3": 0.0, "w": 1e-3}


def neutral_vector() -> np.ndarray:
    """The effect part of the vector with every effect off."""
    return np.array([p.neutral if p.neutral is not None else p.default for p in _EFFECT_PARAMS])


def check_value(name: str, value) -> float:
    """Validate one named value against its bounds; return it as float."""
    if name not in PARAMS:
        raise ValueError(unknown("parameter", name, PARAMS))
    if isinstance(value, (str, bytes, bool)):   # float("805") and float(True) would pass: the CLI's
        raise ValueError(f"parameter {name!r}: expected a number, got {value!r}")   # JSON refuses them
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"parameter {name!r}: {value!r} is not a number") from None
    p = PARAMS[name]
    if not math.isfinite(v):
        raise ValueError(f"parameter {name!r}: {v} is not finite")
    if not (p.lower <= v <= p.upper):
        u = "" if p.unit == "1" else f" {p.unit}"      # a dimensionless value shows no unit
        raise ValueError(f"parameter {name!r}: {v:g}{u} is outside its physical bounds "
                         f"[{p.lower:g}, {p.upper:g}]{u}")
    return v


def _mapping(value, what: str, form: str) -> Mapping:
    """`value` as a mapping: a dict, or anything with .items() of (name, value) pairs (a pandas
    Series of posterior means); a list or array is refused with the form expected."""
    if isinstance(value, Mapping):
        return value
    if hasattr(value, "items") and hasattr(value, "index"):        # a pandas Series
        return dict(value.items())
    raise ValueError(f"{what} must be a mapping {form}, got a {type(value).__name__}")


def check_effects(effects: Mapping[str, Mapping[str, float]] | None, model: str = "three_stage"
                  ) -> dict[str, dict[str, float]]:
    """Validate an effects mapping {effect: {param: value}}; missing parameters take defaults."""
    if model not in MODELS:
        raise ValueError(unknown("model", model, MODELS))
    out: dict[str, dict[str, float]] = {}
    effects = _mapping(effects or {}, "effects", "{effect: {parameter: value}}, e.g. "
                       "{'thermal_fade': {'kappa': 0.2, 'e_fade': 1e4}}")
    for eff, values in effects.items():
        if eff not in EFFECTS:
            raise ValueError(unknown("effect", eff, EFFECTS))
        if model != "three_stage" and eff in NEEDS_BACKLASH:
            raise ValueError(f"effect {eff!r} changes the backlash line and needs model 'three_stage'")
        if values is not None and not isinstance(values, Mapping):
            raise ValueError(f"effect {eff!r}: its parameters must be a mapping {{parameter: "
                             f"value}} (its parameters: {', '.join(EFFECTS[eff])}), got {values!r}")
        values = dict(values or {})
        for name in values:
            if name not in EFFECTS[eff]:
                raise ValueError(f"effect {eff!r} has no parameter {name!r}; "
                                 f"its parameters: {', '.join(EFFECTS[eff])}")
        out[eff] = {n: check_value(n, values.get(n, PARAMS[n].default)) for n in EFFECTS[eff]}
    return out


def pack(params: Mapping[str, float], effects: Mapping[str, Mapping[str, float]] | None = None,
         model: str = "three_stage") -> np.ndarray:
    """Named parameters (+ effects) -> the kernel's float64 vector (len(VECTOR_NAMES)).

    `params` must hold every base name; likelihood-only names (`sigma_noise`, `force_offset`,
    the noise effects' parameters, and a summary's per-test ones such as `sigma_noise[TEST]`)
    are accepted and ignored; anything else is refused. A noise effect in `effects` is
    validated and does not change the vector.
    """
    params = _mapping(params, "params", "{name: value}, e.g. {'fc_fwd': 1200.0, ...}")
    vec = np.empty(len(VECTOR_NAMES))
    for name in params:
        base = name.split("[", 1)[0] if isinstance(name, str) and name.endswith("]") else name
        if base != name and base in PARAMS and PARAMS[base].kind == "likelihood":
            continue                        # sigma_noise[TEST], noise_phi[TEST] of a summary
        if name not in PARAMS or PARAMS[name].kind == "effect":
            hint = " (effect parameters go under `effects`)" if name in EFFECT_PARAM_NAMES else ""
            raise ValueError(f"unknown parameter {name!r}{hint}; the simulator's parameters: "
                             f"{', '.join(BASE_NAMES)}")
    for name in BASE_NAMES:
        if name not in params and model == "lugre" and name in LUGRE_UNUSED:
            vec[INDEX[name]] = LUGRE_UNUSED[name]      # the pure LuGre model has no backlash
            continue
        if name not in params:
            raise ValueError(f"missing parameter {name!r} ({PARAMS[name].description}, "
                             f"{PARAMS[name].unit})")
        vec[INDEX[name]] = check_value(name, params[name])
    vec[len(BASE_NAMES):] = neutral_vector()
    for eff, values in check_effects(effects, model).items():
        for name, v in values.items():
            if name in INDEX:           # noise effects' parameters are not the kernel's
                vec[INDEX[name]] = v
    return vec


def unpack(vec) -> dict[str, float]:
    """Kernel vector -> {name: value} for the base parameters."""
    return {n: float(vec[i]) for i, n in enumerate(BASE_NAMES)}


def table() -> list[dict]:
    """Every parameter's metadata as rows (for docs and reports)."""
    return [dict(name=p.name, unit=p.unit, lower=p.lower, upper=p.upper, kind=p.kind,
                 effect=p.effect, neutral=p.neutral, description=p.description)
            for p in PARAMS.values()]
