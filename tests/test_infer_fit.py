"""End-to-end synthetic recovery: simulate the BRFD model (published 267 N set) on a 25.4 mm,
0.2 Hz sine at 100 Hz (3 cycles), add white noise (1 % of fc) plus an AR(1) part, fit with the
default priors and sampler, and check that the fit converged by the project's rule (R-hat <= 1.01,
bulk and tail ESS >= 400 for every free parameter) and that the 95 % intervals contain the true
values. With 14 free parameters, about 0.7 of them fall outside their 95 % intervals by chance
(more than 2: about 3 % for independent intervals), so at most 2 may miss; the run is seeded,
hence deterministic. Takes a few minutes on 2 cores: marked slow."""
from __future__ import annotations

import json
from types import SimpleNamespace as NS

import numpy as np
import pytest

from frictionuq import published
from frictionuq.infer.fit import FitConfig, FitSpec, run_fit
from frictionuq.model import simulate


def synthetic_test(seed: int = 0, phi: float = 0.8):
    truth = published.brfd_params(267.0)
    t = np.arange(0, 15.0, 0.01)
    x = 0.0254 * np.sin(2 * np.pi * 0.2 * t)
    fc = 0.5 * (truth["fc_fwd"] + truth["fc_bwd"])
    rng = np.random.default_rng(seed)
    ar = np.empty(t.size)
    ar[0] = 0.01 * fc * rng.standard_normal()
    for k in range(1, t.size):
        ar[k] = phi * ar[k - 1] + 0.01 * fc * np.sqrt(1 - phi**2) * rng.standard_normal()
    y = simulate(t, x, truth) + 0.01 * fc * rng.standard_normal(t.size) + ar
    test = NS(id="synthetic-267N-0.2Hz", record=NS(t=t, x=x, force=y, applied=None),
              applied=267.0, kind="harmonic", frequency_hz=0.2)
    return test, {**truth, "force_offset": 0.0}


@pytest.mark.slow
def test_synthetic_recovery(tmp_path):
    test, truth = synthetic_test()
    spec = FitSpec("synthetic", [test], 267.0, FitConfig(seed=1))
    entry = run_fit(spec, tmp_path, "synthetic", resume=False)
    assert entry["converged"], f"not converged: {entry['not_converged_parameters']}"
    missed = []
    for name, row in entry["parameters"].items():
        if name in truth and "q2.5" in row:
            if not row["q2.5"] <= truth[name] <= row["q97.5"]:
                missed.append((name, truth[name], row["q2.5"], row["q97.5"]))
    assert len(missed) <= 2, f"true values outside the 95 % intervals: {missed}"
    rec = json.loads((tmp_path / "synthetic" / "fit.json").read_text())   # writable (no int64)
    assert rec["sampler"]["steps"] == entry["sampler_steps"]


def test_a_given_start_skips_the_multi_start_search(tmp_path, monkeypatch):
    """run_fit(start=...) (discover passes the screening's MAP): find_map only polishes the given
    point, never runs its multi-start search, and never ends below the start; a start that lacks
    a sampled parameter is refused before any work."""
    from frictionuq.infer import optimize
    from frictionuq.infer.fit import prepare
    test, truth = synthetic_test()
    spec = FitSpec("synthetic", [test], 267.0, FitConfig(seed=1, samples_per_cycle=50))
    _, scales, space, lp = prepare(spec)
    monkeypatch.setattr(optimize, "_multi_start", lambda *a, **k: pytest.fail("searched"))
    th0 = space.to_theta({n: truth[n] for n in space.names})
    th, lp_map, info = optimize.find_map(lp, scales, np.random.default_rng(0), start=th0)
    assert info["start"] == "given"
    assert lp_map >= float(lp.log_prob(th0[None, :])[0]) - 1e-9
    with pytest.raises(ValueError, match="lacks"):
        run_fit(spec, tmp_path, "synthetic", start={"fc_fwd": truth["fc_fwd"]})


def test_the_map_search_never_ends_below_a_start_it_refined(tmp_path, monkeypatch):
    """find_map refines its best starts on the full records by least squares; the first, raw
    least squares can lose log-posterior on AR(1) noise. Each start must compete with its
    refinements, so the MAP is at least as high as every start refined (the global searches'
    best included). Seen on a BRFD campaign with a hidden takeup_overshoot (seed 13), records
    kept at 50 Hz or more, the plain 3-stage model: the best global start had -26,819.5 on the
    full records and find_map returned -27,422.5, its best refinement (the polish gained nothing:
    scipy's bounded Powell wandered off to -28,965, see optimize.polish). Now -26,742.5: the start
    kept, and the polish's best point. Since 2026-11-28 the global runs go on until two agree (4
    here). Deterministic, about 30 s."""
    from dataclasses import replace
    from frictionuq.campaign import load_campaign
    from frictionuq.discrepancy import fits as F
    from frictionuq.discrepancy.hidden import hidden_campaign
    from frictionuq.infer import optimize
    hidden_campaign(tmp_path / "c", "brfd", "takeup_overshoot", seed=13, short=True)
    tests = list(load_campaign(tmp_path / "c").tests)
    cfg = replace(FitConfig(samples_per_cycle=100), min_kept_hz=50.0)
    lp, scales = F.logpost_for(tests, (), cfg)
    found = []
    real_global = optimize.global_start

    def recording(*a, **k):
        th, n = real_global(*a, **k)
        found.append(th)
        return th, n
    monkeypatch.setattr(optimize, "global_start", recording)
    _, lp_map, info = optimize.find_map(lp, scales, np.random.default_rng([1, 17, 0]))
    lp_global = lp.log_prob(np.array(found))
    print(f"MAP {lp_map:.1f}; global starts on the full records {np.round(lp_global, 1)}")
    # two global runs at least; more (optimize.GLOBAL_MAX_RUNS at most) until the best two agree
    assert 2 <= len(found) <= optimize.GLOBAL_MAX_RUNS and info["start"] == "search"
    assert len(found) == len(info["global_generations"])
    assert lp_map >= float(np.max(lp_global)) - 1e-6
    assert lp_map >= max(info["refined_starts_log_prob"]) - 1e-6


def test_polish_returns_its_best_point_with_that_points_log_posterior():
    """optimize.polish returns the best point Powell evaluated with the log-posterior it had
    there (no re-evaluation): the two must agree exactly, never fall below the start, and the
    point stays in the prior box. A two-parameter toy whose maximum lies outside the box (at x0 =
    2 against an upper bound of 1), as the real posteriors that press against a bound."""
    sp = NS(lo=np.array([0.0, -1.0]), hi=np.array([1.0, 1.0]), ndim=2)

    class Toy:
        space = sp

        def log_prob(self, X):
            X = np.atleast_2d(X)
            inside = np.all((X >= sp.lo) & (X <= sp.hi), axis=1)
            return np.where(inside, -(X[:, 0] - 2.0) ** 2 - (X[:, 1] - 0.3) ** 2, -np.inf)

    from frictionuq.infer import optimize
    toy = Toy()
    th0 = np.array([0.5, 0.0])
    lp0 = float(toy.log_prob(th0)[0])
    th, lp = optimize.polish(toy, th0, lp0)
    assert lp == float(toy.log_prob(th)[0])
    assert lp >= lp0
    assert np.all(th >= sp.lo) and np.all(th <= sp.hi)
    assert lp == pytest.approx(-1.0, abs=1e-8)       # the maximum on the box: (1, 0.3)
