"""Model comparison per applied force: RMSE of the posterior-median prediction (the BRFD paper's
Table 4 measure) and held-out predictive accuracy (ELPD) by leave-one-TEST-out cross-validation.

For every applied-force level and every model configuration (default: the 3-stage model and pure
LuGre, each with the project's default priors and sampler):

* **RMSE** (N): one fit on all tests of the level (frictionuq.infer.fit.prepare + sampler.sample,
  as `frictionuq fit` does); the noise-free model force (offset included) of up to
  `n_predictive` posterior draws on each test, its pointwise posterior median, and the RMSE of
  the data about it, pooled over the level's tests and per test. Like the fit summaries, it is
  evaluated on the fit's (decimated) records.
* **ELPD** (nats): for each test k of the level, the model is fitted on the other tests only and
  the held-out test is predicted by the fit's draws; ELPD is the sum over the held-out tests, with
  its standard error, and models are compared by paired differences. Whole tests are the
  held-out units (the residuals are strongly autocorrelated within a test). The arithmetic, the
  standard errors and the held-out test's own force offset (integrated out by default,
  `offset="marginal"`; `"shared"` uses the training fit's) are in elpd.py.

Seeds: the full-data fit of every model uses `seed`, the fit without test k uses seed + 1 + k
(the same for all models, so the models see the same random streams).
"""
from __future__ import annotations

import csv
import io
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import atomic, params as P
from ..environment import environment
from ..errors import InputError, check_seed

from .fit import FitConfig, FitSpec, jsonable, plan, prepare
from .elpd import (OFFSET_MODES, elpd_difference, elpd_total, heldout_loglik, log_mean_exp,
                   weights_n_eff)
from .likelihood import LogPosterior, records_from_tests
from .sampler import sample
from ..wording import count

DEFAULT_MODELS = ("three_stage", "lugre")


# ------------------------------------------------------------------ fits
def _draws(res) -> np.ndarray:
    return res.chain.reshape(-1, res.chain.shape[-1])


def _rmse(logpost, res, n_draws: int, rng) -> tuple[float, dict]:
    """RMSE (N) of the pointwise posterior median of the noise-free force (offset included)."""
    th = _draws(res)
    idx = rng.choice(th.shape[0], size=min(n_draws, th.shape[0]), replace=False)
    sel = th[idx]
    sq, n, per = 0.0, 0, {}
    for rec in logpost.records:
        F = logpost.fitted_force(sel, rec)     # per-test offsets: each test's zero, profiled
        r = rec.y - np.median(F, axis=0)
        per[rec.id] = float(np.sqrt(np.mean(r**2)))
        sq += float(np.sum(r**2))
        n += r.size
    return float(math.sqrt(sq / n)), per


def _fit(tests, cfg: FitConfig, seed: int, spec_id: str, work_dir, log):
    spec = FitSpec(spec_id, list(tests), tests[0].applied, replace(cfg, seed=seed, kinds=None, tests=None))
    records, scales, space, logpost = prepare(spec)
    backend = None if work_dir is None else Path(work_dir) / spec_id / "chain.h5"
    res = sample(logpost, scales, seed, backend, cfg.sampler, resume=False,
                 log=lambda m: log(f"{spec_id}: {m}"))
    return records, space, logpost, res


def _fit_record(res) -> dict:
    return {"steps": int(res.n_steps), "converged": bool(res.converged_tau),
            "draws": int(res.chain.shape[0] * res.chain.shape[1]), "seconds": float(res.seconds)}


def _quiet(msg: str) -> None:
    pass


def _compare_fit(job, log) -> dict:
    """One fit of compare_level and what the comparison takes from it: with k None, the fit on
    all tests and its RMSE; else the fit without test k and test k's held-out ELPD."""
    name, cfg, tests, k, seed, offset, work_dir = job
    t0 = time.perf_counter()
    if k is None:
        _, _, lp_full, res = _fit(tests, cfg, seed, f"{name}/all", work_dir, log)
        rmse, per = _rmse(lp_full, res, cfg.n_predictive, np.random.default_rng([seed, 7]))
        log(f"{name}: RMSE {rmse:.4g} N (all {count(len(tests), 'test')})")
        return {"rmse": rmse, "rmse_per_test": per, "fit": _fit_record(res),
                "seconds": time.perf_counter() - t0}
    held = tests[k]
    _, space, _, res_k = _fit(tests[:k] + tests[k + 1:], cfg, seed, f"{name}/without-{held.id}",
                              work_dir, log)
    lp_held = LogPosterior(space, records_from_tests([held], **cfg.record_options()))
    ll, ch = heldout_loglik(lp_held, _draws(res_k), offset)
    elpd, neff, c_hat = log_mean_exp(ll[:, 0]), weights_n_eff(ll[:, 0]), None
    if np.isfinite(ch).any():
        lo, hi = space.offset_box or (space.priors["force_offset"].lower,
                                      space.priors["force_offset"].upper)
        c = float(np.nanmedian(ch[:, 0]))
        c_hat = {"median_N": c, "inside_prior_box": bool(lo < c < hi)}
    log(f"{name}: held-out {held.id}: elpd {elpd:.6g} nats (n_eff of weights {neff:.1f})")
    return {"held": held.id, "elpd": elpd, "n_eff": neff, "c_hat": c_hat, "fit": _fit_record(res_k),
            "seconds": time.perf_counter() - t0}


def _compare_fit_job(job_logs) -> dict:
    """_compare_fit in a worker process (compare_level with workers): messages to standard
    error when the caller logs."""
    from ..workers import stderr_log
    job, logs = job_logs
    return _compare_fit(job, stderr_log if logs else _quiet)


def check_configs(configs: dict) -> dict:
    """Validate {name: FitConfig}: known models, effects the model can carry, a known
    likelihood. Raises InputError (one line). Returns the configurations with one kept-rate
    floor for all (the highest any of them asks for, e.g. a noise effect's: FitConfig.
    record_options), so that every model is scored on the same records."""
    if not configs:
        raise InputError("compare: no model configuration given")
    for name, cfg in configs.items():
        if not isinstance(cfg, FitConfig):
            raise InputError(f"compare: configuration {name!r} is not a FitConfig")
        check_seed(cfg.seed, f"compare: model {name!r}")
        try:
            P.check_effects({e: {} for e in cfg.effects}, cfg.model)
        except ValueError as e:
            raise InputError(f"compare: model {name!r}: {e}") from None
        if cfg.likelihood not in ("iid", "ar1"):
            raise InputError(f"compare: model {name!r}: likelihood {cfg.likelihood!r} is not "
                             "supported by the held-out comparison; use ar1 (default) or iid")
    floor = max((f for f in (c.record_options()["min_kept_hz"] for c in configs.values()) if f),
                default=None)
    return {name: replace(cfg, min_kept_hz=floor) for name, cfg in configs.items()}


def compare_level(tests, configs: dict[str, FitConfig], seed: int, log=None, *,
                  offset: str = "marginal", work_dir=None, workers=None) -> dict:
    """Compare model configurations on the tests of one applied-force level (campaign Test
    objects with SI records). Returns {"tests", "applied", "cross_validated", "models": {name:
    {rmse, rmse_per_test, elpd, se, elpd_per_test, ...}}, "pairs": [...]}: see the module
    docstring. work_dir (optional): where the sampler keeps its HDF5 chains. workers (optional):
    a workers.Workers that runs the level's fits (every model's fit on all tests and its fits
    without each test: independent, seeded) side by side, with the serial results; their
    messages then come from the worker processes, on standard error."""
    log = log or _quiet
    configs = check_configs(configs)
    if offset not in OFFSET_MODES:
        raise InputError(f"compare: offset must be one of {OFFSET_MODES}, got {offset!r}")
    tests = list(tests)
    if not tests:
        raise InputError("compare: a level needs at least one test")
    ids = [t.id for t in tests]
    if len(set(ids)) != len(ids):
        raise InputError(f"compare: duplicate test ids in {ids}")
    K = len(tests)
    cv = K >= 2
    out = {"tests": ids, "applied": float(tests[0].applied), "n_tests": K, "cross_validated": cv,
           "offset": offset, "models": {}, "pairs": []}
    if not cv:
        out["note"] = ("a single test: leave-one-test-out cross-validation is impossible, no ELPD "
                       "reported")
    jobs = []
    for name, cfg in configs.items():
        jobs.append((name, cfg, tests, None, seed, offset, work_dir))
        jobs += [(name, cfg, tests, k, seed + 1 + k, offset, work_dir) for k in range(K)] if cv else []
    if workers is None or workers.jobs == 1:
        done = [_compare_fit(j, log) for j in jobs]
    else:
        log(f"{len(jobs)} fits in {workers.jobs} processes (one numba thread each)")
        done = workers.map(_compare_fit_job, [(j, log is not _quiet) for j in jobs])
    by_model: dict = {}
    for j, r in zip(jobs, done):
        by_model.setdefault(j[0], []).append(r)
    for name, cfg in configs.items():
        full, *folds = by_model[name]
        m: dict = {"model": cfg.model, "effects": list(cfg.effects), "likelihood": cfg.likelihood,
                   "rmse": full["rmse"], "rmse_per_test": full["rmse_per_test"],
                   "fits": {"all": full["fit"]}}
        if cv:
            m["fits"].update({f"without-{r['held']}": r["fit"] for r in folds})
            elpd_k = {r["held"]: r["elpd"] for r in folds}
            tot = elpd_total(list(elpd_k.values()))
            m.update(elpd=tot["elpd"], se=tot["se"], elpd_per_test=elpd_k,
                     n_eff_weights={r["held"]: r["n_eff"] for r in folds},
                     heldout_offset={r["held"]: r["c_hat"] for r in folds if r["c_hat"] is not None})
        else:
            m.update(elpd=None, se=None, elpd_per_test=None)
        m["converged"] = all(f["converged"] for f in m["fits"].values())
        m["seconds"] = sum(r["seconds"] for r in [full] + folds)
        out["models"][name] = m
    return add_pairs(out)


def add_pairs(level: dict) -> dict:
    """Fill level["pairs"] with the paired ELPD differences of its models (in their order)."""
    level["pairs"] = []
    if not level["cross_validated"]:
        return level
    ids, names = level["tests"], list(level["models"])
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            ea = [level["models"][a]["elpd_per_test"][t] for t in ids]
            eb = [level["models"][b]["elpd_per_test"][t] for t in ids]
            d = elpd_difference(ea, eb)
            level["pairs"].append({"a": a, "b": b, "delta_elpd": d["delta_elpd"], "se": d["se"],
                                   "delta_per_test": dict(zip(ids, np.subtract(ea, eb).tolist()))})
    return level


def merge_levels(parts: list[dict]) -> dict:
    """One level's result from compare_level runs on single models (the pipeline runs each model
    of a level as its own task): models in the order given, pairs recomputed."""
    out = dict(parts[0])
    out["models"] = {}
    for p in parts:
        if p["tests"] != out["tests"]:
            raise ValueError("compare: the parts of a level were run on different tests")
        out["models"].update(p["models"])
    return add_pairs(out)


def default_configs(likelihood: str = "ar1", seed: int = 1, sampler=None) -> dict[str, FitConfig]:
    kw = {"likelihood": likelihood, "seed": seed}
    if sampler is not None:
        kw["sampler"] = sampler
    return {m: FitConfig(model=m, **kw) for m in DEFAULT_MODELS}


#: compare.csv: one row per level and model; applied_N (applied_Pa for a pressure): the level's
#: applied force in SI; delta_elpd_nats = ELPD(model) - ELPD(compared_to), the first model of the
#: configuration, with the SE of the paired differences
CSV_COLUMNS = ("level", "applied_{unit}", "model", "n_tests", "rmse_N", "elpd_nats", "elpd_se_nats",
               "compared_to", "delta_elpd_nats", "delta_se_nats", "converged")


def _csv(levels, applied_unit: str) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([c.format(unit=applied_unit) for c in CSV_COLUMNS])

    def f(v):
        return "" if v is None else f"{v:.10g}"
    for lv in levels:
        names = list(lv["models"])
        ref = names[0]
        pairs = {(p["a"], p["b"]): p for p in lv["pairs"]}
        for n in names:
            m = lv["models"][n]
            p = pairs.get((ref, n)) if n != ref else None     # delta of the pair is ref - n
            w.writerow([lv["id"], f(lv["applied"]), n, lv["n_tests"], f(m["rmse"]), f(m["elpd"]),
                        f(m["se"]), ref if p else "", f(-p["delta_elpd"]) if p else "",
                        f(p["se"]) if p else "", m["converged"]])
    return buf.getvalue()


def compare_campaign(campaign_path, out_dir, configs: dict[str, FitConfig] | None = None,
                     kinds=None, tests=None, log=None, *, seed: int | None = None,
                     offset: str = "marginal", work_dir=None, jobs: int = 1) -> dict:
    """Compare models on every applied-force level of a campaign; writes out_dir/compare.json
    and out_dir/compare.csv (atomically). configs: {name: FitConfig}, default three_stage and
    lugre with the default fit settings; kinds / tests: only tests of these kinds / ids; seed:
    default the first configuration's; jobs: processes for each level's fits (compare_level's
    workers; 1: one after the other, the simulator on every core). Bad input is refused
    (InputError) before any sampling."""
    from ..campaign import load_campaign
    from ..workers import Workers
    log = log or _quiet
    workers = Workers(jobs)     # refused here, before any work, if not an int >= 1
    configs = check_configs(dict(configs) if configs else default_configs())
    if offset not in OFFSET_MODES:
        raise InputError(f"compare: offset must be one of {OFFSET_MODES}, got {offset!r}")
    seed = check_seed(next(iter(configs.values())).seed if seed is None else seed, "compare")
    camp = load_campaign(campaign_path)
    # where the results go, checked before any fit: not the campaign folder, not under a file
    if Path(out_dir).resolve() == Path(camp.path).resolve():
        raise InputError(f"--out {out_dir}: must differ from the campaign folder (the results "
                         "would be written among its records)")
    if Path(out_dir).exists() and not Path(out_dir).is_dir():
        raise InputError(f"--out {out_dir}: exists and is not a folder")
    atomic.writable_parent(Path(out_dir) / "compare.json", create=False)
    kinds = ((kinds,) if isinstance(kinds, str) else tuple(kinds)) if kinds else None
    tests = ((tests,) if isinstance(tests, str) else tuple(tests)) if tests else None
    if tests:
        known = {t.id for t in camp.tests}
        unknown = [t for t in tests if t not in known]
        if unknown:
            raise InputError(f"campaign {camp.name!r}: unknown test id(s) {', '.join(unknown)}")
    specs = None
    for cfg in configs.values():     # validates every configuration against the selection
        specs = plan(camp, "applied", replace(cfg, kinds=kinds, tests=tests))
    levels = []
    with workers:
        for spec in specs:
            log(f"level {spec.id}: {len(spec.tests)} test(s): {', '.join(t.id for t in spec.tests)}")
            wd = None if work_dir is None else Path(work_dir) / spec.id
            lv_log = None if log is _quiet else (lambda m, s=spec.id: log(f"{s}: {m}"))
            lv = compare_level(spec.tests, configs, seed, log=lv_log, offset=offset, work_dir=wd,
                               workers=workers)
            lv["id"] = spec.id
            levels.append(lv)
    return write_compare(out_dir, camp.name, campaign_path, configs, levels, seed=seed,
                         offset=offset, kinds=kinds, tests=tests, applied_unit=camp.applied_si_unit)


def write_compare(out_dir, campaign: str, campaign_path, configs: dict, levels: list[dict], *,
                  seed: int, offset: str, kinds=None, tests=None, applied_unit: str) -> dict:
    """Write out_dir/compare.json and compare.csv (atomically) for compared levels; applied_unit:
    the SI unit of the levels' applied force, "N" or "Pa" (Campaign.applied_si_unit)."""
    if applied_unit not in ("N", "Pa"):
        raise ValueError(f"write_compare: applied_unit must be 'N' or 'Pa', got {applied_unit!r}")
    from .. import __version__
    result = {"package_version": __version__, "environment": environment(), "campaign": campaign,
              "campaign_path": str(Path(campaign_path).resolve()), "seed": seed, "offset": offset,
              "config": {"models": {n: c.to_json() for n, c in configs.items()},
                         "kinds": list(kinds) if kinds else None,
                         "tests": list(tests) if tests else None},
              "units": {"rmse": "N", "elpd": "nats (natural-log predictive density of a whole "
                                           "held-out test)", "applied": applied_unit},
              "method": "leave-one-test-out refits per applied-force level; SE = sqrt(K var_k), "
                        "var with divisor K-1 (Vehtari, Gelman & Gabry 2017); see "
                        "frictionuq.infer.compare",
              "levels": levels}
    out_dir = Path(out_dir)
    atomic.write_json(out_dir / "compare.json", jsonable(result))
    atomic.write_text(out_dir / "compare.csv", _csv(levels, applied_unit))
    return result


def format_table(result: dict) -> str:
    """A plain-text table of a compare result (units in the header)."""
    lines = [f"{'level':<18} {'model':<14} {'tests':>5} {'RMSE (N)':>10} {'ELPD (nats)':>14} "
             f"{'SE':>9}"]
    for lv in result["levels"]:
        for n, m in lv["models"].items():
            el = "n/a" if m["elpd"] is None else f"{m['elpd']:.1f}"
            se = "" if m["se"] is None else f"{m['se']:.1f}"
            flag = "" if m["converged"] else "  (not converged)"
            lines.append(f"{lv['id']:<18} {n:<14} {lv['n_tests']:>5} {m['rmse']:>10.4g} {el:>14} "
                         f"{se:>9}{flag}")
        if not lv["cross_validated"]:
            lines.append(f"{'':<18} one test only: cannot hold out a test, no ELPD")
        for p in lv["pairs"]:
            z = f"{p['delta_elpd'] / p['se']:+.1f} SE" if p["se"] > 0 else "SE 0"
            lines.append(f"{'':<18} dELPD {p['a']} - {p['b']}: {p['delta_elpd']:.1f} +- "
                         f"{p['se']:.1f} nats ({z})")
    return "\n".join(lines)
