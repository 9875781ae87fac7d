"""The seed papers' published parameter sets and tables (spec section 6), in SI.

Used by the data twins, by the `table` quick look and by the reports' comparison tables.
BRFD: Downey et al., Eng. Struct. 113 (2016) 287-298, Tables 1-4.
MFD: Cao et al., J. Sound Vib. (2015), Tables 1-4 (unit labels corrected as the spec says).
"""
from __future__ import annotations

from .units import INCH, LBF, PSI

# ---------------------------------------------------------------- BRFD (SI, per applied force)
BRFD_APPLIED_N = (35.0, 53.0, 66.0, 133.0, 267.0)
_BRFD_TABLE2_KN = {          # Table 2, kN (sigma0 in kN/m: the printed "kN^-1" is a typo)
    "fc_fwd": (0.805, 1.91, 13.3, 22.7, 37.3),
    "fc_bwd": (0.538, 0.521, 3.11, 13.4, 37.8),
    "fs_fwd": (0.894, 2.23, 14.2, 23.6, 39.1),
    "fs_bwd": (0.619, 0.579, 3.33, 14.2, 44.5),
    "sigma0": (525.0, 613.0, 1490.0, 5694.0, 9198.0),
}
BRFD_GEOMETRY = {"drum_radius": 0.15, "damping_radius": 0.10, "wrap_deg": 670.0,
                 "mu_design": 0.39, "C_design": 142.0}
#: Table 3: mechanical advantage and friction coefficient from the tests
BRFD_TABLE3 = {"C_fwd": 145.0, "C_bwd": 126.0, "mu_fwd": 0.42, "mu_bwd": 0.41,
               "C_design": 142.0, "mu_design": 0.39}
#: Table 4: fitting RMSE (N), {applied N: {freq Hz: (3-stage, LuGre)}}
BRFD_TABLE4_RMSE_N = {
    35.0: {0.05: (5.96e3, 15.4e3), 0.1: (6.98e3, 13.3e3), 0.2: (8.81e3, 21.1e3), 0.5: (14.3e3, 29.3e3)},
    53.0: {0.05: (3.07e3, 5.38e3), 0.1: (3.25e3, 5.38e3), 0.2: (3.51e3, 6.00e3), 0.5: (3.34e3, 5.47e3)},
    66.0: {0.05: (4.54e3, 44.5e3), 0.1: (2.80e3, 40.7e3), 0.2: (2.45e3, 55.1e3), 0.5: (4.00e3, 100e3)},
    133.0: {0.05: (7.56e3, 76.3e3), 0.1: (15.7e3, 127e3), 0.2: (44.1e3, 46.2e3), 0.5: (27.8e3, 117e3)},
    267.0: {0.05: (5.56e3, 115e3), 0.1: (9.56e3, 58.9e3), 0.2: (12.0e3, 40.5e3), 0.5: (22.7e3, 126e3)},
}
# test programme
BRFD_FREQS_HZ = (0.05, 0.1, 0.2, 0.5)
BRFD_AMPLITUDE_M = 25.4e-3
BRFD_EQ_APPLIED_N = (66.0, 133.0)
BRFD_EQ_PEAK_M = 0.01


def brfd_table2(applied_n: float) -> dict[str, float]:
    """Table 2 values (SI: N, N/m) at one of the tested applied forces."""
    i = _index(BRFD_APPLIED_N, applied_n, "BRFD applied force (N)")
    return {k: v[i] * 1e3 for k, v in _BRFD_TABLE2_KN.items()}


def brfd_params(applied_n: float) -> dict[str, float]:
    """The full BRFD parameter set at a tested applied force (spec section 6), SI."""
    p = brfd_table2(applied_n)
    fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
    d2, d3 = 1.5e-3, 0.5e-3
    p.update(v_s=1e-3, sigma1=500.0, sigma2=1000.0, w=0.2e-3, d2=d2, d3=d3,
             k2=0.05 * fc / d2, k3=0.45 * fc / d3)
    return p


# ---------------------------------------------------------------- MFD (SI, per pressure)
MFD_PRESSURES_PSI = (500.0, 800.0, 1200.0, 1500.0)
#: Table 4 slopes, kip per psi (the printed "kip/in^2" labels are off by 1000)
MFD_SLOPES_KIP_PER_PSI = {"fc_fwd": 0.341e-3, "fc_bwd": 0.457e-3, "fs_fwd": 0.350e-3, "fs_bwd": 0.467e-3}
MFD_SIGMA0_KIP_PER_IN = (0.002, 3.029)      # sigma0 = a p + b (p in psi)
MFD_FREQS_HZ = (0.05, 0.5)
MFD_AMPLITUDE_M = 1.0 * INCH
MFD_EQ_APPLIED_PSI = (500.0, 1000.0)
MFD_EQ_PEAK_M = 0.4 * INCH
#: Tables 2 (0.05 Hz) and 3 (0.5 Hz): experimental values, kip (sigma0 kip/in), per psi
MFD_TABLE2_EXP = {
    0.05: {"fc_fwd": (0.142, 0.239, 0.403, 0.530), "fc_bwd": (0.181, 0.295, 0.549, 0.710),
           "fs_fwd": (0.152, 0.251, 0.417, 0.549), "fs_bwd": (0.185, 0.305, 0.563, 0.727),
           "sigma0": (4.054, 4.754, 5.054, 6.254)},
    0.5: {"fc_fwd": (0.143, 0.260, 0.412, 0.536), "fc_bwd": (0.183, 0.340, 0.587, 0.710),
          "fs_fwd": (0.155, 0.269, 0.417, 0.538), "fs_bwd": (0.188, 0.341, 0.595, 0.730),
          "sigma0": (4.082, 4.702, 5.282, 6.222)},
}


def mfd_params(pressure_psi: float) -> dict[str, float]:
    """The MFD parameter set at pressure p (psi), spec section 6, converted to SI."""
    p = float(pressure_psi)
    kip = 1e3 * LBF
    out = {k: s * p * kip for k, s in MFD_SLOPES_KIP_PER_PSI.items()}
    a, b = MFD_SIGMA0_KIP_PER_IN
    out["sigma0"] = (a * p + b) * kip / INCH
    out.update(sigma1=1.0 * LBF / INCH, sigma2=1.0 * LBF / INCH,
               k2=0.231 * kip / INCH, k3=3.0 * kip / INCH, d2=0.5 * INCH, d3=0.2 * INCH,
               w=0.1 * INCH, v_s=0.1 * INCH)
    return out


def mfd_mechanical_advantage(direction: str) -> float:
    """MFD Table 4: kinetic friction force per applied pressure, N/Pa (C = F / p)."""
    return MFD_SLOPES_KIP_PER_PSI[f"fc_{direction}"] * 1e3 * LBF / PSI


def published_params(device: str, applied_si: float) -> dict[str, float]:
    """Published parameters of `device` ('brfd' or 'mfd') at the published level nearest to
    `applied_si` (N for the BRFD, Pa for the MFD)."""
    device = device.lower()
    if device == "brfd":
        level = min(BRFD_APPLIED_N, key=lambda a: abs(a - applied_si))
        return brfd_params(level)
    if device == "mfd":
        return mfd_params(applied_si / PSI)
    raise ValueError(f"unknown device {device!r}; use 'brfd' or 'mfd'")


def _index(levels, value, what) -> int:
    for i, lv in enumerate(levels):
        if abs(lv - value) <= 1e-9 * max(1.0, abs(lv)):
            return i
    raise ValueError(f"{what} {value:g} is not a published level; published: "
                     f"{', '.join(f'{v:g}' for v in levels)}")
