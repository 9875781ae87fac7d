"""The simulator kernel: numba-compiled functions over plain arrays (spec sections 1-5).

Everything here is SI and positional; names, validation and effects-as-mappings live in
`frictionuq.params` and `frictionuq.model`. The whole kernel stays in this one module because
numba's on-disk cache keys on the file that holds a jitted function: a cached caller is not
recompiled when a helper it calls from another file changes (numba's documented limitation,
numba/numba#1833). Checked on numba 0.68.1 (2026-12-03): `f` in a.py cached with `inc` imported
from b.py, `inc` edited from `return 1` to `return 2`, and `f(1)` still returned 2. Split
across files, an edited kernel could run stale code from an installed cache.

Parameter vector layout (see params.VECTOR_NAMES):
    0 fc_fwd 1 fc_bwd 2 fs_fwd 3 fs_bwd 4 v_s 5 sigma0 6 sigma1 7 sigma2 8 k2 9 d2 10 k3 11 d3 12 w
    13 p2 14 kappa 15 e_fade 16 a_hump 17 l_hump 18 eps_ecc 19 l_ecc 20 psi_ecc 21 beta_rate
    22 v_ref 23 beta_app 24 a_to_fwd 25 a_to_bwd 26 l_to 27 beta_sw 28 v_sw

Speed: the transcendental functions are the cost, so the kernel skips those that cannot change
the result in double precision:
  * the Stribeck term (fs-fc)*exp(-(v/v_s)^2) once (v/v_s)^2 exceeds a per-direction threshold
    beyond which it is below half an ulp of fc (so fc + term == fc exactly);
  * the whole backlash/blend branch once s >= max(40 w, d2 + d3 + 38 w), where tanh(s/2w) and
    the logistic m(s-d2-d3) both round to exactly 1.0 (then F == F1 exactly);
  * effect factors at their neutral values;
  * divisions in the sliding regime: with g == fc, a(v) = (s0/fc)|v| and a(u) dt = (s0/fc)|dx|;
  * there, the bristle update's exponential once z has reached z_ss = +-fc/s0 exactly (z - z_ss
    shrinks by exp(-(s0/fc)|dx|) per step, so in a long slide it rounds to 0 and stays there;
    the update would return z_ss itself);
  * the whole bristle update of a step after which the next sample is still inside the take-up
    and not released (s < d2 + d3 + 5 w): that sample sets z = d Fb / s0 before reading it.
Skipping changes the result by rounding only (relative ~1e-15), never by an approximation.
The last two skips return the same bits as the update they skip (benchmarks/bench_kernel_change.py
against the kernel without them: 1,200 random records and parameter sets, effects on and off,
both models, eps 0 and > 0, none different; tests/test_twins.py regenerates the shipped twins
byte for byte). Gain, 16 walkers on one thread (2026-11-29, that benchmark, nothing else
running): 1.12-1.14x on the real ARTS 35 lb sines at their MAP, 1.06-1.31x on the BRFD twin's
harmonics, 1.11-1.13x on the MFD twin's.
Inside the blend (s < s_sat), its three smooth steps softplus(s - d2), tanh(s/2w) and
m(s - d2 - d3) share one exponential exp(-s/w) (_blend_terms; again rounding only): two
transcendental calls per sample instead of four, 1.1-1.5x faster on records that spend most of
their travel in the blend (benchmarks/bench_simulator.py, the MFD's 25 mm harmonics).

Choices where the spec is silent (documented in docs/model-choices.md):
  * `reversal_hump` scales with the *parameter* fc of direction d (not a faded value);
  * `rate_strengthening` in the z update uses the step velocity |u| (g(u) is g of u);
  * the state-dependent factors of the z update (fade, eccentricity, applied tracking, take-up
    overshoot) are those of the step's start sample k;
  * `takeup_overshoot` (not in the spec's library; docs/model-choices.md, "Effects beyond the
    spec") is a factor on g of direction d: h = 1 + a_d until slip starts after a reversal (the
    first sample where the backlash line reaches the cap g_d*h, or s >= d2 + d3), then
    h = 1 + a_d exp(-(s - s_b)/l_to), s_b the travel at that sample. 3-stage model only (like
    stage2_nonlinear, it is refused with the LuGre model);
  * `speed_weakening` (not in the spec's library either; docs/model-choices.md) is a factor on g
    that falls with the speed: 1 - beta_sw (1 - exp(-|v|/v_sw)), of |u| in the z update like
    rate_strengthening.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

NPARAM = 29
THREE_STAGE = 0
LUGRE = 1


@njit(cache=True, error_model="numpy")
def check_record(t, x):
    """Index of the first problem of a drive record, and its kind: (-1, 0) if fine;
    kind 1 = t not finite, 2 = x not finite, 3 = time not strictly increasing."""
    n = x.shape[0]
    for k in range(n):
        if not math.isfinite(t[k]):
            return k, 1
        if not math.isfinite(x[k]):
            return k, 2
        if k > 0 and not t[k] > t[k - 1]:
            return k, 3
    return -1, 0


@njit(cache=True, error_model="numpy")
def prepare(t, x):
    """Sample velocity v (central differences, one-sided at the ends), step velocity u and step
    length dt (length N-1)."""
    n = x.shape[0]
    v = np.empty(n)
    u = np.empty(max(n - 1, 0))
    dt = np.empty(max(n - 1, 0))
    for k in range(n - 1):
        dt[k] = t[k + 1] - t[k]
        u[k] = (x[k + 1] - x[k]) / dt[k]
    if n >= 2:
        v[0] = u[0]
        v[n - 1] = u[n - 2]
        for k in range(1, n - 1):
            v[k] = (x[k + 1] - x[k - 1]) / (t[k + 1] - t[k - 1])
    elif n == 1:
        v[0] = 0.0
    return v, u, dt


@njit(cache=True, inline="always", error_model="numpy")
def _softplus(q, w, inv_w):
    y = q * inv_w
    if y > 0.0:
        if y > 37.0:           # y + log1p(exp(-y)) == y in double precision
            return w * y
        return w * (y + math.log1p(math.exp(-y)))
    if y < -37.0:              # log1p(e) == e to rounding for e < 1e-16
        return w * math.exp(y)
    return w * math.log1p(math.exp(y))


@njit(cache=True, inline="always", error_model="numpy")
def _logistic(q, inv_w):
    y = q * inv_w
    if y >= 0.0:
        if y > 38.0:           # 1 + exp(-y) == 1.0
            return 1.0
        return 1.0 / (1.0 + math.exp(-y))
    e = math.exp(y)
    if y < -38.0:              # 1 + e == 1.0
        return e
    return e / (1.0 + e)


@njit(cache=True, inline="always", error_model="numpy")
def _blend_terms(s, d2, w, inv_w, a_sat, c_d2, c_d2i, c_d23):
    """(softplus(s - d2), tanh(s/2w), m(s - d2 - d3)) of the blend from one exponential
    e = exp(-s/w): exp(-(s - d2)/w) = e exp(d2/w) (c_d2), exp((s - d2)/w) = exp(-d2/w) / e
    (c_d2i), exp(-(s - d2 - d3)/w) = e exp((d2 + d3)/w) (c_d23), tanh(s/2w) = (1 - e)/(1 + e)
    (from expm1 below s = w/2, where 1 - e would lose digits). The same values as _softplus,
    tanh and _logistic to rounding; the caller uses it only while (d2 + d3)/w < 600, so that
    neither e (s < d2 + d3 + 38 w here) nor the constants leave the double range."""
    xs = s * inv_w
    e = math.exp(-xs)
    y = (s - d2) * inv_w
    if y > 37.0:            # as _softplus: y + log1p(exp(-y)) == y
        sp = w * y
    elif y > 0.0:
        sp = w * (y + math.log1p(e * c_d2))
    elif y < -37.0:
        sp = w * (c_d2i / e)
    else:
        sp = w * math.log1p(c_d2i / e)
    if s >= a_sat:
        A = 1.0
    elif xs > 0.5:
        A = (1.0 - e) / (1.0 + e)
    else:
        em = math.expm1(-xs)
        A = -em / (2.0 + em)
    ed = e * c_d23          # exp(-(s - d2 - d3)/w)
    Cb = 1.0 / (1.0 + ed)
    return sp, A, Cb


@njit(cache=True, inline="always", error_model="numpy")
def _stribeck(vabs, fc, fs, inv_vs, thr):
    r = vabs * inv_vs
    r2 = r * r
    if r2 > thr:
        return fc
    return fc + (fs - fc) * math.exp(-r2)


@njit(cache=True, inline="always", error_model="numpy")
def _skip_threshold(fc, fs):
    # (fs-fc)*exp(-r2) < fc*2^-54 (half an ulp of fc) whenever r2 > this
    ratio = abs(fs - fc) / fc
    return 37.5 + math.log(ratio) if ratio > 1.0 else 37.5


@njit(cache=True, error_model="numpy")
def simulate_into(x, v, u, dt, a_sig, a_med, P, model, eps, rev, F):
    """Run the model over one record; write the force (N) into F (length N).

    a_sig: None when every effect is off (fast specialisation); otherwise the measured
    applied-force signal (length N) or an empty array; a_med its median. rev: empty for the
    spec's causal reversal detector with dead band eps; else (length N) the samples at which
    the motion reverses, rev[k] != 0 (noise.reversal_flags: the reversals of that detector,
    each moved back to the sample after its extreme), and eps is not used.
    """
    n = x.shape[0]
    if n == 0:
        return
    fc_f = P[0]; fc_b = P[1]; fs_f = P[2]; fs_b = P[3]
    inv_vs = 1.0 / P[4]
    s0 = P[5]; s1 = P[6]; s2 = P[7]
    k2 = P[8]; d2 = P[9]; k3 = P[10]; d3 = P[11]; w = P[12]
    p2 = P[13]; kappa = P[14]; e_fade = P[15]; a_h = P[16]; l_h = P[17]
    e_ecc = P[18]; l_ecc = P[19]; psi = P[20]; b_rate = P[21]; v_ref = P[22]; b_app = P[23]
    a_to_f = P[24]; a_to_b = P[25]; l_to = P[26]; b_sw = P[27]; inv_vsw = 1.0 / P[28]

    # a_sig is None when every effect is off: numba then compiles a specialisation in which all
    # effect code below is dead and removed
    use_p2 = False
    use_fade = False
    use_hump = False
    use_ecc = False
    use_rate = False
    use_app = False
    use_to = False
    use_sw = False
    if a_sig is not None:
        use_p2 = p2 != 1.0 and d2 > 0.0
        use_fade = kappa != 0.0
        use_hump = a_h != 0.0
        use_ecc = e_ecc != 0.0
        use_rate = b_rate != 0.0
        use_app = b_app != 0.0 and a_sig.shape[0] == n
        use_to = (a_to_f != 0.0 or a_to_b != 0.0) and model == THREE_STAGE
        use_sw = b_sw != 0.0
    use_fac = use_fade or use_ecc or use_rate or use_app or use_to or use_sw

    thr_f = _skip_threshold(fc_f, fs_f)
    thr_b = _skip_threshold(fc_b, fs_b)
    inv_s0 = 1.0 / s0
    # sliding far from v = 0 with no effect factor: g == fc, so a(v) = (s0/fc)|v| and
    # z_ss = +-fc/s0 need no division
    c_f = s0 / fc_f
    c_b = s0 / fc_b
    zss_f = fc_f * inv_s0
    zss_b = -fc_b * inv_s0
    backlash = d2 > 0.0 or d3 > 0.0
    s_free = d2 + d3 + 5.0 * w
    # beyond s_sat, tanh(s/2w) and m(s-d2-d3) are exactly 1.0 in double precision: F == F1
    s_sat = d2 + d3 + 38.0 * w
    if s_sat < 40.0 * w:
        s_sat = 40.0 * w
    inv_w = 1.0 / w
    # the blend's three smooth steps from one exponential per sample (_blend_terms)
    shared_exp = (d2 + d3) * inv_w < 600.0
    c_d2 = math.exp(d2 * inv_w) if shared_exp else 0.0
    c_d2i = math.exp(-d2 * inv_w) if shared_exp else 0.0
    c_d23 = math.exp((d2 + d3) * inv_w) if shared_exp else 0.0
    half_inv_w = 0.5 / w
    a_sat = 40.0 * w    # tanh(s/2w) == 1.0 beyond
    ecc_k = 2.0 * math.pi / l_ecc
    inv_a_med = 1.0 / a_med
    s_tu = d2 + d3                  # take-up overshoot: slip starts at the latest here
    inv_l_to = 1.0 / l_to
    x_to = 40.0 * l_to              # exp(-40) * |a| < half an ulp of 1 for |a| <= 5: h == 1.0

    # initial state
    d = 1.0
    for j in range(1, n):
        if x[j] != x[0]:
            d = 1.0 if x[j] > x[0] else -1.0
            break
    x_ext = x[0]
    x_r = x[0]
    F_r = 0.0
    z = 0.0
    E = 0.0
    # z is released to evolve freely once s has reached s_free after a reversal, and stays
    # released until the next reversal (with eps > 0, s can fall back inside the dead band)
    released = not backlash
    # take-up overshoot: whether the interface slips since the last reversal, and the travel
    # s_b at which it started to (latched until the next reversal, like `released`)
    slipping = False
    s_b = 0.0

    use_rev = rev.shape[0] == n
    for k in range(n):
        xk = x[k]
        # -- reversal detection
        if k > 0:
            turn = False
            if use_rev:
                turn = rev[k] != 0
            elif d * (xk - x_ext) > 0.0:
                x_ext = xk
            elif d * (x_ext - xk) > eps:
                turn = True
            if turn:
                x_r = x[k - 1]
                F_r = F[k - 1]
                d = -d
                x_ext = xk
                released = not backlash
                slipping = False
        vk = v[k]
        vabs = abs(vk)
        s = d * (xk - x_r)
        if s < 0.0:
            s = 0.0
        if s >= s_free:
            released = True
        # -- multiplicative factors on g at this sample (the rate factor depends on the velocity)
        fac0 = 1.0
        fac_v = 1.0
        if use_fac:
            if use_fade:
                fac0 *= 1.0 - kappa * (1.0 - math.exp(-E / e_fade))
            if use_ecc:
                fac0 *= 1.0 + e_ecc * math.cos(ecc_k * xk + psi)
            if use_app:
                fa = 1.0 + b_app * (a_sig[k] * inv_a_med - 1.0)
                fac0 *= fa if fa > 0.0 else 0.0
            if use_to:
                a_to = a_to_f if d > 0.0 else a_to_b
                if not slipping:
                    fac0 *= 1.0 + a_to
                else:
                    xs = s - s_b
                    if xs <= 0.0:
                        fac0 *= 1.0 + a_to
                    elif xs < x_to:
                        fac0 *= 1.0 + a_to * math.exp(-xs * inv_l_to)
            fac_v = fac0
            if use_rate:
                fac_v *= 1.0 + b_rate * math.log1p(vabs / v_ref)
            if use_sw:
                fac_v *= 1.0 + b_sw * math.expm1(-vabs * inv_vsw)

        # -- g of the sample velocity's direction (d when v == 0), and a(v) = s0|v|/g
        fwd = vk > 0.0 or (vk == 0.0 and d > 0.0)
        r = vabs * inv_vs
        r2 = r * r
        if fwd:
            if r2 > thr_f:
                gv = fc_f * fac_v
                av = c_f * vabs
            else:
                gv = (fc_f + (fs_f - fc_f) * math.exp(-r2)) * fac_v
                av = -1.0
        else:
            if r2 > thr_b:
                gv = fc_b * fac_v
                av = c_b * vabs
            else:
                gv = (fc_b + (fs_b - fc_b) * math.exp(-r2)) * fac_v
                av = -1.0
        if av < 0.0 or use_fac:
            av = s0 * vabs / gv if gv > 0.0 else 0.0

        if model == THREE_STAGE and s < s_sat:
            # backlash line, capped by g of direction d
            if fwd == (d > 0.0):
                gd = gv
            elif d > 0.0:
                gd = _stribeck(vabs, fc_f, fs_f, inv_vs, thr_f) * fac_v
            else:
                gd = _stribeck(vabs, fc_b, fs_b, inv_vs, thr_b) * fac_v
            if shared_exp:
                sp2, A, Cb = _blend_terms(s, d2, w, inv_w, a_sat, c_d2, c_d2i, c_d23)
            else:
                sp2 = _softplus(s - d2, w, inv_w)
                A = math.tanh(s * half_inv_w) if s < a_sat else 1.0
                Cb = _logistic(s - d2 - d3, inv_w)
            q = s - sp2
            if q < 0.0:
                q = 0.0
            elif q > d2:       # q <= d2 exactly; the subtraction's rounding can exceed it
                q = d2
            if use_p2:
                L = k2 * d2 * (q / d2) ** p2 + k3 * sp2
            else:
                L = k2 * q + k3 * sp2
            Fb = L if L < gd else gd
            if use_to and not slipping and (L >= gd or s >= s_tu):
                slipping = True
                s_b = s
            if not released:
                z = d * Fb * inv_s0
            if gv > 0.0:
                F1 = s0 * z + s1 * (vk - av * z) + s2 * vk
            else:
                z = 0.0
                F1 = s2 * vk
            Fk = (1.0 - A) * F_r + A * ((1.0 - Cb) * d * Fb + Cb * F1)
        else:
            if use_to and not slipping:     # s >= s_sat >= d2 + d3: slip has started
                slipping = True
                s_b = s
            if gv > 0.0:
                Fk = s0 * z + s1 * (vk - av * z) + s2 * vk
            else:
                z = 0.0
                Fk = s2 * vk

        if use_hump:
            fcd = fc_f if d > 0.0 else fc_b
            rh = s / l_h
            Fk += d * a_h * fcd * rh * math.exp(1.0 - rh)
        F[k] = Fk

        # -- advance the bristle state over the step k -> k+1 (exact for constant u)
        if k < n - 1:
            dx = x[k + 1] - xk
            if use_fade:
                E += abs(Fk * dx)
            # the next sample overwrites z (z = d Fb / s0, still inside the take-up) when it is
            # not released: then this update is dead. The reversal test is the one at the top of
            # the loop, applied to sample k + 1 (x_ext, x_r, d as they stand): keep the two alike
            dead = False
            if model == THREE_STAGE and backlash:
                xn = x[k + 1]
                if (rev[k + 1] != 0 if use_rev else
                        d * (xn - x_ext) <= 0.0 and d * (x_ext - xn) > eps):   # reversal at k + 1
                    dead = -d * (xn - xk) < s_free
                elif not released:
                    dead = d * (xn - x_r) < s_free
            if dx != 0.0 and not dead:
                uabs = abs(u[k])
                ru = uabs * inv_vs
                ru2 = ru * ru
                if not use_fac:
                    # a(u) dt = s0 |u| dt / g = s0 |dx| / g
                    if dx > 0.0:
                        if ru2 > thr_f:
                            if z != zss_f:
                                z = zss_f + (z - zss_f) * math.exp(-c_f * dx)
                        else:
                            gu = fc_f + (fs_f - fc_f) * math.exp(-ru2)
                            zss = gu * inv_s0
                            z = zss + (z - zss) * math.exp(-s0 * dx / gu)
                    else:
                        if ru2 > thr_b:
                            if z != zss_b:
                                z = zss_b + (z - zss_b) * math.exp(c_b * dx)
                        else:
                            gu = fc_b + (fs_b - fc_b) * math.exp(-ru2)
                            zss = -gu * inv_s0
                            z = zss + (z - zss) * math.exp(s0 * dx / gu)
                else:
                    fac_u = fac0
                    if use_rate:
                        fac_u *= 1.0 + b_rate * math.log1p(uabs / v_ref)
                    if use_sw:
                        fac_u *= 1.0 + b_sw * math.expm1(-uabs * inv_vsw)
                    if dx > 0.0:
                        gu = _stribeck(uabs, fc_f, fs_f, inv_vs, thr_f) * fac_u
                        zss = gu * inv_s0
                    else:
                        gu = _stribeck(uabs, fc_b, fs_b, inv_vs, thr_b) * fac_u
                        zss = -gu * inv_s0
                    if gu > 0.0:
                        z = zss + (z - zss) * math.exp(-s0 * abs(dx) / gu)
                    else:
                        z = 0.0


@njit(cache=True, error_model="numpy")
def simulate_one(x, v, u, dt, a_sig, a_med, P, model, eps, rev):
    F = np.empty(x.shape[0])
    simulate_into(x, v, u, dt, a_sig, a_med, P, model, eps, rev, F)
    return F


@njit(cache=True, parallel=True, error_model="numpy")
def simulate_many(x, v, u, dt, a_sig, a_med, Pmat, model, eps, rev):
    """Many parameter vectors (rows of Pmat) on one record -> forces (rows)."""
    m = Pmat.shape[0]
    out = np.empty((m, x.shape[0]))
    for i in prange(m):
        simulate_into(x, v, u, dt, a_sig, a_med, Pmat[i], model, eps, rev, out[i])
    return out


@njit(cache=True, error_model="numpy")
def simulate_many_serial(x, v, u, dt, a_sig, a_med, Pmat, model, eps, rev):
    """As simulate_many, on one thread (used when the batch is too small to pay for threads)."""
    m = Pmat.shape[0]
    out = np.empty((m, x.shape[0]))
    for i in range(m):
        simulate_into(x, v, u, dt, a_sig, a_med, Pmat[i], model, eps, rev, out[i])
    return out
