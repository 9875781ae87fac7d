"""Priors: physically realistic, bounded, with defaults derived from the records.

Every free parameter has a bounded prior. Positive scale parameters (params.Param.log_scale) are
log-uniform, i.e. uniform in the log space they are sampled in; the others are uniform, except
`force_offset` (a truncated normal centred on 0). Data-derived scales (`RecordScales`):

* friction scale `f_scale`: half the distance between the forward and backward force plateaus
  (median force while sliding forward / backward, |v| > 30 % of its maximum);
* noise scale `noise_hf`: the high-frequency residual of the force, from 4th-order differences
  (robust MAD, as frictionuq.noise does for displacement);
* offset scale `asym`: half the sum of the plateaus, i.e. their asymmetry about zero (a load-cell
  offset and a genuinely asymmetric device look the same while sliding; the offset prior is
  centred on 0 with this spread, and the backlash/rest segments tell them apart);
* stroke `amp`: the largest |x - median x|; velocity scale `v_max`.

The static friction forces have priors relative to the kinetic ones (fs/fc), see Space.RATIO_OF.

Overrides (a workflow's [fit.priors], the CLI's --prior, FitConfig.priors): {name: number} fixes
a parameter; {name: {"dist": "uniform"|"loguniform"|"normal", "lower":..., "upper":..., "mu":...,
"sd":...}} replaces its prior (SI; keys left out keep the default's, except where the default is
relative, fs/fc, which needs both bounds).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from math import comb
from typing import Iterable, Mapping

import numpy as np

from .. import params as P
from ..errors import InputError, unknown
from ..noise import amplitude

DISTS = ("uniform", "loguniform", "normal")


@dataclass(frozen=True)
class Prior:
    name: str
    dist: str               # uniform | loguniform | normal (truncated to [lower, upper])
    lower: float
    upper: float
    mu: float = 0.0
    sd: float = 1.0
    ratio_of: str | None = None   # bounds are of value / value(ratio_of), e.g. fs_fwd / fc_fwd

    @property
    def log(self) -> bool:
        return self.dist == "loguniform"

    def box(self) -> tuple[float, float]:
        """Bounds in sampling coordinates (log for log-uniform)."""
        if self.log:
            return math.log(self.lower), math.log(self.upper)
        return self.lower, self.upper

    def to_json(self) -> dict:
        d = {"dist": self.dist, "lower": self.lower, "upper": self.upper}
        if self.dist == "normal":
            d.update(mu=self.mu, sd=self.sd)
        if self.ratio_of:
            d["ratio_of"] = self.ratio_of
        return d


@dataclass(frozen=True)
class RecordScales:
    f_scale: float      # N
    asym: float         # N
    noise_hf: float     # N
    amp: float          # m
    v_max: float        # m/s

    def to_json(self) -> dict:
        return {k: float(v) for k, v in self.__dict__.items()}


def record_scales(records: Iterable) -> RecordScales:
    """Scales from records with attributes t, x, force (SI); several records are pooled."""
    fwd, bwd, hf, amps, vmax = [], [], [], [], []
    for r in records:
        t, x, f = np.asarray(r.t), np.asarray(r.x), np.asarray(r.force)
        v = np.gradient(x, t)
        vm = np.max(np.abs(v))
        if vm > 0:
            fwd.append(f[v > 0.3 * vm])
            bwd.append(f[v < -0.3 * vm])
        d = np.diff(f, 4)
        hf.append(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(comb(8, 4)))
        amps.append(amplitude(x))
        vmax.append(vm)
    ff = np.concatenate(fwd) if fwd and sum(a.size for a in fwd) else np.array([np.nan])
    fb = np.concatenate(bwd) if bwd and sum(a.size for a in bwd) else np.array([np.nan])
    up, lo = float(np.median(ff)), float(np.median(fb))
    if not (np.isfinite(up) and np.isfinite(lo) and up > lo):
        raise InputError("cannot derive priors: the records show no forward and backward sliding "
                         "plateaus (force while moving forward should exceed force while moving back)")
    f_scale = 0.5 * (up - lo)
    noise = float(np.median(hf))
    return RecordScales(f_scale=f_scale, asym=abs(0.5 * (up + lo)),
                        noise_hf=max(noise, 1e-6 * f_scale),
                        amp=float(max(amps)), v_max=float(max(vmax)))


def _lu(name, lo, hi):
    p = P.PARAMS[name]
    lo = max(lo, p.lower if p.lower > 0 else 1e-300)
    hi = min(hi, p.upper)
    return Prior(name, "loguniform", lo, hi)


def _u(name, lo, hi):
    p = P.PARAMS[name]
    return Prior(name, "uniform", max(lo, p.lower), min(hi, p.upper))


def default_priors(s: RecordScales, model: str = "three_stage", effects: Iterable[str] = (),
                   likelihood: str = "ar1") -> dict[str, Prior]:
    """Default priors of every free parameter of a fit, from the record scales."""
    F, A, V = s.f_scale, s.amp, max(s.v_max, 1e-9)
    pr = {
        "fc_fwd": _lu("fc_fwd", F / 5, F * 5),
        "fc_bwd": _lu("fc_bwd", F / 5, F * 5),
        # static friction relative to kinetic: fs/fc in [0.9, 1.35] (both papers: 1.03-1.18)
        "fs_fwd": Prior("fs_fwd", "loguniform", 0.9, 1.35, ratio_of="fc_fwd"),
        "fs_bwd": Prior("fs_bwd", "loguniform", 0.9, 1.35, ratio_of="fc_bwd"),
        # Stribeck velocity 0.3-30 % of the peak test velocity (papers: 1-3 %)
        "v_s": _lu("v_s", 3e-3 * V, 0.3 * V),
        # pre-sliding displacement fc/sigma0 between 1e-4 and 0.3 of the stroke (papers: 0.06-0.16)
        "sigma0": _lu("sigma0", F / (0.3 * A), F / (1e-4 * A)),
        # micro-damping and viscous friction: at most 10 % / 100 % of the friction at peak speed
        "sigma1": _lu("sigma1", 1e-4 * F / V, 0.1 * F / V),
        "sigma2": _lu("sigma2", 1e-4 * F / V, 1.0 * F / V),
    }
    if model == "three_stage":
        pr.update({
            "k2": _lu("k2", 1e-3 * F / A, 1e3 * F / A),
            "d2": _u("d2", 0.0, 0.6 * A),
            "k3": _lu("k3", 1e-2 * F / A, 1e4 * F / A),
            "d3": _u("d3", 0.0, 0.6 * A),
            "w": _lu("w", 1e-4 * A, 0.2 * A),
        })
    # bounds of the log-uniform prior on the noise's *innovation* sd sigma_noise sqrt(1 -
    # noise_phi^2) (noisemodel: integrated out in closed form); noise_phi is uniform on [0, 0.999]
    pr["sigma_noise"] = _lu("sigma_noise", 0.3 * s.noise_hf, 2.0 * F)
    off_sd = max(s.asym, 0.02 * F)
    pr["force_offset"] = Prior("force_offset", "normal", -3 * off_sd, 3 * off_sd, 0.0, off_sd)
    if likelihood in ("ar1", "arma"):
        pr["noise_phi"] = Prior("noise_phi", "uniform", 0.0, 0.999)
    for eff in effects:
        pr.update(effect_priors(eff, s))
    return pr


def _unit(name: str) -> str:
    """A parameter's unit as a message shows it ("1" is dimensionless)."""
    u = P.PARAMS[name].unit
    return "dimensionless" if u == "1" else u


def effect_priors(effect: str, s: RecordScales) -> dict[str, Prior]:
    """Realistic priors of one effect's parameters (registry: EFFECT_PRIORS)."""
    if effect not in EFFECT_PRIORS:
        raise InputError(f"no priors: {unknown('effect', effect, EFFECT_PRIORS)}")
    return {p.name: p for p in EFFECT_PRIORS[effect](s)}


#: the override that frees chatter's tail b_ch (opt-in): FitConfig(priors={"b_ch": TAIL_PRIOR}),
#: or `b_ch = {dist = "uniform", lower = 0, upper = 1}` in a workflow's [fit.priors]
TAIL_PRIOR = {"dist": "uniform", "lower": 0.0, "upper": 1.0}

EFFECT_PRIORS = {
    "stage2_nonlinear": lambda s: [_lu("p2", 0.25, 4.0)],
    "thermal_fade": lambda s: [_u("kappa", 0.0, 0.6),
                               _lu("e_fade", 0.1 * s.f_scale * s.amp, 1e3 * s.f_scale * s.amp)],
    "reversal_hump": lambda s: [_u("a_hump", 0.0, 1.5), _lu("l_hump", 2e-3 * s.amp, 0.8 * s.amp)],
    "eccentricity": lambda s: [_u("eps_ecc", 0.0, 0.4), _lu("l_ecc", 0.05 * s.amp, 4.0 * s.amp),
                               _u("psi_ecc", -math.pi, math.pi)],
    "rate_strengthening": lambda s: [_u("beta_rate", 0.0, 1.0),
                                     _lu("v_ref", 1e-3 * max(s.v_max, 1e-9), 1.0 * max(s.v_max, 1e-9))],
    "applied_tracking": lambda s: [_u("beta_app", 0.0, 1.5)],
    # the decay length's floor, 0.04 amplitude, is about one fitted sample of travel: with a
    # floor of 0.01 amplitude a fit of one real 1 Hz test put a 0.3 mm spike on the take-up
    "takeup_overshoot": lambda s: [_u("a_to_fwd", -0.6, 2.0), _u("a_to_bwd", -0.6, 2.0),
                                   _lu("l_to", 0.04 * s.amp, 0.5 * s.amp)],
    # the velocity scale from a tenth of the peak speed (below it the drop overlaps the
    # Stribeck term's, v_s <= 0.3 v_max) to three times it (beyond, only beta_sw/v_sw is seen)
    "speed_weakening": lambda s: [_u("beta_sw", 0.0, 0.6),
                                  _lu("v_sw", 0.1 * max(s.v_max, 1e-9), 3.0 * max(s.v_max, 1e-9))],
    # a noise effect: the noise variance up to 1 + 400 times (sd 20 times) in a window along the
    # half-cycle (travel since the reversal 0 to 2 amplitudes), 0.02-0.5 amplitude wide. Its
    # tail b_ch stays at 0 (the one-bump window) unless a prior override frees it (TAIL_PRIOR;
    # docs/model-choices.md, "chatter", for what it buys on the real records and what it costs)
    "chatter": lambda s: [_u("a_ch", 0.0, 400.0), _u("s_ch", 0.0, 2.0 * s.amp),
                          _lu("w_ch", 0.02 * s.amp, 0.5 * s.amp)],
}


def apply_overrides(priors: Mapping[str, Prior], overrides: Mapping | None, source: str = "config"
                    ) -> tuple[dict[str, Prior], dict[str, float]]:
    """Apply {name: value | {dist...}} overrides. Returns (priors of free params, fixed values)."""
    out = dict(priors)
    fixed: dict[str, float] = {}
    for name, spec in (overrides or {}).items():
        if name not in P.PARAMS:
            raise InputError(f"{source}: unknown parameter {name!r} in priors/fixed")
        if isinstance(spec, (int, float)) and not isinstance(spec, bool):
            try:
                fixed[name] = P.check_value(name, spec)
            except ValueError as e:
                raise InputError(f"{source}: {e}") from None
            out.pop(name, None)
            continue
        if not isinstance(spec, Mapping):
            raise InputError(f"{source}: prior of {name!r} must be a number (fixed) or a table "
                             f"with dist/lower/upper, got {spec!r}")
        extra = sorted(set(spec) - {"dist", "lower", "upper", "mu", "sd"})
        if extra:
            raise InputError(f"{source}: prior of {name!r}: "
                             f"{unknown('key', extra[0], ('dist', 'lower', 'upper', 'mu', 'sd'))}")
        base = out.get(name) or Prior(name, "uniform", P.PARAMS[name].lower, P.PARAMS[name].upper)
        if base.ratio_of and not {"lower", "upper"} <= set(spec):
            # the default's bounds are of the ratio to ratio_of: kept, they would read as newtons
            raise InputError(f"{source}: prior of {name!r}: its default is relative to "
                             f"{base.ratio_of} ({name}/{base.ratio_of} in [{base.lower:g}, "
                             f"{base.upper:g}]); an override must give both lower and upper "
                             f"({P.PARAMS[name].unit})")
        # an override gives absolute bounds (SI), even where the default is relative
        if spec.get("dist", base.dist) == "normal" and base.dist != "normal" and \
                not {"mu", "sd"} <= set(spec):
            # the Prior's own defaults (mu 0, sd 1) are no one's choice: a normal prior on a
            # stiffness of 1e5 N/m with sd 1 N/m fixes it (a new user's trial, 2026-12-05)
            raise InputError(f"{source}: prior of {name!r}: a normal prior needs both mu and sd "
                             f"({_unit(name)})")
        new = replace(base, ratio_of=None, **{k: (float(v) if k != "dist" else v) for k, v in spec.items()})
        if new.dist not in DISTS:
            raise InputError(f"{source}: prior of {name!r}: unknown dist {new.dist!r}; use one of {DISTS}")
        lo_b, hi_b = P.PARAMS[name].lower, P.PARAMS[name].upper
        if not (lo_b <= new.lower < new.upper <= hi_b):
            raise InputError(f"{source}: prior of {name!r}: need {lo_b:g} <= lower < upper <= {hi_b:g} "
                             f"({_unit(name)}), got [{new.lower:g}, {new.upper:g}]")
        if new.dist == "loguniform" and new.lower <= 0:
            raise InputError(f"{source}: prior of {name!r}: a log-uniform prior needs lower > 0")
        if new.dist == "normal" and not new.sd > 0:
            raise InputError(f"{source}: prior of {name!r}: sd must be > 0")
        out[name] = new
    return out, fixed


def parse_prior_option(text: str) -> tuple[str, float | dict]:
    """One command-line prior, `NAME=VALUE` (fixes the parameter), `NAME=uniform:LOWER:UPPER`,
    `NAME=loguniform:LOWER:UPPER` or `NAME=normal:MU:SD[:LOWER:UPPER]` (SI units), as the
    (name, override) pair apply_overrides takes; the values are checked there."""
    def bad(why):
        return InputError(f"--prior {text!r}: {why}; expected NAME=VALUE (fixed) or NAME=uniform:"
                          "LOWER:UPPER, NAME=loguniform:LOWER:UPPER, NAME=normal:MU:SD[:LOWER:UPPER] (SI)")
    name, sep, rhs = text.partition("=")
    name, rhs = name.strip(), rhs.strip()
    if not sep or not name or not rhs:
        raise bad("no NAME=")
    if name not in P.PARAMS:
        raise InputError(f"--prior {text!r}: unknown parameter {name!r}; the spec's names are "
                         f"{', '.join(P.PARAMS)}")
    dist, *nums = rhs.split(":")
    try:
        vals = [float(v) for v in (nums if nums else [dist])]
    except ValueError:
        raise bad("not a number") from None
    if not nums:
        return name, vals[0]
    keys = {"uniform": [("lower", "upper")], "loguniform": [("lower", "upper")],
            "normal": [("mu", "sd"), ("mu", "sd", "lower", "upper")]}.get(dist)
    if keys is None:
        raise bad(f"unknown dist {dist!r}")
    ks = next((k for k in keys if len(k) == len(vals)), None)
    if ks is None:
        raise bad(f"{dist} takes {' or '.join(str(len(k)) for k in keys)} numbers, got {len(vals)}")
    return name, {"dist": dist, **dict(zip(ks, vals))}


def prior_options(texts) -> dict:
    """{name: override} of repeated --prior options; a name given twice is refused."""
    out: dict = {}
    for t in texts or ():
        name, spec = parse_prior_option(t)
        if name in out:
            raise InputError(f"--prior {t!r}: {name} is given twice")
        out[name] = spec
    return out
