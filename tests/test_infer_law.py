"""The force-dependence law (frictionuq.infer.law): recovery of a known law from per-level
posteriors, held-out comparison of the families, and draws at untested forces.

The per-level posteriors are synthetic (a fake `fit --by applied` folder with known posterior
draws), so these tests exercise the second stage alone, in seconds."""
import json
import math

import numpy as np
import pytest

from frictionuq import azadapter
from frictionuq.errors import InputError
from frictionuq.infer import law, lawdraws

A = np.array([20.0, 22.0, 25.0, 35.0, 70.0, 80.0]) * 4.448    # N, the ARTS d1 levels


def _levels(fn, a=A, sd=0.02, scatter=0.0, seed=0):
    rng = np.random.default_rng(seed)
    m = np.log(fn(a)) + scatter * rng.standard_normal(a.size)
    return a, m, np.full(a.size, sd)


def test_linear_law_recovers_slope():
    c = 2.5
    a, m, s = _levels(lambda a: c * a, scatter=0.03, seed=1)
    ch = law.fit_family("linear", a, m, s, seed=3)
    lo, hi = np.quantile(np.exp(ch[:, 0]), [0.025, 0.975])
    assert lo < c < hi
    assert hi / lo < 1.2           # six levels determine the slope to a few percent


def test_threshold_law_recovers_threshold():
    a, m, s = _levels(lambda a: 3.0 * (a - 60.0), scatter=0.02, seed=2)
    ch = law.fit_family("threshold", a, m, s, seed=4)
    lo, hi = np.quantile(ch[:, 1], [0.025, 0.975])
    assert lo < 60.0 < hi


def test_heldout_prefers_the_generating_family():
    """Threshold data (band slack below 60 N): the threshold law predicts held-out levels
    far better than a line through the origin, which cannot bend. Linear data: the line is not
    beaten by more than 2 SE by the threshold law (which contains it, a0 = 0). Deterministic
    (fixed seeds); the margins are many SE on these data."""
    a, m, s = _levels(lambda a: 3.0 * (a - 60.0), scatter=0.02, seed=2)
    thr = law._heldout("threshold", a, m, s, True, seed=5)
    lin = law._heldout("linear", a, m, s, True, seed=5)
    d = thr - lin
    assert d.sum() > 2 * math.sqrt(d.size * np.var(d))
    a, m, s = _levels(lambda a: 2.0 * a, scatter=0.02, seed=3)
    thr = law._heldout("threshold", a, m, s, True, seed=6)
    lin = law._heldout("linear", a, m, s, True, seed=6)
    d = thr - lin
    assert d.sum() < 2 * math.sqrt(d.size * np.var(d)) + 1.0


def _fake_fit_dir(tmp_path, fc_of_a, k2=5e4, n=400, seed=0, A=A, ids=None):
    """A `fit --by applied` folder whose posteriors are known: fc_fwd log-normal around
    fc_of_a(a) (sd 2 %), k2 shared, fs_fwd = 1.2 fc_fwd (perfectly correlated). ids: the fits'
    ids (a `--by test` folder's are the tests')."""
    rng = np.random.default_rng(seed)
    fits = []
    for i, a in enumerate(A):
        fid = ids[i] if ids else f"applied-{a:.4g}N"
        fc = fc_of_a(a) * np.exp(0.02 * rng.standard_normal((2, n)))
        post = {"fc_fwd": fc, "fs_fwd": 1.2 * fc, "k2": k2 * np.exp(0.05 * rng.standard_normal((2, n)))}
        (tmp_path / fid).mkdir()
        azadapter.save(azadapter.build(post), tmp_path / fid / "posterior.nc")
        space = {"model": "three_stage", "effects": [], "free": list(post),
                 "priors": {k: {"dist": "loguniform", "lower": 1e-3, "upper": 1e9} for k in post},
                 "fixed": {"w": 1e-3}}
        (tmp_path / fid / "fit.json").write_text(json.dumps({"space": space}))
        fits.append({"id": fid, "applied": float(a), "converged": True})
    (tmp_path / "summary.json").write_text(json.dumps({"campaign": "fake", "fits": fits}))
    return tmp_path


def test_fit_law_and_draws_at(tmp_path):
    d = _fake_fit_dir(tmp_path, lambda a: 1.5 * a)
    doc = law.fit_law(d, seed=2)
    assert (d / "law.json").is_file()
    assert doc["laws"]["k2"]["family"] == "constant"
    assert doc["laws"]["fc_fwd"]["family"] == doc["family"]
    assert set(doc["comparison"]) == set(law.FAMILIES)
    assert "package_version" in doc and doc["seed"] == 2
    # an untested force between two levels: the law's value, with an honest spread
    a_new = 50.0 * 4.448
    draws, model, effects = lawdraws.draws_at(d, a_new, 2000, np.random.default_rng(0))
    assert model == "three_stage" and effects == ()
    med = np.median(draws["fc_fwd"])
    assert abs(med / (1.5 * a_new) - 1) < 0.05
    lo, hi = np.quantile(draws["fc_fwd"], [0.025, 0.975])
    assert lo < 1.5 * a_new < hi
    # within-level correlation kept: fs_fwd / fc_fwd stays 1.2 for every draw
    assert np.allclose(draws["fs_fwd"] / draws["fc_fwd"], 1.2, rtol=0.15)
    assert abs(np.median(draws["k2"]) / 5e4 - 1) < 0.1
    assert np.all(draws["w"] == 1e-3)
    # far outside the tested range the law's values are clipped to the prior box and the
    # physical bounds, never passed on to the simulator out of range
    from frictionuq import params as P
    far, _, _ = lawdraws.draws_at(d, 1e9, 500, np.random.default_rng(1))
    for name, v in far.items():
        assert np.all((v >= P.PARAMS[name].lower) & (v <= P.PARAMS[name].upper)), name
    # reproducible: same seed, same law file
    text = (d / "law.json").read_text()
    law.fit_law(d, seed=2)
    assert (d / "law.json").read_text() == text
    # the summary names the law now in the folder, with its hash (after a refit with another
    # family too: it said the first family until 2026-12-05)
    entry = json.loads((d / "summary.json").read_text())["law"]
    assert entry == law.law_entry(d) and entry["family"] == doc["family"] and len(entry["sha256"]) == 64
    other = "threshold" if doc["family"] != "threshold" else "linear"
    law.fit_law(d, family=other, seed=2)
    assert json.loads((d / "summary.json").read_text())["law"]["family"] == other


def test_law_needs_levels_and_a_folder(tmp_path):
    with pytest.raises(InputError, match="summary.json"):
        law.fit_law(tmp_path)
    with pytest.raises(InputError, match="law.json"):
        lawdraws.draws_at(tmp_path, 100.0, 10, np.random.default_rng(0))


def test_a_by_test_folder_with_one_force_is_refused(tmp_path):
    """Two fits of one applied force (`fit --by test` on two tests at 133 N) are not two levels:
    law fitted a 'law' on [133, 133] until 2026-12-05."""
    d = _fake_fit_dir(tmp_path, lambda a: 1.5 * a, A=(133.0, 133.0), ids=("h-133N-0.5Hz", "h-133N-0.2Hz"))
    with pytest.raises(InputError, match=r"needs one fit per applied force at 2 or more forces > 0 "
                                         r"\(found 2 fit\(s\) at 1 force\(s\)\)"):
        law.fit_law(d)


def test_zero_force_level_is_left_out_of_the_law(tmp_path):
    """A campaign with a test at zero applied force (the ARTS d2 0 lb sines): the level is fitted
    but lies outside every law family's support (log force), so the law leaves it out and says
    so, instead of failing."""
    d = _fake_fit_dir(tmp_path, lambda a: 1.5 * a + 30.0, A=(0.0, 100.0, 200.0, 300.0))
    doc = law.fit_law(d, seed=3)
    assert [L["applied"] for L in doc["levels"]] == [100.0, 200.0, 300.0]
    assert doc["excluded_levels"][0]["id"].startswith("applied-0")
    draws, _, _ = lawdraws.draws_at(d, 150.0, 100, np.random.default_rng(0))
    assert np.all(np.isfinite(draws["fc_fwd"]))


def test_scatter_normals_follow_the_levels_departures_from_their_laws():
    """Parameters whose levels depart from their laws together get the same scatter normal
    (correlation 1 in the departures); a parameter that departs on its own gets its own.
    Six constant-law levels with known departures; fixed seed, deterministic."""
    rng = np.random.default_rng(4)
    dep = rng.standard_normal(6)
    other = rng.standard_normal(6)
    levels = [{"applied": 10.0 * (i + 1),
               "draws": {"fc_fwd": np.exp(np.full(50, dep[i])), "fs_fwd": np.exp(np.full(50, 2 * dep[i])),
                         "k2": np.exp(np.full(50, other[i]))}} for i in range(6)]
    laws = {n: {"family": "constant", "log_space": True, "beta_draws": [[0.0]], "tau_draws": [1.0]}
            for n in ("fc_fwd", "fs_fwd", "k2")}
    z = lawdraws.scatter_normals({"laws": laws}, levels, ["fc_fwd", "fs_fwd", "k2"], 4000,
                            np.random.default_rng(0))
    assert np.allclose(z[:, 0], z[:, 1], atol=1e-9)
    r = np.corrcoef(z.T)
    assert abs(r[0, 2] - np.corrcoef(dep, other)[0, 1]) < 0.1     # the departures' correlation
    assert np.allclose(z.std(axis=0), 1.0, atol=0.05)
    # with too few levels to estimate a correlation: independent normals
    z2 = lawdraws.scatter_normals({"laws": laws}, levels[:2], ["fc_fwd", "fs_fwd", "k2"], 4000,
                             np.random.default_rng(0))
    assert abs(np.corrcoef(z2[:, 0], z2[:, 1])[0, 1]) < 0.1
