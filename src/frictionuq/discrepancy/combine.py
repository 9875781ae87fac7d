"""The residual diagnostics of a level's tests taken together: is a view's structure significant
in the level as a whole, where no single test shows it?

A missing effect acts in every test of a level, but a short record or a weak drift can leave
each test's own p-value just above its Holm threshold. Seen (docs/log-discrepancy.md,
2026-11-25): on the full-length MFD campaign with a hidden thermal fade the baseline's 0.5 Hz
test showed its drift (p = 0.001), the 0.1 Hz test (501 samples, 20 blocks) and the Kobe replay
did not (p = 0.039 and 0.038), although the workflow named the fade.

For each view (diagnostics.diagnose: displacement ... energy, applied, the spectrum, chatter's
bursts) present in two or more tests of the level, Fisher's combination of the tests' raw
permutation p-values,

    X = -2 sum_i ln p_i,  p_combined = P(chi2 with 2 k degrees of freedom >= X),

then Holm's step-down correction over the views combined, at the diagnostics' alpha. Under the
null of every test (its residual a stationary short-memory process unrelated to the features)
each permutation p-value is super-uniform (P(p <= a) <= a) and the tests' permutations are drawn
independently (discover gives each test of a level its own permutation seed), so p_combined is
valid (conservative) when the records' residuals are independent of each other: they are
separate records, coupled only through the parameters fitted to all of them.

Which tests enter. A test's own null is only roughly calibrated when its blocks are capped at
n / 20 samples and so hold few of the residual's correlation lengths (diagnostics.py,
`block_capped`), and Fisher's sum adds up those small biases. Measured (three independent AR(1)
records on the BRFD sine, alpha 0.01 family-wise, script of the replicates: the harness of
tests/test_discrepancy_combine.py with more seeds): 500 samples at phi 0.95 (blocks of 25
samples, 0.6 correlation lengths) **3 alarms in 20** combined; 2,400 samples at phi 0.95 (blocks
of 120 samples, about 3 lengths) 0 in 100; 4,000 samples at phi 0.95 (about 5 lengths) 2 in 100;
2,000 samples at phi 0.8 (5-10 lengths) 1 in 100; on this last case a fade of 0.75 % of fc
in all three records was found combined in 88 of 100 replicates, by some single test in 61.
So a test enters the combination only if its blocks hold at least MIN_BLOCK_TAU = 3
correlation lengths; the others are listed as `excluded`. Structure in a residual lengthens its
estimated correlation length (the drift itself), so a test with a strong drift can be left out;
it then shows that drift on its own. The full-length MFD campaign with the hidden fade above
(seed 11, the baseline's MAP): the 0.1 Hz test is left out (blocks 0.7 lengths); the 0.5 Hz
test (3.5 lengths) and the Kobe replay (8.3) combined show the drift in the energy view, p
0.0007 from 0.002 and 0.035 (Holm-adjusted below 1 %), which the replay alone does not; with the
fade modelled, no view of the three tests combined is significant (smallest p 0.137).
"""
from __future__ import annotations

import math

from scipy import stats

from .diagnostics import holm

MIN_BLOCK_TAU = 3.0
METHOD = ("Fisher's combination of the tests' permutation p-values (-2 sum ln p, chi-square "
          "with 2k degrees of freedom), Holm's correction over the views combined")


def _p_values(d: dict) -> dict[str, float]:
    """{view: raw p-value} of one test's diagnostics (views, the spectrum, chatter's bursts)."""
    out = {name: v["p_value"] for name, v in d["views"].items()}
    for extra in ("spectrum", "chatter"):
        if d.get(extra) and d[extra].get("p_value") is not None:
            out[extra] = d[extra]["p_value"]
    return {k: float(v) for k, v in out.items() if v is not None and math.isfinite(v)}


def fisher(p: list[float]) -> float:
    """Fisher's combined p-value of independent p-values (scipy's combine_pvalues)."""
    return float(stats.combine_pvalues([max(v, 1e-300) for v in p], method="fisher").pvalue)


def reliable(d: dict) -> bool:
    """Whether a test's null is trusted in a combination: its blocks at least MIN_BLOCK_TAU
    autocorrelation lengths long (module docstring)."""
    nl = d["null"]
    return nl["block_length_samples"] >= MIN_BLOCK_TAU * nl["autocorrelation_length_samples"]


def combine(diagnostics: list[dict], tests: list[str], alpha: float | None = None) -> dict:
    """The level's combined verdict from its tests' diagnostics (diagnose's outputs, in the order
    of `tests`): {"tests" (combined), "excluded" (left out: reliable() fails), "method",
    "alpha", "family_size", "views": {view: {"tests", "p_values", "p_combined", "p_adjusted",
    "significant"}}, "significant": [views]}. A view in fewer than two tests is not combined;
    alpha defaults to the tests' own. The p-values must come from independent permutations (a
    seed per test)."""
    if len(diagnostics) != len(tests):
        raise ValueError("combine: one diagnostics entry per test")
    if alpha is None:
        alpha = diagnostics[0]["alpha"] if diagnostics else 0.01
    alpha = float(alpha)
    keep = [reliable(d) for d in diagnostics]
    excluded = [t for t, k in zip(tests, keep) if not k]
    tests = [t for t, k in zip(tests, keep) if k]
    per = [_p_values(d) for d, k in zip(diagnostics, keep) if k]
    names = sorted({n for p in per for n in p})
    views = {}
    for n in names:
        have = [(t, p[n]) for t, p in zip(tests, per) if n in p]
        if len(have) >= 2:
            views[n] = {"tests": [t for t, _ in have], "p_values": [v for _, v in have],
                        "p_combined": fisher([v for _, v in have])}
    adj = holm({n: v["p_combined"] for n, v in views.items()})
    for n, v in views.items():
        v["p_adjusted"], v["significant"] = adj[n], bool(adj[n] <= alpha)
    order = sorted(views, key=lambda k: views[k]["p_combined"])
    return {"tests": list(tests), "excluded": excluded, "method": METHOD, "alpha": alpha,
            "family_size": len(views),
            "views": views, "significant": [n for n in order if views[n]["significant"]]}
