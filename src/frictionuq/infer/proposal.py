"""The sampler's independence proposal: fitted to a burn-in round, fixed during the stored run.

A multivariate t (5 degrees of freedom, covariance inflated by 1.25^2) on marginally Gaussianised
coordinates. Each sampling coordinate x_i is mapped to z_i by a Johnson SU transform,
z_i = a_i + b_i asinh((x_i - loc_i) / sc_i), fitted by maximum likelihood to the round's states,
where it beats a Gaussian by more than its two extra parameters (AIC); otherwise z_i is the
standardised x_i. The t's mean and covariance are those of z over the round. Its density in x is
the t density of z(x) times the Jacobian prod_i dz_i/dx_i.

Why the marginal transform: the posteriors of the Stribeck parameters are skewed in the sampler's
coordinates (BRFD twin 267 N: skewness 1.0-1.1, excess kurtosis 1.3-2.4 for fs_fwd and fs_bwd),
and a t fitted to their first two moments puts too little mass in the long tail and too much
beyond the short one. Measured on the stored posterior of that level (3,000 proposals evaluated):
acceptance 0.22 with the plain t, 0.33 with the Johnson SU marginals (same df and scale).

emcee's MHMove applies the Hastings factor log q(x) - log q(x') returned by `_propose`.

With the burn-in's mode search (infer.modes) the proposal carries further components of the same
construction, and the stored run proposes from their fixed mixture (MixtureMove, the exact
mixture density in the Hastings factor).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import emcee
import numpy as np

#: Johnson SU's extra log-likelihood over a Gaussian must exceed its two extra parameters (AIC)
AIC_GAIN = 2.0
#: at most this many states of the round enter the marginal fits (an even stride over the pool)
MAX_FIT_POINTS = 4000
#: sinh's argument is clipped here so that a draw in the t's far tail stays finite
_SINH_MAX = 700.0


def fit_marginal(x: np.ndarray) -> tuple[float, float, float, float]:
    """(a, b, loc, sc) of the transform of one coordinate: Johnson SU by maximum likelihood when
    it gains more than AIC_GAIN over a Gaussian, else (0, 0, mean, sd) (b = 0: linear)."""
    from scipy import stats
    m, s = float(np.mean(x)), float(np.std(x))
    linear = (0.0, 0.0, m, s if s > 0 else 1.0)
    if not s > 0:
        return linear
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            a, b, loc, sc = stats.johnsonsu.fit(x, loc=float(np.median(x)), scale=s)
            gain = np.sum(stats.johnsonsu.logpdf(x, a, b, loc, sc)) - np.sum(stats.norm.logpdf(x, m, s))
        except Exception:         # an optimiser failure: the Gaussian will do
            return linear
    ok = all(np.isfinite((a, b, loc, sc, gain))) and 0 < b < 1e3 and sc > 0
    return (float(a), float(b), float(loc), float(sc)) if ok and gain > AIC_GAIN else linear


@dataclass
class Proposal:
    """Marginal transforms (arrays of a, b, loc, sc; b == 0 marks a linear one), the t's mean and
    covariance in z, and the median and half the 15.9-84.1 % range of each coordinate of x it was
    fitted to (the burn-in's stability rule; quantiles, not moments: the real records' heavy
    tails, excess kurtosis up to 4.6, made the sd of a round vary by 1.3-1.7x from round to round
    and kept the burn-in going for all its rounds)."""
    a: np.ndarray
    b: np.ndarray
    loc: np.ndarray
    sc: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    x_centre: np.ndarray
    x_width: np.ndarray
    df: float = 5.0
    scale: float = 1.25
    x_cov: np.ndarray | None = None   # covariance of the states in x (the random-walk move's)
    # further components found by the burn-in's mode search (infer.modes), each a Proposal, and
    # their total weight in the stored run's independence move (MixtureMove); none by default
    modes: tuple = ()
    mode_weight: float = 0.0

    @classmethod
    def fit(cls, pool: np.ndarray, df: float = 5.0, scale: float = 1.25) -> "Proposal":
        pool = np.atleast_2d(np.asarray(pool, float))
        sub = pool[::max(1, -(-pool.shape[0] // MAX_FIT_POINTS))]
        a, b, loc, sc = np.array([fit_marginal(sub[:, i]) for i in range(pool.shape[1])]).T
        lo, med, hi = np.quantile(pool, [0.159, 0.5, 0.841], axis=0)
        p = cls(a, b, loc, sc, np.zeros(pool.shape[1]), np.eye(pool.shape[1]), med, (hi - lo) / 2,
                df, scale)
        z = p.to_z(pool)[0]
        p.mean, p.cov = z.mean(axis=0), np.atleast_2d(np.cov(z.T))
        p.x_cov = np.atleast_2d(np.cov(pool.T))
        return p

    @classmethod
    def gaussian(cls, mean, cov, df: float = 5.0, scale: float = 1.25) -> "Proposal":
        """A plain multivariate t on x (every marginal transform the identity)."""
        mean, cov = np.asarray(mean, float), np.atleast_2d(np.asarray(cov, float))
        d = mean.size
        return cls(np.zeros(d), np.zeros(d), np.zeros(d), np.ones(d), mean, cov, mean,
                   np.sqrt(np.diag(cov)), df, scale, cov)

    def __post_init__(self):
        # per-coordinate constants of to_z / from_z, computed once (to_z runs twice per step)
        self._su = self.b > 0
        self._b = np.where(self._su, self.b, 1.0)
        self._log_b, self._log_sc = np.log(self._b), np.log(self.sc)

    @property
    def spread(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x_centre, self.x_width

    def to_z(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(z, log |dz/dx|) of a batch (n, D)."""
        y = (np.atleast_2d(x) - self.loc) / self.sc
        z = np.where(self._su, self.a + self.b * np.arcsinh(y), y)
        lj = np.where(self._su, self._log_b - 0.5 * np.log1p(y * y), 0.0) - self._log_sc
        return z, lj.sum(axis=1)

    def from_z(self, z) -> np.ndarray:
        z = np.atleast_2d(z)
        w = np.clip((z - self.a) / self._b, -_SINH_MAX, _SINH_MAX)
        return self.loc + self.sc * np.where(self._su, np.sinh(w), z)

    def to_attrs(self, prefix: str = "proposal") -> dict:
        """HDF5 attributes (names `prefix`_...); the mode components as `prefix`_mode<k>_..."""
        attrs = {f"{prefix}_marginals": np.vstack([self.a, self.b, self.loc, self.sc]),
                 f"{prefix}_mean": self.mean, f"{prefix}_cov": self.cov,
                 f"{prefix}_x_centre": self.x_centre, f"{prefix}_x_width": self.x_width,
                 f"{prefix}_df": self.df, f"{prefix}_scale": self.scale}
        if self.x_cov is not None:
            attrs[f"{prefix}_x_cov"] = self.x_cov
        if self.modes:
            attrs[f"{prefix}_modes"] = len(self.modes)
            attrs[f"{prefix}_mode_weight"] = self.mode_weight
            for k, m in enumerate(self.modes):
                attrs.update(m.to_attrs(f"{prefix}_mode{k}"))
        return attrs

    @classmethod
    def from_attrs(cls, attrs, prefix: str = "proposal") -> "Proposal":
        a, b, loc, sc = np.array(attrs[f"{prefix}_marginals"])
        x_cov = attrs.get(f"{prefix}_x_cov")
        modes = tuple(cls.from_attrs(attrs, f"{prefix}_mode{k}")
                      for k in range(int(attrs.get(f"{prefix}_modes", 0))))
        return cls(a, b, loc, sc, np.array(attrs[f"{prefix}_mean"]), np.array(attrs[f"{prefix}_cov"]),
                   np.array(attrs[f"{prefix}_x_centre"]), np.array(attrs[f"{prefix}_x_width"]),
                   float(attrs[f"{prefix}_df"]), float(attrs[f"{prefix}_scale"]),
                   None if x_cov is None else np.array(x_cov), modes,
                   float(attrs.get(f"{prefix}_mode_weight", 0.0)))

    def move(self) -> "IndependenceMove":
        """The stored run's independence move: this t alone, or with mode components the
        mixture (MixtureMove)."""
        return MixtureMove(self) if self.modes else IndependenceMove(self)

    def random_walk(self) -> "RandomWalkMove":
        """A Gaussian random-walk Metropolis move with the states' covariance scaled by
        2.38^2 / D (Roberts, Gelman & Gilks 1997): the local move beside the independence move
        when each walker is its own chain (no ensemble move). Without x_cov: the widths."""
        d = self.mean.size
        cov = self.x_cov if self.x_cov is not None else np.diag(self.x_width ** 2)
        cov = np.atleast_2d(cov) + 1e-12 * np.trace(np.atleast_2d(cov)) / d * np.eye(d)
        return RandomWalkMove(cov * 2.38 ** 2 / d)


class RandomWalkMove(emcee.moves.MHMove):
    """Gaussian random-walk Metropolis with a full covariance, every walker its own displacement.
    Not emcee's GaussianMove: with a covariance matrix it draws one displacement
    (`multivariate_normal` without a size) and moves every walker by it in the same step, which
    makes the stored run's independent chains move in concert (R-hat compares them as
    independent) and breaks the swaps of tempered chains (infer.tempering: a 2-level ladder on a
    Gaussian gave the cold level 1.12-1.15 times the variance)."""

    def __init__(self, cov):
        cov = np.atleast_2d(np.asarray(cov, float))
        try:
            self.L = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:    # not positive definite: the widths alone
            self.L = np.diag(np.sqrt(np.maximum(np.diag(cov), 1e-300)))
        super().__init__(self._propose, ndim=cov.shape[0])

    def _propose(self, x0, random):
        z = random.standard_normal(x0.shape)
        return x0 + np.einsum("ij,nj->ni", self.L, z), np.zeros(x0.shape[0])


def proposal_change(old, new) -> tuple[float, float]:
    """How much a burn-in round moved the proposal, from Proposal.spread (centres and widths of x)
    of the old and new rounds: (largest ratio of a parameter's width, new over old or old over
    new; largest shift of a centre in units of the new width). inf when there was no old one."""
    if old is None:
        return float("inf"), float("inf")
    sd0, sd1 = np.asarray(old[1], float), np.asarray(new[1], float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(sd0 > 0, sd1 / sd0, np.inf)
        shift = np.abs(new[0] - old[0]) / sd1
    ratio = np.where(np.isfinite(ratio) & (ratio > 0), np.maximum(ratio, 1.0 / ratio), np.inf)
    return float(np.max(ratio)), float(np.max(np.where(np.isfinite(shift), shift, np.inf)))


class IndependenceMove(emcee.moves.MHMove):
    """Independence Metropolis-Hastings (emcee MHMove): every walker proposes a fresh point from
    the fixed Proposal, accepted with the Hastings ratio p(x') q(x) / (p(x) q(x')). The proposal
    never changes during the stored run, so the chain keeps the posterior as its stationary
    distribution. Where the posterior is close to the proposal a walker decorrelates in a few
    steps; where it is not, the move is mostly rejected and the DE moves do the work."""

    def __init__(self, proposal: Proposal):
        self.p = proposal
        d = proposal.mean.size
        cov = proposal.cov * proposal.scale**2
        try:
            self.L = np.linalg.cholesky(cov + 1e-12 * np.trace(cov) / d * np.eye(d))
        except np.linalg.LinAlgError:
            self.L = np.diag(np.sqrt(np.maximum(np.diag(cov), 1e-300)))
        self.Linv = np.linalg.inv(self.L)
        self.df = float(proposal.df)
        super().__init__(self._propose, ndim=d)

    # einsum, not BLAS: on a loaded 2-core machine OpenBLAS's thread wake-up made these tiny
    # products (ndim x walkers) cost milliseconds each, a third of a whole fit
    def _logq(self, x):
        """log q(x) up to a constant: the t density of z(x) plus log |dz/dx|."""
        z, lj = self.p.to_z(x)
        y = np.einsum("ij,nj->ni", self.Linv, z - self.p.mean)
        return -0.5 * (self.df + self.p.mean.size) * np.log1p(np.einsum("ni,ni->n", y, y) / self.df) + lj

    def logq(self, x) -> np.ndarray:
        """log q(x) up to a constant (the importance weights' denominator; MixtureMove's is
        normalised)."""
        return self._logq(x)

    def log_norm(self) -> float:
        """The constant _logq leaves out: log of the t's normalisation in z."""
        d = self.p.mean.size
        return (math.lgamma(0.5 * (self.df + d)) - math.lgamma(0.5 * self.df)
                - 0.5 * d * math.log(self.df * math.pi) - float(np.sum(np.log(np.diag(self.L)))))

    def draw(self, n: int, random) -> np.ndarray:
        """n draws from the proposal (emcee's RandomState `random`)."""
        z = random.standard_normal((n, self.p.mean.size))
        g = random.chisquare(self.df, n)
        return self.p.from_z(self.p.mean + np.einsum("ij,nj->ni", self.L, z) * np.sqrt(self.df / g)[:, None])

    def _propose(self, x0, random):
        x = self.draw(x0.shape[0], random)
        return x, self._logq(x0) - self._logq(x)


class MixtureMove(emcee.moves.MHMove):
    """Independence Metropolis-Hastings from a fixed mixture: the proposal's own t with weight
    1 - mode_weight and each of its K mode components (infer.modes) with mode_weight / K. The
    Hastings factor is that of the exact mixture density, a log-sum-exp of the normalised
    component densities (each with its own marginal transforms and Jacobian). A walker picks its
    component, then draws from it; every component is drawn for every walker and the picked one
    kept (K + 1 small t draws a step)."""

    def __init__(self, proposal: Proposal):
        self.parts = [IndependenceMove(p) for p in (proposal, *proposal.modes)]
        k = len(proposal.modes)
        w = np.array([1.0 - proposal.mode_weight] + [proposal.mode_weight / k] * k)
        self.cum = np.cumsum(w)[:-1]
        self.log_w = np.log(w) + np.array([m.log_norm() for m in self.parts])
        super().__init__(self._propose, ndim=proposal.mean.size)

    def terms(self, x) -> np.ndarray:
        """Each part's weighted, normalised log density at x ((parts, n)): their log-sum-exp is
        log q(x); their argmax, the part x most likely came from (modes.refine)."""
        return np.stack([lw + m._logq(x) for lw, m in zip(self.log_w, self.parts)])

    def logq(self, x) -> np.ndarray:
        """log q(x) of the mixture (normalised)."""
        return np.logaddexp.reduce(self.terms(x), axis=0)

    def _propose(self, x0, random):
        pick = np.searchsorted(self.cum, random.random_sample(x0.shape[0]), side="right")
        draws = np.stack([m.draw(x0.shape[0], random) for m in self.parts])
        x = draws[pick, np.arange(x0.shape[0])]
        return x, self.logq(x0) - self.logq(x)
