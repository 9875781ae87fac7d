"""Likelihood: records prepared for fitting (decimated with an anti-alias filter), and the
vectorized log-posterior over a batch of walkers.

data = simulated force + force_offset + noise, with noise either independent Gaussian
(`iid`, sd sigma_noise), a stationary AR(1) process (`ar1`, marginal sd sigma_noise, lag-1
correlation noise_phi) or ARMA(1,1) (`arma`: AR(1) plus white noise, the record's MA
coefficient noise_theta fixed at the MAP), per record, with sigma_noise and noise_phi integrated
out (frictionuq.infer.noisemodel). With the `chatter` noise effect (not in the spec's library)
the noise is g(s) times such a process, g(s) = sqrt(1 + a_ch h(s)) at the travel s since the
last reversal, h = exp(-(s - s_ch)^2 / (2 w_ch^2)) before s_ch and b_ch + (1 - b_ch) times it
after (noise.chatter_gain): more noise in a window after each reversal, where the real ARTS
loops carry stick-slip chatter; sigma_noise is then the noise's sd before the window.
Residuals of a friction model on a 100-1000 Hz record are strongly autocorrelated; the iid
form then treats thousands of dependent samples as independent and makes posteriors far too
narrow, which is why `ar1` is the default.

Decimation (infer.decimate). Long records are filtered and downsampled (scipy.signal.resample_poly:
a zero-phase Kaiser-windowed FIR anti-alias filter) so that the excitation is still resolved: the kept rate
is at least `samples_per_cycle` x the dominant frequency and 20 x the frequency below which 99 %
of the velocity power above the displacement's noise floor lies (dominant_frequency).
Displacement, force and the applied-force signal are filtered alike.

The simulated force is filtered alike too (`simulate_at="raw"`, the default): the spec's model
is a discrete-time model of the record's own samples, so each decimated record is simulated on
its raw-rate displacement and the simulated force goes through the same linear anti-alias
filter and downsampling as the measured force. Simulating on the decimated displacement
(`simulate_at="kept"`, cheaper by the decimation factor) is a different model: measured on the
BRFD twin's 0.05 Hz records (q = 5) at the published values, it costs the truth 102 nats (35 N)
and 635 nats (53 N) against the raw-rate simulation, mostly through the coarser time step
(benchmarks/decimation_bias.py).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import model as M
from ..noise import chatter_gain, default_eps, since_reversal
from . import drivefilter, noisemodel
from .offsetnoise import log_marginal_offset
from .decimate import decimate, decimator
from .space import Space

LOG2PI = math.log(2 * math.pi)


@dataclass
class FitRecord:
    id: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray               # observed force (N), decimated
    applied: np.ndarray | None
    drive: M.Drive
    eps: float
    q: int                      # decimation factor
    fs_raw: float
    applied_level: float = float("nan")   # nominal applied force of the test (SI)
    kind: str = "other"
    frequency_hz: float | None = None
    noise_theta: float = 0.0     # MA coefficient of `arma` noise (noisemodel), set at the MAP
    sim_drive: M.Drive | None = None   # raw-rate drive when the model is simulated at the raw rate
    stride: int = 1              # compare every stride-th kept sample only (coarsened copies)
    drive_cutoff_hz: float | None = None   # displacement low-passed here first (drivefilter)
    reversal: str = "detection"  # model.REVERSAL_RULES

    @property
    def n(self) -> int:
        return self.y.size


def dominant_frequency(t, x) -> tuple[float, float]:
    """(dominant frequency of x, frequency under which 99 % of the velocity power lies), Hz.

    The velocity power is taken from the displacement spectrum above its noise floor: a measured
    displacement carries white sensor noise whose velocity power grows as f^2 and would otherwise
    put the 99 % frequency near Nyquist (no decimation at all; measured on the ARTS records: 25+
    Hz for 0.25 Hz sines). The floor is the median displacement power over the upper half of the
    band; only spectral lines 10 x above it and within 50 dB of the strongest line count (the
    servo-valve noise of the ARTS records shows as weak lines near 340 Hz)."""
    dt = float(np.median(np.diff(t)))
    xd = x - np.mean(x)
    X = np.abs(np.fft.rfft(xd * np.hanning(xd.size))) ** 2
    f = np.fft.rfftfreq(xd.size, dt)
    if X.size < 3 or not np.any(X[1:] > 0):
        return 1.0 / (t[-1] - t[0]), 0.5 / dt
    f_dom = float(f[1:][np.argmax(X[1:])])
    floor = float(np.median(X[f >= 0.25 / dt])) if np.any(f >= 0.25 / dt) else 0.0
    Xs = np.where(X > max(10.0 * floor, 1e-5 * float(np.max(X[1:]))), X, 0.0)
    pv = Xs * f**2                                  # velocity power above the noise floor
    if not np.sum(pv) > 0:
        return f_dom, f_dom
    c = np.cumsum(pv) / np.sum(pv)
    f99 = float(f[min(np.searchsorted(c, 0.99), f.size - 1)])
    return f_dom, f99


#: the lowest kept rate (Hz) of a record fitted with a noise effect (`chatter`), and of every
#: record `discover` screens when it is a candidate. Chatter is the load path ringing at 10-15 Hz
#: (the ARTS records); decimated below about three times that, the anti-alias filter removes it
#: from the slow tests only (a hidden 12.3 Hz ring keeps 31 % of its rms at a 20 Hz kept rate,
#: 15 % at 10 Hz, 99 % at 50 Hz), while the effect's window is shared by the tests of a level:
#: fitted on the faster tests, it then predicts chatter the slow test's kept samples cannot hold
#: (docs/log-discrepancy.md, 2026-11-27).
NOISE_EFFECT_MIN_KEPT_HZ = 50.0


def decimation_factor(t, x, samples_per_cycle: float = 128, frequency_hz: float | None = None,
                      min_kept_hz: float | None = None) -> int:
    """The decimation factor q: the kept rate is at least samples_per_cycle x the dominant
    frequency, 20 x the 99 % velocity-power frequency and min_kept_hz (if given)."""
    if min_kept_hz is not None and not (math.isfinite(min_kept_hz) and min_kept_hz > 0):
        raise ValueError(f"min_kept_hz must be a positive number of Hz, got {min_kept_hz!r}")
    dt = float(np.median(np.diff(t)))
    f_dom, f99 = dominant_frequency(t, x)
    if frequency_hz:
        f_dom = frequency_hz
    rate = max(samples_per_cycle * f_dom, 20.0 * f99, min_kept_hz or 0.0)
    return max(1, int(math.floor(1.0 / dt / rate)))


SIMULATE_AT = ("raw", "kept")
N_STATS = len(noisemodel.STATS)      # sufficient statistics of a record's residuals


def prepare_record(test_id, t, x, force, applied=None, *, q: int | str = "auto", eps="auto",
                   samples_per_cycle: float = 128, frequency_hz=None, applied_level=float("nan"),
                   kind="other", simulate_at: str = "raw", drive_lowpass=None,
                   min_kept_hz: float | None = None, reversal: str = "detection") -> FitRecord:
    """Decimate one record (SI arrays) and prepare it for the likelihood. simulate_at: "raw"
    (the model runs on the raw-rate record and its force is decimated like the data's) or
    "kept" (the model runs on the decimated displacement). drive_lowpass: None, or low-pass the
    displacement first at this multiple of its 99 % velocity-power frequency, or "auto" (20 when
    the record's eps > 0, else off; drivefilter.resolve).
    min_kept_hz: None, or the lowest kept rate (Hz) of the automatic q (decimation_factor).
    reversal: where the model's reversals start the backlash (model.REVERSAL_RULES)."""
    if simulate_at not in SIMULATE_AT:
        raise ValueError(f"simulate_at must be one of {SIMULATE_AT}, got {simulate_at!r}")
    if reversal not in M.REVERSAL_RULES:
        raise ValueError(f"reversal must be one of {M.REVERSAL_RULES}, got {reversal!r}")
    t = np.asarray(t, float)
    x = np.asarray(x, float)
    force = np.asarray(force, float)
    e = default_eps(x, where=f"test {test_id}") if eps == "auto" else float(eps)
    mult = drivefilter.resolve(drive_lowpass, e)
    if q == "auto":
        q = decimation_factor(t, x, samples_per_cycle, frequency_hz, min_kept_hz)
    q = int(q)
    x, cut = lowpass_drive(t, x, mult)
    td = t[::q]
    xd = decimate(x, q)[: td.size]
    yd = decimate(force, q)[: td.size]
    ad = None if applied is None else decimate(np.asarray(applied, float), q)[: td.size]
    td = td[: xd.size]
    drive = M.prepare(td, xd, ad)
    sim_drive = M.prepare(t, x, applied) if q > 1 and simulate_at == "raw" else None
    return FitRecord(str(test_id), td, xd, yd, ad, drive, e, q, 1.0 / float(np.median(np.diff(t))),
                     float(applied_level), kind, frequency_hz, sim_drive=sim_drive,
                     drive_cutoff_hz=cut, reversal=reversal)


def lowpass_drive(t, x, multiple: float | None) -> tuple[np.ndarray, float | None]:
    """(x as the model sees it, the cutoff in Hz or None): x low-passed at `multiple` x its 99 %
    velocity-power frequency (drivefilter), or x itself when off."""
    cut = drive_cutoff(t, x, multiple)
    if cut is None:
        return x, None
    return drivefilter.lowpass(x, 1.0 / float(np.median(np.diff(t))), cut), cut


def drive_cutoff(t, x, multiple: float | None) -> float | None:
    """The drive low-pass cutoff (Hz) of a record for `drive_lowpass` = multiple (drivefilter),
    None when off or when it would be close to Nyquist."""
    if multiple is None:
        return None
    t = np.asarray(t, float)
    return drivefilter.cutoff_hz(1.0 / float(np.median(np.diff(t))),
                                 dominant_frequency(t, np.asarray(x, float))[1], multiple)


def records_from_tests(tests, **kw) -> list[FitRecord]:
    """FitRecords from campaign Test objects (frictionuq.campaign)."""
    out = []
    for te in tests:
        r = te.record
        out.append(prepare_record(te.id, r.t, r.x, r.force, r.applied, frequency_hz=te.frequency_hz,
                                  applied_level=te.applied, kind=te.kind, **kw))
    return out


def gauss_loglik(e: np.ndarray, sigma: np.ndarray, phi: np.ndarray, pointwise: bool = False):
    """Log-likelihood of residuals e (W, N) under iid (phi = 0) or AR(1) Gaussian noise with
    marginal sd sigma (W,) and lag-1 correlation phi (W,). Sum over N, or per sample."""
    s = sigma[:, None]
    ph = phi[:, None]
    innov_sd = s * np.sqrt(1.0 - ph**2)
    first = -0.5 * (e[:, :1] / s) ** 2 - np.log(s) - 0.5 * LOG2PI
    rest = e[:, 1:] - ph * e[:, :-1]
    rest = -0.5 * (rest / innov_sd) ** 2 - np.log(innov_sd) - 0.5 * LOG2PI
    if pointwise:
        return np.concatenate([first, rest], axis=1)
    return first[:, 0] + rest.sum(axis=1)


class LogPosterior:
    """Vectorized log-posterior: theta (W, D) -> (W, 1 + n_records) array, column 0 the log
    posterior, then each record's log-likelihood (emcee blobs). Invalid proposals get -inf."""

    def __init__(self, space: Space, records: list[FitRecord], parallel: bool | None = None):
        self.space = space
        self.records = records
        self.parallel = parallel
        self.noise = space.noise_config()
        # per-test offsets (Space.offset_box): each record's blob also carries its offset, the
        # conditional optimum at the most probable phi (outputs draws the offsets from it)
        self.n_stats = N_STATS + (1 if space.per_test_offset else 0)
        self.n_evals = 0
        self._since: dict[int, np.ndarray] = {}

    def since(self, j: int) -> np.ndarray:
        """Travel since the last reversal (m) at record j's compared samples."""
        if j not in self._since:
            rec = self.records[j]
            self._since[j] = since_reversal(rec.x, rec.eps)[: rec.n]
        return self._since[j]

    def noise_gain(self, theta, j: int) -> np.ndarray | None:
        """(W, N) sd multiplier of record j's noise under the `chatter` noise effect
        (noise.chatter_gain at the travel since the reversal), or None without it."""
        ch = self.space.chatter(theta)
        return None if ch is None else chatter_gain(self.since(j), *ch)

    def simulate(self, theta, rec: FitRecord) -> np.ndarray:
        """Simulated force (W, N) at the record's kept samples (filtered and decimated like the
        measured force when the record is simulated at its raw rate)."""
        Mx = self.space.kernel_matrix(theta)
        drive = rec.drive if rec.sim_drive is None else rec.sim_drive
        F = M.simulate_batch(drive, None, Mx, model=self.space.model, eps=rec.eps,
                             parallel=self.parallel, check=False, reversal=rec.reversal)
        if rec.sim_drive is not None:
            F = decimator(F.shape[1], rec.q)(F)
        return F[:, ::rec.stride][:, : rec.n]

    def loglik_records(self, theta) -> np.ndarray:
        """(W, n_records) log-likelihood of each record (no prior check)."""
        return self.loglik_and_stats(theta)[0]

    def loglik_and_stats(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """(W, n_records) log-likelihood of each record and (W, n_records, N_STATS) the
        sufficient statistics of its (prefiltered) residuals, from which
        noisemodel.draw_noise_stats draws the record's noise parameters (no prior check)."""
        theta = np.atleast_2d(theta)
        off = self.space.offset(theta)
        out = np.empty((theta.shape[0], len(self.records)))
        stats = np.empty((theta.shape[0], len(self.records), self.n_stats))
        for j, rec in enumerate(self.records):
            if self.space.per_test_offset:
                out[:, j], stats[:, j, :] = self._loglik_own_offset(theta, rec)
                continue
            e = self.residuals(theta, rec, off)
            g = self.noise_gain(theta, j)
            if g is not None:      # e = g u, u the stationary noise: p(e) = p(u) / prod g
                e = e / g
            e = noisemodel.prefilter(e, rec.noise_theta)
            st = noisemodel.suff_stats(e)
            out[:, j] = noisemodel.log_marginal_stats(st, rec.n, **self.noise)
            if g is not None:
                out[:, j] -= np.log(g).sum(axis=1)
            stats[:, j, :] = np.column_stack(st)
        self.n_evals += theta.shape[0]
        return out, stats

    def _loglik_own_offset(self, theta, rec: FitRecord):
        """(W,) log-likelihood of one record with its own offset integrated out under a uniform
        prior on the space's offset box, together with the noise (offsetnoise, the held-out
        test's marginal of compare.py), and (W, n_stats) the sufficient statistics of y - F - c
        with c, the offset's conditional optimum, last."""
        e = rec.y[None, :] - self.simulate(theta, rec)
        n = self.noise
        ll, c = log_marginal_offset(e, n["kind"], n["sigma_bounds"], n["sigma_fixed"],
                                    n["phi_fixed"], offset_box=self.space.offset_box)
        st = noisemodel.suff_stats(e - c[:, None])
        return ll, np.column_stack(st + (c,))

    def fitted_force(self, theta, rec: FitRecord) -> np.ndarray:
        """(W, N) simulated force plus the load-cell zero: the shared offset, or with per-test
        offsets each row's own, profiled (the mean of y - F)."""
        theta = np.atleast_2d(theta)
        F = self.simulate(theta, rec)
        if self.space.per_test_offset:
            return F + np.mean(rec.y[None, :] - F, axis=1, keepdims=True)
        return F + self.space.offset(theta)[:, None]

    def residuals(self, theta, rec: FitRecord, off=None) -> np.ndarray:
        """Residuals y - F - offset (W, N) of one record; with per-test offsets (Space.offset_box)
        minus each row's own mean (the offset profiled out, as least squares and the residual
        diagnostics need it)."""
        theta = np.atleast_2d(theta)
        if self.space.per_test_offset:
            e = rec.y[None, :] - self.simulate(theta, rec)
            return e - e.mean(axis=1, keepdims=True)
        off = self.space.offset(theta) if off is None else off
        return rec.y[None, :] - self.simulate(theta, rec) - off[:, None]

    def __call__(self, theta, stats: bool = False) -> np.ndarray:
        """With stats=True, each row also carries every record's residual sufficient statistics
        after the log-likelihoods (n_records x N_STATS columns, record by record)."""
        theta = np.atleast_2d(theta)
        lp = self.space.log_prior(theta)
        R = len(self.records)
        res = np.full((theta.shape[0], 1 + R * (1 + self.n_stats * stats)), -np.inf)
        ok = np.isfinite(lp)
        if ok.any():
            ll, st = self.loglik_and_stats(theta[ok])
            ll = np.where(np.isfinite(ll), ll, -np.inf)
            res[ok, 1:1 + R] = ll
            res[ok, 0] = lp[ok] + ll.sum(axis=1)
            if stats:
                res[ok, 1 + R:] = st.reshape(st.shape[0], -1)
        res[:, 1:] = np.where(np.isfinite(res[:, 1:]), res[:, 1:], -1e300)  # finite blobs
        res[:, 0] = np.where(np.isnan(res[:, 0]), -np.inf, res[:, 0])
        return res

    def log_prob(self, theta) -> np.ndarray:
        return self(theta)[:, 0]


class UnboundedPosterior:
    """The log-posterior in the sampler's unbounded coordinates u (Space.to_u): same output
    layout as LogPosterior, column 0 = log p(theta(u) | data) + log |d theta / d u|, the density
    of u. Every finite u maps strictly inside the prior box."""

    def __init__(self, logpost: LogPosterior, stats: bool = False):
        self.logpost = logpost
        self.space = logpost.space
        self.stats = stats          # also the records' residual statistics (LogPosterior.__call__)

    def __call__(self, u) -> np.ndarray:
        u = np.atleast_2d(np.asarray(u, dtype=float))
        R, ns = len(self.logpost.records), self.logpost.n_stats
        res = np.full((u.shape[0], 1 + R * (1 + ns * self.stats)), -np.inf)
        ok = np.all(np.isfinite(u), axis=1)
        if ok.any():
            r = self.logpost(self.space.from_u(u[ok]), stats=self.stats)
            r[:, 0] = r[:, 0] + self.space.log_jac_u(u[ok])
            res[ok] = r
        res[:, 1:] = np.where(np.isfinite(res[:, 1:]), res[:, 1:], -1e300)
        res[:, 0] = np.where(np.isnan(res[:, 0]), -np.inf, res[:, 0])
        return res

    def log_prob(self, u) -> np.ndarray:
        return self(u)[:, 0]
