"""The stored run's mode search (frictionuq.infer.stuck): a chunk in which a chain sticks where
the proposal underweights the posterior gets a component there, a chunk of a covered posterior
gets none, and a seeded statistical harness: on the two-mode target of test_infer_modes, whose
minor mode the burn-in's proposal misses, the stored run that starts again with the component
samples the minor mode at its weight. The sampler's own use of it (the restart from the chains'
positions, the count kept for a resume) is tested through infer.sampler.sample."""
from __future__ import annotations

import emcee
import numpy as np

from frictionuq import azadapter
from frictionuq.infer import sampler as S
from frictionuq.infer import stuck
from frictionuq.infer.burnin import moves_for
from frictionuq.infer.proposal import Proposal
from frictionuq.infer.sampler import SamplerConfig
from frictionuq.infer.stuck import StuckCheck
from test_infer_modes import M, _draws, _log_target, assert_minor_share
from test_infer_restart import CENTRE, SD, Toy, _Stored


def _target(x):
    """The vectorized emcee target: the two-mode log density as its only column."""
    return _log_target(np.atleast_2d(x))[:, None]


def _chunk(stuck_chain: bool, seed=1, steps=500, nw=16):
    """A stored chunk of `nw` chains on the two-mode target: every chain draws the major mode,
    except (stuck_chain) chain 3, which sits in the minor mode, its state changing every 50
    steps (a stuck chain repeats its states: 3-20 distinct ones per 500 steps at arts-d1's
    80 lb level). Returns (sampler stand-in, the major mode's proposal)."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((steps, nw, 3))
    if stuck_chain:
        u[:, 3] = np.repeat(_draws(steps // 50, rng, minor=True), 50, axis=0)
    main = Proposal.fit(_draws(4000, np.random.default_rng(seed + 100)))
    return _Stored(u, _log_target(u.reshape(-1, 3)).reshape(steps, nw)), main


def test_a_stuck_chain_gets_a_component_on_its_region_and_a_covered_chunk_none():
    """Chain 3 stuck in the minor mode for a whole chunk (100 kept states, 10 distinct): the
    check adds one component whose centre lies within 0.3 of the mode's (its sd 0.5), and says
    so in its log. With every chain in the major mode nothing is flagged, no search runs, and
    None comes back; so it does once the fit's searches reach the limit. Fixed seeds:
    deterministic."""
    s, main = _chunk(True)
    msgs = []
    check = StuckCheck(main, _target, 0.1, searches=0, limit=2, seed=4, log=msgs.append)
    p = check(s, slice(None), 0)
    assert p is not None and len(p.modes) == 1 and p.mode_weight == 0.1, msgs
    assert np.all(np.abs(p.modes[0].x_centre - M) < 0.3), p.modes[0].x_centre
    assert check.searches == 1 and "chain 3: 100" in msgs[0], msgs
    assert any("component 1 fitted to 10 distinct stored states" in m for m in msgs), msgs

    clean, main = _chunk(False)
    msgs = []
    assert StuckCheck(main, _target, 0.1, 0, 2, 4, log=msgs.append)(clean, slice(None), 0) is None
    assert msgs == []
    s, main = _chunk(True)
    assert StuckCheck(main, _target, 0.1, searches=2, limit=2, seed=4)(s, slice(None), 0) is None


def test_a_few_flagged_states_start_no_search():
    """A chain in the minor mode for 200 steps (40 kept states, under STUCK_STATES = 50): no
    search, None. Deterministic."""
    s, main = _chunk(True)
    s.u[:300, 3] = s.u[:300, 4]
    s.lp[:300, 3] = s.lp[:300, 4]
    msgs = []
    assert StuckCheck(main, _target, 0.1, 0, 2, 4, log=msgs.append)(s, slice(None), 0) is None
    assert msgs == []


def _run_with_check(proposal, seed=5, steps=3000, chunk=500):
    """The stored run's moves (16 chains) on the two-mode target from the major mode, checked by
    StuckCheck at every chunk; when it adds components the run starts again from the chains'
    positions with the new proposal (as infer.sampler does). Returns (the last run's chain
    after 500 discarded steps, its R-hat max, the searches, the proposal)."""
    state, key, searches = _draws(16, np.random.default_rng(seed)), seed, 0
    while True:
        check = StuckCheck(proposal, _target, 0.1, searches, 2, seed)
        s = emcee.EnsembleSampler(16, 3, _log_target, vectorize=True,
                                  moves=moves_for(SamplerConfig(run_walkers=16), proposal, stored=True))
        s.random_state = np.random.RandomState(key).get_state()
        found = None
        while s.iteration < steps and found is None:
            start = s.iteration
            s.run_mcmc(state if start == 0 else None, chunk, progress=False)
            found = check(s, slice(None), start)
        if found is None:
            break
        searches = check.searches
        proposal, state, key = found, s.get_last_sample().coords, [seed, searches]
    chain = s.get_chain(discard=500)
    r_hat = np.max(azadapter.diagnostics(np.transpose(chain, (1, 0, 2)))["r_hat"])
    return chain, float(r_hat), searches, proposal


def test_the_stored_run_started_again_with_the_component_samples_the_minor_mode_at_its_weight():
    """Seeded statistical harness. The proposal is the major mode's t alone (the burn-in never
    visited the minor mode); test_infer_modes measured that the plain stored run at this seed
    ends with R-hat 1.068, one chain 60 % of its steps in the minor mode. With the check, a
    chain that sticks there starts the search, the stored run starts again with the component,
    and then: one search, one component on the mode (centre within 0.3), R-hat over the 16
    chains below 1.01, and the minor mode's share of the draws its weight 0.05 within 5
    standard errors of a proportion with the chain's effective sample size (false-alarm rate
    below 1e-5). Measured: R-hat 1.0011, share 0.0525."""
    main = Proposal.fit(_draws(4000, np.random.default_rng(6)))
    chain, r_hat, searches, p = _run_with_check(main)
    assert searches == 1 and len(p.modes) == 1, (searches, len(p.modes))
    assert np.all(np.abs(p.modes[0].x_centre - M) < 0.3), p.modes[0].x_centre
    assert r_hat < 1.01, r_hat
    assert_minor_share(chain)


def test_the_search_count_is_kept_in_the_chain_file(tmp_path):
    from frictionuq.infer.storage import open_backend
    be, _ = open_backend(tmp_path / "chain.h5", 8, 2, resume=False)
    assert stuck.load_searches(be) == 0
    stuck.store_searches(be, 2)
    assert stuck.load_searches(be) == 2 and stuck.load_searches(None) == 0


MINOR, MINOR_SD, MINOR_W = np.array([9.0, 0.5, 0.5]), 0.15, 0.05


class TwoModeToy(Toy):
    """test_infer_restart's Toy (its major mode at CENTRE, sd SD, in the prior box of three
    free parameters) with a narrow minor mode at fc_fwd 9 (weight 0.05, sd 0.15 SD): 5 sds of
    the major mode away, 40 of its own, where the burn-in's proposal does not reach."""

    def __call__(self, theta, stats=False):
        theta = np.atleast_2d(theta)
        self.n_evals += len(theta)
        inside = np.all((theta > self.space.lo) & (theta < self.space.hi), axis=1)
        msd = MINOR_SD * SD
        a = np.log(1 - MINOR_W) - 0.5 * np.sum(((theta - CENTRE) / SD) ** 2, axis=1) \
            - np.sum(np.log(SD))
        b = np.log(MINOR_W) - 0.5 * np.sum(((theta - MINOR) / msd) ** 2, axis=1) \
            - np.sum(np.log(msd))
        lp = np.where(inside, np.logaddexp(a, b), -np.inf)
        return np.column_stack([lp, lp, np.zeros_like(lp)])


def _sample_two_modes(monkeypatch, tmp_path, resume=False, searches=2, msgs=None):
    """sample() on TwoModeToy from its major mode (the multi-start search replaced by one that
    returns CENTRE), seed 1."""
    toy = TwoModeToy()
    monkeypatch.setattr(S, "find_map", lambda lp, *a, **k: (CENTRE, toy(CENTRE)[0, 0],
                                                            {"start": "search"}))
    monkeypatch.setattr(S, "gauss_newton_cov", lambda lp, th: np.diag((0.3 * SD) ** 2))
    cfg = SamplerConfig(run_walkers=8, chunk=250, min_steps=500, max_steps=3000, burn_steps=100,
                        start_profile=False, progress=False, n_stored_searches=searches)
    msgs = [] if msgs is None else msgs
    res = S.sample(toy, None, seed=1, backend_path=tmp_path / "chain.h5", cfg=cfg, resume=resume,
                   log=msgs.append)
    return res, msgs


def test_the_sampler_starts_the_stored_run_again_with_the_component_and_a_resume_keeps_it(
        monkeypatch, tmp_path):
    """Through infer.sampler.sample: the burn-in's search finds nothing; in the stored run a
    chain sticks in the minor mode (its state unchanged for the 250 steps of a chunk), the
    check adds a component, the stored steps so far are discarded (counted with the burn-in
    phase) and the run starts again from the chains' positions; it then converges with the
    minor mode's share of the draws within 0.02 of its weight 0.05 (measured 0.051). Without
    the check (n_stored_searches = 0) the same seed ends at the 3,000-step cap, unconverged.
    A resumed run reads the count and the mixture from the chain's file and searches no more.
    Seeded: deterministic."""
    res, msgs = _sample_two_modes(monkeypatch, tmp_path)
    again = [m for m in msgs if "stored-run mode search 1 of 2" in m]
    assert res.stored_searches == 1 and res.mode_components == 1 and len(again) == 1, msgs
    discarded = int(again[0].split("the ")[1].split(" stored steps")[0])
    assert res.burn_in_steps > discarded > 0 and res.converged_tau
    assert abs(np.mean(res.chain[..., 0] > 7.0) - MINOR_W) < 0.02
    from frictionuq.infer.storage import load_proposal, open_backend
    be, _ = open_backend(tmp_path / "chain.h5", 8, 3, resume=True)
    assert stuck.load_searches(be) == 1 and len(load_proposal(be).modes) == 1

    more = []
    resumed, _ = _sample_two_modes(monkeypatch, tmp_path, resume=True, msgs=more)
    assert resumed.stored_searches == 1 and resumed.mode_components == 1
    assert not any("mode search" in m for m in more), more
    assert np.array_equal(resumed.chain, res.chain)

    off, _ = _sample_two_modes(monkeypatch, tmp_path / "off", searches=0)
    assert off.stored_searches == 0 and not off.converged_tau and off.n_steps == 3000


def test_the_report_says_where_the_components_were_found():
    from frictionuq.report.sections.fits import _stored_run
    rec = {"config": {"sampler": {"stored_run": "chains"}}}
    assert _stored_run(rec, {"walkers": 16, "mode_components": 2}).endswith(
        "a mixture with 2 mode components found in the burn-in")
    assert _stored_run(rec, {"walkers": 16, "mode_components": 3, "stored_searches": 1}).endswith(
        "found in the burn-in and the stored run (started again 1 time where chains stuck)")
