"""Residual diagnostics of a fitted test: where do model and data disagree, and is it significant?

Input: the residual r = data - posterior predictive median (N) along the record, optionally the
posterior predictive spread (N, to report r in spread units), and the per-sample features of
frictionuq.discrepancy.features. Output: one *view* per feature (displacement, velocity, time,
cycle, since_reversal, energy, applied) plus a position-locked spectrum, each with a statistic,
a p-value that accounts for autocorrelation, and a Holm-corrected verdict.

Views are binned per direction of motion. Every friction effect of the library changes the
force by d x (something), d = the direction of motion, so forward and backward passes cancel
in a plain bin mean of r (an eccentricity is invisible in r against x). Each feature is cut
into `n_bins` quantile bins (`cycle`: one bin per cycle index), each bin split by d into two
cells. The statistic is the partial correlation ratio

    T = (SS_cells - SS_direction) / SS_total,  SS_cells = sum over cells n_c (mean_c - mean)^2,

the fraction of the residual variance explained by the feature within each direction (the
direction main effect, e.g. a misfitted fc_fwd vs fc_bwd, would otherwise light up every view).
The plotted bin mean is that of d*r: the excess friction, positive where the data has more
friction than the model.

Null, and why not a circular shift. A circular shift of r against the features has no power
here: on a sine drive the phase is a function of (x, d), so a rotated phase-locked residual is
still phase-locked (every offset, not only multiples of the period), and a rotated smooth drift
is a drift with one jump. We use a *random-cut block permutation*: cut r at K - 1 uniformly
random points (K = n / L blocks, mean length L) and put the blocks in a random order. This
keeps the residual's values exactly (SS_total is invariant) and its autocorrelation inside each
block (only about 1/L of the adjacent pairs are separated), and moves every block by a random,
continuous amount, so its alignment with every feature (periodic or monotone) is broken at
scales beyond L. The null hypothesis is: r is a stationary short-memory process (correlation
length << L) unrelated to the features. L = BLOCK_FACTOR x the autocorrelation length
(2 x the e-folding lag of r's sample autocorrelation after removing the direction means:
(1+phi)/(1-phi) for AR(1) phi near 1, 39 samples at phi = 0.95), capped at n / MIN_BLOCKS.
Structure in r lengthens the estimate, i.e. longer blocks: conservative. The broken pairs bias
the null slightly low (order tau/L, 10 %); the tests measure the false-alarm rate on AR(1) noise.
An iid shuffle (block_length=1) flags AR(1) noise almost always. Measured (BRFD 267 N sine, 10
cycles at 1000 Hz, AR(1) phi = 0.95, 300 replicates): family-wise alarms 1 % at alpha = 0.05;
per view, unadjusted, 2.7-7.3 % at 0.05 (the phase-locked views slightly above, the drift
views below: their bins span several blocks). White noise (150 replicates): family-wise 4 %.
When the cap binds (`block_capped`; phi = 0.99, tau ~ 180 samples, 20 blocks) the binned drift
views ran at 13 % for a nominal 5 %; with their trend statistic (below) at 5 %.

Drift views (time, cycle, energy: TREND_VIEWS). Their statistic is not the binned T but the
fraction of the residual variance explained by a smooth trend in the feature, a polynomial of
degree TREND_DEGREE = 2 per direction (direction means removed, as in T; the tested `statistic`,
with the binned T kept as `statistic_binned` and for the plotted bins). Why (2026-11-25): with 16
free bins, T measures any level variation along the record, and the null's blocks keep their
levels; when the blocks are capped (short records: discover's decimated records hold 100
samples per cycle, e.g. 500 samples for 5 cycles, so at most n/20 = 25-sample blocks), a
reordering of 20 blocks varies in level from bin to bin about as much as a real drift does. On
pure AR(1) noise on such a 500-sample record (alpha 0.01 family-wise, 100 replicates) the binned
drift views raised 17 alarms at phi = 0.95 and 81 at phi = 0.99; the trend statistic 2 and 20
(a reordered block sequence has little smooth trend, a drift has one). On the test module's
long record (20,000 samples; 300 replicates, alpha 0.05, unadjusted): phi = 0.95, time / cycle /
energy 5.0 / 5.7 / 5.0 % (binned 4.0 / 4.0 / 4.0 %), family-wise 3.3 % (2.7 %); white noise
family-wise 3.3 % (4.0 %); capped, phi = 0.99: 5.0 / 5.0 / 4.7 % (binned 13.7 / 9.0 / 13.7 %),
family-wise 1.7 % (2.7 %). On the full-length MFD campaign with a hidden thermal fade, whose
drift the binned views missed (p 0.14-0.16), the baseline's 0.5 Hz test now shows a significant
drift (cycle, p = 0.001). A phi = 0.99 record of 2.5 correlation lengths is still beyond any
null built from the record itself (20 alarms in 100): `block_capped` says when to be wary.

p = (1 + #{T* >= T}) / (1 + n_perm); the smallest attainable p is 1/(1 + n_perm). All views and
the spectrum share the same permutations; Holm's step-down correction over them (family size
m = number of views + 1, + 1 for the high-frequency bursts of chatter.py, reported as `chatter`)
keeps the family-wise error rate at `alpha`. With the default n_perm = 999, p_min = 0.001 <
0.01/9. Bin standard errors are the standard deviations of the
bin means over the permutations, so they include the autocorrelation.

Position-locked spectrum. For each direction, the bin means of d*r on a uniform grid of N_GRID
displacement bins (empty bins interpolated), minus a straight line, Hann-windowed, zero-padded
PAD times; the two periodograms against spatial wavenumber k (1/m), 2/range <= k <= 1/(4 step),
are added. Per direction, because the bristle (presliding) length fc/sigma0 (4 mm for the BRFD)
low-passes a position-periodic friction and lags it in the direction of motion: the forward and
backward profiles are phase-shifted against each other and would partly cancel if averaged.
AR(1) noise gives a red spectrum, so each power is divided by its mean under the permutation null
at that k; statistic = the largest ratio, p from the same permutations, and the wavelength 1/k of
that peak (`eccentricity` leaves a peak at l_ecc; wavelengths longer than half the stroke show
up as a trend in the displacement view instead).

On a constant-amplitude sine, x, v and s are all functions of the phase given d, so one
phase-locked effect lights all three views; records of varying amplitude separate them.
"""
from __future__ import annotations

import numpy as np

from . import chatter as C
from .features import FEATURE_UNITS, features as compute_features
from .nullperm import (Spectrum, accumulate, autocorrelation_length, permutation_chunks, row_bincount, stat,
                       trend_basis, trend_stat)

VIEW_ORDER = ("displacement", "velocity", "time", "cycle", "since_reversal", "energy", "applied")
#: views tested with the smooth-trend statistic (module docstring: "Drift views")
TREND_VIEWS = ("time", "cycle", "energy")
TREND_DEGREE = 2
N_BINS = 16
N_PERM = 999
N_GRID = 256
PAD = 8
BLOCK_FACTOR = 10
MIN_BLOCKS = 20

#: effect (spec section 5) -> the views it is expected to light up and how
EXPECTED_SIGNATURES: dict[str, dict] = {
    "reversal_hump": {"views": ["since_reversal"], "shape": "hump", "odd_in_direction": True,
                      "scale_param": "l_hump",
                      "description": "excess friction d*r rises and falls after every reversal, "
                                     "peak at since_reversal ~ l_hump, gone by ~5 l_hump"},
    "thermal_fade": {"views": ["energy", "time", "cycle"], "shape": "monotone_decrease",
                     "odd_in_direction": True, "scale_param": "e_fade",
                     "description": "excess friction drifts down with the dissipated energy like "
                                    "-(1 - exp(-E/e_fade)), saturating; time and cycle follow"},
    "eccentricity": {"views": ["spectrum", "displacement"], "shape": "periodic_in_x",
                     "odd_in_direction": True, "scale_param": "l_ecc",
                     "description": "spectrum peak at wavelength l_ecc; cos(2 pi x/l_ecc + psi) "
                                    "in the displacement view (a trend if l_ecc > half the stroke)"},
    "rate_strengthening": {"views": ["velocity"], "shape": "log_in_abs_velocity",
                           "odd_in_direction": True, "scale_param": "v_ref",
                           "description": "excess friction grows like ln(1 + |v|/v_ref), the same "
                                          "in both directions (d*r even in v)"},
    "speed_weakening": {"views": ["velocity"], "shape": "saturating_decrease_in_abs_velocity",
                        "odd_in_direction": True, "scale_param": "v_sw",
                        "description": "excess friction falls like -(1 - exp(-|v|/v_sw)), the same "
                                       "in both directions: lowest mid-stroke, highest at the "
                                       "stroke ends"},
    "stage2_nonlinear": {"views": ["since_reversal", "displacement"], "shape": "localized_backlash",
                         "odd_in_direction": True, "scale_param": "d2",
                         "description": "structure confined to since_reversal < d2 (+ d3) after "
                                        "each reversal, i.e. near the ends of the stroke in x"},
    "applied_tracking": {"views": ["applied"], "shape": "linear", "odd_in_direction": True,
                         "scale_param": "beta_app",
                         "description": "excess friction proportional to a/a_med - 1 in the "
                                        "applied-force channel"},
}


def _f(v):
    v = float(v)
    return v if np.isfinite(v) else None


def _fl(a):
    return [_f(v) for v in np.asarray(a, dtype=float)]


def _bins(f: np.ndarray, n_bins: int, integer: bool):
    if integer:
        _, idx = np.unique(f, return_inverse=True)
    else:
        edges = np.unique(np.quantile(f, np.linspace(0.0, 1.0, n_bins + 1)))
        idx = np.searchsorted(edges[1:-1], f, side="right")
    return idx.astype(np.int64), int(idx.max()) + 1


def holm(p: dict) -> dict:
    """Holm's step-down adjusted p-values {name: p_adjusted} of {name: p} (also combine.py's)."""
    names = sorted(p, key=p.get)
    m, run, out = len(names), 0.0, {}
    for i, name in enumerate(names):
        run = max(run, min(1.0, (m - i) * p[name]))
        out[name] = run
    return out


def _view_result(name, s, obs, tn, acc, n_perm, ss, n):
    T, S, mb, mz = obs
    binned = None
    if "trend" in s:           # drift view: the tested statistic is the smooth trend's
        binned, T, tn = T, s["trend_obs"], s["trend_null"]
    a = acc / n_perm
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = np.bincount(s["bin"], weights=s["f"], minlength=s["nb"]) / s["n_b"]
        # per-direction means only where that direction holds a fair share of the bin
        cm = np.where(s["n_c"] >= np.maximum(10, 0.05 * np.repeat(s["n_b"], 2)), S / s["n_c"], np.nan)
    bins = {"centre": _fl(centre), "mean": _fl(mb), "se": _fl(np.sqrt(np.maximum(a[1] - a[0] ** 2, 0))),
            "count": [int(c) for c in s["n_b"]], "mean_fwd": _fl(cm[1::2]), "mean_bwd": _fl(cm[0::2])}
    if mz is not None:
        bins["mean_z"] = _fl(mz)
        bins["se_z"] = _fl(np.sqrt(np.maximum(a[3] - a[2] ** 2, 0.0)))
    out = {"feature": name, "unit": FEATURE_UNITS.get(name, ""), "statistic": _f(T),
           "null_median": _f(np.median(tn)), "p_value": _f((1.0 + np.sum(tn >= T)) / (1.0 + n_perm)),
           "structure_rms_n": _f(np.sqrt(max(0.0, T - tn.mean()) * ss / n)), "bins": bins,
           "test": "binned" if binned is None else f"trend (degree {TREND_DEGREE} per direction)"}
    if binned is not None:
        out["statistic_binned"] = _f(binned)
    return out


def _evaluate(R, H, setup, burst, spec, d, sp, n_d, ss) -> dict:
    """Every statistic of diagnose on the residual rows R (m, n) (observed, or permuted copies),
    with H (m, n) the high-passed rows for the bursts: {"views": {name: (T, S, mean of d*r,
    mean of d*z or None, trend statistic or None)}, "burst": (T, bin means of h), "spectrum": P}."""
    out = {"views": {}}
    if burst is not None:
        h = C.power(H, *burst["lock"])
        out["burst"] = (stat(row_bincount(burst["cell"], h, 2 * burst["nb"]), burst["n_c"], n_d, burst["ss"]),
                        row_bincount(burst["b"], h, burst["nb"]) / burst["n_b"])
    dz = None if sp is None else d * R / sp
    for name, s in setup.items():
        S = row_bincount(s["cell"], R, 2 * s["nb"])
        with np.errstate(invalid="ignore", divide="ignore"):
            mb = (S[:, 1::2] - S[:, 0::2]) / s["n_b"]
            mz = None if dz is None else row_bincount(s["bin"], dz, s["nb"]) / s["n_b"]
        Tt = trend_stat(s["trend"], R, ss) if "trend" in s else None
        out["views"][name] = (stat(S, s["n_c"], n_d, ss), S, mb, mz, Tt)
    if spec.ok:
        out["spectrum"] = spec.power(d * R)
    return out


def diagnose(t, x, resid, spread=None, features=None, alpha: float = 0.01, n_perm: int = N_PERM,
             seed: int = 0, *, n_bins: int = N_BINS, force_model=None, eps: float = 0.0, applied=None,
             views=None, block_length: float | None = None, n_grid: int = N_GRID,
             bursts: bool = True) -> dict:
    """Residual diagnostics of one record (see the module docstring); a JSON-ready dict.

    resid: data - posterior predictive median (N); spread: posterior predictive spread (N,
    scalar or per sample) for the bin means in spread units; features: from
    `frictionuq.discrepancy.features` (None: computed from t, x, force_model, eps, applied);
    views: feature names to test (default: all present); block_length: mean block length of the
    null in samples (None: automatic; 1: a naive iid shuffle, for comparison only); bursts: run
    the high-frequency burst test (chatter.py; only on records whose half-cycles repeat)."""
    x, r = np.asarray(x, dtype=float), np.asarray(resid, dtype=float)
    if r.shape != x.shape or not np.all(np.isfinite(r)):
        raise ValueError(f"resid must be finite and as long as x ({r.size} vs {x.size} samples)")
    if not 0 < alpha < 1 or int(n_perm) < 1:
        raise ValueError(f"need 0 < alpha < 1 and n_perm >= 1, got {alpha!r}, {n_perm!r}")
    feats = compute_features(t, x, force_model, eps, applied) if features is None else dict(features)
    d = np.asarray(feats["direction"] if "direction" in feats else compute_features(t, x, None, eps)["direction"])
    sp = None if spread is None else np.broadcast_to(np.asarray(spread, dtype=float), r.shape)
    if sp is not None and not np.all(sp > 0):
        raise ValueError("spread must be positive")
    names = views or [v for v in VIEW_ORDER if v in feats] + [v for v in feats if v not in VIEW_ORDER + ("direction",)]
    if missing := [v for v in names if v not in feats]:
        raise ValueError(f"no feature {missing} in features ({', '.join(feats)})")
    n, n_perm = r.size, int(n_perm)
    up = (d > 0).astype(np.int64)
    n_d = np.array([(up == 0).sum(), (up == 1).sum()], float)
    # the null permutes r minus its per-direction means: a misfit like fc_fwd != fc_bwd would
    # otherwise be scrambled into spurious structure (T itself is blind to it)
    rc = r - np.where(up == 1, r[up == 1].mean() if n_d[1] else 0.0, r[up == 0].mean() if n_d[0] else 0.0)
    tau = autocorrelation_length(rc)
    block = float(block_length) if block_length is not None else min(BLOCK_FACTOR * tau, n / MIN_BLOCKS)
    ss = float(np.sum((r - r.mean()) ** 2)) or 1.0
    setup = {}
    for name in names:
        f = np.asarray(feats[name], dtype=float)
        b, nb = _bins(f, n_bins, integer=(name == "cycle"))
        if nb >= 2:
            cell = 2 * b + up
            setup[name] = dict(bin=b, nb=nb, cell=cell, n_c=np.bincount(cell, minlength=2 * nb).astype(float),
                               n_b=np.bincount(b, minlength=nb).astype(float), f=f)
            if name in TREND_VIEWS:
                setup[name].update(trend=trend_basis(f, up, TREND_DEGREE), trend_null=np.empty(n_perm))
    spec = Spectrum(x, up, n_grid, PAD)
    burst = None        # high-frequency bursts against since_reversal (chatter.py)
    if bursts and "since_reversal" in feats and t is not None:
        s_rev = np.asarray(feats["since_reversal"], dtype=float)
        b_s, nb_s = _bins(s_rev, n_bins, integer=False)
        sig = C.highpass(t, x, rc) if nb_s >= 2 else None
        if sig is not None:
            hp, f_cut = sig
            lock = C.lock_cells(up, s_rev)
            h = C.power(hp, *lock)
            cell_s = 2 * b_s + up
            burst = dict(hp=hp, lock=lock, h=h, f_cut=f_cut, cell=cell_s, b=b_s, nb=nb_s,
                         n_c=np.bincount(cell_s, minlength=2 * nb_s).astype(float),
                         n_b=np.bincount(b_s, minlength=nb_s).astype(float),
                         ss=float(np.sum((h - h.mean()) ** 2)) or 1.0,
                         null=np.empty(n_perm), null_bins=np.empty((n_perm, nb_s)))

    rng = np.random.default_rng(seed)
    T_null = {name: np.empty(n_perm) for name in setup}
    acc = {name: np.zeros((4, s["nb"])) for name, s in setup.items()}   # sum, sum^2 of d*r and d*z
    P_null = np.empty((n_perm, spec.k.size)) if spec.ok else None
    # the observed residual (one row), then the permuted copies a chunk of rows at a time
    # (nullperm: the same numbers as one copy at a time)
    res = _evaluate(r[None, :], None if burst is None else burst["hp"][None, :], setup, burst, spec, d, sp, n_d, ss)
    obs = {name: (T[0], S[0], mb[0], None if mz is None else mz[0]) for name, (T, S, mb, mz, _) in res["views"].items()}
    for name, (*_, Tt) in res["views"].items():
        if Tt is not None:
            setup[name]["trend_obs"] = float(Tt[0])
    if burst is not None:
        burst["obs"] = res["burst"][0][0]
    if spec.ok:
        P_obs = res["spectrum"][0]
    for start, perms in permutation_chunks(n, block, rng, n_perm):
        rows = slice(start, start + perms.shape[0])
        res = _evaluate(rc[perms], None if burst is None else burst["hp"][perms], setup, burst, spec, d, sp, n_d, ss)
        if burst is not None:
            burst["null"][rows], burst["null_bins"][rows] = res["burst"]
        for name, (T, S, mb, mz, Tt) in res["views"].items():
            T_null[name][rows] = T
            if Tt is not None:
                setup[name]["trend_null"][rows] = Tt
            acc[name][0], acc[name][1] = accumulate(acc[name][0], mb), accumulate(acc[name][1], mb * mb)
            if mz is not None:
                acc[name][2], acc[name][3] = accumulate(acc[name][2], mz), accumulate(acc[name][3], mz * mz)
        if spec.ok:
            P_null[rows] = res["spectrum"]

    out_views = {name: _view_result(name, s, obs[name], T_null[name], acc[name], n_perm, ss, n)
                 for name, s in setup.items()}
    pvals = {name: v["p_value"] for name, v in out_views.items()}
    bursts = None      # before the spectrum: its critical level is alpha / (the whole family)
    if burst is not None:
        bursts = C.result(burst["obs"], burst["null"], np.sqrt(np.quantile(burst["null_bins"], 0.95, axis=0)),
                          burst["h"], burst["f_cut"], burst["b"], burst["nb"], s_rev, up)
        pvals["chatter"] = bursts["p_value"]
    spectrum = None
    if spec.ok:
        n_family = len(pvals) + 1
        mean_null = P_null.mean(0)
        ratio, null_max = P_obs / mean_null, (P_null / mean_null).max(1)
        i = int(np.argmax(ratio))
        pvals["spectrum"] = (1.0 + np.sum(null_max >= ratio[i])) / (1.0 + n_perm)
        spectrum = {"wavelength_m": _f(1.0 / spec.k[i]), "peak_ratio": _f(ratio[i]),
                    "p_value": _f(pvals["spectrum"]), "grid_step_m": _f(spec.step),
                    "wavelength_band_m": [_f(1.0 / spec.k[-1]), _f(1.0 / spec.k[0])],
                    "critical_ratio": _f(np.quantile(null_max, 1.0 - alpha / n_family)),
                    "wavenumber_per_m": _fl(spec.k), "power_ratio": _fl(ratio)}
    adj = holm(pvals)
    for name, v in list(out_views.items()) + ([("spectrum", spectrum)] if spectrum else []) + \
            ([("chatter", bursts)] if bursts else []):
        v["p_adjusted"], v["significant"] = _f(adj[name]), bool(adj[name] <= alpha)
    return {"n_samples": n, "alpha": alpha, "correction": "holm", "family_size": len(pvals),
            "n_perm": n_perm, "p_min": 1.0 / (1.0 + n_perm), "seed": seed, "n_bins": n_bins,
            "null": {"method": "iid shuffle" if block <= 1 else "random-cut block permutation",
                     "block_length_samples": block, "autocorrelation_length_samples": tau,
                     "n_blocks": max(1, int(round(n / block))) if block > 1 else n,
                     "block_capped": block_length is None and BLOCK_FACTOR * tau > n / MIN_BLOCKS},
            "residual_sd_n": _f(np.sqrt(ss / n)), "views": out_views, "spectrum": spectrum,
            "chatter": bursts,
            "significant": [k for k, v in adj.items() if v <= alpha]}
