"""Sampler helpers (fast): burn-in re-initialisation, walker count, JSON-safe fit records and the
prior-bound flag of the identifiability report."""
from __future__ import annotations

import json

import numpy as np
import pytest

from frictionuq.infer.fit import jsonable
from frictionuq.infer.outputs import identifiability
from frictionuq.infer.priors import Prior
from frictionuq.infer.sampler import SamplerConfig, _nwalkers
from frictionuq.infer.walkers import reinitialise
from frictionuq.infer.space import Space


def test_reinitialise_draws_distinct_states_and_drops_stuck_walkers():
    rng = np.random.default_rng(0)
    steps, W, D = 40, 16, 3
    chain = rng.normal(size=(steps, W, D))
    chain[:, 5] = 100.0                      # a stuck walker: never moves, far below the others
    chain[10:20, 3] = chain[10, 3]           # rejected proposals repeat a state
    lp = np.full((steps, W), -1.0)
    lp[:, 5] = -1e4
    p, stuck = reinitialise(chain, lp, W, rng)
    assert stuck == 1
    assert p.shape == (W, D)
    assert not np.any(np.all(p == 100.0, axis=1))
    assert np.unique(p, axis=0).shape[0] == W          # no two walkers identical


def test_reinitialise_with_a_tiny_pool_still_gives_distinct_walkers():
    rng = np.random.default_rng(1)
    chain = np.repeat(rng.normal(size=(1, 8, 2)), 4, axis=0)   # nobody moved
    p, _ = reinitialise(chain, np.zeros((4, 8)), 20, rng)
    assert p.shape == (20, 2) and np.unique(p, axis=0).shape[0] == 20


def test_walker_count_needs_more_than_twice_ndim():
    assert _nwalkers(SamplerConfig(), 14) == 32
    assert _nwalkers(SamplerConfig(), 20) == 44
    with pytest.raises(ValueError, match="more than 2 x ndim"):
        _nwalkers(SamplerConfig(nwalkers=20), 10)


def test_jsonable_turns_numpy_scalars_into_json():
    rec = {"steps": np.int64(5), "acc": np.float32(0.5), "ok": np.bool_(True),
           "tau": np.arange(3.0), "nested": [{"n": np.int32(2)}], 3: "key"}
    out = json.loads(json.dumps(jsonable(rec)))
    assert out == {"steps": 5, "acc": 0.5, "ok": True, "tau": [0.0, 1.0, 2.0],
                   "nested": [{"n": 2}], "3": "key"}


def _three_free_space():
    """fc_fwd on [0, 10], d3 and v_s on [0, 1] free, the rest fixed."""
    pri = {"fc_fwd": Prior("fc_fwd", "uniform", 0.0, 10.0), "d3": Prior("d3", "uniform", 0.0, 1.0),
           "v_s": Prior("v_s", "uniform", 0.0, 1.0),
           "sigma_noise": Prior("sigma_noise", "loguniform", 0.1, 10.0)}
    fixed = {n: 1.0 for n in ("fc_bwd", "fs_fwd", "fs_bwd", "sigma0", "sigma1", "sigma2", "k2",
                              "d2", "k3", "w")}
    return Space("three_stage", (), "iid", pri, fixed)


def test_identifiability_flags_posteriors_at_a_prior_bound():
    sp = _three_free_space()
    rng = np.random.default_rng(2)
    th = np.stack([rng.normal(5, 0.1, 4000), rng.uniform(0, 0.005, 4000),
                   1 - rng.uniform(0, 0.005, 4000)], axis=1)
    rep = identifiability(sp, {"theta": th.reshape(2, 2000, 3)})
    assert rep["at_prior_bound"] == {"d3": "lower", "v_s": "upper"}


def test_identifiability_flags_a_wide_posterior_cut_off_by_a_bound_not_one_merely_near_it():
    """The demo's 36 lb v_s: 95 % interval [41.6, 56.0] mm/s against a bound of 56.1, the
    histogram piled at the bound. A rule on the interval's distance from the bound (the whole
    interval within 2 % of the prior width) missed it; the density at the bound does not."""
    sp = _three_free_space()
    rng = np.random.default_rng(3)
    n = 4000
    th = np.stack([rng.normal(5.0, 0.1, n),                       # fc_fwd: well inside
                   rng.normal(0.02, 0.003, n),                     # d3: near the bound, not at it
                   1 - np.abs(rng.normal(0.0, 0.1, n))], axis=1)   # v_s: cut off at its upper bound
    rep = identifiability(sp, {"theta": th.reshape(2, n // 2, 3)})
    assert rep["at_prior_bound"] == {"v_s": "upper"}
    assert "v_s" not in rep["close_to_prior"]
    # a posterior as wide as its prior touches both bounds but is reported as close to the prior
    th[:, 2] = rng.uniform(0, 1, n)
    rep = identifiability(sp, {"theta": th.reshape(2, n // 2, 3)})
    assert rep["at_prior_bound"] == {} and "v_s" in rep["close_to_prior"]


def test_identifiability_flags_a_bound_cut_mode_beside_a_far_one_not_close_to_the_prior():
    """The real 70 lb level of arts-d1 (2026-12-06): v_s's draws in two modes, 73 % in the top
    2.4 % of the box (cut by the bound) and the rest far below. Its sd was 0.93 of the prior's,
    so the sd rule alone listed it as close to the prior and never checked the bound. Its
    Kolmogorov-Smirnov distance to the prior (0.71 there) now keeps it out of that list; a
    posterior spread like the prior is still listed (distance ~0.01)."""
    from frictionuq.infer.outputs import PRIOR_LIKE_KS, ks_to_prior
    sp = _three_free_space()
    rng = np.random.default_rng(4)
    n = 4000
    cut = 1 - np.abs(rng.normal(0.0, 0.01, n))                 # piled at the upper bound
    far = rng.uniform(0.05, 0.5, n)                           # a second mode far below it
    v_s = np.where(rng.uniform(size=n) < 0.73, cut, far)
    th = np.stack([rng.normal(5.0, 0.1, n), rng.uniform(0, 1, n), v_s], axis=1)
    rep = identifiability(sp, {"theta": th.reshape(2, n // 2, 3)})
    assert rep["posterior_over_prior_sd"]["v_s"] > 0.5           # the sd rule's "close"
    assert rep["ks_to_prior"]["v_s"] > PRIOR_LIKE_KS
    assert "v_s" not in rep["close_to_prior"] and rep["at_prior_bound"] == {"v_s": "upper"}
    assert "d3" in rep["close_to_prior"] and rep["ks_to_prior"]["d3"] < 0.05   # uniform draws
    # the distance itself: 0 for the prior's own quantiles, 0.5 for all draws in one half
    q = (np.arange(1000) + 0.5) / 1000
    assert ks_to_prior(sp, 1, q) == pytest.approx(0.0005)
    assert ks_to_prior(sp, 1, 0.5 + 0.5 * q) == pytest.approx(0.5, abs=1e-3)


def test_an_unreadable_stored_chain_is_started_afresh(tmp_path):
    """A chain file left unreadable (a process killed inside an HDF5 write) is not resumed and
    does not fail the fit: it is replaced, and the log says why."""
    from frictionuq.infer.storage import open_backend
    p = tmp_path / "chain.h5"
    p.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\x00" * 64)     # an HDF5 signature and nothing more
    msgs = []
    be, done = open_backend(p, 8, 3, resume=True, log=msgs.append)
    assert done == 0 and be.iteration == 0
    assert msgs and "unreadable" in msgs[0] and "starting afresh" in msgs[0]


def _narrow_start_burn_in(burn_stable: float, burn_shift: float):
    """Burn-in on a 14-D standard Gaussian (the twin fit's dimension and walker count) from a
    start ball 1,000 times too narrow along the first axis (as the Gauss-Newton ball of the BRFD
    twin's d3, 0.009 of its posterior sd): (proposal, steps run)."""
    from frictionuq.infer.burnin import burn_in

    def target(x):
        return (-0.5 * np.sum(x * x, axis=1))[:, None]

    rng = np.random.default_rng(3)
    state = rng.standard_normal((32, 14)) * np.r_[1e-3, np.ones(13)]
    cfg = SamplerConfig(nwalkers=32, burn_steps=100, burn_rounds=2, burn_max_rounds=20,
                        burn_stable=burn_stable, burn_shift=burn_shift, progress=False)
    state, proposal, steps = burn_in(target, state, cfg, seed=7, rng=rng)
    return proposal, steps


def test_burn_in_goes_on_until_the_ensemble_has_spread():
    """With the proposal-stability rule the burn-in runs until the fitted proposal stops changing,
    and the proposal the stored run keeps then has the posterior's width along the axis the start
    ball missed (every sd within 25 % of 1); without the rule it stops after the minimum two
    rounds with a proposal far too narrow there (measured 0.04), which the independence move
    would then almost never accept from. Fixed seeds: deterministic."""
    prop, steps = _narrow_start_burn_in(1.25, 0.5)
    sd = prop.x_width
    assert steps > 200
    assert np.all(np.abs(sd - 1.0) < 0.25), sd
    prop_old, steps_old = _narrow_start_burn_in(np.inf, np.inf)
    assert steps_old == 200
    assert prop_old.x_width[0] < 0.25


def test_independent_chains_move_each_walker_on_its_own_and_sample_the_target():
    """The stored run's moves with `run_walkers` (the independence move fitted to a small,
    shifted pool, plus the random walk with that pool's covariance) on the skewed 3-D target of
    test_infer_proposal: no ensemble move among them, and 8 walkers x 4,000 steps give the exact
    means, variances and 10 % / 90 % quantiles of x0 within 5 standard errors (>= 3,000
    effective draws; false-alarm rate below 1e-5), with R-hat over the walkers below 1.01."""
    import emcee
    from frictionuq import azadapter
    from frictionuq.infer.proposal import IndependenceMove, Proposal, RandomWalkMove
    from frictionuq.infer.burnin import moves_for
    from test_infer_proposal import _log_p, _skewed, check_skewed_sample
    pool = _skewed(600, np.random.default_rng(7)) + np.array([0.2, 0.0, -0.1])
    moves = moves_for(SamplerConfig(run_walkers=8), Proposal.fit(pool), stored=True)
    assert [type(m) for m, _ in moves] == [IndependenceMove, RandomWalkMove]
    assert [w for _, w in moves] == [0.8, pytest.approx(0.2)]
    s = emcee.EnsembleSampler(8, 3, _log_p, vectorize=True, moves=moves)
    s.random_state = np.random.RandomState(8).get_state()
    s.run_mcmc(_skewed(8, np.random.default_rng(9)), 4000, progress=False)
    chain = s.get_chain(discard=500)
    ch = chain.reshape(-1, 3)
    tau = np.max(emcee.autocorr.integrated_time(chain, quiet=True))
    assert np.max(azadapter.diagnostics(np.transpose(chain, (1, 0, 2)))["r_hat"]) < 1.01
    check_skewed_sample(ch, ch.shape[0] / tau)


def test_run_walkers_is_refused_below_four_and_weight_above_one():
    from frictionuq.errors import InputError
    with pytest.raises(InputError, match="stored_run must be one of chains, ensemble, got 'chain'"):
        SamplerConfig(stored_run="chain")
    with pytest.raises(InputError, match="run_walkers"):
        SamplerConfig(run_walkers=3)
    with pytest.raises(InputError, match="independence_weight"):
        SamplerConfig(independence_weight=1.5)
    for bad in (1.0, 0.0, -0.1):
        with pytest.raises(InputError, match="mode_weight must be"):
            SamplerConfig(mode_weight=bad)
    with pytest.raises(InputError, match="mode_search needs the independence move"):
        SamplerConfig(mode_search=True, independence=False)


def test_the_mode_search_is_on_by_default_wherever_the_independence_move_runs():
    """mode_search None (the default): the burn-in searches when the independence move runs and
    not without it (no error: only an explicit True needs the move); False turns it off."""
    assert SamplerConfig().mode_search is None and SamplerConfig().searches_modes
    assert not SamplerConfig(independence=False).searches_modes
    assert not SamplerConfig(mode_search=False).searches_modes
    assert SamplerConfig(mode_search=True).searches_modes


def test_profile_sides_find_a_one_sided_kink_and_widen_the_start_ball_on_its_flat_side():
    """A posterior with a cliff just above the MAP in x0 (-1000 x0 nats) and a Gaussian of sd 1
    below it, while the Gauss-Newton sd says 0.01: the profile reaches all 64 sds below (half-width
    32), only 1/8 sd above (1/16); x1, a Gaussian of sd 1 with a correct sd, reaches 2 sds each
    way (half-width 1, the default ball's 0.5 doubled). The ball then spreads below the MAP."""
    from types import SimpleNamespace
    from frictionuq.infer.walkers import initial_ball, profile_sides

    def log_prob(x):
        x = np.atleast_2d(x)
        return np.where(x[:, 0] < 0, -0.5 * x[:, 0] ** 2, -1000.0 * x[:, 0]) - 0.5 * x[:, 1] ** 2

    space = SimpleNamespace(lo=np.array([-50.0, -50.0]), hi=np.array([50.0, 50.0]))
    cov = np.diag([1e-4, 1.0])
    sides = profile_sides(log_prob, np.zeros(2), float(log_prob(np.zeros(2))[0]), cov, space)
    assert np.array_equal(sides, [[32.0, 1 / 16], [1.0, 1.0]])
    ball = initial_ball(np.zeros(2), cov, 4000, np.random.default_rng(0), space, sides)
    below, above = ball[ball[:, 0] < 0, 0], ball[ball[:, 0] > 0, 0]
    assert 0.25 < np.sqrt(np.mean(below ** 2)) < 0.4          # 32 x 0.01 = 0.32
    assert np.sqrt(np.mean(above ** 2)) < 1e-3                # 0.01 / 16
    assert 0.9 < np.std(ball[:, 1]) < 1.1
    plain = initial_ball(np.zeros(2), cov, 4000, np.random.default_rng(0), space)
    assert np.std(plain[:, 0]) < 0.006                        # 0.5 x 0.01: the kink's flat side missed


def _stop_step(monkeypatch, rule_met: list[bool], confirm_checks: int) -> tuple[int, bool, list]:
    """The stored run (storedrun.run_chunks) on a 2-D Gaussian, chunks of 10 steps, with the
    check scripted: at the k-th check R-hat is 1.0 where rule_met[k] and 1.05 elsewhere (tau
    stable, ESS ample): (the step it stopped at, converged, the log)."""
    import emcee
    from frictionuq.infer import storedrun
    calls = iter(rule_met)

    def scripted(chain, cfg, space=None):
        r = 1.0 if next(calls) else 1.05
        return {"tau": np.full(2, 0.1), "tau_max": 0.1, "r_hat_max": r, "ess_min": 1000.0,
                "r_hat": np.full(2, r)}

    monkeypatch.setattr(storedrun, "check", scripted)
    s = emcee.EnsembleSampler(8, 2, lambda x: -0.5 * np.sum(x * x, axis=1), vectorize=True)
    s.random_state = np.random.RandomState(1).get_state()
    cfg = SamplerConfig(chunk=10, min_steps=10, max_steps=10 * len(rule_met),
                        confirm_checks=confirm_checks, progress=False)
    sp = type("Sp", (), {"names": ["a", "b"]})()
    msgs = []
    n, conv, found = storedrun.run_chunks(s, np.random.default_rng(2).standard_normal((8, 2)), cfg,
                                          sp, 0, [], msgs.append)
    assert found is None                   # no MAP check given: none run
    return n, conv, msgs


def test_the_tau_condition_refuses_a_growing_tau_and_not_a_falling_one():
    """convergence.rule_met's tau condition is one-sided (since 2026-12-06): a max tau that grew
    by tau_rtol or more since the previous check fails the rule (the chain may still be finding
    a slow direction), one that fell by as much passes it, all else equal (R-hat, ESS and the
    kept length ample). The refit of item 6's campaign failed the old two-sided condition on
    11.7 -> 10.9 steps with R-hat 1.005 and ESS 2,845, which cost it 1,000 stored steps. The
    length condition still applies to the new tau. Deterministic."""
    from frictionuq.infer.convergence import rule_met
    cfg = SamplerConfig()                                   # tau_rtol 0.05, tau_factor 50

    def c(tau, r_hat=1.005, ess=2845.0):
        return {"tau_max": tau, "r_hat_max": r_hat, "ess_min": ess}

    assert rule_met(c(10.9), 11.7, 2250, cfg)               # fell 7 %: passes (failed before)
    assert rule_met(c(8.0), 11.7, 2250, cfg)                # fell by a third: passes
    assert not rule_met(c(12.5), 11.7, 2250, cfg)           # grew 6.4 % of 12.5: fails
    assert rule_met(c(12.2), 11.7, 2250, cfg)               # grew 4.1 %: passes, as before
    assert not rule_met(c(20.7), 14.8, 2625, cfg)           # the dataset-2 chain at 3,500 steps
    assert not rule_met(c(10.9), None, 2250, cfg)           # no previous check: never
    assert not rule_met(c(46.0), 50.0, 2250, cfg)           # fell, but 2,250 < 50 x 46
    assert not rule_met(c(10.9, r_hat=1.011), 11.7, 2250, cfg)
    assert not rule_met(c(10.9, ess=399.0), 11.7, 2250, cfg)


def test_the_run_stops_only_when_the_rule_holds_at_two_checks_in_a_row(monkeypatch):
    """A single check at which the rule holds is not enough: the run goes on a chunk and stops
    only when the next check agrees (confirm_checks = 2, the default); a failed check in between
    starts the count again. The real dataset-2 fit of 2026-12-05 met the rule at 3,000 steps and
    failed it at 3,500 (ESS 155) with d3's tail still unexplored. confirm_checks = 1 keeps the
    old rule (stop at the first pass). The first check never passes (tau has no predecessor).
    Deterministic."""
    script = [False, True, False, True, True, True, True]
    n, conv, msgs = _stop_step(monkeypatch, script, 2)
    assert (n, conv) == (50, True)
    assert sum("to confirm" in m for m in msgs) == 2       # at 20 and at 40 steps
    n, conv, _ = _stop_step(monkeypatch, script, 1)
    assert (n, conv) == (20, True)
    n, conv, msgs = _stop_step(monkeypatch, [False, True, False, True, False], 2)
    assert (n, conv) == (50, False)                         # never twice in a row: the cap
    n, conv, msgs = _stop_step(monkeypatch, [False, False, True], 2)
    assert (n, conv) == (30, False) and not any("to confirm" in m for m in msgs)   # at the cap


def test_the_replay_of_a_stored_chain_repeats_the_runs_own_checks():
    """convergence.replay (benchmarks/replay_stop.py) on the chain a stored run left gives, check
    for check, the run's own history: the same steps, max tau, R-hat, ESS and rule verdicts. Run
    on a 2-D Gaussian that the rule accepts from the second check on, with confirm_checks so
    high that the run goes to its cap. Deterministic (seeded)."""
    import emcee
    from frictionuq.infer.convergence import replay
    from frictionuq.infer.storedrun import run_chunks

    class Identity:
        names = ["a", "b"]
        from_u = to_values = staticmethod(lambda x: x)

    s = emcee.EnsembleSampler(16, 2, lambda x: -0.5 * np.sum(x * x, axis=1), vectorize=True)
    s.random_state = np.random.RandomState(3).get_state()
    cfg = SamplerConfig(chunk=400, min_steps=800, max_steps=2400, confirm_checks=99,
                        tau_factor=5.0, tau_rtol=0.5, ess_min=50.0, r_hat_max=1.05,
                        progress=False)
    hist = []
    n, conv, found = run_chunks(s, np.random.default_rng(4).standard_normal((16, 2)), cfg,
                                Identity(), 0, hist, lambda m: None)
    assert (n, conv, found) == (2400, False, None)
    rows = replay(s.get_chain(), cfg, Identity())
    assert [r["steps"] for r in rows] == [h["steps"] for h in hist] == [800, 1200, 1600, 2000, 2400]
    for r, h in zip(rows, hist):
        assert (r["tau_max"], r["r_hat_max"], r["ess_min"], r["rule_met"]) == \
            (h["tau_max"], h["r_hat_max"], h["ess_min"], h["rule_met"])
    assert [r["rule_met"] for r in rows][1:] == [True] * 4      # the rule did hold: not vacuous
    tail = replay(s.get_chain(), cfg, Identity(), from_step=1600)   # what a resumed run replays
    assert [r["steps"] for r in tail] == [1600, 2000, 2400]
    assert [(r["tau_max"], r["r_hat_max"], r["ess_min"]) for r in tail] == \
        [(r["tau_max"], r["r_hat_max"], r["ess_min"]) for r in rows[2:]]
    assert [r["rule_met"] for r in tail] == [False, True, True]    # no previous tau at its first
