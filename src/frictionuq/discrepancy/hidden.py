"""Campaigns with one hidden effect (or none), for testing the discrepancy workflow.

A campaign of three tests at one applied force of a paper device (BRFD or MFD, published
parameters): two harmonics and one ground-motion replay, about 5,000 samples each at 100 Hz, with
one effect of the library switched on at parameters drawn at random within realistic ranges, and
AR(1) force noise. The generator's answer (effect, parameters, noise scale) is returned separately
and written to a file OUTSIDE the campaign folder, so the workflow never sees it.

ramp=True appends a fourth test, a sine of geometrically growing amplitude (an experiment of
2026-11-26 on stage2_nonlinear: 2 of 8 BRFD draws named against 1 of 8, none of 4 MFD;
not used by the CI or the benchmark's default set; docs/log-discrepancy.md).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import atomic, published as pub
from ..model import simulate
from ..noise import ar1_from_normals, chatter_gain, since_reversal
from ..params import NOISE_EFFECTS
from ..twins import earthquake_drive, harmonic_drive

LEVEL = {"brfd": 133.0, "mfd": 1200.0}          # applied force (N) / pressure (psi)
NOISE_PHI = 0.9
NOISE_REL_SD = 0.01                             # marginal sd, fraction of Fc


def applied_signals(t, a_si: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """(actual, measured) applied force (SI) of a test: the actuator's force wanders around its
    nominal value, smoothly (a slow sine of 8 % and three random components of 2 % between 0.05
    and 1 Hz: a servo actuator does not follow white noise), and its load cell reads it with 0.3 %
    white noise. The friction follows the actual force; the record carries the measured one."""
    actual = 1.0 + 0.08 * np.sin(2 * np.pi * 0.37 * t + rng.uniform(0, 2 * np.pi))
    for f in rng.uniform(0.05, 1.0, 3):
        actual += 0.02 * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    actual *= a_si
    return actual, actual + 0.003 * a_si * rng.standard_normal(t.size)


SHORT_EQ_SECONDS = 30.0


def strong_motion(t, x, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """The `seconds` of a ground-motion displacement from 1 s before |x| first exceeds 1 % of its
    peak, time restarted at 0. The Kobe replay's first 10 s are pre-event quiet (0.1 mm of
    motion), which carries no information on any effect; 30 s from 10 s hold the strong pulse
    (22 mm peak to peak), the moderate motion after it (12.7 mm) and small cycles inside the
    backlash (1.8 mm), whose varying amplitudes show the shape of the stage-2 line. Measured on
    the hidden stage2_nonlinear campaigns of seeds 11 and 12 (both devices): named 0 of 4 with
    the first 20 s, 1 of 4 with 20 s from here, 2 of 4 with 30 s (docs/log-discrepancy.md)."""
    t0 = t[int(np.argmax(np.abs(x) > 0.01 * np.max(np.abs(x))))] - 1.0
    keep = (t >= t0) & (t < t0 + seconds)
    return t[keep] - t[keep][0], x[keep]


def draw_effect(effect: str | None, rng, amp: float, v_max: float, energy: float) -> dict:
    """Effect parameters within realistic ranges (scaled to the drive where they are lengths).

    The effects of _ALWAYS_DRAWN are all drawn, whichever is hidden (the campaigns' random stream
    since 2026-11-22); an effect added later goes in _DRAWN_WHEN_HIDDEN and draws after them,
    only when hidden, so that adding it leaves every other campaign's noise as it was."""
    drawn = {name: f(rng.uniform, amp, v_max, energy) for name, f in _ALWAYS_DRAWN.items()}
    if effect in _DRAWN_WHEN_HIDDEN:
        return _DRAWN_WHEN_HIDDEN[effect](rng.uniform, amp, v_max, energy)
    return drawn[effect]


_ALWAYS_DRAWN = {
    None: lambda u, amp, v_max, energy: {},
    "stage2_nonlinear": lambda u, amp, v_max, energy: {"p2": float(u(1.8, 3.0))},
    "thermal_fade": lambda u, amp, v_max, energy: {"kappa": float(u(0.15, 0.3)),
                                                   "e_fade": float(u(0.2, 0.5) * energy)},
    "reversal_hump": lambda u, amp, v_max, energy: {"a_hump": float(u(0.3, 0.6)),
                                                    "l_hump": float(u(0.06, 0.15) * amp)},
    "eccentricity": lambda u, amp, v_max, energy: {"eps_ecc": float(u(0.12, 0.25)),
                                                   "l_ecc": float(u(0.4, 0.8) * amp),
                                                   "psi_ecc": float(u(-3.0, 3.0))},
    "rate_strengthening": lambda u, amp, v_max, energy: {"beta_rate": float(u(0.2, 0.4)),
                                                         "v_ref": float(u(0.05, 0.2) * v_max)},
    "applied_tracking": lambda u, amp, v_max, energy: {"beta_app": float(u(0.6, 1.0))},
    "takeup_overshoot": lambda u, amp, v_max, energy: {"a_to_fwd": float(u(0.3, 0.6)),
                                                       "a_to_bwd": float(u(-0.25, 0.25)),
                                                       "l_to": float(u(0.08, 0.2) * amp)},
}
_DRAWN_WHEN_HIDDEN = {
    "speed_weakening": lambda u, amp, v_max, energy: {"beta_sw": float(u(0.2, 0.35)),
                                                      "v_sw": float(u(0.3, 0.6) * v_max)},
    # a noise effect: the noise sd up to 2.2-4.6 times in a window after each reversal (the real
    # ARTS loops: a_ch about 29 at 35 lb, s_ch 13 mm of a 25 mm amplitude, w_ch 3.3 mm)
    "chatter": lambda u, amp, v_max, energy: {"a_ch": float(u(4.0, 20.0)),
                                              "s_ch": float(u(0.3, 0.8) * amp),
                                              "w_ch": float(u(0.08, 0.15) * amp)},
}


RAMP_FREQ_HZ = 0.5
RAMP_CYCLES = 10
RAMP_START = 0.02          # first cycle's amplitude, fraction of the full amplitude


def ramp_drive(frequency_hz: float, amp: float, cycles: int = RAMP_CYCLES,
               start: float = RAMP_START, fs: float = 100.0) -> tuple[np.ndarray, np.ndarray]:
    """A sine whose amplitude grows geometrically from start x amp to amp over `cycles` cycles:
    reversals at amplitudes spread evenly on a log scale (from inside the backlash to the full
    stroke), like the ramped sines of the ARTS programme (data/brfd-arts-d1)."""
    n = int(round(cycles / frequency_hz * fs))
    t = np.arange(n + 1) / fs
    env = amp * np.exp(np.log(start) * (1.0 - t / t[-1]))
    return t, env * np.sin(2 * np.pi * frequency_hz * t)


def hidden_campaign(out_dir, device: str, effect: str | None, seed: int,
                    answer_path=None, short: bool = False, eq_seconds: float = SHORT_EQ_SECONDS,
                    eq_from: str = "strong", ramp: bool = False,
                    ramp_start: float = RAMP_START, also: str | None = None) -> dict:
    """Write a 3-test campaign with `effect` hidden (None: no effect) to out_dir; returns the
    answer {effect, parameters, noise_sd_N, ...} (also written to answer_path if given).
    short: 4 cycles per harmonic and `eq_seconds` of the ground motion, from its strong motion
    (eq_from="strong", strong_motion) or from its start ("start": the CI campaigns before
    2026-11-25, night, whose Kobe replay was the first 20 s). ramp: a fourth test, a sine of
    geometrically growing amplitude (ramp_drive) from ramp_start x the full amplitude (1: a
    constant-amplitude sine of the same length, the control that adds the data without the
    small reversals). also: a second effect hidden with the first (discover --max-effects), its
    parameters drawn from a separate random stream, so that the campaign is the one-effect
    campaign of the same seed plus this effect; the answer lists both under "effects"."""
    if eq_from not in ("strong", "start"):
        raise ValueError(f"hidden_campaign: eq_from must be 'strong' or 'start', got {eq_from!r}")
    out = Path(out_dir)
    rng = np.random.default_rng([seed, 4242])
    level = LEVEL[device]
    if device == "brfd":
        p = pub.published_params("brfd", level)
        amp, freqs, unit_applied = pub.BRFD_AMPLITUDE_M, (0.2, 0.5), "N"
        a_si = level
    else:
        p = pub.published_params("mfd", level * 6894.757293168)
        amp, freqs, unit_applied = pub.MFD_AMPLITUDE_M, (0.1, 0.5), "psi"
        a_si = level * 6894.757293168
    drives = []
    for f in freqs:
        t, x = harmonic_drive(f, amp, cycles=4 if short else max(4, int(round(50 * f))))
        drives.append((f"h-{f:g}Hz", "harmonic", f, t, x))
    t, x = earthquake_drive("kobe", 0.5 * amp)
    if short:
        t, x = strong_motion(t, x, eq_seconds) if eq_from == "strong" else \
            (t[t < eq_seconds], x[t < eq_seconds])
    drives.append(("eq-kobe", "earthquake", None, t, x))
    if ramp:      # appended last: the other tests' random draws stay as without it
        t, x = ramp_drive(RAMP_FREQ_HZ, amp, start=ramp_start)
        drives.append((f"ramp-{RAMP_FREQ_HZ:g}Hz", "other", RAMP_FREQ_HZ, t, x))
    v_max = max(float(np.max(np.abs(np.gradient(x, t)))) for tid, _, _, t, x in drives
                if not tid.startswith("ramp"))     # the effect draws as without the ramp
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    e_ref = 4 * fc * amp * 10                   # energy of ~10 harmonic cycles (J)
    eff_p = draw_effect(effect, rng, amp, v_max, e_ref)
    effects = {effect: eff_p} if effect else {}
    if also is not None:
        if also == effect or effect is None:
            raise ValueError(f"hidden_campaign: also={also!r} needs a different first effect")
        effects[also] = draw_effect(also, np.random.default_rng([seed, 4243]), amp, v_max, e_ref)
    noise_effects = [e for e in effects if e in NOISE_EFFECTS]
    sd = NOISE_REL_SD * fc
    tests, toml = [], []
    (out / "tests").mkdir(parents=True, exist_ok=True)
    for tid, kind, f, t, x in drives:
        n = t.size
        actual, measured = applied_signals(t, a_si, rng)
        F = simulate(t, x, p, effects=effects or None, eps=0.0,
                     applied=actual if "applied_tracking" in effects else None)
        noise = ar1_from_normals(rng.standard_normal(n), NOISE_PHI, sd)
        for e in noise_effects:      # chatter: more noise in a window after each reversal
            q = effects[e]
            noise = noise * chatter_gain(since_reversal(x), q["a_ch"], q["s_ch"], q["w_ch"])[0]
        y = F + noise
        a_out = measured if unit_applied == "N" else measured / 6894.757293168
        body = "time,displacement,force,applied\n" + "".join(
            f"{a:.6f},{b:.9g},{c:.6f},{d:.6f}\n" for a, b, c, d in zip(t, x, y, a_out))
        atomic.write_text(out / "tests" / f"{tid}.csv", body)
        tests.append({"id": tid, "samples": n})
        toml.append(f'[[tests]]\nid = "{tid}"\nfile = "tests/{tid}.csv"\napplied = {level:g}\n'
                    f'kind = "{kind}"\n' + (f"frequency_hz = {f:g}\n" if f else ""))
    head = (f'name = "hidden-{device}-{seed}"\ndevice = "{device.upper()} '
            f'paper twin with a hidden effect"\n[units]\ntime = "s"\ndisplacement = "m"\n'
            f'force = "N"\napplied = "{unit_applied}"\n\n')
    atomic.write_text(out / "campaign.toml", head + "\n".join(toml))
    answer = {"device": device, "effect": effect or "none", "parameters": eff_p,
              "effects": effects, "seed": seed,
              "noise_sd_N": sd, "noise_phi": NOISE_PHI, "applied": level,
              "applied_unit": unit_applied, "tests": tests}
    if answer_path is not None:
        atomic.write_json(answer_path, answer)
    return answer
