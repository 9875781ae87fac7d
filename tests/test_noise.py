"""The displacement-noise estimator and the default reversal dead-band."""
import gzip
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import savgol_filter

from frictionuq.noise import count_reversals, default_eps, displacement_noise_sd, reversal_indices

ARTS = Path(__file__).resolve().parents[1] / "data" / "brfd-arts-d2"
SHARED_ARTS = Path(__file__).resolve().parents[2] / "shared/data/real/brfd-arts-lab/dataset-2/characterization"


def _sine(f=0.5, fs=1024.0, cycles=5, amp=0.0254):
    t = np.arange(int(cycles / f * fs)) / fs
    return t, amp * np.sin(2 * np.pi * f * t)


@pytest.mark.parametrize("sd", [0.5e-6, 2e-6, 20e-6])
@pytest.mark.parametrize("f", [0.25, 1.0, 2.0])
def test_estimator_recovers_white_noise_sd(sd, f):
    t, x = _sine(f=f)
    rng = np.random.default_rng(7)
    est = displacement_noise_sd(x + rng.normal(0, sd, x.size))
    # MAD of ~5000 4th differences: sampling error of the robust scale ~ 2-3 %
    assert est == pytest.approx(sd, rel=0.10)


def test_estimator_on_quantised_noise():
    t, x = _sine()
    rng = np.random.default_rng(3)
    q = 1.5e-6                                # quantisation step like the ARTS records
    xq = np.round((x + rng.normal(0, 1.3e-6, x.size)) / q) * q
    total = np.sqrt(1.3e-6**2 + q**2 / 12)   # noise plus quantisation error
    assert displacement_noise_sd(xq) == pytest.approx(total, rel=0.15)


def test_clean_record_gives_tiny_eps():
    t, x = _sine()
    assert default_eps(x) < 1e-9


def test_default_eps_removes_noise_reversals():
    t, x = _sine(f=0.5, cycles=5)
    rng = np.random.default_rng(11)
    xn = x + rng.normal(0, 2e-6, x.size)
    true = count_reversals(x, 0.0)
    assert true == 10                         # 5 cycles: 5 peaks and 5 troughs
    assert count_reversals(xn, 0.0) > 10 * true
    assert count_reversals(xn, default_eps(xn)) == true


def test_too_short():
    with pytest.raises(ValueError, match="at least"):
        displacement_noise_sd(np.zeros(5))


@pytest.mark.skipif(not SHARED_ARTS.exists(), reason="ARTS records not available")
@pytest.mark.parametrize("name", ["0.5Hz36lbtension1amplitude.json.gz", "1Hz0lbtension1amplitude.json.gz"])
def test_default_eps_on_real_arts_record(name):
    """On a measured record, the default dead-band sees the same reversals (of more than eps)
    as a heavily smoothed, noise-free copy of the record."""
    a = np.array(json.load(gzip.open(SHARED_ARTS / name))["data"])
    x = a[:, 1] * 0.0254
    sd = displacement_noise_sd(x)
    assert 0.5e-6 < sd < 5e-6
    smooth = savgol_filter(x, 201, 3)
    eps = default_eps(x)
    edge = 201                                # the smoothing filter's end effects
    inner = lambda idx: idx[(idx > edge) & (idx < x.size - edge)]   # noqa: E731
    ref = inner(reversal_indices(smooth, eps))
    got = inner(reversal_indices(x, eps))
    assert 12 <= ref.size <= 20               # about 2 per cycle of the test programme
    assert count_reversals(x, 0.0) > 3 * ref.size
    assert got.size == ref.size
    assert np.max(np.abs(got - ref)) < 20     # same reversals, within 20 ms


def test_ar1_from_normals():
    """The one AR(1) generator (twins and posterior predictive): the recursion exactly, per-path
    parameters, and the stationary marginal sd and lag-1 correlation."""
    from frictionuq.noise import ar1_from_normals
    z = np.random.default_rng(5).standard_normal((3, 200_000))
    phi, sd = np.array([0.0, 0.5, 0.95]), np.array([1.0, 2.0, 0.3])
    y = ar1_from_normals(z, phi, sd)
    for i in range(3):
        assert y[i, 0] == pytest.approx(sd[i] * z[i, 0])
        np.testing.assert_allclose(y[i, 1:10], phi[i] * y[i, :9] + sd[i] * np.sqrt(1 - phi[i] ** 2) * z[i, 1:10])
        assert np.std(y[i]) == pytest.approx(sd[i], rel=0.02)
        assert np.corrcoef(y[i, 1:], y[i, :-1])[0, 1] == pytest.approx(phi[i], abs=0.01)
