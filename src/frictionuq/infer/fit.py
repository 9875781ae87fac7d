"""Fits: per test or per applied force (one joint posterior over all tests at that force), with
their outputs: an ArviZ netCDF per fit and the campaign's summary.json.

Layout of an output folder:
    summary.json                  {"package_version", "campaign", "fits": [...]} (SI units)
    <fit id>/chain.h5             emcee HDF5 backend (resumable)
    <fit id>/posterior.nc         ArviZ DataTree: posterior, sample_stats, observed_data,
                                  log_likelihood (per test), posterior_predictive
    <fit id>/fit.json             configuration, priors, seed, MAP, sampler record, convergence
    law.json                      with --by applied and 2+ levels: the force-dependence law
                                  (frictionuq.infer.law)
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import atomic, params as P
from ..environment import environment
from ..errors import InputError, check_seed, unknown
from ..units import from_si
from . import drivefilter
from .likelihood import SIMULATE_AT, LogPosterior, records_from_tests
from .priors import apply_overrides, default_priors, record_scales
from .config import FitConfig  # noqa: F401  (re-exported: its home until 2026-12-01)
from .sampler import _nwalkers, sample
from .space import Space
from ..wording import count

CONVERGENCE = {"r_hat_max": 1.01, "ess_min": 400}


@dataclass
class FitSpec:
    id: str
    tests: list
    applied: float | None           # SI (N or Pa), None for a mixed group
    config: FitConfig


def jsonable(obj):
    """obj with numpy scalars and arrays (e.g. the HDF5 backend's np.int64 step counts) turned
    into plain Python numbers and lists, so that json can write it."""
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.floating):
        return float(obj)
    return obj


def _scales(spec: FitSpec) -> dict:
    """record_scales of a fit's tests; when they show no sliding plateaus, the error names the
    fit and the tests that show none on their own."""
    try:
        return record_scales([t.record for t in spec.tests])
    except InputError as e:
        bad = []
        for t in spec.tests:
            try:
                record_scales([t.record])
            except InputError:
                bad.append(t.id)
        raise InputError(f"fit {spec.id}: {e}" + (f"; none in test(s) {', '.join(bad)}" if bad
                                                  else "")) from None


def _fmt_applied(value_si: float, unit: str) -> str:
    v = from_si(value_si, "applied", unit)
    return f"{v:g}{unit}"


def plan(campaign, by: str = "applied", config: FitConfig | None = None) -> list[FitSpec]:
    """The fits of a campaign: one per applied force (default) or one per test."""
    config = config or FitConfig()
    check_seed(config.seed, "fit")
    try:    # unknown effects, or effects the model cannot carry: refused before any work
        P.check_effects({e: {} for e in config.effects}, config.model)
    except ValueError as e:
        raise InputError(f"fit: {e}") from None
    try:
        drivefilter.check_multiple(config.drive_lowpass)
    except ValueError as e:
        raise InputError(f"fit: {e}") from None
    tests = [t for t in campaign.tests
             if (config.kinds is None or t.kind in config.kinds)
             and (config.tests is None or t.id in config.tests)]
    # any unknown id is refused, not only when nothing matches: a typo would drop a test
    missing = [i for i in (config.tests or ()) if i not in {t.id for t in campaign.tests}]
    if not tests or missing:
        what = (f"no test {', '.join(map(repr, missing))}" if missing else
                f"no test of kind {', '.join(config.kinds or ())} among the tests selected")
        ids = [t.id for t in campaign.tests]
        listed = ", ".join(ids[:20]) + (f", ... ({len(ids)} in all)" if len(ids) > 20 else "")
        raise InputError(f"campaign {campaign.name!r}: {what}; its tests: {listed}")
    if by == "test":
        return [FitSpec(t.id, [t], t.applied, config) for t in tests]
    if by != "applied":
        raise InputError(f"--by must be 'test' or 'applied', got {by!r}")
    groups: dict[float, list] = {}
    for t in tests:
        key = round(t.applied, 9)
        groups.setdefault(key, []).append(t)
    unit = campaign.units.get("applied", "N")
    specs = [FitSpec(f"applied-{_fmt_applied(a, unit)}", g, a, config)
             for a, g in sorted(groups.items())]
    for s0, s1 in zip(specs, specs[1:]):    # levels apart by less than the id's 6 digits
        if s0.id == s1.id:
            raise InputError(
                f"campaign {campaign.name!r}: tests {s0.tests[0].id!r} and {s1.tests[0].id!r} have "
                f"applied levels that differ only beyond 6 significant digits (both "
                f"{s0.id}): give them the same value in campaign.toml if they are one level")
    return specs


def _check_noise_overrides(overrides: dict, where: str) -> None:
    """The noise parameters are integrated out under fixed prior forms (noisemodel): they can be
    fixed, and sigma_noise's log-uniform bounds moved, but no other prior is honoured, so none
    is accepted."""
    phi, sig = overrides.get("noise_phi"), overrides.get("sigma_noise")
    if isinstance(phi, dict):
        raise InputError(f"{where}: noise_phi is integrated out under a uniform prior on [0, 0.999]; "
                         "give a number to fix it instead of a distribution")
    if isinstance(sig, dict) and (sig.get("dist", "loguniform") != "loguniform"
                                  or "mu" in sig or "sd" in sig):
        raise InputError(f"{where}: sigma_noise takes a number (fixed) or loguniform bounds "
                         "(lower, upper) of the innovation sd, which is integrated out")


def unused_parameters(config: FitConfig, names) -> list[str]:
    """Those of `names` the fit's model does not have: an effect's parameters without the effect,
    the backlash's with the LuGre model (their overrides do not apply; build_space)."""
    return [n for n in names
            if P.PARAMS[n].effect is not None and P.PARAMS[n].effect not in config.effects
            or config.model == "lugre" and n in P.LUGRE_UNUSED]


def build_space(spec: FitSpec, scales) -> Space:
    """The fit's sampling space: default priors, then the config's overrides. An override of an
    effect's parameter applies only when that effect is in the model (a workflow's priors serve
    its baseline and every candidate of the discrepancy screening alike; applied without the
    effect, a fixed p2 = 2 would have put a stage-2 curve into the baseline and a prior on b_ch
    an unused dimension into the sampler); the override is still validated."""
    c = spec.config
    _check_noise_overrides(dict(c.priors or {}), f"fit {spec.id} priors")
    pri = default_priors(scales, c.model, c.effects, c.likelihood)
    pri, fixed = apply_overrides(pri, c.priors, source=f"fit {spec.id} priors")
    off = set(unused_parameters(c, list(pri) + list(fixed)))
    pri = {n: p for n, p in pri.items() if n not in off}
    fixed = {n: v for n, v in fixed.items() if n not in off}
    box = None
    if c.force_offset == "per_test":      # each test's zero integrated out (per_test_offset_box)
        pri.pop("force_offset")
        box = per_test_offset_box(scales, (c.priors or {}).get("force_offset"))
    return Space(c.model, tuple(c.effects), c.likelihood, pri, fixed, offset_box=box)


def per_test_offset_box(scales, override=None) -> tuple[float, float]:
    """The uniform prior box (N) of each test's own zero under per-test offsets: +-F, the records'
    friction-force scale (a zero as large as the friction itself is no zero), or a user's
    {"dist": "uniform", "lower", "upper"} (FitConfig checks its form). Not the shared offset's
    +-3 sd box: its sd comes from the level's pooled plateau asymmetry, in which zeros of
    opposite sign cancel (arts-d1 22 lb: +-381 N, where one test's zero lies near -440 N). The
    width enters each record's likelihood only as the constant -log(width)."""
    if override is not None:
        return float(override["lower"]), float(override["upper"])
    return -float(scales.f_scale), float(scales.f_scale)


def prepare(spec: FitSpec):
    """Records, scales, space and log-posterior of a fit (no sampling)."""
    c = spec.config
    for eff in c.effects:
        if eff not in P.EFFECTS:
            raise InputError(unknown("effect", eff, P.EFFECTS))
        if eff in P.NEEDS_APPLIED:
            missing = [t.id for t in spec.tests if t.record.applied is None]
            if missing:
                raise InputError(f"effect {eff!r} needs the measured applied-force signal, which "
                                 f"tests {missing} do not carry (campaign column `applied`)")
    if c.simulate_at not in SIMULATE_AT:
        raise InputError(f"fit: simulate_at must be one of {', '.join(SIMULATE_AT)}, got {c.simulate_at!r}")
    records = records_from_tests(spec.tests, **c.record_options())
    scales = _scales(spec)
    space = build_space(spec, scales)
    return records, scales, space, LogPosterior(space, records)


def run_fit(spec: FitSpec, out_dir, campaign_name: str = "", resume: bool = True, log=None,
            start: dict | None = None) -> dict:
    """Sample one fit and write its outputs under out_dir/<fit id>/. Returns its summary entry.
    start: {parameter: SI value} of every sampled parameter, a MAP estimate found by another
    search on the same log-posterior (discover passes the screening's): the sampler polishes it
    instead of running its own multi-start search."""
    from .. import __version__
    from . import outputs
    log = log or (lambda m: None)
    t0 = time.perf_counter()
    records, scales, space, logpost = prepare(spec)     # bad config: refused before any file
    fdir = atomic.writable_parent(Path(out_dir) / spec.id / "fit.json")
    theta0 = None
    if start is not None:
        missing = [n for n in space.names if n not in start]
        if missing:
            raise ValueError(f"run_fit {spec.id}: the start lacks {missing}")
        theta0 = space.to_theta({n: start[n] for n in space.names})
    log(f"fit {spec.id}: {count(len(records), 'test')}, {sum(r.n for r in records)} samples after decimation "
        f"(factors {[r.q for r in records]}), {space.ndim} free parameters")
    from .priorpred import outside, prior_predictive
    ppc = prior_predictive(logpost, n=200, seed=spec.config.seed)
    log(f"fit {spec.id}: prior predictive check: " + (
        "passed (measured peak, trough and energy inside the central 98 % of the prior "
        "predictive)" if ppc["passed"] else "FAILED: " + "; ".join(outside(ppc))))
    res = sample(logpost, scales, spec.config.seed, fdir / "chain.h5", spec.config.sampler,
                 resume=resume, log=lambda m: log(f"fit {spec.id}: {m}"), start=theta0,
                 run_key=run_key(spec, space, records))
    rng = np.random.default_rng([spec.config.seed, 7])
    post = outputs.posterior_draws(logpost, res, rng)
    pred = outputs.predictive(logpost, post, spec.config.n_predictive, rng)
    dt = outputs.datatree(logpost, post, pred, attrs={
        "package_version": __version__, "environment": environment(),
        "campaign": campaign_name, "fit": spec.id,
        "seed": spec.config.seed, "config": spec.config.to_json()})
    from .. import azadapter
    azadapter.save(dt, fdir / "posterior.nc")
    entry = outputs.summary_entry(spec, logpost, res, dt, post, pred)
    # this session's wall time, plus the sampler's in the sessions before a resumed one
    entry["seconds"] = time.perf_counter() - t0 + res.earlier_seconds
    entry["prior_predictive_passed"] = ppc["passed"]
    record = {"package_version": __version__, "environment": environment(),
              "campaign": campaign_name, "fit": spec.id,
              "tests": [t.id for t in spec.tests], "seed": spec.config.seed,
              "config": spec.config.to_json(), "space": space.to_json(), "scales": scales.to_json(),
              "records": [{"id": r.id, "decimation": r.q, "samples": r.n, "eps_m": r.eps,
                           "rate_hz": r.fs_raw / r.q, "noise_theta": r.noise_theta,
                           "simulated_at_hz": r.fs_raw if r.sim_drive is not None or r.q == 1
                           else r.fs_raw / r.q, "drive_cutoff_hz": r.drive_cutoff_hz}
                          for r in records],
              "sampler": {"steps": res.n_steps, "burn": res.burn, "thin": res.thin,
                          "burn_in_phase_steps": res.burn_in_steps,
                          "mode_components": res.mode_components,
                          "map_restarts": res.map_restarts,
                          "stored_searches": res.stored_searches,
                          "walkers": int(res.chain.shape[1]), "acceptance": res.acceptance,
                          "tau": dict(zip(space.names, map(float, res.tau))),
                          "converged_tau": res.converged_tau, "model_evaluations": res.n_evals,
                          "seconds": res.seconds, "history": res.history,
                          # model_evaluations, seconds and burn_in_phase_steps count every
                          # session that wrote the chain; the stored step each resumed one began at
                          "resumed_from_steps": res.resumed_from},
              "map": dict(zip(space.names, map(float, space.to_values(res.theta_map)))),
              "map_start": res.map_start,
              "log_prob_map": res.log_prob_map, "prior_predictive": ppc, "summary": entry}
    atomic.write_json(fdir / "fit.json", jsonable(record))
    log(f"fit {spec.id}: {'converged' if entry['converged'] else 'NOT converged'} "
        f"after {res.n_steps} steps ({entry['seconds']:.0f} s), rmse {entry['rmse']:.4g} N")
    edge = (entry.get("per_test_offsets") or {}).get("at_box_edge")
    if edge:
        lo, hi = entry["per_test_offsets"]["box_N"]
        log(f"fit {spec.id}: the zero of test(s) {', '.join(edge)} presses against its prior box "
            f"[{lo:.0f}, {hi:.0f}] N: widen it with --prior force_offset=uniform:LOWER:UPPER")
    bt = entry["between_tests"]
    if bt and bt["significant"]:
        log(f"fit {spec.id}: the tests' force zeros differ beyond the noise (per-test mean "
            f"residual spread {bt['spread_N']:.0f} N, chi-square {bt['chi2']:.1f} on {bt['df']} "
            f"degrees of freedom, p = {bt['p_value']:.2g}): a shared force_offset does not fit them")
    return entry


def run_key(spec: FitSpec, space: Space, records) -> str:
    """What a stored chain must have been made by to be resumed: the fit's configuration (all
    but the step cap, which a resumed run may raise, and the progress bar), its space (priors
    derived from the data included) and the records it is fitted to, hashed."""
    import hashlib
    import json
    cfg = spec.config.to_json()
    cfg["sampler"] = {k: v for k, v in cfg["sampler"].items() if k not in ("max_steps", "progress")}
    h = hashlib.sha256(json.dumps(jsonable({"config": cfg, "space": space.to_json(),
                                            "tests": [t.id for t in spec.tests]}),
                                  sort_keys=True, default=str).encode())
    for r in records:
        for a in (r.t, r.x, r.y):
            h.update(np.ascontiguousarray(a, float).tobytes())
        h.update(repr((r.q, r.eps, r.stride)).encode())
    return h.hexdigest()


def fit_campaign(campaign_path, out_dir, by: str = "applied", config: FitConfig | None = None,
                 resume: bool = True, log=None, jobs: int = 1) -> dict:
    """Fit every group of a campaign (a folder, or a Campaign from load_campaign) and write
    out_dir/summary.json.

    jobs: processes for the fits (workers.Workers; one numba thread each). With jobs=1 they run
    here one after the other, the simulator on every core. With more, `jobs` fits run side by
    side, each in a spawned process, with the same results (each fit's random numbers come from
    its own seed); their progress messages then go to the processes' standard error, prefixed
    with the fit's id as here, and the sampler's progress bar is off."""
    from ..campaign import load_campaign
    from ..workers import Workers
    jobs = Workers(jobs).jobs               # refused here, before any work, if not an int >= 1
    atomic.writable_parent(Path(out_dir) / "summary.json", create=False)   # out: a folder, or none yet
    from ..campaign import Campaign, check_campaign
    if isinstance(campaign_path, Campaign):     # built in memory: checked as files are on loading
        check_campaign(campaign_path)
        camp, campaign_path = campaign_path, campaign_path.path
    else:
        camp = load_campaign(campaign_path)
    if Path(out_dir).resolve() == Path(campaign_path).resolve():
        raise InputError(f"--out {out_dir}: must differ from the campaign folder (the fits would "
                         "be written among its records)")
    _check_fit_folder(Path(out_dir), camp.name)
    specs = plan(camp, by, config)
    for s in specs:               # every fit's priors and walkers checked before the first fit
        space = build_space(s, _scales(s))
        try:
            _nwalkers(s.config.sampler, space.ndim)
        except ValueError as e:
            raise InputError(f"fit {s.id}: sampler nwalkers: {e}") from None
    jobs = min(jobs, len(specs)) if specs else 1
    if jobs == 1:
        fits = [run_fit(s, out_dir, camp.name, resume, log) for s in specs]
    else:
        if log:
            log(f"fitting {len(specs)} groups in {jobs} processes (one numba thread each)")
        with Workers(jobs) as w:
            fits = w.map(_run_fit_job, [(s, str(out_dir), camp.name, resume, log is not None)
                                        for s in specs])
    return write_summary(out_dir, camp, by, config or FitConfig(), fits, campaign_path, log=log)


#: the files a fit folder holds beside its fits' own folders (summary, law, advantage)
FIT_FOLDER_FILES = {"summary.json", "law.json", "advantage.csv", "advantage.json"}


def _check_fit_folder(out: Path, campaign_name: str) -> None:
    """--out: empty or new, or a fit folder of this campaign (fits resume or are added there).
    A folder with other files (a prediction's, an ingested campaign's, one's own notes) is
    refused: a later command replacing it as its own output would take the fits with it; and
    so is another campaign's fit folder, whose fits would stay listed beside this one's."""
    if not out.is_dir():
        return
    def fit_own(d: Path) -> bool:          # a fit's folder, maybe of an interrupted run
        return all(q.name in ("fit.json", "posterior.nc") or q.name.startswith(("chain", "."))
                   for q in d.iterdir())
    foreign = sorted(p.name for p in out.iterdir() if not p.name.startswith(".") and
                     (p.is_file() and p.name not in FIT_FOLDER_FILES or p.is_dir() and not fit_own(p)))
    if foreign:
        raise InputError(f"--out {out}: holds {', '.join(foreign[:3])}"
                         f"{', ...' if len(foreign) > 3 else ''}, not a fit folder's; choose an "
                         "empty or new folder")
    s = out / "summary.json"
    from ..fitdir import read_json
    other = read_json(s, "a fit summary").get("campaign") if s.is_file() else None
    if other is not None and other != campaign_name:
        raise InputError(f"--out {out}: holds fits of campaign {other!r}, not {campaign_name!r}; "
                         "choose an empty or new folder")


def _run_fit_job(job) -> dict:
    """run_fit in a worker process (fit_campaign with jobs > 1), messages to standard error when
    the caller logs (the worker turns the progress bar off; the config is untouched, so fit.json
    is the serial run's)."""
    from ..workers import stderr_log
    spec, out_dir, name, resume, logs = job
    return run_fit(spec, out_dir, name, resume, stderr_log if logs else None)


def write_summary(out_dir, camp, by: str, config: FitConfig, fits: list[dict], campaign_path, *,
                  law: bool = True, family: str = "auto", extra: dict | None = None,
                  log=None) -> dict:
    """Write out_dir/summary.json for finished fits and, with fits by applied force at 2 or more
    levels above zero (and `law`), fit the force-dependence law (law.json, named in the summary;
    a stale law.json is removed otherwise). Returns the summary."""
    from .. import __version__
    from .law import LAW_FILE, fit_law, law_entry
    log = log or (lambda m: None)
    out_dir = Path(out_dir)
    summary = {"package_version": __version__, "environment": environment(), "campaign": camp.name,
               "campaign_path": str(Path(campaign_path).resolve()), "by": by,
               "units": {"applied": camp.units.get("applied", "N"),
                         "note": "every value in this file is SI (N, m, s, Pa); `applied` names "
                                 "the campaign's unit for the applied force, used by the CLI"},
               "config": config.to_json(), **(extra or {}), "fits": fits}
    (out_dir / LAW_FILE).unlink(missing_ok=True)
    atomic.write_json(out_dir / "summary.json", jsonable(summary))
    if law and by == "applied" and sum(1 for f in fits if (f.get("applied") or 0) > 0) >= 2:
        fit_law(out_dir, family=family, seed=config.seed, log=log)    # names itself in summary.json
        summary["law"] = law_entry(out_dir)
    else:
        log("force-dependence law not fitted (needs fits by applied force at 2 or more levels "
            "above zero)")
    return summary

