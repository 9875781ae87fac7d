"""frictionuq.validate's scores and the sentences that flag a miscalibrated band (deterministic:
the bands are built from known errors)."""
import re

import numpy as np
import pandas as pd
import pytest

from frictionuq.validate import calibration_notes, score
from scipy.stats import norm


def _bands(median, sd):
    """Gaussian predictive bands of the given median and sd (the columns predict writes)."""
    cols = {"force_median": median}
    for name, q in (("force_q2.5", 0.025), ("force_q25", 0.25), ("force_q75", 0.75),
                    ("force_q97.5", 0.975)):
        cols[name] = median + sd * norm.ppf(q)
    return pd.DataFrame(cols)


def calibrated_scores():
    rng = np.random.default_rng(1)
    y = rng.normal(0.0, 1000.0, 20000)
    return score(y, _bands(np.zeros(y.size), 1000.0))


def test_calibrated_bands_score_about_right_and_say_nothing():
    s = calibrated_scores()
    assert s["coverage95"] == pytest.approx(0.95, abs=0.01)
    assert s["coverage50"] == pytest.approx(0.50, abs=0.02)
    assert abs(s["bias_N"]) < 30.0
    assert s["rmse_N"] == pytest.approx(1000.0, rel=0.03)
    assert calibration_notes(s) == []


def test_a_biased_median_inside_a_wide_band_is_flagged_by_the_50_percent_band():
    """The demo's Imperial Valley replay: the 95 % band covered 98.9 % while the median sat
    2.6 kN off, and only the 50 % band (15 %) showed it."""
    rng = np.random.default_rng(2)
    y = rng.normal(2600.0, 300.0, 20000)                     # measured: offset by +2.6 kN
    s = score(y, _bands(np.zeros(y.size), 2000.0))           # wide band around 0
    assert s["coverage95"] > 0.9 and s["coverage50"] < 0.3
    assert s["bias_N"] == pytest.approx(2600.0, rel=0.02)
    notes = calibration_notes(s)
    assert len(notes) == 1
    assert "50 % band" in notes[0] and "overstates" in notes[0]
    assert re.search(r"off by \+2[56]\d\d N on average", notes[0]), notes[0]
    # validate()'s whole result gives every test's sentences, named; before, it said nothing
    # (no coverage keys at its top level: read as "calibrated")
    doc = {"tests": [dict(s, test="eq-iv"), dict(calibrated_scores(), test="sine")]}
    assert calibration_notes(doc) == [f"eq-iv: {notes[0]}"]
    for wrong in ([s], {"package_version": "x"}, None):
        with pytest.raises(ValueError, match="expected one test's scores"):
            calibration_notes(wrong)


def test_overconfident_and_conservative_bands_are_named():
    rng = np.random.default_rng(3)
    y = rng.normal(0.0, 1000.0, 20000)
    narrow = calibration_notes(score(y, _bands(np.zeros(y.size), 300.0)))
    assert any("overconfident" in n for n in narrow)
    wide = calibration_notes(score(y, _bands(np.zeros(y.size), 5000.0)))
    assert len(wide) == 1 and "conservative" in wide[0]
