"""The discrepancy workflow end to end (check: tests/discover_check.py) on the cases that cost the
most: the MCMC refit with the named effect's parameters inside their intervals, and forward
selection (discover(max_effects=2)): two hidden effects named one per round, and a second round
that says none after a single hidden effect. A file of its own so that pytest-xdist (--dist
loadfile) runs it on the other worker from test_discrepancy_discover.py."""
from __future__ import annotations

import pytest

from discover_check import check_discover


@pytest.mark.slow
@pytest.mark.parametrize("device, effect, seed, refit, also, max_effects", [
    ("mfd", "thermal_fade", 11, True, None, 1),
    ("brfd", "reversal_hump", 7, False, None, 2),    # round 2 must say none
    # two effects hidden, named one per round, as in the real ARTS loops: the force overshoot at
    # the take-up and chatter, a noise effect (more noise in a window after each reversal)
    ("brfd", "takeup_overshoot", 11, False, "chatter", 2),
])
def test_discover_refit_and_rounds(tmp_path, device, effect, seed, refit, also, max_effects):
    check_discover(tmp_path, device, effect, seed, refit, also=also, max_effects=max_effects)
