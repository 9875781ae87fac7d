"""A fit's configuration (FitConfig): what frictionuq fit's options and a workflow's [fit]
table set, checked at construction so that bad settings are refused before any work."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field
from numbers import Integral, Real

import numpy as np

from .. import params as P
from ..errors import InputError, check_seed, unknown
from . import drivefilter
from .likelihood import NOISE_EFFECT_MIN_KEPT_HZ, SIMULATE_AT
from .sampler import SamplerConfig

LIKELIHOODS = ("iid", "ar1", "arma")
#: the load-cell zero of a joint fit's tests: one `force_offset` for all ("shared"), or each
#: test's own, integrated out under a uniform prior on the force_offset prior's box ("per_test":
#: infer.likelihood; the tests were re-zeroed or drifted between them, infer.between)
OFFSETS = ("shared", "per_test")


def _names(value, what: str) -> tuple[str, ...] | None:
    """A tuple of names from a tuple/list, or from one string (one name, not its letters)."""
    if value is None:
        return None
    if isinstance(value, str):
        return (value,)
    if isinstance(value, dict) and any(v not in (None, {}) for v in value.values()):
        # simulate's {effect: {param: value}} form: its values would be dropped silently
        raise InputError(f"fit config: {what} takes names, got values too ({value!r}); fix an "
                         "effect's parameter with priors={NAME: VALUE}")
    try:
        out = tuple(value)
    except TypeError:
        raise InputError(f"fit config: {what} must be a list of names, got {value!r}") from None
    if not all(isinstance(v, str) for v in out):
        raise InputError(f"fit config: {what} must be a list of names (strings), got {value!r}")
    return out


def _positive(name: str, v, allow_none: bool = False) -> None:
    if v is None and allow_none:
        return
    if isinstance(v, bool) or not isinstance(v, Real) or not np.isfinite(v) or v <= 0:
        raise InputError(f"fit config: {name} must be a number > 0"
                         + (" or None" if allow_none else "") + f", got {v!r}")


@dataclass
class FitConfig:
    """How a campaign is fitted (frictionuq fit's options; a workflow's [fit] table).

    model: "three_stage" or "lugre"; effects: names of the spec's effect library (one string is
    one name); likelihood: "ar1" (default), "iid" or "arma"; priors: overrides {NAME: VALUE}
    (fixes it), {NAME: {"dist": "uniform"|"loguniform", "lower", "upper"}} or {"dist": "normal",
    "mu", "sd"[, "lower", "upper"]}, or the command line's text form {NAME: "uniform:LO:HI"} or
    a list of "NAME=SPEC" strings, SI units; samples_per_cycle: the kept rate's multiple of the
    dominant frequency (decimation); eps: the reversal dead band in m, or "auto" (the record's
    estimator); force_offset: "shared" (one load-cell zero for all tests) or "per_test" (each
    test's own zero, integrated out); tests / kinds: only these test ids / kinds; sampler: a
    SamplerConfig (or a dict of its fields); seed: the sampler's seed. Checked at construction (InputError naming the
    field), before any folder is made."""
    model: str = "three_stage"
    effects: tuple[str, ...] = ()
    likelihood: str = "ar1"
    priors: dict = field(default_factory=dict)     # overrides; a number fixes the parameter
    samples_per_cycle: float = 400.0
    # the kept rate's floor (Hz); with a noise effect at least NOISE_EFFECT_MIN_KEPT_HZ
    min_kept_hz: float | None = None
    simulate_at: str = "raw"                       # "raw" or "kept" (infer.likelihood)
    eps: float | str = "auto"
    # infer.drivefilter: "auto" (20 on a record with eps > 0, which eps "auto" gives any record
    # read from a file; off only at eps = 0), a multiple, or None / "off" (the raw displacement)
    drive_lowpass: float | str | None = "auto"
    # where a reversal starts the backlash (model.REVERSAL_RULES): "extreme" (default; docs/
    # model-choices.md, "Reversals at the extreme") or "detection", the spec's causal rule; the
    # same at eps 0
    reversal: str = "extreme"
    force_offset: str = "shared"                   # OFFSETS
    kinds: tuple[str, ...] | None = None           # only tests of these kinds
    tests: tuple[str, ...] | None = None           # only these test ids
    sampler: SamplerConfig = field(default_factory=SamplerConfig)
    seed: int = 1
    n_predictive: int = 200

    def __post_init__(self):
        from .priors import parse_prior_option, prior_options
        if self.likelihood not in LIKELIHOODS:
            raise InputError(f"fit config: likelihood must be one of {', '.join(LIKELIHOODS)}, "
                             f"got {self.likelihood!r}")
        self.effects = _names(self.effects, "effects") or ()
        try:
            P.check_effects({e: {} for e in self.effects}, self.model)
        except ValueError as e:
            raise InputError(f"fit config: {e}") from None
        self.tests, self.kinds = _names(self.tests, "tests"), _names(self.kinds, "kinds")
        if isinstance(self.priors, (list, tuple)):          # ["NAME=SPEC", ...], as --prior
            self.priors = prior_options(self.priors)
        elif isinstance(self.priors, dict):
            self.priors = {k: (parse_prior_option(f"{k}={v}")[1] if isinstance(v, str) else v)
                           for k, v in self.priors.items()}
        else:
            raise InputError(f"fit config: priors must be a dict of overrides, got {self.priors!r}")
        # each override checked on its own now (names, dists, bounds, numbers); against the
        # record's default priors (relative bounds) again when the fit builds its space
        from .priors import apply_overrides
        apply_overrides({}, self.priors, source="fit config")
        if self.tests is not None and not self.tests:
            raise InputError("fit config: tests is empty; give test ids, or None for every test")
        _positive("samples_per_cycle", self.samples_per_cycle)
        _positive("min_kept_hz", self.min_kept_hz, allow_none=True)
        try:
            self.drive_lowpass = drivefilter.check_multiple(self.drive_lowpass)
        except ValueError as e:
            raise InputError(f"fit config: {e}") from None
        from ..model import REVERSAL_RULES
        if self.reversal not in REVERSAL_RULES:
            raise InputError(f"fit config: reversal must be one of {', '.join(REVERSAL_RULES)}, "
                             f"got {self.reversal!r}")
        if self.force_offset not in OFFSETS:
            raise InputError(f"fit config: force_offset must be one of {', '.join(OFFSETS)}, got "
                             f"{self.force_offset!r}")
        if self.force_offset == "per_test":
            box = self.priors.get("force_offset")
            if box is not None and not (isinstance(box, dict) and box.get("dist") == "uniform"):
                raise InputError("fit config: force_offset 'per_test' integrates each test's "
                                 "zero out under a uniform prior; its prior can only be "
                                 "force_offset=uniform:LOWER:UPPER (N), not a value or "
                                 f"another distribution (got {box!r})")
            if self.likelihood == "arma" or set(self.effects) & P.NOISE_EFFECTS:
                raise InputError("fit config: force_offset 'per_test' works with the iid and ar1 "
                                 "likelihoods and no noise effect (chatter)")
        if self.simulate_at not in SIMULATE_AT:
            raise InputError(f"fit config: simulate_at must be one of {', '.join(SIMULATE_AT)}, "
                             f"got {self.simulate_at!r}")
        if self.eps != "auto":
            if (isinstance(self.eps, bool) or not isinstance(self.eps, Real)
                    or not np.isfinite(self.eps) or self.eps < 0):
                raise InputError(f"fit config: eps must be 'auto' or a dead band in m >= 0, got "
                                 f"{self.eps!r}")
        if isinstance(self.sampler, dict):
            import dataclasses
            known = {f.name for f in dataclasses.fields(SamplerConfig)}
            bad = sorted(set(self.sampler) - known)
            if bad:
                raise InputError(f"fit config: sampler: {unknown('field', bad[0], sorted(known))}")
            self.sampler = SamplerConfig(**self.sampler)
        elif not isinstance(self.sampler, SamplerConfig):
            raise InputError(f"fit config: sampler must be a SamplerConfig (or a dict of its "
                             f"fields), got {self.sampler!r}")
        check_seed(self.seed, "fit")
        if isinstance(self.n_predictive, bool) or not isinstance(self.n_predictive, Integral) \
                or self.n_predictive < 0:
            raise InputError(f"fit config: n_predictive must be an integer >= 0, got "
                             f"{self.n_predictive!r}")

    def to_json(self) -> dict:
        d = asdict(self)
        d["sampler"] = self.sampler.to_json()
        return d

    def record_options(self) -> dict:
        """How each test's record is prepared (likelihood.records_from_tests keywords). With a
        noise effect (chatter) no record is kept at less than NOISE_EFFECT_MIN_KEPT_HZ: the
        anti-alias filter would take the chatter out of the slow tests only."""
        floor = self.min_kept_hz
        if set(self.effects) & P.NOISE_EFFECTS:
            floor = max(floor or 0.0, NOISE_EFFECT_MIN_KEPT_HZ)
        return {"samples_per_cycle": self.samples_per_cycle, "eps": self.eps,
                "simulate_at": self.simulate_at, "drive_lowpass": self.drive_lowpass,
                "min_kept_hz": floor, "reversal": self.reversal}
