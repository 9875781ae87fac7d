"""Section "fits": per fit of fit/summary.json, the data against the posterior predictive, the
residuals, the corner and rank plots, the convergence and parameter tables and the
identifiability list."""
from __future__ import annotations

import numpy as np

from ... import params as P
from ... import units
from ...errors import InputError
from .. import blocks as B
from .. import figures as F
from .. import figures_fit as FF
from ..tables import DASH, badge, bullet_list, kv_table, num, scaled, table
from ...wording import count


def unit_of(name: str) -> str:
    """Unit of a summary parameter name ('sigma_noise[test]' -> N, 'noise_phi[test]' -> 1)."""
    base = name.split("[", 1)[0]
    return P.PARAMS[base].unit if base in P.PARAMS else "?"


def display_of(name: str) -> tuple[str, float]:
    """(display unit, factor from SI) of a summary parameter name: kN, mm, mm/s, kN/mm, kN s/m."""
    return units.display(unit_of(name))


def description_of(name: str) -> str:
    base = name.split("[", 1)[0]
    d = P.PARAMS[base].description if base in P.PARAMS else ""
    return d + (f" (test {name.split('[', 1)[1].rstrip(']')})" if "[" in name else "")


def _count(v) -> str:
    """An effective sample size, rounded to a whole number of draws."""
    return f"{v:.0f}" if isinstance(v, (int, float)) and np.isfinite(v) else num(v)


def _rules():
    from ...infer.fit import CONVERGENCE
    return CONVERGENCE


def overview(ctx, fits) -> list[dict]:
    rows, classes = [], []
    for f in fits:
        ok = bool(f.get("converged"))
        rows.append([f["id"], ctx.applied_number(f.get("applied")), ", ".join(f.get("tests", [])),
                     f.get("model", DASH), f.get("sampler_steps", DASH),
                     badge("yes" if ok else "NO", ok), scaled(f.get("rmse"), 1e-3)])
        classes.append("" if ok else "flagged")
    out = [B.html(table(["fit", f"applied force ({ctx.applied_unit()})", "tests", "model",
                         "sampler steps", "converged", "RMSE (kN)"], rows, row_classes=classes,
                        caption="fits: one per applied force (or test), summary.json"))]
    bad = [f["id"] for f in fits if not f.get("converged")]
    if bad:
        out.insert(0, B.warn(f"{len(bad)} of {len(fits)} fits did NOT converge ({', '.join(bad)}): "
                             "their posterior intervals, corner plots and every quantity derived "
                             "from them below are not reliable; run the sampler longer."))
    return out


def _data(dt):
    """(t, x, y, test ids, predictive with noise (S, N), noise-free model (S, N)) of a fit."""
    y = np.asarray(dt["observed_data"]["force"].values, float)
    const = dt["constant_data"]
    pp = dt["posterior_predictive"]
    rep = np.asarray(pp["force"].values, float).reshape(-1, y.size)
    mod = np.asarray(pp["force_model"].values, float).reshape(-1, y.size)
    return (np.asarray(const["time"].values, float), np.asarray(const["displacement"].values, float),
            y, np.asarray(const["test_of_obs"].values).astype(str), rep, mod)


def data_figures(fid: str, dt) -> list[dict]:
    groups = set(dt.children)
    if not {"observed_data", "constant_data", "posterior_predictive"} <= groups:
        return [B.note("posterior.nc holds no observed data or posterior predictive: data plots "
                       "not available for this fit.")]
    t, x, y, tid, rep, mod = _data(dt)
    out, resid = [], []
    for test in dict.fromkeys(tid):
        s = tid == test
        bands = F.quantile_bands(rep[:, s])
        bands["median"] = np.median(mod[:, s], axis=0)
        png = F.band_panels(t[s], x[s], bands, measured=y[s], title=f"fit {fid}: test {test}",
                            median_label="median of the noise-free model")
        out.append(B.figure(png, f"fit {fid}, test {test}: force against displacement, velocity and time",
                            f"Test {test}: measured force (black) and the posterior predictive: "
                            f"95 % and 50 % bands with measurement noise, median of the noise-free "
                            f"model (offset included); {rep.shape[0]} draws, the record as fitted "
                            "(decimated)."))
        resid.append((test, t[s], x[s], y[s] - bands["median"]))
    out.append(B.figure(FF.residual_figure(resid, f"fit {fid}: residuals"),
                        f"fit {fid}: residuals against time and displacement",
                        "Residual = measured force minus the median of the noise-free model."))
    return out


def model_names(ctx, fid: str) -> list[str]:
    """The fit's free friction and backlash parameters (no noise, no offset)."""
    free = ctx.fit_record(fid).get("space", {}).get("free", [])
    return [n for n in free if n not in P.LIKELIHOOD_NAMES]


def posterior_figures(ctx, fid: str, dt) -> list[dict]:
    names = [n for n in model_names(ctx, fid) if n in dt["posterior"].data_vars]
    if not names:
        return [B.note("No free friction or backlash parameter: no corner or rank plot.")]
    post = dt["posterior"]
    draws = {n: np.asarray(post[n].values, float) for n in names}
    out = [B.figure(FF.corner_figure(draws, f"fit {fid}: posterior of the model parameters"),
                    f"fit {fid}: corner plot", "Corner plot of the friction and backlash parameters "
                    f"(at most {FF.MAX_CORNER_DRAWS} draws; noise parameters left out).")]
    shown = names[:FF.MAX_RANK_PARAMS]
    out.append(B.figure(FF.rank_figure(dt, shown, f"fit {fid}: rank plot", FF.RANK_CHAINS),
                        f"fit {fid}: rank plot of the chains",
                        f"Rank plot (ArviZ) of the first {min(FF.RANK_CHAINS, post.sizes['chain'])} "
                        f"of {post.sizes['chain']} chains (the stored "
                        "run's independent chains, or its ensemble's walkers): lines leaving the "
                        "envelope mean chains that have not mixed" +
                        (f"; first {len(shown)} of {len(names)} parameters." if len(shown) < len(names) else ".")))
    return out


def _stored_run(rec: dict, smp: dict) -> str:
    """How the stored run moved its walkers, from the fit's sampler config (fit.json)."""
    cfg = (rec.get("config") or {}).get("sampler") or {}
    design = cfg.get("stored_run")
    if design is None and "run_walkers" in cfg:      # a fit written before 2026-12-01
        design = "ensemble" if cfg["run_walkers"] is None else "chains"
    n = smp.get("walkers", DASH)
    k = int(smp.get("mode_components") or 0)
    again = int(smp.get("stored_searches") or 0)
    where = "the burn-in" if not again else (
        f"the burn-in and the stored run (started again {again} time{'s' if again > 1 else ''} "
        f"where chains stuck)")
    modes = "" if not k else (f"; the independence proposal a mixture with {k} mode "
                              f"component{'s' if k > 1 else ''} found in {where}")
    if design == "chains":
        L = int(cfg.get("temperatures") or 1)
        tempered = "" if L < 2 else (f", each with {L - 1} tempered copies (parallel tempering; "
                                     f"only the untempered chains are the posterior)")
        return f"{n} independent chains (independence move and random walk){tempered}{modes}"
    if design == "ensemble":
        return f"ensemble of {n} walkers (independence and differential-evolution moves){modes}"
    return DASH


def convergence(ctx, f: dict) -> list[dict]:
    rules = _rules()
    rec = ctx.fit_record(f["id"])
    smp = rec.get("sampler", {}) if isinstance(rec.get("sampler"), dict) else {}
    tau = smp.get("tau", {}) if isinstance(smp.get("tau"), dict) else {}
    rows, classes = [], []
    for name, p in (f.get("parameters") or {}).items():
        if "fixed" in p:
            continue
        bad = not (p.get("r_hat", np.inf) <= rules["r_hat_max"] and p.get("ess_bulk", 0) >= rules["ess_min"]
                   and p.get("ess_tail", 0) >= rules["ess_min"])
        rhat = p.get("r_hat")
        # four decimals: the rule's 1.01 must not show as "1.01" on a value of 1.0105 that fails it
        rows.append([name, f"{rhat:.4f}" if isinstance(rhat, (int, float)) and np.isfinite(rhat)
                     else num(rhat), _count(p.get("ess_bulk")), _count(p.get("ess_tail")),
                     num(tau.get(name), 3) if name in tau else "not sampled (integrated out)",
                     badge("no" if bad else "yes", not bad)])
        classes.append("flagged" if bad else "")
    ok = bool(f.get("converged"))
    status = [B.html(badge("converged: yes" if ok else "converged: NO", ok))]
    if not ok:
        status.append(B.warn(
            f"Fit {f['id']} did NOT converge. Parameters failing the rule: "
            f"{', '.join(f.get('not_converged_parameters') or []) or 'none'}; sampler's own "
            f"stopping rule met: {'yes' if f.get('sampler_criteria_met') else 'no'}."))
    info = kv_table([("stored run", _stored_run(rec, smp)),
                     ("stored steps", smp.get("steps", f.get("sampler_steps", DASH))),
                     ("burn-in phase steps (discarded)", smp.get("burn_in_phase_steps", DASH)),
                     ("discarded from the stored run", smp.get("burn", DASH)),
                     ("thinning", smp.get("thin", DASH)), ("walkers", smp.get("walkers", DASH)),
                     ("acceptance fraction", num(smp.get("acceptance"), 3)),
                     ("max autocorrelation time tau (steps)", num(f.get("tau_max"), 4)),
                     ("model evaluations", f.get("model_evaluations", DASH)),
                     ("run time (s)", num(f.get("seconds"), 3))], caption="sampler")
    tab = table(["parameter", "R-hat", "ESS bulk", "ESS tail", "autocorrelation time tau (steps)",
                 "passes"], rows, row_classes=classes, caption="convergence per parameter")
    return status + [B.html(info), B.html(tab), B.note(f"Rule: {f.get('convergence_rule', '')}")]


def parameters(f: dict) -> list[dict]:
    rows = []
    for name, p in (f.get("parameters") or {}).items():
        unit, fac = display_of(name)
        if "fixed" in p:
            rows.append([name, unit, f"{scaled(p['fixed'], fac)} (fixed)", DASH, DASH, DASH,
                         description_of(name)])
        else:
            rows.append([name, unit] + [scaled(p.get(k), fac) for k in ("mean", "sd", "q2.5", "q97.5")]
                        + [description_of(name)])
    return [B.html(table(["parameter", "unit", "mean", "sd", "2.5 %", "97.5 %", "meaning"], rows,
                         caption="posterior of the parameters (summary.json holds them in SI)",
                         cls="params"))]


def identifiability(f: dict) -> list[dict]:
    idf = f.get("identifiability")
    if not isinstance(idf, dict):
        return [B.note("No identifiability summary in this fit's entry.")]
    ratio = idf.get("posterior_over_prior_sd", {}) or {}
    items = []
    close = idf.get("close_to_prior") or []
    items.append("close to the prior: " + (", ".join(f"{n} (sd ratio {num(ratio.get(n), 3)})" for n in close)
                                           if close else "none"))
    pairs = idf.get("strongly_correlated") or []
    items.append("strongly correlated pairs: " + (", ".join(f"{a} / {b} (rho {num(r, 3)})" for a, b, r in pairs)
                                                  if pairs else "none"))
    bounds = idf.get("at_prior_bound") or {}
    items.append("at a prior bound: " + (", ".join(f"{n} ({side})" for n, side in bounds.items())
                                         if bounds else "none"))
    out = [B.html(bullet_list(items)), B.note(f"Rule: {idf.get('rule', '')}")]
    return out + _between_tests(f.get("between_tests")) + _per_test_offsets(f.get("per_test_offsets"))


def _per_test_offsets(pt) -> list[dict]:
    """Per-test offsets (FitConfig.force_offset): their prior box and any zero pressing on it."""
    if not isinstance(pt, dict):
        return []
    lo, hi = (pt.get("box_N") or [None, None])[:2]
    edge = pt.get("at_box_edge") or []
    text = (f"Each test has its own force zero, integrated out under a uniform prior on "
            f"[{num(lo, 4)}, {num(hi, 4)}] N (force_offset[TEST] in the table above); "
            + (f"pressing against that box: {', '.join(edge)} (the box, not the data, bounds "
               "them: widen it with --prior force_offset=uniform:LOWER:UPPER)" if edge
               else "none presses against it") + ".")
    return [B.html(bullet_list([text]))]


def _between_tests(bt) -> list[dict]:
    """Whether the fit's tests share one force zero (infer.between), with each test's mean
    residual; nothing for a single-test fit."""
    if not isinstance(bt, dict):
        return []
    verdict = ("differ beyond the noise: a shared force_offset does not fit them, and bands for a "
               "new test are too narrow by about the spread" if bt.get("significant")
               else "agree within the noise")
    each = ", ".join(f"{t} {num(m, 4)} N (se {num(bt.get('se_N', {}).get(t), 3)} N)"
                     for t, m in (bt.get("mean_residual_N") or {}).items())
    text = (f"The tests' force zeros {verdict} (spread of the per-test mean residuals "
            f"{num(bt.get('spread_N'), 4)} N; chi-square {num(bt.get('chi2'), 4)} on "
            f"{count(bt.get('df'), 'degree')} of freedom, p = {num(bt.get('p_value'), 2)}, alpha {bt.get('alpha')}). "
            f"Mean residual per test: {each}.")
    return [B.html(bullet_list([text])), B.note(f"Method: {bt.get('method', '')}")]


_FIGURES = {"peak_N": ("peak force", 1e-3, "kN"), "trough_N": ("trough force", 1e-3, "kN"),
            "energy_J": ("energy dissipated", 1e-3, "kJ")}


def _prior_predictive(passed, pp) -> str:
    """'passed', or 'FAILED' with the figures outside the prior predictive's central 98 %."""
    if passed is None:
        return DASH
    if passed:
        return "passed"
    misses = []
    for tid, figs in ((pp or {}).get("records") or {}).items():
        for key, (label, fac, unit) in _FIGURES.items():
            g = (figs or {}).get(key)
            if isinstance(g, dict) and g.get("inside") is False:
                misses.append(f"{tid}: {label} {scaled(g.get('measured'), fac)} {unit} measured, "
                              f"outside the prior's 1-99 % range [{scaled(g.get('q1'), fac)}, "
                              f"{scaled(g.get('q99'), fac)}] {unit}")
        if (figs or {}).get("non_finite_draws"):
            misses.append(f"{tid}: {figs['non_finite_draws']} prior draws gave no finite force")
    return "FAILED" + (" (" + "; ".join(misses) + ")" if misses else "")


def _drive_text(rec: dict) -> str:
    """How the fit prepared each record's drive (fit.json's config and records): the low-pass
    cutoffs and the reversal rule."""
    cfg = rec.get("config") or {}
    if not cfg:
        return DASH
    from ...infer.drivefilter import AUTO_MULTIPLE
    cuts = [(r.get("id"), r.get("drive_cutoff_hz")) for r in rec.get("records", [])]
    each = [f"{i} {c:.3g} Hz" if c else f"{i} as recorded" for i, c in cuts]
    lp = cfg.get("drive_lowpass")
    if lp == "auto":
        rule = f"drive_lowpass auto: {AUTO_MULTIPLE:g} x the 99 % velocity-power frequency where eps > 0"
    else:
        rule = f"drive_lowpass {lp:g} x that frequency" if lp is not None else "drive_lowpass off"
    head = ("low-passed: " + ", ".join(each) if any(c for _, c in cuts) else "as recorded") + \
        f" ({rule})"
    rev = cfg.get("reversal", "detection")
    return head + ("; reversals at the motion's extreme" if rev == "extreme" else
                   "; reversals where the dead band eps detects them (the spec's rule)")


def fit_blocks(ctx, f: dict) -> list[dict]:
    fid = f["id"]
    per = f.get("rmse_per_test") or {}
    rec = ctx.fit_record(fid)
    info = [("tests", ", ".join(f.get("tests", []))),
            (f"applied force ({ctx.applied_unit()})", ctx.applied_number(f.get("applied"))),
            ("model", f.get("model", DASH)), ("effects", ", ".join(f.get("effects") or []) or "none"),
            ("likelihood", f.get("likelihood", DASH)),
            ("displacement the model ran on", _drive_text(rec)),
            ("RMSE of the posterior-median model, all tests (kN)", scaled(f.get("rmse"), 1e-3)),
            *[(f"RMSE, test {t} (kN)", scaled(v, 1e-3)) for t, v in per.items()],
            ("prior predictive check", _prior_predictive(f.get("prior_predictive_passed"),
                                                         rec.get("prior_predictive"))),
            ("seed", rec.get("seed", DASH))]
    dt = ctx.posterior(fid)
    out = [B.html(kv_table(info, caption="fit"))]
    out.append(B.heading("Data and posterior predictive"))
    out += data_figures(fid, dt)
    out.append(B.heading("Posterior and mixing"))
    out += posterior_figures(ctx, fid, dt)
    out.append(B.heading("Convergence"))
    out += convergence(ctx, f)
    out.append(B.heading("Parameters"))
    out += parameters(f)
    out.append(B.heading("Identifiability"))
    out += identifiability(f)
    return out


def build(ctx) -> list[dict]:
    if ctx.summary() is None:
        return [B.note("This run has no fits (fit/summary.json missing).")]
    fits = ctx.fits()
    if not fits:
        return [B.note("fit/summary.json lists no fits.")]
    out = overview(ctx, fits)
    for f in fits:
        try:
            content = fit_blocks(ctx, f)
        except InputError as e:     # an incomplete fit folder: say so, keep the other fits
            content = [B.warn(f"Fit {f['id']}: its outputs cannot be read: {e}")]
        out.append(B.sub(f"fit-{B.slug(f['id'])}", f"Fit {f['id']}", content))
    return out

