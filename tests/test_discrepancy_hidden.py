"""discrepancy/hidden.py: the generator's noise scale in its answer (noise_rms_N), which a hidden
effect's rmse_after is measured against. (The campaigns' other properties are tested with the
screening that uses them: tests/test_discrepancy_screen.py.)"""
from __future__ import annotations

import numpy as np
import pytest

from frictionuq import published as pub
from frictionuq.campaign import load_campaign
from frictionuq.discrepancy.hidden import LEVEL, hidden_campaign
from frictionuq.model import simulate
from frictionuq.noise import chatter_gain, since_reversal


def _realised_rms(path, p, effects=None) -> float:
    """The rms over every sample of the campaign's force minus the generating model's."""
    e = [t.record.force - simulate(t.record.t, t.record.x, p, effects=effects, eps=0.0)
         for t in load_campaign(path).tests]
    return float(np.sqrt(np.mean(np.concatenate(e) ** 2)))


def test_noise_rms_is_the_sd_without_a_noise_effect_and_the_windows_rms_with_chatter(tmp_path):
    """Fixed seed (deterministic). Without a noise effect noise_rms_N is noise_sd_N exactly;
    with chatter it is the sd times the rms of the window's gain over every sample (recomputed
    here from the records and the drawn parameters), above the sd, and the realised noise of the
    campaign (force minus the generating model) is near it, far from the stationary sd."""
    p = pub.published_params("brfd", LEVEL["brfd"])
    plain = hidden_campaign(tmp_path / "f", "brfd", "thermal_fade", seed=11, short=True)
    assert plain["noise_rms_N"] == plain["noise_sd_N"]
    ch = hidden_campaign(tmp_path / "c", "brfd", "chatter", seed=11, short=True)
    q = ch["effects"]["chatter"]
    g2 = np.concatenate([chatter_gain(since_reversal(t.record.x), q["a_ch"], q["s_ch"],
                                      q["w_ch"])[0] ** 2 for t in load_campaign(tmp_path / "c").tests])
    sd = ch["noise_sd_N"]
    assert ch["noise_rms_N"] == pytest.approx(sd * np.sqrt(np.mean(g2)), rel=1e-9)
    assert ch["noise_rms_N"] > 1.1 * sd
    real = _realised_rms(tmp_path / "c", p)
    assert abs(real / ch["noise_rms_N"] - 1.0) < abs(real / sd - 1.0), (real, ch["noise_rms_N"], sd)
    assert 0.8 < real / ch["noise_rms_N"] < 1.25, (real, ch["noise_rms_N"])
