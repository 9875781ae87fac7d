"""Decimated records (frictionuq.infer.likelihood): the anti-alias filter is linear and acts
row by row, and with simulate_at="raw" (the default) the model force goes through exactly the
data's filter, so at the true parameters the residual of a decimated record is the decimated
noise and nothing else; simulate_at="kept" (the model run on the decimated displacement) is a
different model and leaves a systematic residual. The coarsened records run on their own
coarse displacement, or on the kept or raw samples with every k-th output compared."""
from __future__ import annotations

import numpy as np
import pytest

from frictionuq import published
from frictionuq.infer.decimate import decimate as _decimate, decimator
from frictionuq.infer.likelihood import LogPosterior, prepare_record
from frictionuq.infer.optimize import coarsened
from frictionuq.infer.priors import default_priors, record_scales
from frictionuq.infer.space import Space
from frictionuq.model import simulate

Q = 5


def test_decimate_acts_row_by_row_and_linearly():
    rng = np.random.default_rng(0)
    a = rng.standard_normal((3, 1001)).cumsum(axis=1)
    rows = np.array([_decimate(r, Q) for r in a])
    assert np.allclose(_decimate(a, Q), rows, rtol=0, atol=1e-12)
    b = rng.standard_normal(1001)
    assert np.allclose(_decimate(a[0] - 2.0 * b, Q), rows[0] - 2.0 * _decimate(b, Q), atol=1e-12)


@pytest.mark.parametrize("n,q", [(1001, 2), (1001, 5), (997, 10), (64, 7), (4000, 3)])
def test_banded_decimator_equals_the_definition(n, q):
    """The log-posterior's decimator (a banded matrix read off resample_poly, infer.decimate)
    gives decimate()'s numbers on every kept sample, the ends included, for any row."""
    rng = np.random.default_rng(n + q)
    a = rng.standard_normal((4, n)).cumsum(axis=1) + 50.0 * np.linspace(-1, 2, n)
    ref = _decimate(a, q)
    got = decimator(n, q)(a)
    assert got.shape == ref.shape
    assert np.max(np.abs(got - ref)) <= 1e-12 * np.max(np.abs(ref))
    with pytest.raises(ValueError, match="rows of"):
        decimator(n, q)(a[:, :-1])


class _Rec:
    def __init__(self, t, x, force):
        self.t, self.x, self.force, self.applied = t, x, force, None


@pytest.fixture(scope="module")
def decimated_case():
    """0.05 Hz sine of the BRFD at 53 N sampled at 100 Hz (2 cycles, 4,000 samples) plus white
    noise, decimated by 5: the twin's low-force, low-frequency case."""
    truth = published.brfd_params(53.0)
    t = np.arange(4000) / 100.0
    x = 0.0254 * np.sin(2 * np.pi * 0.05 * t)
    fc = 0.5 * (truth["fc_fwd"] + truth["fc_bwd"])
    noise = 0.01 * fc * np.random.default_rng(1).standard_normal(t.size)
    y = simulate(t, x, truth) + noise
    scales = record_scales([_Rec(t, x, y)])
    space = Space("three_stage", (), "ar1", default_priors(scales, likelihood="ar1"))
    th = space.to_theta({**truth, "force_offset": 0.0})[None]
    recs = {at: prepare_record("syn", t, x, y, q=Q, eps=0.0, simulate_at=at) for at in ("raw", "kept")}
    return space, th, recs, _decimate(noise, Q)


def test_raw_rate_simulation_leaves_exactly_the_filtered_noise(decimated_case):
    space, th, recs, noise_d = decimated_case
    rec = recs["raw"]
    assert rec.q == Q and rec.n == 800 and rec.sim_drive is not None and rec.sim_drive.n == 4000
    e = LogPosterior(space, [rec]).residuals(th, rec)[0]
    assert e.shape == (rec.n,)
    assert np.allclose(e, noise_d[: rec.n], rtol=0, atol=1e-9 * np.std(noise_d))


def test_kept_rate_simulation_is_a_different_model(decimated_case):
    space, th, recs, noise_d = decimated_case
    rec = recs["kept"]
    assert rec.sim_drive is None
    e = LogPosterior(space, [rec]).residuals(th, rec)[0]
    bias = e - noise_d[: rec.n]
    # measured: a systematic residual of 2.7 x the (filtered) noise sd, 409 nats; raw: 1e-13 x
    assert np.sqrt(np.mean(bias**2)) > 0.5 * np.std(noise_d)
    # and the raw form scores the truth higher
    ll = {at: LogPosterior(space, [r]).loglik_records(th)[0, 0] for at, r in recs.items()}
    assert ll["raw"] > ll["kept"]


def test_coarsened_records_simulate_on_their_own_samples(decimated_case):
    space, th, recs, _ = decimated_case
    lp = LogPosterior(space, [recs["raw"]])
    c = coarsened(lp, max_samples=200)
    r = c.records[0]
    assert r.sim_drive is None and r.n == r.drive.n <= 200
    assert c.simulate(th, r).shape == (1, r.n)
    assert np.isfinite(c.log_prob(th)).all()


def test_coarsened_kept_and_full_modes_compare_every_kth_output(decimated_case):
    """simulate="kept": the model runs on the kept samples and every k-th output is compared;
    "full": as the fit simulates it (raw rate, filtered), every k-th output compared, so its
    residual is exactly the fit's residual at those samples."""
    space, th, recs, _ = decimated_case
    lp = LogPosterior(space, [recs["raw"]])
    full_res = lp.residuals(th, recs["raw"])[0]
    kept_lp = LogPosterior(space, [recs["kept"]])
    kept_res = kept_lp.residuals(th, recs["kept"])[0]
    for mode, ref in (("full", full_res), ("kept", kept_res)):
        c = coarsened(lp, max_samples=200, simulate=mode)
        r = c.records[0]
        k = r.stride
        assert k == int(np.ceil(recs["raw"].n / 200)) > 1 and r.n <= 200
        assert (r.sim_drive is None) == (mode == "kept")
        assert np.allclose(c.residuals(th, r)[0], ref[::k], rtol=0, atol=1e-9 * np.abs(ref).max())
        assert np.isfinite(c.log_prob(th)).all()
    # the coarse mode is a different (coarser) model: its residual is not the kept model's
    c = coarsened(lp, max_samples=200)
    assert c.records[0].stride == 1 and not np.allclose(c.residuals(th, c.records[0])[0], kept_res[::k])
    with pytest.raises(ValueError, match="simulate"):
        coarsened(lp, simulate="raw")


def test_bad_simulate_at_is_refused():
    t = np.arange(100) / 100.0
    with pytest.raises(ValueError, match="simulate_at"):
        prepare_record("syn", t, np.sin(t), np.sin(t), q=1, simulate_at="fine")


def test_kept_rate_floor():
    """decimation_factor's min_kept_hz: the kept rate is at least that (a 0.2 Hz sine sampled at
    100 Hz: q 5 at 100 samples per cycle, 2 with a 40 Hz floor, 1 with a 60 Hz one); a floor
    that is not a positive number is refused."""
    from frictionuq.infer.likelihood import decimation_factor
    t = np.arange(2001) / 100.0
    x = 0.0254 * np.sin(2 * np.pi * 0.2 * t)
    assert [decimation_factor(t, x, 100, 0.2, f) for f in (None, 40.0, 60.0)] == [5, 2, 1]
    for bad in (0.0, -5.0, float("nan")):
        with pytest.raises(ValueError, match="min_kept_hz"):
            decimation_factor(t, x, 100, 0.2, bad)
