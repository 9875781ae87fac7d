"""The sampling space of a fit: which parameters are free, in which coordinates they are sampled
(log for log-uniform priors), what is fixed, and the map from a batch of sampling vectors to the
kernel's parameter matrix plus the force offset.

The noise parameters (`sigma_noise`, `noise_phi`) are per record and integrated out by
frictionuq.infer.noisemodel; their priors (bounds) and any fixed values are kept here as
`noise_priors` / `fixed` but they are not sampling dimensions."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .. import params as P
from .priors import Prior

LIKELIHOODS = ("iid", "ar1", "arma")
NOISE = ("sigma_noise", "noise_phi")
#: parameters whose prior is given relative to another one: fs_* = fc_* x ratio (the ratio's
#: prior is `Prior.ratio_of`); sampled as log(ratio), which decouples the static friction from
#: the sharply determined kinetic friction
RATIO_OF = {"fs_fwd": "fc_fwd", "fs_bwd": "fc_bwd"}


@dataclass
class Space:
    model: str
    effects: tuple[str, ...]
    likelihood: str
    priors: dict[str, Prior]              # free parameters (noise ones are integrated out)
    fixed: dict[str, float] = field(default_factory=dict)
    # (lower, upper) N: each record's own force offset, integrated out under a uniform prior on
    # this box (FitConfig.force_offset = "per_test"; force_offset is then not a sampling dimension)
    offset_box: tuple[float, float] | None = None

    def __post_init__(self):
        if self.likelihood not in LIKELIHOODS:
            raise ValueError(f"unknown likelihood {self.likelihood!r}; use one of {LIKELIHOODS}")
        self.noise_priors = {n: p for n, p in self.priors.items() if n in NOISE}
        self.priors = {n: p for n, p in self.priors.items() if n not in NOISE}
        if "sigma_noise" not in self.noise_priors and "sigma_noise" not in self.fixed:
            raise ValueError("sigma_noise needs a prior (bounds) or a fixed value")
        if self.offset_box is not None:
            if "force_offset" in self.priors or "force_offset" in self.fixed:
                raise ValueError("a per-test offset box and a shared force_offset exclude each other")
            lo, hi = map(float, self.offset_box)
            if not lo < hi:
                raise ValueError(f"offset box needs lower < upper, got {self.offset_box}")
            self.offset_box = (lo, hi)
        self.names = list(self.priors)
        self.ndim = len(self.names)
        self.log = np.array([self.priors[n].log for n in self.names])
        box = np.array([self.priors[n].box() for n in self.names]).reshape(-1, 2)
        self.lo, self.hi = box[:, 0], box[:, 1]
        self._normal = [(i, self.priors[n].mu, self.priors[n].sd) for i, n in enumerate(self.names)
                        if self.priors[n].dist == "normal"]
        # kernel matrix template: base names must be free or fixed; effects at neutral unless on
        need = list(P.BASE_NAMES) if self.model == "three_stage" else \
            [n for n in P.BASE_NAMES if n not in ("k2", "d2", "k3", "d3", "w")]
        missing = [n for n in need if n not in self.priors and n not in self.fixed]
        if missing:
            raise ValueError(f"parameters neither free nor fixed: {', '.join(missing)}")
        tmpl = np.empty(len(P.VECTOR_NAMES))
        tmpl[len(P.BASE_NAMES):] = P.neutral_vector()
        if self.model == "lugre":   # backlash parameters are unused by LuGre: any valid value
            for n, v in {"k2": 0.0, "d2": 0.0, "k3": 0.0, "d3": 0.0, "w": 1e-3}.items():
                tmpl[P.INDEX[n]] = self.fixed.get(n, v)
        for n, v in self.fixed.items():
            if n in P.INDEX:
                tmpl[P.INDEX[n]] = v
        for eff in self.effects:
            for n in P.EFFECTS[eff]:
                if n not in self.priors and n not in self.fixed and n in P.INDEX:
                    tmpl[P.INDEX[n]] = P.PARAMS[n].default
        self._template = tmpl
        self._kernel_cols = [(i, P.INDEX[n]) for i, n in enumerate(self.names) if n in P.INDEX]
        # relative parameters: (column of the ratio, column of the reference or None, fixed ref)
        self._ratios = []
        for i, n in enumerate(self.names):
            ref = self.priors[n].ratio_of
            if ref:
                if ref in self.names:
                    self._ratios.append((i, self.names.index(ref), None))
                elif ref in self.fixed:
                    self._ratios.append((i, None, self.fixed[ref]))
                else:
                    raise ValueError(f"prior of {n} is relative to {ref}, which is neither free nor fixed")

    # ---------------------------------------------------------------- coordinates
    def to_values(self, theta: np.ndarray) -> np.ndarray:
        """Sampling coordinates -> parameter values (SI), same shape."""
        theta = np.asarray(theta, dtype=float)
        vals = np.where(self.log, np.exp(np.where(self.log, theta, 0.0)), theta)
        for i, j, ref in self._ratios:
            vals[..., i] = vals[..., i] * (vals[..., j] if j is not None else ref)
        return vals

    def to_theta(self, values: Mapping[str, float] | np.ndarray) -> np.ndarray:
        if isinstance(values, Mapping):
            values = np.array([values[n] for n in self.names], dtype=float)
        values = np.array(values, dtype=float)
        for i, j, ref in self._ratios:
            values[..., i] = values[..., i] / (values[..., j] if j is not None else ref)
        return np.where(self.log, np.log(np.where(self.log, values, 1.0)), values)

    def named(self, theta) -> dict[str, np.ndarray]:
        """All parameters (free and fixed) as {name: array over the batch}."""
        vals = np.atleast_2d(self.to_values(theta))
        out = {n: vals[:, i] for i, n in enumerate(self.names)}
        for n, v in self.fixed.items():
            out[n] = np.full(vals.shape[0], v)
        return out

    def kernel_matrix(self, theta) -> np.ndarray:
        """(W, D) sampling vectors -> (W, 24) kernel parameter matrix."""
        vals = np.atleast_2d(self.to_values(theta))
        M = np.repeat(self._template[None, :], vals.shape[0], axis=0)
        for i, j in self._kernel_cols:
            M[:, j] = vals[:, i]
        return M

    @property
    def per_test_offset(self) -> bool:
        return self.offset_box is not None

    def offset(self, theta) -> np.ndarray:
        """force_offset of each row (W,); 0 with per-test offsets (the likelihood's)."""
        vals = np.atleast_2d(self.to_values(theta))
        if "force_offset" in self.priors:
            return vals[:, self.names.index("force_offset")]
        return np.full(vals.shape[0], self.fixed.get("force_offset", 0.0))

    def chatter(self, theta) -> tuple[np.ndarray, ...] | None:
        """(a_ch, s_ch, w_ch, b_ch) of each row (W,) when the fit has the `chatter` noise effect,
        else None (params: the noise effects)."""
        if "chatter" not in self.effects:
            return None
        named = self.named(theta)
        W = np.atleast_2d(theta).shape[0]
        return tuple(np.broadcast_to(np.asarray(named.get(n, P.PARAMS[n].default), float), (W,))
                     for n in P.EFFECTS["chatter"])

    def noise_config(self) -> dict:
        """Arguments of noisemodel.log_marginal / draw_noise: kind, bounds, fixed values."""
        sp = self.noise_priors.get("sigma_noise")
        return {"kind": self.likelihood,
                "sigma_bounds": (sp.lower, sp.upper) if sp else (1.0, math.e),
                "sigma_fixed": self.fixed.get("sigma_noise"),
                "phi_fixed": 0.0 if self.likelihood == "iid" else self.fixed.get("noise_phi")}

    # ---------------------------------------------------------------- unbounded coordinates
    # The sampler works in u = logit((theta - lo) / (hi - lo)), which maps the prior box onto
    # R^D. The prior is unchanged: its density in u is the density in theta times the Jacobian
    # |d theta / d u| = (hi - lo) p (1 - p), p = expit(u) (log_jac_u). Posteriors that press
    # against a bound (a gap length near 0, a Stribeck velocity at its upper bound) then become
    # smooth exponential tails instead of hard walls, which differential-evolution proposals
    # cross all the time (about half of them were rejected outright in the box coordinates).
    def to_u(self, theta) -> np.ndarray:
        """Box (sampling) coordinates -> unbounded coordinates; theta must lie inside the box."""
        p = (np.asarray(theta, dtype=float) - self.lo) / (self.hi - self.lo)
        p = np.clip(p, 1e-12, 1.0 - 1e-12)
        return np.log(p) - np.log1p(-p)

    def from_u(self, u) -> np.ndarray:
        """Unbounded coordinates -> box (sampling) coordinates, strictly inside the box."""
        from scipy.special import expit
        th = self.lo + (self.hi - self.lo) * expit(np.asarray(u, dtype=float))
        m = 1e-12 * (self.hi - self.lo)      # expit rounds to 0 or 1 far out in the tails
        return np.clip(th, self.lo + m, self.hi - m)

    def log_jac_u(self, u) -> np.ndarray:
        """log |d theta / d u| summed over the coordinates, (W,)."""
        u = np.atleast_2d(np.asarray(u, dtype=float))
        return np.sum(np.log(self.hi - self.lo) - np.logaddexp(0.0, u) - np.logaddexp(0.0, -u), axis=1)

    # ---------------------------------------------------------------- prior
    def log_prior(self, theta) -> np.ndarray:
        """Log prior density in sampling coordinates (up to a constant): flat inside the box
        (log-uniform is flat in log coordinates), Gaussian for normal priors; -inf outside."""
        theta = np.atleast_2d(theta)
        inside = np.all((theta >= self.lo) & (theta <= self.hi), axis=1) & np.all(np.isfinite(theta), axis=1)
        lp = np.zeros(theta.shape[0])
        for i, mu, sd in self._normal:
            lp -= 0.5 * ((theta[:, i] - mu) / sd) ** 2
        return np.where(inside, lp, -np.inf)

    def sample_prior(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """n draws from the prior, in sampling coordinates."""
        th = rng.uniform(self.lo, self.hi, size=(n, self.ndim))
        for i, mu, sd in self._normal:
            from scipy.stats import truncnorm
            a, b = (self.lo[i] - mu) / sd, (self.hi[i] - mu) / sd
            th[:, i] = truncnorm.rvs(a, b, loc=mu, scale=sd, size=n, random_state=rng)
        return th

    @classmethod
    def from_json(cls, d: dict) -> "Space":
        """The space a fit record's "space" entry (to_json) describes."""
        pri = {n: Prior(name=n, **p) for n, p in {**d["priors"], **d["noise_priors"]}.items()}
        box = d.get("offset", {}).get("prior_box_N")
        return cls(d["model"], tuple(d["effects"]), d["likelihood"], pri,
                   {k: float(v) for k, v in d["fixed"].items()}, None if box is None else tuple(box))

    def to_json(self) -> dict:
        return {"model": self.model, "effects": list(self.effects), "likelihood": self.likelihood,
                "free": self.names, "priors": {n: p.to_json() for n, p in self.priors.items()},
                "noise_priors": {n: p.to_json() for n, p in self.noise_priors.items()},
                "noise": "per record, integrated out (frictionuq.infer.noisemodel)",
                "fixed": dict(self.fixed),
                **({"offset": {"per_test": True, "prior_box_N": list(self.offset_box)}}
                   if self.offset_box is not None else {})}
