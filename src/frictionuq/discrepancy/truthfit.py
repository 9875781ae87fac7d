"""How much in-sample evidence a hidden-effect campaign carries for its hidden effects (issue 5,
item 4; benchmarks/bench_discover.py --truth-fit).

The generator knows what it hid (hidden.hidden_campaign's answer: the 3-stage parameters it
simulated with, "model_parameters", and the effects' parameters). The truth fit is the baseline
plus the hidden effects fitted from those values (whitened least squares, as the candidates'
searches end, fits.white_fit); its gain is its log-posterior over the baseline's MAP, the same
difference as a candidate's in-sample gain in the screening (screen.screen_level). It is a lower
bound on the best fit of that model; with the candidate's own in-sample gain beside it (the
larger of the two is the evidence a search could have found), a missed effect is one of two
kinds:

* the evidence is under the decision rule's threshold (rule.min_gain): the records carry too
  little for any search to name the effect at the rule's false-alarm rate. Seen (2026-12-05) on
  the short MFD campaigns of seeds 12 and 25 with stage2_nonlinear hidden at p2 2.97 and 2.95:
  truth fits +3.5 and -0.9 nats, the candidates' searches +3.5 and +0.0, the threshold 5.4. A
  steep late stage-2 rise is imitated by the baseline's stage 3 (k2 near 0, d3 moved); the better
  of two fits at each p2 held between 1.0 and 3.5 (from the baseline's MAP and from the truth
  fit) is within -1.7 and +0.7 nats of the baseline's MAP on the seed-25 campaign;
* the evidence is over the threshold and the candidate's gain under it: the search fell short.
  Seen on the short BRFD campaign of seed 32 (p2 2.10): the truth fit +5.9 (at p2 1.69), the
  candidate +4.8.

Not used by discover (which never sees the answer); a tool for judging the hidden-effect set.
"""
from __future__ import annotations

import numpy as np

from . import fits as F


def generating_theta(space, answer: dict, base_map: dict) -> np.ndarray:
    """The point of `space` (sampling coordinates) at the generator's 3-stage and effect
    parameters where the answer has them and the baseline's MAP (base_map) for the rest (the
    likelihood's force_offset, anything the generator left at its default), clipped into the
    prior box in sampling coordinates (where fs_* are ratios to fc_* and scales are logs; a
    generating value on a bound would give a -inf start)."""
    truth = dict(answer.get("model_parameters", {}))
    for q in answer["effects"].values():
        truth.update(q)
    vals = {}
    for n in space.names:
        vals[n] = truth.get(n, base_map.get(n))
        if vals[n] is None:
            raise KeyError(f"truthfit: no generating or baseline value for {n!r}")
    pad = 1e-6 * np.where(np.isfinite(space.hi - space.lo), space.hi - space.lo, 0.0)
    return np.clip(space.to_theta(vals), space.lo + pad, space.hi - pad)


def truth_fit_gain(level_tests, cfg, answer: dict, base_map: dict, base_log_prob: float) -> dict:
    """The truth fit of one level: {"effects", "gain" (nats over the baseline's MAP, whose
    log-posterior is base_log_prob), "log_prob", "map"} for the baseline plus every hidden
    effect of the answer, fitted from the generating values (3 rounds of whitened least
    squares). The answer must carry "model_parameters" (hidden_campaign's since 2026-12-05)."""
    if "model_parameters" not in answer:
        raise KeyError("truthfit: the answer has no 'model_parameters' (made before 2026-12-05? "
                       "write the campaign again with hidden.hidden_campaign)")
    effects = tuple(answer["effects"])
    lp, _ = F.logpost_for(level_tests, effects, cfg)
    th0 = generating_theta(lp.space, answer, base_map)
    th = F.white_fit(lp, th0, rounds=3)
    lp_th = F.log_prob(lp, th)
    return {"effects": list(effects), "gain": lp_th - base_log_prob, "log_prob": lp_th,
            "map": F.values(lp.space, th)}
