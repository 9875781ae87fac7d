"""`frictionuq table`: the per-test quick look, checked on the BRFD twin where the published
model is the truth (its residual must be the twin's noise) and on a real campaign."""
from pathlib import Path

import numpy as np
import pytest

from frictionuq.cli import main
from frictionuq.published import brfd_params
from frictionuq.quicklook import campaign_frame

ROOT = Path(__file__).resolve().parents[1]


def test_twin_residual_is_the_noise():
    df, camp = campaign_frame(ROOT / "data/brfd-twin", published="brfd")
    h = df[df["kind"] == "harmonic"]
    assert len(h) == 20
    for _, row in h.iterrows():
        p = brfd_params(row["published at (N)"])
        fc = 0.5 * (p["fc_fwd"] + p["fc_bwd"])
        # the twin's force noise: white sd 1 % of Fc plus AR(1) sd 0.5 % of Fc
        expected = np.hypot(0.01, 0.005) * fc
        assert row["RMSE (kN)"] * 1e3 == pytest.approx(expected, rel=0.15), row["test"]
        assert abs(row["mean resid (kN)"] * 1e3) < 0.01 * fc
        assert row["published at (N)"] == row["applied (N)"]
        # NRMSE as validate defines it: RMSE over the measured force's peak to peak
        force = next(te for te in camp.tests if te.id == row["test"]).record.force
        assert row["NRMSE (% of p-p)"] == pytest.approx(100 * row["RMSE (kN)"] * 1e3 / np.ptp(force))
    assert df.attrs["far_from_published"] == []
    assert set(df["reversals"][df["kind"] == "harmonic"]) == {20}   # 10 cycles: 10 peaks, 10 troughs


def test_real_campaign_table(capsys):
    assert main(["table", str(ROOT / "data/brfd-arts-d1"), "--published", "brfd"]) == 0
    out = capsys.readouterr().out
    assert "applied (lb)" in out and "RMSE (kN)" in out and "sine-1Hz-80lb" in out
    assert out.count("\n") >= 14
    # the source units as words, not a Python dict (until 2026-12-05)
    assert "source units time s, displacement in, force kip, applied lb;" in out and "{" not in out


def test_levels_far_from_the_published_ones_are_flagged(capsys):
    """The 0 lb sines of arts-d2 are compared with the published model at 35 N, and the table
    says that is an extrapolation (beyond 1.5 x the nearest published level); the 36 lb sines
    (160 N, nearest 133 N) are not flagged; an MFD campaign is judged by the paper's 500-1500 psi."""
    assert main(["table", str(ROOT / "data/brfd-arts-d2"), "--published", "brfd"]) == 0
    out = capsys.readouterr().out
    flagged = [ln for ln in out.splitlines() if "the published model is extrapolated" in ln]
    assert flagged and all("-0lb-" in ln and "nearest published level is 35 N" in ln for ln in flagged)
    assert len(flagged) == sum(1 for ln in out.splitlines() if "-0lb-" in ln and "harmonic" in ln)
    df, _ = campaign_frame(ROOT / "data/mfd-twin", published="mfd")
    assert df.attrs["far_from_published"] == []


def test_bad_eps(capsys):
    assert main(["table", str(ROOT / "data/brfd-twin"), "--eps", "wide"]) == 2
    assert "--eps" in capsys.readouterr().err


def test_wrong_device(capsys):
    assert main(["table", str(ROOT / "data/mfd-twin"), "--published", "brfd"]) == 2
    assert "psi" in capsys.readouterr().err
