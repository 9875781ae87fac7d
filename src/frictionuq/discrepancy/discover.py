"""`frictionuq discover CAMPAIGN --out DIR`: name the missing effect and show the gap shrink.

1. Screen (screen.py): per applied-force level, the baseline 3-stage model and every candidate
   effect of the library by the held-out tests' log predictive densities, leave one test out
   (ratios of Laplace evidences, predictive.py).
2. Decide (screen.decide): the best candidate, or "none" (decision rule in screen.py).
3. Refit by MCMC (infer.fit.run_fit) with the named effect, per level: the effect's parameters
   with 95 % intervals, and the RMSE after. The sampler starts from the screening's MAP of the
   named model on that level (polished, no second multi-start search: it cost 30 s of a 5-minute
   run on a full-length MFD campaign).
4. The gap before and after, per test: residual diagnostics (diagnostics.py) at the baseline's MAP
   and, when an effect is named, at the MAP with it: which views show significant structure
   before and after (figures DIR/residuals-<model>-<test>.png), and the force-displacement loops
   of both models over the data with their residuals (DIR/loops-<test>.png).
5. Write DIR/discrepancy.json (forces in N) and the chains/posteriors of the refit under
   DIR/refit/.

rmse_before is the baseline's RMSE at its MAP (offset removed) on the fit's records;
candidate rmse_after values are at each candidate's MAP; the final rmse_after is the refit's
posterior-median prediction. noise_scale is the marginal sd of the measurement noise the refit
(or, with "none", the baseline) estimates: sigma_noise (a marginal sd), median over the tests;
with a noise effect (chatter) each test's sigma_noise times the rms of its gain g over the test,
i.e. the rms of the fitted noise sd. Such an effect does not change the force, so it closes no
RMSE; the gap it closes shows in the held-out score and in the bands; its diagnostics are
those of the residual in units of its noise model (divided by g).
"""
from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import atomic
from ..errors import InputError
from ..infer.fit import FitConfig, FitSpec, jsonable, plan, run_fit
from . import fits, screen


def _noise_scale(entry: dict, gain_rms: dict | None = None) -> float | None:
    """Median over the tests of the posterior mean of sigma_noise (the marginal sd of the
    measurement noise, AR(1) included: see infer.noisemodel), each times the rms of its noise
    effect's gain over the test when the fit has one (gain_rms: {test id: rms of g}), i.e. the
    rms of the fitted noise sd over the record."""
    gain_rms = gain_rms or {}
    vals = [st["mean"] * gain_rms.get(name[len("sigma_noise["):-1], 1.0)
            for name, st in entry["parameters"].items() if name.startswith("sigma_noise[")]
    return float(np.median(vals)) if vals else None


def _gain_rms(level_tests, cfg, effects, entry: dict) -> dict:
    """{test id: rms over its samples of the noise gain at the posterior means} for a fit with
    a noise effect (chatter), else {}."""
    from .. import params as P
    if not set(effects) & P.NOISE_EFFECTS:
        return {}
    lp, _ = fits.logpost_for(level_tests, effects, cfg)
    th = lp.space.to_theta({n: entry["parameters"][n]["mean"] for n in lp.space.names})[None, :]
    return {rec.id: float(np.sqrt(np.mean(lp.noise_gain(th, j)[0] ** 2)))
            for j, rec in enumerate(lp.records)}


def _model_forces(level_tests, cfg, effects, map_values: dict) -> list[tuple]:
    """[(fit record, simulated force at the MAP point incl. the load-cell offset (N), the noise
    gain of a noise effect there or None)] per test."""
    lp, _ = fits.logpost_for(level_tests, effects, cfg)
    th = lp.space.to_theta({n: map_values[n] for n in lp.space.names})[None, :]
    off = float(lp.space.offset(th)[0])
    out = []
    for j, rec in enumerate(lp.records):
        g = lp.noise_gain(th, j)
        out.append((rec, lp.simulate(th, rec)[0] + off, None if g is None else g[0]))
    return out


def _label(view: str, d: dict) -> str:
    """A significant view as the report lists it (the spectrum with its wavelength, the
    high-frequency bursts with their band and where they sit)."""
    if view == "spectrum":
        return f"spectrum ({d['spectrum']['wavelength_m'] * 1e3:.3g} mm)"
    if view == "chatter":
        c = d["chatter"]
        lo, hi = c["peak_since_reversal_m"]
        return (f"chatter (bursts > {c['highpass_hz']:.3g} Hz, strongest {lo * 1e3:.3g}-{hi * 1e3:.3g} mm "
                f"after the reversal, {c['peak_rms_n']:.3g} N rms)")
    return view


def _gap(level_tests, cfg, level: dict, named: str, seed: int, fig_dir: Path, log) -> list[dict]:
    """The gap before and after, per test of a level: residual diagnostics (diagnostics.diagnose)
    at the baseline's MAP and, when an effect is named, at the MAP with it (figures
    residuals-<model>-<test>.png), and the loops of both models over the data with their
    residuals (loops-<test>.png); RMSE (offset removed) of each."""
    from .diagnostics import diagnose
    from .plots import centred_rmse, loop_figure, residual_figure
    models = [("baseline", ())] + ([(f"with {named}", (named,))] if named != "none" else [])
    forces = {tag: _model_forces(level_tests, cfg, eff, level["models"][eff[0] if eff else "baseline"]["map"])
              for tag, eff in models}
    out = []
    for tag, _ in models:
        for rec, F, g in forces[tag]:
            # with a noise effect (chatter) the residual in units of its noise model, which the
            # likelihood takes as stationary: what the effect leaves unexplained
            r = rec.y - F if g is None else (rec.y - F) / g
            d = diagnose(rec.t, rec.x, r, force_model=F, eps=rec.eps, applied=rec.applied,
                         seed=seed, bursts=rec.kind != "earthquake")   # chatter.py: why
            d["scaled_by_noise_gain"] = g is not None
            name = f"residuals-{tag.replace(' ', '-')}-{rec.id}.png"
            title = f"{rec.id}: residuals, {tag}" + ("" if g is None else " (divided by the noise gain)")
            atomic.write_bytes(fig_dir / name, residual_figure(d, None, title=title))
            sig = [_label(k, d) for k in d["significant"]]
            log(f"diagnostics {tag} {rec.id}: significant structure in {', '.join(sig) or 'none'}")
            out.append({"test": rec.id, "model": tag, "figure": name, "significant_views": sig,
                        "rmse": centred_rmse(rec.y - F), "diagnostics": d})
    for i, (rec, _, _) in enumerate(forces["baseline"]):
        name = f"loops-{rec.id}.png"
        png = loop_figure(rec.t, rec.x, rec.y, {tag: forces[tag][i][1] for tag, _ in models},
                          title=f"{rec.id}: measured and modelled force, "
                                + (f"baseline and with {named}" if named != "none" else "baseline (none named)"))
        atomic.write_bytes(fig_dir / name, png)
        for g in out:
            if g["test"] == rec.id:
                g["loop_figure"] = name
    return out


def discover(campaign_path, out_dir, config: FitConfig | None = None, *, seed: int = 1,
             effects=None, extra_effects=(), refit: bool = True, diagnostics: bool = True,
             log=None) -> dict:
    """Run the workflow on a campaign; returns (and writes) the discrepancy document.
    effects: the candidates (default: screen.candidates, the spec's library); extra_effects:
    effects beyond the spec (params.BEYOND_SPEC) to screen as well.

    Decimated records are simulated as the config says (raw rate by default, as the fits)."""
    from .. import __version__
    from ..campaign import load_campaign
    log = log or (lambda m: None)
    cfg = replace(config or FitConfig(), seed=seed)  # recorded in discrepancy.json
    if cfg.effects:
        raise InputError("discover: the baseline is the plain 3-stage model; do not give effects")
    if cfg.likelihood not in ("iid", "ar1"):
        raise InputError(f"discover: likelihood {cfg.likelihood!r} is not supported by the "
                         "held-out screening; use ar1 (default) or iid")
    from .. import params as P
    bad = [e for e in extra_effects if e not in P.BEYOND_SPEC]
    if bad:
        raise InputError(f"discover: extra effect {bad[0]!r} is not an effect beyond the spec's "
                         f"library; known: {', '.join(sorted(P.BEYOND_SPEC))}")
    t0 = time.perf_counter()
    camp = load_campaign(campaign_path)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    specs = plan(camp, "applied", cfg)
    levels = []
    for s in specs:
        log(f"level {s.id}: screening {len(s.tests)} test(s)")
        cands = list(effects) if effects is not None else screen.candidates(s.tests, extra_effects)
        lv = screen.screen_level(s.tests, cfg, seed, effects=cands,
                                 log=lambda m, i=s.id: log(f"{i}: {m}"))
        lv["id"] = s.id
        levels.append(lv)
    ranked = screen.rank(levels)
    named, reason = screen.decide(ranked, levels)
    log(f"named effect: {named} ({reason})")
    rmse_before = float(np.mean([lv["models"]["baseline"]["rmse_map"] for lv in levels]))
    doc = {"package_version": __version__, "campaign": camp.name, "campaign_path": str(campaign_path),
           "seed": seed, "config": cfg.to_json(), "named_effect": named, "reason": reason,
           "decision_rule": screen.RULE, "extra_effects": list(extra_effects),
           "candidates": [{"effect": r["effect"], "elpd_gain": r["elpd_gain"],
                           "elpd_gain_se": r["elpd_gain_se"], "rmse_after": r["rmse_map"],
                           "gain_per_unit": r["gain_per_unit"], "map_gain": r["map_gain"],
                           "screened_out": r["screened_out"], "n_params": r["n_params"]}
                          for r in ranked],
           "candidates_screened": [n for n in levels[0]["models"] if n != "baseline"],
           "rmse_before": rmse_before, "rmse_after": rmse_before, "noise_scale": None,
           "effect_parameters": {}, "levels": levels,
           "units": {"rmse": "N", "noise_scale": "N", "elpd": "nats"}}
    if refit:
        eff = () if named == "none" else (named,)
        entries = []
        for s, lv in zip(specs, levels):
            spec = FitSpec(s.id, s.tests, s.applied, replace(cfg, effects=eff))
            start = lv["models"][named if eff else "baseline"]["map"]
            entries.append(run_fit(spec, out / "refit", camp.name, resume=False, log=log,
                                   start=start))
        doc["refit"] = [{"id": e["id"], "converged": e["converged"], "rmse": e["rmse"],
                         "effects": list(eff)} for e in entries]
        doc["rmse_after"] = float(np.mean([e["rmse"] for e in entries]))
        scales = [v for v in (_noise_scale(e, _gain_rms(s.tests, cfg, eff, e))
                              for s, e in zip(specs, entries)) if v is not None]
        doc["noise_scale"] = float(np.median(scales)) if scales else None
        if named != "none":
            from .. import params as P
            for n in P.EFFECTS[named]:
                st = [e["parameters"][n] for e in entries if n in e["parameters"]]
                if st:
                    doc["effect_parameters"][n] = {k: st[0][k] for k in ("mean", "sd", "q2.5", "q97.5")}
                    doc["effect_parameters"][n]["unit"] = P.PARAMS[n].unit
    elif named != "none":
        best = next(r for r in ranked if r["effect"] == named)
        doc["rmse_after"] = best["rmse_map"]
    if diagnostics:
        doc["diagnostics"] = []
        for s_, lv in zip(specs, levels):
            doc["diagnostics"] += _gap(s_.tests, cfg, lv, named, seed, out, log)
    doc["seconds"] = time.perf_counter() - t0
    atomic.write_json(out / "discrepancy.json", jsonable(doc))
    return doc
