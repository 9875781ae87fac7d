"""The stored run's check of the MAP (frictionuq.infer.restart): a chain that climbs more than
ABOVE_MAP nats above the MAP restarts the burn-in from the point polished there, once; the
discarded run's states reach the next burn-in's mode search; a resumed run keeps the new MAP.
On toy posteriors whose densities are known (the real case, arts-d1's 80 lb level, is in
docs/log-calibration.md, 2026-12-07, stop 85)."""
from __future__ import annotations

import re

import numpy as np
import pytest

from frictionuq.infer import restart
from frictionuq.infer import sampler as S
from frictionuq.infer.sampler import SamplerConfig
from test_infer_sampler import _three_free_space as _space

# a Gaussian posterior in the prior box's coordinates of three free parameters
CENTRE = np.array([5.0, 0.5, 0.5])
SD = np.array([0.8, 0.08, 0.08])


class Toy:
    """What the sampler reads of a LogPosterior, on a known density: one record whose
    log-likelihood blob is the density itself, and one residual statistic (0)."""
    n_stats = 1

    def __init__(self):
        self.space = _space()
        assert self.space.names == ["fc_fwd", "d3", "v_s"]
        self.records = [None]
        self.n_evals = 0

    def __call__(self, theta, stats=False):
        theta = np.atleast_2d(theta)
        self.n_evals += len(theta)
        inside = np.all((theta > self.space.lo) & (theta < self.space.hi), axis=1)
        lp = np.where(inside, -0.5 * np.sum(((theta - CENTRE) / SD) ** 2, axis=1), -np.inf)
        return np.column_stack([lp, lp, np.zeros_like(lp)])

    def log_prob(self, theta):
        return self(theta)[:, 0]


def _sample(monkeypatch, tmp_path, restarts=1, max_steps=1500, resume=False, msgs=None,
            burn_in_rises=False):
    """sample() on the Toy with the multi-start search replaced by one that returns a point 3 sd
    off the mode in fc_fwd (log-posterior -4.5 against the mode's 0), as a search that missed
    the highest region would. The burn-in's walkers climb to the mode; unless `burn_in_rises`,
    the sampler is kept from seeing it (restart.burn_in_map replaced by one that never moves the
    MAP), as when the burn-in stays out of the higher region and only the stored chains find
    it."""
    poor = CENTRE + np.array([3.0, 0.0, 0.0]) * SD
    monkeypatch.setattr(S, "find_map", lambda lp, *a, **k: (poor, -4.5, {"start": "search"}))
    monkeypatch.setattr(S, "gauss_newton_cov", lambda lp, th: np.diag((0.3 * SD) ** 2))
    if not burn_in_rises:
        monkeypatch.setattr(S, "burn_in_map", lambda lp, kept, th, v: (th, v, False))
    cfg = SamplerConfig(run_walkers=8, chunk=250, min_steps=500, max_steps=max_steps,
                        burn_steps=100, start_profile=False, progress=False,
                        n_map_restarts=restarts)
    msgs = [] if msgs is None else msgs
    res = S.sample(Toy(), None, seed=3, backend_path=tmp_path / "chain.h5", cfg=cfg,
                   resume=resume, log=msgs.append)
    return res, msgs


def test_a_chain_above_the_map_restarts_the_burn_in_from_the_point_polished_there(monkeypatch, tmp_path):
    """The chains, started from the poor point's burn-in, soon hold states more than 3 nats above
    its -4.5: the run restarts once, its MAP polished to the mode (log-posterior within 1e-6 of
    0), the discarded stored steps counted with the burn-in phase, the new MAP kept in the chain
    file; the stored run after it samples the Gaussian (each mean within 5 standard errors of
    the effective draws of the thinned chains: false-alarm rate below 1e-5). Without restarts
    (n_map_restarts = 0) the MAP stays at the poor point. Seeded: deterministic."""
    res, msgs = _sample(monkeypatch, tmp_path)
    assert res.map_restarts == 1
    assert sum(m.startswith("restart 1: a chain reached") for m in msgs) == 1, msgs
    assert abs(res.log_prob_map) < 1e-6 and np.allclose(res.theta_map, CENTRE, atol=1e-3 * SD)
    stored = restart.load_map(_open(tmp_path / "chain.h5"))
    assert stored[1] == res.log_prob_map and stored[2] == 1
    # the burn-in phase: the first burn-in, the discarded stored steps (a multiple of the chunk)
    # and the second burn-in
    discarded = int(re.search(r"the (\d+) stored steps are discarded", " ".join(msgs)).group(1))
    assert discarded % 250 == 0 and res.burn_in_steps >= discarded + 2 * 200
    draws = res.chain.reshape(-1, 3)
    n_eff = draws.shape[0] * res.thin / max(1.0, res.tau.max())     # thinned by about tau / 4
    se = SD / np.sqrt(n_eff)
    assert np.all(np.abs(draws.mean(axis=0) - CENTRE) < 5 * se), (draws.mean(axis=0), se)
    off, off_msgs = _sample(monkeypatch, tmp_path / "off", restarts=0)
    assert off.map_restarts == 0 and off.log_prob_map == -4.5
    assert not any(m.startswith("restart") for m in off_msgs)


def test_a_resumed_run_keeps_the_restarts_map_and_does_not_restart_again(monkeypatch, tmp_path):
    """A run stopped at its cap after a restart, resumed with a higher cap: the resumed session
    starts from the stored MAP (the search's poor point is not used again, nor does the stored
    chain, which lies above it, trigger a second restart), and goes on from the stored step."""
    first, _ = _sample(monkeypatch, tmp_path, max_steps=1000)
    assert first.map_restarts == 1
    msgs = []
    res, _ = _sample(monkeypatch, tmp_path, max_steps=1500, resume=True, msgs=msgs)
    assert any("MAP kept with the stored chain" in m and "restarts before it: 1" in m
               for m in msgs), msgs
    assert not any(m.startswith("restart") for m in msgs)
    assert res.map_restarts == 1 and res.log_prob_map == first.log_prob_map
    assert res.resumed_from == [first.n_steps] == [1000] and res.n_steps > 1000


def test_a_burn_in_that_climbs_above_the_map_polishes_it_and_the_stored_run_does_not_restart(
        monkeypatch, tmp_path):
    """The same poor search point, the sampler as it is: the burn-in's walkers climb to the
    mode, so the MAP is polished from the last round's highest state (to the mode, within 1e-6
    nats), kept in the chain file, and the stored run, whose proposal covers the mode, never
    finds a chain above it: no restart (one would discard the stored steps and run the burn-in
    again). A resumed run keeps that MAP. Seeded: deterministic."""
    res, msgs = _sample(monkeypatch, tmp_path, max_steps=1000, burn_in_rises=True)
    assert res.map_restarts == 0 and not any(m.startswith("restart") for m in msgs), msgs
    assert sum(m.startswith("the burn-in's last round rose") for m in msgs) == 1, msgs
    assert abs(res.log_prob_map) < 1e-6 and np.allclose(res.theta_map, CENTRE, atol=1e-3 * SD)
    assert restart.load_map(_open(tmp_path / "chain.h5"))[1:] == (res.log_prob_map, 0)
    again, more = _sample(monkeypatch, tmp_path, max_steps=1500, resume=True,
                          burn_in_rises=True)
    assert any("MAP kept with the stored chain" in m for m in more), more
    assert again.log_prob_map == res.log_prob_map and again.map_restarts == 0
    assert not any(m.startswith(("restart", "the burn-in's")) for m in more), more


def test_burn_in_map_moves_only_past_above_map():
    """burn_in_map polishes from the highest kept state (box coordinates) only when it lies more
    than ABOVE_MAP above the MAP."""
    sp = _space()
    toy = Toy()
    theta = CENTRE + np.array([[1.0, 0, 0], [2.0, 0, 0]]) * SD      # -0.5 and -2.0
    u = sp.to_u(theta)
    kept = (u, toy.log_prob(theta) + sp.log_jac_u(u))
    th0 = CENTRE + np.array([3.0, 0, 0]) * SD
    th, lp, moved = restart.burn_in_map(toy, kept, th0, -4.5)
    assert moved and abs(lp) < 1e-6
    th, lp, moved = restart.burn_in_map(toy, kept, th0, -3.4)      # -0.5 is 2.9 above
    assert not moved and lp == -3.4 and th is th0


def _open(path):
    from frictionuq.infer.storage import OpenHDFBackend
    return OpenHDFBackend(str(path))


def test_above_map_finds_the_highest_state_of_the_new_steps_only():
    """above_map reads the cold chains' states from `start` on, in the prior box's log-posterior
    (the stored one less the coordinates' Jacobian), and returns the highest when it lies more
    than ABOVE_MAP above the MAP."""
    import emcee
    sp = _space()
    toy = Toy()
    from frictionuq.infer.likelihood import UnboundedPosterior
    target = UnboundedPosterior(toy, stats=True)
    s = emcee.EnsembleSampler(8, 3, target, vectorize=True)
    s.random_state = np.random.RandomState(0).get_state()
    s.run_mcmc(sp.to_u(CENTRE + 0.1 * SD * np.random.default_rng(0).standard_normal((8, 3))), 50,
               progress=False)
    u, lp = restart.above_map(s, slice(0, 8), 0, sp, -10.0)
    assert lp == pytest.approx(toy.log_prob(sp.from_u(u))[0])
    lps = s.get_log_prob() - sp.log_jac_u(s.get_chain().reshape(-1, 3)).reshape(50, 8)
    assert lp == pytest.approx(lps.max())
    assert restart.above_map(s, slice(0, 8), 0, sp, lp - restart.ABOVE_MAP + 1e-9) is None
    assert restart.above_map(s, slice(0, 8), 50, sp, -10.0) is None      # no new steps
    k = np.unravel_index(np.argmax(lps[20:]), lps[20:].shape)
    assert restart.above_map(s, slice(0, 8), 20, sp, -10.0)[1] == pytest.approx(lps[20:][k])


def test_the_burn_in_after_a_restart_searches_every_state_kept_since_the_fit_began():
    """The burn-in started in the major mode of the two-mode target of test_infer_modes (5 % minor
    mode far away), with cfg.mode_search off. Told to search (as after a restart) with `memory`
    holding an earlier run's states of the minor mode (the first burn-in's, or the discarded
    chains' as restart.carried gives them): the proposal gets one component near the minor
    mode's centre, and the rounds' own kept states are appended to `memory`. Not told to search:
    no component, nothing logged, whatever `memory` holds. Seeded: deterministic."""
    from frictionuq.infer.burnin import burn_in
    from test_infer_modes import M, _draws, _log_target

    def target(x):
        return _log_target(x)[:, None]

    def run(memory, search):
        rng = np.random.default_rng(5)
        state = 0.3 * rng.standard_normal((32, 3))
        cfg = SamplerConfig(nwalkers=32, burn_steps=100, progress=False, mode_search=False)
        msgs = []
        _, p, steps = burn_in(target, state, cfg, seed=5, rng=rng, log=msgs.append,
                              memory=memory, search=search)
        return p, steps, msgs
    minor = _draws(400, np.random.default_rng(6), minor=True)
    memory = [(minor, _log_target(minor))]
    p, steps, msgs = run(memory, True)
    assert len(p.modes) == 1, msgs
    assert np.all(np.abs(p.modes[0].x_centre - M) < 0.3), p.modes[0].x_centre
    # each round's every fifth step of its 32 walkers, after the earlier run's states
    assert memory[0][0] is minor and sum(len(m[0]) for m in memory[1:]) == steps // 5 * 32
    for mem in ([(minor, _log_target(minor))], None):
        plain, _, msgs = run(mem, None)
        assert plain.modes == () and not any("mode search" in m for m in msgs)


class _Stored:
    """What MapCheck reads of an emcee sampler: a stored chain (steps, chains, D) in the
    sampler's coordinates and its log-posteriors there."""

    def __init__(self, u, lp_u):
        self.u, self.lp, self.iteration = u, lp_u, len(u)

    def get_chain(self, discard=0):
        return self.u[discard:]

    def get_log_prob(self, discard=0):
        return self.lp[discard:]


def _underweighted_run(sp, toy, k=2.0):
    """40 steps of 4 chains around the poor point 3 sd off the Toy's mode (log-posterior about
    -4.5), but one state at step 35, k sd off the mode (k = 2: log-posterior -2.0, 2.5 nats above
    the poor point, under ABOVE_MAP), far outside the proposal: a normal in u fitted to the
    other states. Returns (sampler stand-in, logq)."""
    rng = np.random.default_rng(8)
    poor = CENTRE + np.array([3.0, 0.0, 0.0]) * SD
    theta = poor + 0.2 * SD * rng.standard_normal((40, 4, 3))
    theta[35, 2] = CENTRE + np.array([k, 0.0, 0.0]) * SD
    u = sp.to_u(theta.reshape(-1, 3))
    lp_u = toy.log_prob(theta.reshape(-1, 3)) + sp.log_jac_u(u)
    others = np.delete(u, 35 * 4 + 2, axis=0)
    mu, sd = others.mean(axis=0), others.std(axis=0)

    def logq(x):
        return -0.5 * np.sum(((x - mu) / sd) ** 2, axis=1)
    return _Stored(u.reshape(40, 4, 3), lp_u.reshape(40, 4)), logq


def test_the_check_polishes_a_state_the_proposal_underweights_and_restarts_from_above_the_map():
    """No stored state lies ABOVE_MAP above the MAP (-4.5), but one lies far outside the stored
    run's proposal: MapCheck polishes from it (Powell, on the log-posterior) and returns the
    polished point, the Toy's mode (log-posterior 0 within 1e-6), to restart from. Steps before
    the chunk are not read again; a state deeper than ABOVE_MAP - D / 2 above the MAP is not
    polished; a polish that ends less than ABOVE_MAP above the MAP is spent (counted) and returns
    nothing; with the budget spent no polish runs. Deterministic."""
    sp = _space()
    toy = Toy()
    stored, logq = _underweighted_run(sp, toy)
    assert restart.above_map(stored, slice(0, 4), 30, sp, -4.5) is None
    msgs = []
    check = restart.MapCheck(toy, -4.5, logq, log=msgs.append)
    theta, lp, how = check(stored, slice(0, 4), 30)
    assert abs(lp) < 1e-6 and np.allclose(theta, CENTRE, atol=1e-3 * SD)
    assert how == "a polish from such a state reached" and check.polishes == 1
    assert "(log-posterior -2 nats, +2.5 against the MAP)" in msgs[0], msgs
    n = toy.n_evals
    assert restart.MapCheck(toy, -4.5, logq)(stored, slice(0, 4), 36) is None   # chunk after it
    assert toy.n_evals == n                                                      # nothing polished
    deep = restart.MapCheck(toy, -2.9, logq)      # -2.0 is deeper than -2.9 + 3 - 1.5
    assert deep(stored, slice(0, 4), 30) is None and deep.polishes == 0 and toy.n_evals == n
    closer, logq15 = _underweighted_run(sp, toy, k=1.5)     # -1.125: polished, but the mode
    near = restart.MapCheck(toy, -2.9, logq15)              # is only 2.9 above the MAP
    assert near(closer, slice(0, 4), 30) is None and near.polishes == 1 and toy.n_evals > n
    spent = restart.MapCheck(toy, -4.5, logq, polishes=restart.MAX_POLISHES)
    n = toy.n_evals
    assert spent(stored, slice(0, 4), 30) is None and toy.n_evals == n
    assert restart.MapCheck(toy, -4.5, None)(stored, slice(0, 4), 30) is None   # no proposal


def test_the_checks_polish_is_one_pass_of_at_most_polish_evals_per_parameter(monkeypatch):
    """MapCheck's polish stops at POLISH_EVALS evaluations per free parameter (a polish that
    wanders back to the MAP's region on a flat ridge must not cost a fit's worth); optimize.polish
    honours `max_evals` (Powell's maxfev, read between line searches, so a search under way may
    finish: from 3 sd off the Toy's mode, capped at 12 it stops after 12-20 evaluations, uncapped
    it needs 38 and reaches the mode)."""
    from frictionuq.infer.optimize import polish
    toy = Toy()
    th0 = CENTRE + np.array([3.0, 1.0, -1.0]) * SD
    lp0 = float(toy.log_prob(th0[None])[0])
    _, lp = polish(toy, th0, lp0, passes=1, max_evals=12)
    assert 12 <= toy.n_evals <= 20 and lp > lp0
    toy.n_evals = 0
    _, lp = polish(toy, th0, lp0, passes=1)
    assert toy.n_evals > 20 and abs(lp) < 1e-6
    seen = {}
    monkeypatch.setattr(restart, "polish", lambda lp, th, v, **kw: seen.update(kw) or (th, v))
    sp = _space()
    stored, logq = _underweighted_run(sp, toy)
    restart.MapCheck(toy, -4.5, logq)(stored, slice(0, 4), 30)
    assert seen == {"passes": 1, "max_evals": restart.POLISH_EVALS * 3}


def test_the_polish_count_is_kept_in_the_chain_file(tmp_path):
    """A resumed fit reads the polishes spent so far (store_polishes / load_polishes): 0 on a new
    chain file."""
    from frictionuq.infer.storage import open_backend
    backend, _ = open_backend(tmp_path / "chain.h5", 4, 3, False)
    assert restart.load_polishes(backend) == 0
    restart.store_polishes(backend, 3)
    assert restart.load_polishes(_open(tmp_path / "chain.h5")) == 3
