"""Each candidate effect's in-sample (MAP) gain on clean campaigns against campaigns where it is
hidden, from the rows `bench_discover.py --rows ROWS.jsonl` writes: how far apart the two lie, per
effect and device. Not a test: figures only.

    .venv/bin/python benchmarks/gain_table.py ROWS.jsonl [MORE.jsonl ...]

Why: the decision rule's in-sample stage (discrepancy/screen.py, rule (e)) asked every candidate
for the same MIN_GAIN (20 nats) over the baseline's MAP, whatever its number of parameters, until
2026-12-04; since then an effect whose null is regular (params.REGULAR_NULL) is asked for the
chi2 column's value instead (rule.min_gain), and this table is how that is checked. A
hidden stage2_nonlinear (one parameter) mostly stays under it (10-17 nats on short campaigns,
docs/log-discrepancy.md), while on the clean campaigns the best candidate, mostly eccentricity
(three parameters), reaches up to about 10. Whether a threshold per effect could separate the two
is a question of each effect's own gains on clean campaigns, which the printed runs did not keep
(only the best two candidates'). The chi2 column is the reference of regular nested-model
theory: half the 99.9 % point of chi2 with the effect's number of parameters, what the in-sample
gain of a correct baseline would exceed once in a thousand clean campaigns if that theory held
(it need not: bounded parameters, the MAP searches, AR(1) noise, a misspecified baseline).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.stats import chi2


def read_rows(paths) -> list[dict]:
    """Every row of the JSON-lines files (one campaign per line); a line that is not a JSON
    object is refused with its file and line number (ValueError)."""
    rows = []
    for path in paths:
        for i, line in enumerate(Path(path).read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError as e:
                raise ValueError(f"{path}, line {i}: not JSON ({e.msg})") from None
            if not isinstance(row, dict) or "candidates" not in row or "hidden" not in row:
                raise ValueError(f"{path}, line {i}: not a row of bench_discover.py --rows "
                                 "(no 'hidden' or 'candidates')")
            rows.append(row)
    return rows


def gain_table(rows: list[dict]) -> list[dict]:
    """Per (effect, device) seen among the rows' candidates: the effect's in-sample gains (nats)
    on the clean campaigns ("clean": hidden none) and on those with it alone hidden ("hidden"),
    with how many of the latter it was named in and how many lie above every clean gain; the
    chi2 reference (module docstring); and its held-out gains where it was scored held out
    ("*_heldout_*": stage 1 scores only candidates above MIN_GAIN in-sample, --score-all every
    one). Campaigns with another effect hidden are left out (there
    a candidate's gain is its share of another effect's gap, not a null)."""
    out = []
    keys = sorted({(c["effect"], r["device"]) for r in rows for c in r["candidates"]})
    for eff, dev in keys:
        clean, hidden, named, k = [], [], 0, None
        clean_ho, hidden_ho = [], []      # held-out gains, where scored (--score-all: always)
        for r in rows:
            if r["device"] != dev:
                continue
            c = next((c for c in r["candidates"] if c["effect"] == eff), None)
            if c is None:
                continue
            k = c["n_params"]
            if r["hidden"] == "none":
                clean.append(c["map_gain"])
                if c["elpd_gain"] is not None:
                    clean_ho.append(c["elpd_gain"])
            elif r["hidden"] == eff:
                hidden.append(c["map_gain"])
                named += r["named"] == eff
                if c["elpd_gain"] is not None:
                    hidden_ho.append(c["elpd_gain"])
        cmax = max(clean) if clean else None
        out.append({"effect": eff, "device": dev, "n_params": k,
                    "chi2_ref": float(chi2.ppf(0.999, k) / 2),
                    "clean_n": len(clean), "clean_max": cmax,
                    "clean_q90": float(np.quantile(clean, 0.9)) if clean else None,
                    "hidden_n": len(hidden), "hidden_min": min(hidden) if hidden else None,
                    "hidden_median": float(np.median(hidden)) if hidden else None,
                    "hidden_named": named,
                    "hidden_above_clean": (sum(g > cmax for g in hidden) if clean and hidden
                                           else None),
                    "clean_heldout_n": len(clean_ho),
                    "clean_heldout_max": max(clean_ho) if clean_ho else None,
                    "hidden_heldout_n": len(hidden_ho),
                    "hidden_heldout_min": min(hidden_ho) if hidden_ho else None,
                    "hidden_heldout_median": float(np.median(hidden_ho)) if hidden_ho else None})
    return out


def _f(v, spec="+.1f") -> str:
    return "-" if v is None else format(v, spec)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("rows", nargs="+", type=Path, help="JSON-lines files of bench_discover.py --rows")
    a = ap.parse_args(argv)
    for p in a.rows:
        if not p.is_file():
            ap.error(f"{p}: no such file")
    try:
        rows = read_rows(a.rows)
    except ValueError as e:
        ap.error(str(e))
    if not rows:
        ap.error(f"no rows in {', '.join(map(str, a.rows))}: expected JSON lines of "
                 "bench_discover.py --rows")
    print(f"{len(rows)} campaigns ({sum(r['hidden'] == 'none' for r in rows)} clean); in-sample "
          "(MAP) gains over the baseline, nats")
    print(f"{'effect':<20} {'dev':<5} {'k':>2} {'chi2':>5} | {'clean n':>7} {'max':>7} {'q90':>7} | "
          f"{'hidden n':>8} {'min':>7} {'median':>7} {'named':>5} {'> clean max':>11} | held out: "
          f"{'clean n':>7} {'max':>7} | {'hidden n':>8} {'min':>7} {'median':>7}")
    for t in gain_table(rows):
        print(f"{t['effect']:<20} {t['device']:<5} {t['n_params']:>2} {t['chi2_ref']:5.1f} | "
              f"{t['clean_n']:>7} {_f(t['clean_max']):>7} {_f(t['clean_q90']):>7} | "
              f"{t['hidden_n']:>8} {_f(t['hidden_min']):>7} {_f(t['hidden_median']):>7} "
              f"{t['hidden_named']:>5} {_f(t['hidden_above_clean'], 'd'):>11} | "
              f"{'':>10}{t['clean_heldout_n']:>7} {_f(t['clean_heldout_max']):>7} | "
              f"{t['hidden_heldout_n']:>8} {_f(t['hidden_heldout_min']):>7} "
              f"{_f(t['hidden_heldout_median']):>7}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
