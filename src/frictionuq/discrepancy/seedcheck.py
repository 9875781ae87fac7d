"""Does the name hold when the searches start elsewhere? `discover --check-seed N`.

The screening's maxima come from multi-start searches (candidate.py, fits.py) whose random
starts follow the run's seed. Where the gap is hundreds of nats wide (the hidden-effect
campaigns) the names held when code changes moved the starts (docs/log-discrepancy.md,
2026-12-03). On the real ARTS records, where candidates differ by tens of nats, they need not:
at 25 lb of dataset 1 (2026-12-04, one host) seed 1 named eccentricity (+330.0 nats held out),
seed 2 none (eccentricity's MAP raised the RMSE, rule (f)), and the same code on another CPU
type, whose rounding moves the searches' optima, named takeup_overshoot; 20 and 70 lb moved
with the seed and the CPU type as well; 35 lb (takeup_overshoot), 22 and 80 lb (none) held
across both. Where a name moves, the candidate's own optimum is rugged: at 20 and 25 lb four
searches per seed ended over 93 and 425 nats (benchmarks/bench_search_spread.py), so more
searches would not settle it; the check reports it. A check seed screens the campaign again,
every round, with its own starts (the baseline's too), and the document says whether every
seed names the same effects. It costs one more screening per check seed; the refit and the
diagnostics are the main seed's only.
"""
from __future__ import annotations


def summarize(seed: int, named: list[str], checks: list[tuple[int, list[dict]]]) -> dict:
    """The document's `seed_check`: {"seeds", "named_effects" (one list per seed, the main seed
    first), "stable" (every seed names the same effects, in the same order), "runs": per check
    seed {"seed", "named_effects", "reason" (round 1's), "candidates" (round 1's held-out and
    MAP gains)}}. checks: [(seed, its rounds as discover._screen_rounds returns them)]."""
    runs = []
    for s, rounds in checks:
        runs.append({"seed": s,
                     "named_effects": [r["named"] for r in rounds if r["named"] != "none"],
                     "reason": rounds[0]["reason"],
                     "candidates": [{"effect": c["effect"], "elpd_gain": c["elpd_gain"],
                                     "map_gain": c["map_gain"]} for c in rounds[0]["ranked"]]})
    names = [list(named)] + [r["named_effects"] for r in runs]
    return {"seeds": [seed] + [r["seed"] for r in runs], "named_effects": names,
            "stable": all(n == names[0] for n in names), "runs": runs}


def _names(named: list[str]) -> str:
    return " + ".join(named) if named else "none"


def sentence(check: dict) -> str:
    """One sentence for the log, the CLI and the report page."""
    seeds, names = check["seeds"], check["named_effects"]
    if check["stable"]:
        return (f"Seed check: seeds {', '.join(map(str, seeds))} all name {_names(names[0])}; the "
                "name did not change with the searches' random starts.")
    per = "; ".join(f"seed {s}: {_names(n)}" for s, n in zip(seeds, names))
    return (f"Seed check: the name depends on the searches' random starts ({per}), so it rests on "
            "where the searches end, not on the data alone: take the names the seeds give as "
            "alternatives.")
