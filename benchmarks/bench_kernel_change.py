"""A kernel change against an earlier revision of src/frictionuq/kernel.py, side by side in one run:
speed per sample on the shipped records, and whether the forces are the same bits.

    .venv/bin/python benchmarks/bench_kernel_change.py [--against HEAD~1] [--walkers 16]
        [--repeat 3] [--random 300]

The earlier kernel is read with `git show REV:src/frictionuq/kernel.py` into a temporary module,
so both are compiled by the same numba. Cases (one thread, `simulate_many_serial`, `--walkers`
parameter sets jittered by 5 % around a centre): the real ARTS 35 lb sines of
data/brfd-arts-d1 at the baseline MAP that `frictionuq discover` found there on 2026-11-29
(REAL_35LB below), and the first three tests of each twin at the published values. Timing: the
two kernels alternate, best of `--repeat`. Identity: every case above, then `--random` random
records (2,000 samples, irregular steps, sines with or without jitter, a measured applied-force
channel) with parameter sets drawn over the whole prior box, effects on in half of them, both
models, eps 0 and > 0; the count of cases whose forces differ in any bit is printed (a kernel
change meant to be exact must print 0).
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from frictionuq import kernel as current
from frictionuq import params as P
from frictionuq.campaign import load_campaign
from frictionuq.model import _fx, pack_batch, prepare
from frictionuq.published import published_params

ROOT = Path(__file__).resolve().parents[1]
#: the baseline's MAP of `frictionuq discover data/brfd-arts-d1 --test sine-0.5Hz-35lb --test
#: sine-1Hz-35lb` (2026-11-29), SI
REAL_35LB = dict(fc_fwd=11010.16, fc_bwd=7386.03, fs_fwd=11058.08, fs_bwd=9971.15, v_s=0.049505,
                 sigma0=2.7730e7, sigma1=5.557, sigma2=1942.47, k2=168378.8, d2=5.7942e-3,
                 k3=3.94876e6, d3=2.837e-11, w=6.0797e-4)


def load_revision(rev: str, where: Path):
    got = subprocess.run(["git", "show", f"{rev}:src/frictionuq/kernel.py"], cwd=ROOT,
                         capture_output=True, text=True)
    if got.returncode != 0:
        why = got.stderr.strip().splitlines()[-1] if got.stderr.strip() else "git failed"
        print(f"bench_kernel_change: --against {rev}: no src/frictionuq/kernel.py there ({why})",
              file=sys.stderr)
        sys.exit(2)
    src = got.stdout
    path = where / "kernel_ref.py"
    path.write_text(src)
    spec = importlib.util.spec_from_file_location("kernel_ref", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def cases():
    c = load_campaign(ROOT / "data" / "brfd-arts-d1")
    for tid in ("sine-0.5Hz-35lb", "sine-1Hz-35lb"):
        r = c.test(tid).record
        yield f"real {tid}", r.t, r.x, REAL_35LB
    for dev, folder in (("brfd", "brfd-twin"), ("mfd", "mfd-twin")):
        c = load_campaign(ROOT / "data" / folder)
        for t in c.tests[:3]:
            yield f"{dev} twin {t.id}", t.record.t, t.record.x, published_params(dev, t.applied)


def args_for(d, M, model=0, eps=0.0):
    return (d.x, d.v, d.u, d.dt, _fx(d, M), d.a_med, M, model, eps)


def random_vector(rng, effects: bool) -> np.ndarray:
    v = np.concatenate([np.zeros(len(P.BASE_NAMES)), P.neutral_vector()])
    for j, name in enumerate(P.VECTOR_NAMES):
        p = P.PARAMS[name]
        if name in P.BASE_NAMES or (effects and rng.random() < 0.5):
            lo, hi = p.lower, p.upper
            if lo > 0 and np.isfinite(hi) and hi / lo > 100:
                v[j] = np.exp(rng.uniform(np.log(lo), np.log(hi)))
            elif np.isfinite(lo) and np.isfinite(hi):
                v[j] = rng.uniform(lo, hi)
    return v


def random_differences(ref, n_records: int) -> tuple[int, int]:
    rng = np.random.default_rng(1)
    total = differ = 0
    for trial in range(n_records):
        n = 2000
        t = np.cumsum(rng.uniform(0.5, 1.5, n)) * 1e-3
        amp = 10 ** rng.uniform(-4, -1.5)
        x = amp * np.sin(2 * np.pi * rng.uniform(0.2, 3) * t)
        if rng.random() < 0.5:
            x = x + 0.05 * amp * rng.standard_normal(n)
        d = prepare(t, x, 1 + 0.1 * rng.standard_normal(n))
        M = np.array([random_vector(rng, trial % 2 == 1) for _ in range(4)])
        for model in (current.THREE_STAGE, current.LUGRE):
            for eps in (0.0, amp * 1e-3):
                a = args_for(d, M, model, eps)
                total += 1
                differ += not np.array_equal(ref.simulate_many_serial(*a),
                                             current.simulate_many_serial(*a), equal_nan=True)
    return total, differ


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--against", default="HEAD~1", help="git revision of the earlier kernel")
    ap.add_argument("--walkers", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--random", type=int, default=300, help="random records for the identity check")
    a = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        ref = load_revision(a.against, Path(tmp))
        print(f"kernel of the working tree against {a.against}, one thread "
              f"(NUMBA_NUM_THREADS={os.environ.get('NUMBA_NUM_THREADS', 'unset')}), "
              f"{a.walkers} parameter sets per case")
        print(f"{'case':34s} {'samples':>8s} {a.against + ' ns':>12s} {'now ns':>8s} "
              f"{'speed-up':>9s}  same bits")
        for name, t, x, p in cases():
            M = pack_batch([{k: v * float(np.exp(rng.normal(0, 0.05))) for k, v in p.items()}
                            for _ in range(a.walkers)])
            d = prepare(t, x)
            args = args_for(d, M)
            same = np.array_equal(ref.simulate_many_serial(*args),
                                  current.simulate_many_serial(*args))
            best = {"ref": np.inf, "now": np.inf}
            for _ in range(a.repeat):
                for key, mod in (("ref", ref), ("now", current)):
                    t0 = time.perf_counter()
                    mod.simulate_many_serial(*args)
                    best[key] = min(best[key], time.perf_counter() - t0)
            per = {k: v / (a.walkers * d.n) * 1e9 for k, v in best.items()}
            print(f"{name:34s} {d.n:8d} {per['ref']:12.1f} {per['now']:8.1f} "
                  f"{per['ref'] / per['now']:9.2f}  {'yes' if same else 'NO'}")
        total, differ = random_differences(ref, a.random)
        print(f"\nrandom records and parameter sets: {total} cases, {differ} with different bits")


if __name__ == "__main__":
    main()
