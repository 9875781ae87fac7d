"""Does displacement noise bias the bristle stiffness? A 35 lb-like BRFD level (the real arts-d1
fit's posterior means as the truth, v_s set inside its prior), two 25 mm sines (0.5 and 1 Hz,
six cycles each) at 1024 Hz, AR(1) force noise (phi 0.8, sd 1 kN), and the displacement the fit
sees with white noise of the ARTS records' sd (1.6 um) or none. One fit per configuration (16
chains, at most 1,500 stored steps; a few minutes each on 2 cores), printing the 95 % intervals
of sigma0, v_s and sigma1 beside the truth:

    .venv/bin/python benchmarks/bench_reversal.py [--configs clean noisy ...]

The configurations: the clean drive (eps = 0), the noisy drive with the spec's reversal rule
and the recorded samples ("noisy": the defaults until 2026-12-01 night; eps = 8 x the noise sd),
with --drive-lowpass 20, with reversal "extreme", and with both ("noisy+both": the defaults
since). Measured 2026-12-01 (docs/log-calibration.md): only both together give the clean
drive's posterior."""
from __future__ import annotations

import argparse
import time
from types import SimpleNamespace as NS

import numpy as np

from frictionuq.infer.fit import FitConfig, FitSpec, run_fit
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.model import simulate
from frictionuq.noise import ar1_from_normals

TRUTH = dict(fc_fwd=14500.0, fc_bwd=12800.0, fs_fwd=15500.0, fs_bwd=13700.0, v_s=0.01,
             sigma0=2.5e7, sigma1=1000.0, sigma2=10000.0, k2=3.5e5, d2=0.007, k3=5e6,
             d3=0.008, w=6e-4)
CONFIGS = {"clean": (0.0, None, "detection"), "noisy": (1.6, None, "detection"),
           "noisy+lowpass": (1.6, 20.0, "detection"), "noisy+extreme": (1.6, None, "extreme"),
           "noisy+both": (1.6, 20.0, "extreme")}


def tests(noise_um: float):
    rng = np.random.default_rng(11)
    out = []
    for f in (0.5, 1.0):
        t = np.arange(0, 6.0 / f, 1 / 1024)
        x = 0.025 * np.sin(2 * np.pi * f * t)
        y = simulate(t, x, TRUTH) + ar1_from_normals(rng.standard_normal(t.size), 0.8, 1000.0)
        xm = x + noise_um * 1e-6 * rng.standard_normal(t.size)
        out.append(NS(id=f"s{f:g}", record=NS(t=t, x=xm, force=y, applied=None), applied=156.0,
                      kind="harmonic", frequency_hz=f))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--configs", nargs="+", choices=list(CONFIGS), default=list(CONFIGS))
    ap.add_argument("--out", default="/tmp/bench-reversal")
    a = ap.parse_args(argv)
    print(f"{'config':<15}{'sigma0 95 % (N/m)':>28}{'v_s 95 % (mm/s)':>20}{'sigma1 95 % (N s/m)':>24}"
          f"{'truth inside':>14}{'s':>6}")
    for name in a.configs:
        noise, lp, rev = CONFIGS[name]
        cfg = FitConfig(seed=1, drive_lowpass=lp, reversal=rev,
                        sampler=SamplerConfig(max_steps=1500, progress=False))
        t0 = time.perf_counter()
        e = run_fit(FitSpec(name, tests(noise), 156.0, cfg), f"{a.out}/{name}", "bench", resume=False)
        p = e["parameters"]
        inside = [n for n in ("sigma0", "v_s", "sigma1")
                  if p[n]["q2.5"] <= TRUTH[n] <= p[n]["q97.5"]]
        print(f"{name:<15}{p['sigma0']['q2.5']:>13.3g} - {p['sigma0']['q97.5']:<12.3g}"
              f"{p['v_s']['q2.5'] * 1e3:>9.3g} - {p['v_s']['q97.5'] * 1e3:<8.3g}"
              f"{p['sigma1']['q2.5']:>11.3g} - {p['sigma1']['q97.5']:<10.3g}"
              f"{','.join(inside) or 'none':>14}{time.perf_counter() - t0:6.0f}", flush=True)


if __name__ == "__main__":
    main()
