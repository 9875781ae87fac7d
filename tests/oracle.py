"""Reference implementation of the 3-stage friction-damper model, for the tests only.

Written from the spec text (shared/spec/three-stage-model.md, sections 1-5) and the choices of
docs/model-choices.md, independently of src/frictionuq/kernel.py: plain Python loops over plain
floats, one sample at a time, every transcendental evaluated literally (no skipping of terms
that round away, no precomputed quotients). Slow on purpose; use records of a few thousand
samples at most.

Choices where neither the spec nor docs/model-choices.md says anything, made here and matched
by the kernel (a mismatch would show up in tests/test_kernel.py):
  * the reversal state (d, x_ext, x_r, F_r, s) is tracked in both models, so `reversal_hump`
    also applies to the pure LuGre model;
  * `stage2_nonlinear` with d2 = 0 keeps the term k2*q (q is then 0 up to rounding: there is no
    stage-2 travel to shape); with d2 > 0 the power law is evaluated on min(q, d2) (q <= d2
    holds exactly; the clamp only removes rounding of q, which (q/d2)^p2 amplifies when d2 is
    below ~1e-15 m);
  * F_r and the fade energy E use the full force F[k], hump included ("add ... to F").
"""
from __future__ import annotations

import math

import numpy as np

from frictionuq.params import EFFECTS, PARAMS

#: When z is released after the backlash. "per_sample" (the kernel before the fix): z is set at
#: every sample with s < d2+d3+5w, also when s falls back below that after having passed it, which
#: a dead band eps > 0 allows (motion reversing by less than eps is not a reversal); z then snaps
#: from its free value to d*Fb/sigma0: a force discontinuity. "latched": once s >= d2+d3+5w, z
#: evolves freely until the next reversal ("from s >= d2+d3+5w on, z evolves freely"), which keeps
#: F continuous. With eps = 0 the two agree (s never decreases within a half-cycle). The kernel
#: latches (docs/model-choices.md); "per_sample" stays available to show the difference.
Z_RELEASE = "latched"

BASE = ("fc_fwd", "fc_bwd", "fs_fwd", "fs_bwd", "v_s", "sigma0", "sigma1", "sigma2",
        "k2", "d2", "k3", "d3", "w")


def softplus(q, w):
    """sp(q) = w ln(1 + exp(q/w)), overflow-safe: w (max(y,0) + ln(1 + exp(-|y|)))."""
    y = q / w
    return w * (max(y, 0.0) + math.log1p(math.exp(-abs(y))))


def logistic(q, w):
    """m(q) = 1/(1 + exp(-q/w)), overflow-safe (exp only of non-positive arguments)."""
    y = q / w
    if y >= 0.0:
        return 1.0 / (1.0 + math.exp(-y))
    e = math.exp(y)
    return e / (1.0 + e)


def _effect_values(effects, model):
    """{param: value} of every effect parameter, with the neutral value for effects not given."""
    vals = {}
    for eff, names in EFFECTS.items():
        for n in names:
            p = PARAMS[n]
            vals[n] = p.neutral if p.neutral is not None else p.default
    for eff, given in (effects or {}).items():
        if eff not in EFFECTS:
            raise ValueError(f"unknown effect {eff!r}")
        if eff == "stage2_nonlinear" and model != "three_stage":
            raise ValueError("stage2_nonlinear needs the three_stage model")
        for n in EFFECTS[eff]:
            vals[n] = float((given or {}).get(n, PARAMS[n].default))
    return vals


def oracle_simulate(t, x, params: dict, effects: dict | None = None, model: str = "three_stage",
                    eps: float = 0.0, applied=None, *, return_trace: bool = False, _bug=None,
                    z_release: str | None = None):
    """Force (N) of the model driven by x (m) at times t (s); spec sections 1-5.

    return_trace: also return a dict of per-sample internals (F1, z at the force, s, d, Fb, A, Cb,
    z_set: whether z was set by the backlash rule, g: g at v[k]).
    _bug: deliberately broken variants, used only to prove that a test can fail:
      "F_r=0" (the blend restarts from 0 at a reversal), "no_z_set" (z is never set in the backlash).
    z_release: "per_sample" or "latched" (see Z_RELEASE, the default).
    """
    z_release = Z_RELEASE if z_release is None else z_release
    if z_release not in ("per_sample", "latched"):
        raise ValueError(z_release)
    t = [float(a) for a in t]
    x = [float(a) for a in x]
    n = len(x)
    if model not in ("three_stage", "lugre"):
        raise ValueError(model)
    P = {k: float(params[k]) for k in BASE}
    E_ = _effect_values(effects, model)
    fc = {1: P["fc_fwd"], -1: P["fc_bwd"]}
    fs = {1: P["fs_fwd"], -1: P["fs_bwd"]}
    v_s, s0, s1, s2 = P["v_s"], P["sigma0"], P["sigma1"], P["sigma2"]
    k2, d2, k3, d3, w = P["k2"], P["d2"], P["k3"], P["d3"], P["w"]
    on = effects or {}
    p2 = E_["p2"]
    kappa, e_fade = E_["kappa"], E_["e_fade"]
    a_hump, l_hump = E_["a_hump"], E_["l_hump"]
    eps_ecc, l_ecc, psi = E_["eps_ecc"], E_["l_ecc"], E_["psi_ecc"]
    beta_rate, v_ref = E_["beta_rate"], E_["v_ref"]
    beta_app = E_["beta_app"]
    a_to = {1: E_["a_to_fwd"], -1: E_["a_to_bwd"]}
    l_to = E_["l_to"]
    beta_sw, v_sw = E_["beta_sw"], E_["v_sw"]
    to_on = "takeup_overshoot" in on and model == "three_stage"
    if "applied_tracking" in on:
        if applied is None:
            raise ValueError("applied_tracking needs the applied signal")
        a_sig = [float(a) for a in applied]
        a_med = float(np.median(np.asarray(a_sig)))
    else:
        a_sig = None

    # -- section 1: velocities
    u = [(x[k + 1] - x[k]) / (t[k + 1] - t[k]) for k in range(n - 1)]
    v = [0.0] * n
    if n >= 2:
        v[0] = u[0]
        v[n - 1] = u[n - 2]
        for k in range(1, n - 1):
            v[k] = (x[k + 1] - x[k - 1]) / (t[k + 1] - t[k - 1])

    def sgn_dir(vel, d):
        if vel > 0:
            return 1
        if vel < 0:
            return -1
        return d

    def factor(k, vel, E, h_to=1.0):
        """Product of the multiplicative factors on g at sample k (velocity vel, energy E)."""
        f = h_to
        if "thermal_fade" in on:
            f *= 1.0 - kappa * (1.0 - math.exp(-E / e_fade))
        if "eccentricity" in on:
            f *= 1.0 + eps_ecc * math.cos(2.0 * math.pi * x[k] / l_ecc + psi)
        if "rate_strengthening" in on:
            f *= 1.0 + beta_rate * math.log(1.0 + abs(vel) / v_ref)
        if "applied_tracking" in on:
            f *= max(0.0, 1.0 + beta_app * (a_sig[k] / a_med - 1.0))
        if "speed_weakening" in on:
            f *= 1.0 - beta_sw * (1.0 - math.exp(-abs(vel) / v_sw))
        return f

    def g_of(direction, vel, fac):
        return (fc[direction] + (fs[direction] - fc[direction]) * math.exp(-(vel / v_s) ** 2)) * fac

    # -- section 4: initial state
    d = 1
    for j in range(1, n):
        if x[j] - x[0] != 0.0:
            d = 1 if x[j] - x[0] > 0 else -1
            break
    x_ext = x_r = x[0]
    F_r = 0.0
    released = False          # z_release == "latched": s has reached d2+d3+5w since the reversal
    slipping = False          # takeup_overshoot: slip has started since the reversal, at s = s_b
    s_b = 0.0
    z = 0.0
    E = 0.0
    F = [0.0] * n
    backlash = d2 > 0.0 or d3 > 0.0
    trace = {key: [0.0] * n for key in ("F1", "z", "s", "d", "Fb", "A", "Cb", "z_set", "g")}

    for k in range(n):
        if k >= 1:
            if d * (x[k] - x_ext) > 0:
                x_ext = x[k]
            elif d * (x_ext - x[k]) > eps:
                x_r = x[k - 1]
                F_r = F[k - 1] if _bug != "F_r=0" else 0.0
                d = -d
                x_ext = x[k]
                released = False
                slipping = False
        vk = v[k]
        s = max(0.0, d * (x[k] - x_r))
        h_to = 1.0
        if to_on:
            h_to = 1.0 + a_to[d] if not slipping else 1.0 + a_to[d] * math.exp(-max(0.0, s - s_b) / l_to)
        fac = factor(k, vk, E, h_to)
        gv = g_of(sgn_dir(vk, d), vk, fac)
        Fb = A = Cb = 0.0
        z_set = False
        if model == "three_stage":
            spd = softplus(s - d2, w)
            q = max(0.0, s - spd)
            if "stage2_nonlinear" in on and d2 > 0.0:
                # q <= d2 exactly (sp(y) >= y); the computed q carries an absolute rounding
                # error of ~ulp(s) from the cancellation s - sp(s - d2), which (q/d2)^p2 would
                # blow up when d2 << ulp(s): evaluate the spec's formula on min(q, d2)
                stage2 = k2 * d2 * (min(q, d2) / d2) ** p2
            else:
                stage2 = k2 * q
            L = stage2 + k3 * spd
            g_d = g_of(d, vk, fac)
            Fb = min(L, g_d)
            if to_on and not slipping and (L >= g_d or s >= d2 + d3):
                slipping = True
                s_b = s
            if s >= d2 + d3 + 5.0 * w and z_release == "latched":
                released = True
            if backlash and s < d2 + d3 + 5.0 * w and not released and _bug != "no_z_set":
                z = d * Fb / s0
                z_set = True
        if gv > 0.0:
            a_v = s0 * abs(vk) / gv
            F1 = s0 * z + s1 * (vk - a_v * z) + s2 * vk
        else:                              # no friction at this sample
            z = 0.0
            F1 = s2 * vk
        if model == "three_stage":
            A = math.tanh(s / (2.0 * w))
            Cb = logistic(s - d2 - d3, w)
            Fk = (1.0 - A) * F_r + A * ((1.0 - Cb) * d * Fb + Cb * F1)
        else:
            Fk = F1
        if "reversal_hump" in on:
            r = s / l_hump
            Fk += d * a_hump * fc[d] * r * math.exp(1.0 - r)
        F[k] = Fk
        for key, val in (("F1", F1), ("z", z), ("s", s), ("d", d), ("Fb", Fb), ("A", A),
                         ("Cb", Cb), ("z_set", float(z_set)), ("g", gv)):
            trace[key][k] = val

        # -- section 3: advance z over the step k -> k+1 (factors of the step's start sample k)
        if k < n - 1:
            uk = u[k]
            if uk != 0.0:
                fac_u = factor(k, uk, E, h_to)
                du = 1 if uk > 0 else -1
                gu = g_of(du, uk, fac_u)
                if gu > 0.0:
                    z_ss = du * gu / s0
                    a_u = s0 * abs(uk) / gu
                    z = z_ss + (z - z_ss) * math.exp(-a_u * (t[k + 1] - t[k]))
                else:
                    z = 0.0
            E += abs(Fk * (x[k + 1] - x[k]))

    F = np.array(F)
    if return_trace:
        return F, {key: np.array(val) for key, val in trace.items()}
    return F
