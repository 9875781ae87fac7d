"""Section "predictions": validation on held-out tests (predict/validation, written by
frictionuq.validate) and predictions for new drives (predict/<name>, written by
frictionuq.predict.write_prediction)."""
from __future__ import annotations

from pathlib import Path

from ...errors import InputError
from ...validate import calibration_notes
from .. import blocks as B
from .. import figures as F
from ..context import read_json
from ..tables import DASH, interval, kv_table, num, pct, scaled, table

def bands_of(df, prefix: str = "force", median: str = "force_median") -> dict:
    return {"lo95": df[f"{prefix}_q2.5"].to_numpy(), "lo50": df[f"{prefix}_q25"].to_numpy(),
            "hi50": df[f"{prefix}_q75"].to_numpy(), "hi95": df[f"{prefix}_q97.5"].to_numpy(),
            "median": df[median].to_numpy()}


def _read_csv(path: Path):
    import pandas as pd
    return pd.read_csv(path)


def validation(ctx, vdir: Path) -> list[dict]:
    doc = read_json(vdir / "validation.json", "the validation summary")
    tests = [t for t in doc.get("tests") or [] if isinstance(t, dict) and "test" in t]
    if not tests:
        return [B.note("predict/validation/validation.json lists no test.")]
    unit = ctx.applied_unit()
    rows, classes = [], []
    for s in tests:
        low = bool(calibration_notes(s))
        rows.append([s["test"], s.get("kind", DASH), ctx.applied_number(s.get("applied_si")),
                     "yes" if s.get("held_out") else "NO (fitted)", s.get("draws_source", DASH),
                     pct(s.get("coverage95")), pct(s.get("coverage50")), scaled(s.get("rmse_N"), 1e-3),
                     pct(s.get("nrmse"), 2), scaled(s.get("bias_N"), 1e-3),
                     scaled(s.get("rmse_offset_free_N"), 1e-3),
                     scaled(s.get("peak_to_peak_N"), 1e-3), s.get("samples", DASH),
                     num((s.get("eps_m") or float("nan")) * 1e6, 3)])
        classes.append("flagged" if low or not s.get("held_out") else "")
    cols = ["test", "kind", f"applied force ({unit})", "held out", "parameter draws",
            "coverage of the 95 % band", "coverage of the 50 % band", "RMSE (kN)",
            "NRMSE (RMSE / peak-to-peak)", "mean error, measured minus median (kN)",
            "RMSE without the mean error (kN)",
            "measured peak-to-peak (kN)", "samples", "dead band eps (µm)"]
    out = [B.para(f"Each test predicted from the fit folder with its measured displacement "
                  f"({doc.get('n_draws', '?')} draws, load-cell offset and measurement noise "
                  "included) and scored against the measured force. A calibrated band covers "
                  "about 95 % (50 %) of the samples; far less means overconfident."),
           B.html(table(cols, rows, row_classes=classes, caption="validation scores"))]
    from ...extrapolation import notes
    for s in tests:
        for line in calibration_notes(s):
            out.append(B.warn(f"{s['test']}: {line[0].upper()}{line[1:]}."))
        for line in notes(s):          # (validation.json of 2026-12-05 on: the ranges recorded)
            out.append(B.note(f"{s['test']}: {line[0].upper()}{line[1:]}."))
    fitted = [s["test"] for s in tests if not s.get("held_out")]
    if fitted:
        out.append(B.warn(f"Not held out (the fit saw them): {', '.join(fitted)}."))
    camp = ctx.campaign()
    for s in tests:
        tid = s["test"]
        path = vdir / f"{tid}.bands.csv"
        if not path.is_file():
            out.append(B.note(f"{tid}: bands file {path.name} missing, no figure."))
            continue
        df = _read_csv(path)
        measured = None
        try:
            rec = camp.test(tid).record if camp is not None else None
        except InputError:      # the test is not in this run's ingested campaign
            rec = None
        if rec is not None and rec.n == len(df):
            measured = rec.force
        else:
            out.append(B.note(f"{tid}: the measured record is not in this run's ingested campaign "
                              "(or differs in length): bands shown without it."))
        png = F.band_panels(df["time"], df["displacement"], bands_of(df), measured=measured,
                            title=f"validation {tid}: coverage95 {pct(s.get('coverage95'))}, "
                                  f"NRMSE {pct(s.get('nrmse'), 2)}",
                            panels=("ft", "fx"), median_label="predictive median")
        out.append(B.figure(png, f"validation of {tid}: force history and loop with bands",
                            f"{tid}: measured force (black) against the posterior predictive 95 % and "
                            "50 % bands (with noise and offset) and their median."))
    return out


def _input_rows(meta: dict) -> list[tuple[str, object]]:
    inp = meta.get("input") or {}
    if inp.get("kind") == "harmonic":
        return [("input", "harmonic (clean sine from x = 0)"),
                ("amplitude (mm)", scaled(inp.get("amplitude_m"), 1e3)),
                ("frequency (Hz)", num(inp.get("frequency_hz"))), ("cycles", inp.get("cycles", DASH))]
    src = inp.get("source") or {}
    if inp.get("kind") == "generated record" and src:
        what = (f"ground motion {src.get('record') or src.get('file')}, scaled to a peak of "
                f"{scaled(src.get('peak_m'), 1e3)} mm, at {num(src.get('rate_hz'))} Hz (a clean "
                f"generated drive: dead band 0, unfiltered), written to {inp.get('file', DASH)}")
    else:
        what = f"record {inp.get('file', DASH)}"
    return [("input", what), ("samples", inp.get("samples", DASH)),
            ("duration (s)", num(inp.get("duration_s"))),
            ("dead band eps (µm)", scaled(inp.get("eps_m"), 1e6, 3)),
            ("applied-force signal", inp.get("applied_signal", DASH))]


def prediction(ctx, pdir: Path) -> list[dict]:
    meta = read_json(pdir / "prediction.json", "the prediction record")
    ap = meta.get("applied") or {}
    info = [("applied force", f"{num(ap.get('value'))} {ap.get('unit', '')}".strip()),
            *_input_rows(meta), ("parameter draws", meta.get("draws_source", DASH)),
            ("fits", ", ".join(meta.get("fits") or []) or DASH), ("model", meta.get("model", DASH)),
            ("number of draws", meta.get("n_draws", DASH)), ("seed", meta.get("seed", DASH)),
            ("load-cell offset", meta.get("offset", DASH))]
    out = [B.html(kv_table(info, caption="prediction"))]
    from ...extrapolation import notes
    out += [B.note(f"Note: {n}.") for n in notes(meta)]
    if (pdir / "bands.csv").is_file():
        df = _read_csv(pdir / "bands.csv")
        png = F.band_panels(df["time"], df["displacement"], bands_of(df, median="force_model_median"),
                            title=f"prediction {pdir.name}", panels=("ft", "fx"),
                            median_label="median of the noise-free model")
        out.append(B.figure(png, f"prediction {pdir.name}: force history and loop with bands",
                            "Posterior predictive 95 % and 50 % bands of the force with measurement "
                            "noise, and the median of the noise-free model."))
    else:
        out.append(B.note("bands.csv missing: no figure."))
    if (pdir / "cycles.csv").is_file():
        cy = _read_csv(pdir / "cycles.csv")
        if cy.empty:
            out.append(B.note("No complete cycle in this input: no per-cycle table."))
        else:
            rows = [[int(r["cycle"]), num(r["t_start"]), num(r["t_end"]),
                     scaled(r["peak_force_median"], 1e-3),
                     interval(r["peak_force_q2.5"], r["peak_force_q97.5"], factor=1e-3),
                     num(r["energy_median"]), interval(r["energy_q2.5"], r["energy_q97.5"])]
                    for r in cy.to_dict(orient="records")]
            out.append(B.html(table(["cycle", "start (s)", "end (s)", "peak |force| median (kN)",
                                     "peak |force| 95 % interval (kN)", "energy median (J)",
                                     "energy 95 % interval (J)"], rows,
                                    caption="per cycle (noise-free model)")))
            out.append(B.note(meta.get("cycles", "")))
    else:
        out.append(B.note("cycles.csv missing: no per-cycle table."))
    return out


def build(ctx) -> list[dict]:
    pdir = ctx.run_dir / "predict"
    if not pdir.is_dir():
        return [B.note("No prediction or validation was run in this workflow (predict/ absent).")]
    out = []
    # only what the workflow asks for: a folder of a prediction it no longer lists is an earlier
    # run's, left in the run folder
    wanted = ctx.predictions()
    vdir = pdir / "validation"
    if (vdir / "validation.json").is_file() and (wanted is None or "validation" in wanted):
        out.append(B.sub("predictions-validation", "Validation on held-out tests", validation(ctx, vdir)))
    else:
        out.append(B.note("No validation on held-out tests in this workflow "
                          "([predict] validate is empty, or predict/validation/validation.json "
                          "is absent)."))
    others = sorted(d for d in pdir.iterdir()
                    if d.is_dir() and d.name != "validation" and (d / "prediction.json").is_file()
                    and (wanted is None or d.name in wanted))
    for d in others:
        out.append(B.sub(f"prediction-{B.slug(d.name)}", f"Prediction {d.name}", prediction(ctx, d)))
    if not others:
        out.append(B.note("No prediction for a new drive in this workflow."))
    return out

