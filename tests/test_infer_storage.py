"""infer/storage.py: the HDF5 backend kept open during a run writes each step itself
(_StepWriter); the file must be the one emcee's own save_step writes, read back by emcee."""
from __future__ import annotations

import emcee
import numpy as np
import pytest

from frictionuq.infer.storage import OpenHDFBackend, open_backend


def _log_prob(x):
    """A vectorised target with three blob columns (as the fits' per-record statistics)."""
    r = np.zeros((x.shape[0], 4))
    r[:, 0] = -0.5 * np.sum(x**2, axis=1)
    r[:, 1:] = x[:, :3] ** 2
    return r


def _run(path, keep_open: bool, chunks=(7, 5)):
    be, _ = open_backend(path, 8, 3, resume=False)
    if keep_open:
        be.keep_open()
    s = emcee.EnsembleSampler(8, 3, _log_prob, vectorize=True, backend=be,
                              moves=[(emcee.moves.GaussianMove(0.5), 0.5),
                                     (emcee.moves.StretchMove(), 0.5)])
    s.random_state = np.random.RandomState(3).get_state()
    state = np.random.default_rng(0).standard_normal((8, 3))
    for n in chunks:              # two sample() calls: the datasets grow twice
        s.run_mcmc(state, n)
        state = None
    be.close()
    return emcee.backends.HDFBackend(str(path), read_only=True)


def test_the_open_files_steps_are_those_emcee_writes(tmp_path):
    ours = _run(tmp_path / "ours.h5", keep_open=True)
    ref = _run(tmp_path / "ref.h5", keep_open=False)       # emcee's own save_step
    assert ours.iteration == ref.iteration == 12
    for get in ("get_chain", "get_log_prob", "get_blobs"):
        a, b = getattr(ours, get)(), getattr(ref, get)()
        assert a.shape == b.shape and np.array_equal(a, b), get
    assert np.array_equal(ours.accepted, ref.accepted) and ours.accepted.sum() > 0
    assert all(np.array_equal(np.asarray(x), np.asarray(y))
               for x, y in zip(ours.random_state, ref.random_state))
    # a resumed run reads the last stored step, random state included
    be, done = open_backend(tmp_path / "ours.h5", 8, 3, resume=True)
    assert done == 12
    last, last_ref = be.get_last_sample(), ref.get_last_sample()
    assert np.array_equal(last.coords, last_ref.coords)
    assert np.array_equal(last.random_state[1], last_ref.random_state[1])


def test_the_open_file_refuses_a_step_of_the_wrong_shape(tmp_path):
    be, _ = open_backend(tmp_path / "b.h5", 8, 3, resume=False)
    be.keep_open()
    be.grow(2, None)
    rs = np.random.RandomState(0).get_state()
    good = emcee.State(np.zeros((8, 3)), log_prob=np.zeros(8), random_state=rs)
    bad = emcee.State(np.zeros((8, 2)), log_prob=np.zeros(8), random_state=rs)
    with pytest.raises(ValueError, match="coordinate dimensions"):
        be.save_step(bad, np.zeros(8, bool))
    with pytest.raises(ValueError, match="unexpected blobs"):
        be.save_step(emcee.State(good.coords, log_prob=good.log_prob, blobs=np.zeros(8),
                                 random_state=rs), np.zeros(8, bool))
    be.save_step(good, np.ones(8, bool))
    be.close()
    assert OpenHDFBackend(str(tmp_path / "b.h5")).iteration == 1
