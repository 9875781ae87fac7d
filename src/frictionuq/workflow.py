"""Workflow files (TOML in workflows/): what `frictionuq run` does, read and validated here.

A workflow names a campaign, the fits to run, the sampler and likelihood settings, the
prediction inputs and the report. Every key is checked: an unknown key or a bad value is refused
with the file, the key and the problem (InputError, exit code 2 in the CLI). Paths are relative
to the workflow file's folder. Units: as the CLI's, SI for lengths (`amplitude_m`, `peak_m`),
the campaign's own applied unit for `applied` (e.g. lb).

    [workflow]  name (required), campaign (required), description, seed = 1,
                output = "../out/<name>", report = "../reports/<name>"
    [fit]       by = "applied" | "test", model = "three_stage" | "lugre", effects = [],
                likelihood = "ar1" | "iid" | "arma", tests = [...], kinds = [...], samples_per_cycle = 400,
                simulate_at = "raw" | "kept" (decimated records: model force filtered like the
                data, or simulated on the decimated displacement), eps = "auto" | metres,
                drive_lowpass = "auto" (default: 20 where eps > 0) | "off" | MULT
                (infer.drivefilter), reversal = "extreme" (default) | "detection"
                (model.REVERSAL_RULES), force_offset = "shared" (default) | "per_test" (each
                test's own load-cell zero, integrated out), n_predictive = 200, [fit.priors]
                (spec names: a number fixes the parameter, a table {dist, lower, upper, mu, sd} sets its prior; an
                effect's parameter only where that effect is in the model, e.g. chatter's
                opt-in tail b_ch = {dist = "uniform", lower = 0, upper = 1}),
                [fit.sampler] (frictionuq.infer.sampler.SamplerConfig fields)
    [law]       enabled = true, family = "auto" | "linear" | "threshold" | "saturating"
    [predict]   n_draws = 400, validate = [test ids of the campaign, predicted and scored],
                [[predict.harmonic]] amplitude_m, frequency_hz, applied (, name)
                [[predict.ground_motion]] record (a data/ground-motions key) or file (your own
                                          accelerogram, relative to this file: .AT2, or columns
                                          / one value per line with dt, unit = "g", column = 0),
                                          peak_m, applied, rate_hz = 256 (, name)
    [compare]   enabled = false, models = ["three_stage", "lugre"], tests/kinds (default: the
                fit's), samples_per_cycle (default: the fit's), [compare.sampler] (default: the
                fit's)
    [report]    enabled = true, title, published = "none" | "brfd" | "mfd"
    [discrepancy] enabled = false, refit = true, tests/kinds (default: the fit's),
                extra_effects = [] (effects beyond the spec to screen too: "takeup_overshoot",
                "speed_weakening", "chatter"), max_effects = 1 (how many effects may be named,
                one per round), check_seeds = [] (screen again with these seeds: does the name
                hold? discover --check-seed):
                the `frictionuq discover` stage (screen the effect library, name, refit)
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .errors import MAX_SEED, InputError, bom_hint, not_a_file
from .tomlcheck import Checker
from .units import AMPLITUDE_PLAUSIBLE_M, harmonic_speed_problem, metres_note

NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]*$")
MODELS = ("three_stage", "lugre")
LIKELIHOODS = ("ar1", "iid", "arma")
KINDS = ("harmonic", "earthquake", "other")
FAMILIES = ("auto", "linear", "threshold", "saturating")
PUBLISHED = ("none", "brfd", "mfd")

SECTIONS = {
    "workflow": {"name", "description", "campaign", "seed", "output", "report"},
    "fit": {"by", "model", "effects", "likelihood", "tests", "kinds", "samples_per_cycle",
            "simulate_at", "eps", "drive_lowpass", "reversal", "force_offset", "n_predictive",
            "priors", "sampler"},
    "law": {"enabled", "family"},
    "predict": {"n_draws", "validate", "harmonic", "ground_motion"},
    "compare": {"enabled", "models", "tests", "kinds", "samples_per_cycle", "sampler"},
    "report": {"enabled", "title", "published"},
    "discrepancy": {"enabled", "refit", "tests", "kinds", "extra_effects", "max_effects",
                    "check_seeds"},
}
HARMONIC_KEYS = {"name", "amplitude_m", "frequency_hz", "applied"}
GROUND_KEYS = {"name", "record", "file", "dt", "unit", "column", "peak_m", "applied", "rate_hz"}


@dataclass
class Workflow:
    path: Path                 # the workflow file
    sha256: str                # of its bytes
    config: dict               # every section with its defaults filled in (JSON-able)
    campaign: Path
    out: Path                  # the run folder (stage outputs, cache, logs)
    report_dir: Path           # reports/<name>/ (index.html)

    @property
    def name(self) -> str:
        return self.config["workflow"]["name"]

    @property
    def seed(self) -> int:
        return self.config["workflow"]["seed"]

    def section_hash(self, *names: str) -> str:
        """Content hash of some sections (canonical JSON): part of the stage cache keys."""
        doc = {n: self.config[n] for n in names}
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()

    def fit_config(self, compare_model: str | None = None):
        """The FitConfig of the fits (or, with compare_model, of that comparison model)."""
        from .infer.fit import FitConfig
        from .infer.sampler import SamplerConfig
        f = self.config["fit"]
        c = self.config["compare"]
        if compare_model is None:
            sampler, spc, model, effects = f["sampler"], f["samples_per_cycle"], f["model"], f["effects"]
        else:
            sampler = c["sampler"] if c["sampler"] is not None else f["sampler"]
            spc = c["samples_per_cycle"] or f["samples_per_cycle"]
            model = compare_model
            effects = f["effects"] if compare_model == f["model"] else []
        return FitConfig(model=model, effects=tuple(effects), likelihood=f["likelihood"],
                         priors=dict(f["priors"]) if compare_model in (None, f["model"]) else {},
                         samples_per_cycle=spc, simulate_at=f["simulate_at"], eps=f["eps"],
                         drive_lowpass=f["drive_lowpass"], reversal=f["reversal"],
                         force_offset=f["force_offset"], n_predictive=f["n_predictive"],
                         kinds=tuple(f["kinds"]) if f["kinds"] else None,
                         tests=tuple(f["tests"]) if f["tests"] else None,
                         sampler=SamplerConfig(**{**sampler, "progress": False}),
                         seed=self.seed)


def _sampler(c: Checker, t: dict, where: str) -> dict:
    from .infer.sampler import STORED_RUNS, SamplerConfig
    if not isinstance(t, dict):
        c.fail(where, "must be a table of sampler settings")
    fields = {f.name: f for f in dataclasses.fields(SamplerConfig)}
    fields.pop("progress")               # the pipeline shows its own progress
    c.unknown(t, fields, where)
    out = {}
    for name, f in fields.items():
        if name not in t:
            continue
        typ = str(f.type)
        if t[name] is None:
            c.fail(f"{where}.{name}", "must be given a value (omit the key for the default)")
        if typ.startswith("bool"):
            out[name] = c.bool_(t, name, where, None)
        elif typ.startswith("str"):
            out[name] = c.str_(t, name, where, choices=STORED_RUNS if name == "stored_run" else None)
        else:
            out[name] = c.num(t, name, where, integer=typ.startswith("int"),
                              minimum=0 if name.startswith("n_") else None,
                              positive=not name.startswith("n_"))
    if "min_steps" in out and "max_steps" in out and out["min_steps"] > out["max_steps"]:
        c.fail(f"{where}.min_steps", f"({out['min_steps']}) exceeds max_steps ({out['max_steps']})")
    try:
        SamplerConfig(**out)
    except (TypeError, ValueError) as e:
        c.fail(where, str(e))
    return out


def _priors(c: Checker, t, where: str) -> dict:
    from .infer.fit import _check_noise_overrides
    from .infer.priors import apply_overrides
    if not isinstance(t, dict):
        c.fail(where, "must be a table {parameter: number or {dist, lower, upper}}")
    try:
        apply_overrides({}, t, source=f"{c.path}: {where}")
        _check_noise_overrides(t, f"{c.path}: {where}")
    except InputError:
        raise
    return dict(t)


def _fit(c: Checker, t: dict) -> dict:
    from . import params as P
    w = "[fit]"
    c.unknown(t, SECTIONS["fit"], "fit")
    eps = t.get("eps", "auto")
    if eps != "auto":
        eps = c.num(t, "eps", w, minimum=0)
    lowpass = t.get("drive_lowpass", "auto")
    if lowpass not in ("auto", "off") and (isinstance(lowpass, bool) or not isinstance(
            lowpass, (int, float)) or not math.isfinite(lowpass) or lowpass <= 0):
        c.fail(f"{w}.drive_lowpass", f"must be 'auto', 'off' or a number > 0 (a multiple of the "
               f"record's 99 % velocity-power frequency), got {lowpass!r}")
    model = c.str_(t, "model", w, "three_stage", MODELS)
    effects = c.strings(t, "effects", w, tuple(P.EFFECTS))
    try:
        P.check_effects({e: {} for e in effects}, model)
    except ValueError as e:
        c.fail(f"{w}.effects", str(e))
    return {"by": c.str_(t, "by", w, "applied", ("applied", "test")), "model": model,
            "effects": effects, "likelihood": c.str_(t, "likelihood", w, "ar1", LIKELIHOODS),
            "tests": c.strings(t, "tests", w), "kinds": c.strings(t, "kinds", w, KINDS),
            "samples_per_cycle": c.num(t, "samples_per_cycle", w, 400.0, positive=True),
            "simulate_at": c.str_(t, "simulate_at", w, "raw", ("raw", "kept")),
            "eps": eps, "drive_lowpass": lowpass,
            "reversal": c.str_(t, "reversal", w, "extreme", ("detection", "extreme")),
            "force_offset": c.str_(t, "force_offset", w, "shared", ("shared", "per_test")),
            "n_predictive": c.num(t, "n_predictive", w, 200, integer=True, positive=True),
            "priors": _priors(c, t.get("priors", {}), "[fit.priors]"),
            "sampler": _sampler(c, t.get("sampler", {}), "[fit.sampler]")}


def _entries(c: Checker, t: dict, key: str, allowed: set, where: str) -> list[dict]:
    v = t.get(key, [])
    if not isinstance(v, list) or not all(isinstance(e, dict) for e in v):
        c.fail(f"{where}.{key}", "must be an array of tables ([[predict.%s]])" % key)
    for i, e in enumerate(v):
        c.unknown(e, allowed, f"[[predict.{key}]][{i}]")
    return v


def _ground_source(c: Checker, e: dict, wh: str, base: Path) -> dict:
    """A ground motion's source: a shipped record's key, or the user's own accelerogram file
    (resolved against the workflow's folder and read now, so that a bad file is refused before
    any work)."""
    from .groundmotion import RECORDS
    if ("record" in e) == ("file" in e):
        c.fail(wh, "give either record (a shipped accelerogram: " + ", ".join(RECORDS) +
               ") or file (your own accelerogram), not both or neither")
    def refuse_format_keys(why: str) -> None:
        for k in ("dt", "unit", "column"):
            if k in e:
                c.fail(f"{wh}.{k}", why)
    if "record" in e:
        refuse_format_keys("applies to file only (a shipped record knows its own)")
        return {"record": c.str_(e, "record", wh, required=True, choices=tuple(RECORDS))}
    path = (base / c.str_(e, "file", wh, required=True)).resolve()
    if not path.is_file():
        c.fail(f"{wh}.file", f"{path} is not a file")
    if path.suffix.lower() == ".at2":
        refuse_format_keys("an .AT2 file states its own time step and unit (g); remove it")
    src = {"file": str(path), "dt": c.num(e, "dt", wh, None, positive=True),
           "unit": c.str_(e, "unit", wh, None),
           "column": c.num(e, "column", wh, 0, integer=True, minimum=0)}
    from .groundmotion import load_source
    try:
        load_source(src)
    except InputError as err:
        c.fail(f"{wh}.file", str(err))
    return src


def _predict(c: Checker, t: dict, base: Path) -> dict:
    w = "[predict]"
    c.unknown(t, SECTIONS["predict"], "predict")
    out = {"n_draws": c.num(t, "n_draws", w, 400, integer=True, minimum=2),
           "validate": c.strings(t, "validate", w), "harmonic": [], "ground_motion": []}
    names = set()

    def named(e, default, where):
        n = c.str_(e, "name", where, default)
        if not NAME.match(n):
            c.fail(f"{where}.name", f"{n!r} is not a valid name (letters, digits, . _ + -)")
        if n in names or n == "validation":
            c.fail(f"{where}.name", f"{n!r} is used twice (or is the reserved 'validation')")
        names.add(n)
        return n
    for i, e in enumerate(_entries(c, t, "harmonic", HARMONIC_KEYS, w)):
        wh = f"[[predict.harmonic]][{i}]"
        amp = c.num(e, "amplitude_m", wh, positive=True, required=True)
        if amp > AMPLITUDE_PLAUSIBLE_M:
            c.fail(f"{wh}.amplitude_m", f"{amp:g} m is {metres_note()}")
        f = c.num(e, "frequency_hz", wh, positive=True, required=True)
        if problem := harmonic_speed_problem(amp, f):
            c.fail(f"{wh}.frequency_hz", problem)
        a = c.num(e, "applied", wh, minimum=0, required=True)
        out["harmonic"].append({"name": named(e, f"harmonic-{amp * 1e3:g}mm-{f:g}Hz-{a:g}", wh),
                                "amplitude_m": amp, "frequency_hz": f, "applied": a})
    for i, e in enumerate(_entries(c, t, "ground_motion", GROUND_KEYS, w)):
        wh = f"[[predict.ground_motion]][{i}]"
        src = _ground_source(c, e, wh, base)
        label = src.get("record") or (re.sub(r"[^A-Za-z0-9._+-]+", "_", Path(src["file"]).stem)
                                         .lstrip("._+-") or "ground-motion")
        peak = c.num(e, "peak_m", wh, positive=True, required=True)
        if peak > AMPLITUDE_PLAUSIBLE_M:
            c.fail(f"{wh}.peak_m", f"{peak:g} m is {metres_note()}")
        a = c.num(e, "applied", wh, minimum=0, required=True)
        out["ground_motion"].append({"name": named(e, f"{label}-{a:g}", wh), **src,
                                     "peak_m": peak, "applied": a,
                                     "rate_hz": c.num(e, "rate_hz", wh, 256.0, positive=True)})
    return out


def _compare(c: Checker, t: dict) -> dict:
    w = "[compare]"
    c.unknown(t, SECTIONS["compare"], "compare")
    models = c.strings(t, "models", w, MODELS) if "models" in t else list(MODELS)
    if len(models) < 2:
        c.fail(f"{w}.models", "a comparison needs two models")
    return {"enabled": c.bool_(t, "enabled", w, False), "models": models,
            "tests": c.strings(t, "tests", w), "kinds": c.strings(t, "kinds", w, KINDS),
            "samples_per_cycle": c.num(t, "samples_per_cycle", w, None, positive=True),
            "sampler": _sampler(c, t["sampler"], "[compare.sampler]") if "sampler" in t else None}


def load_workflow(path) -> Workflow:
    """Read and validate a workflow file. Raises InputError naming the file, key and problem."""
    path = Path(path)
    if not path.is_file():
        why = not_a_file(path)
        raise InputError(f"{path}: " + ("workflow file not found" if why == "file not found" else
                                        f"{why}; give the workflow's .toml file"))
    raw = path.read_bytes()
    try:
        doc = tomllib.loads(raw.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise InputError(f"{path}: not valid TOML ({e}){bom_hint(raw)}") from None
    c = Checker(path)
    c.unknown(doc, SECTIONS, "")
    tables = {s: c.table(doc, s) for s in SECTIONS}
    t = tables["workflow"]
    c.unknown(t, SECTIONS["workflow"], "workflow")
    name = c.str_(t, "name", "[workflow]", required=True)
    if not NAME.match(name):
        c.fail("[workflow].name", f"{name!r} is not a valid name (letters, digits, . _ + -)")
    base = path.resolve().parent
    campaign = (base / c.str_(t, "campaign", "[workflow]", required=True)).resolve()
    if not (campaign / "campaign.toml").is_file():
        c.fail("[workflow].campaign", f"{campaign} is not a campaign folder (no campaign.toml)")
    out = (base / c.str_(t, "output", "[workflow]", f"../out/{name}")).resolve()
    rep = (base / c.str_(t, "report", "[workflow]", f"../reports/{name}")).resolve()
    if out == campaign or campaign in out.parents:
        c.fail("[workflow].output", f"{out} lies inside the campaign folder")
    if out in campaign.parents or out == base or out in base.parents:
        c.fail("[workflow].output", f"{out} holds the campaign or this workflow file; a run "
               "folder of its own is needed (e.g. ../out/<name>)")
    if out.exists() and not out.is_dir():
        c.fail("[workflow].output", f"{out} is a file, not a folder")
    if rep == campaign or campaign in rep.parents:
        c.fail("[workflow].report", f"{rep} lies inside the campaign folder")
    if rep.exists() and not rep.is_dir():
        c.fail("[workflow].report", f"{rep} is a file, not a folder (the report is "
               "<report>/index.html)")
    cfg = {"workflow": {"name": name, "description": c.str_(t, "description", "[workflow]", ""),
                        "campaign": str(campaign), "seed": c.num(t, "seed", "[workflow]", 1,
                                                                 integer=True, minimum=0,
                                                                 maximum=MAX_SEED),
                        "output": str(out), "report": str(rep)},
           "fit": _fit(c, tables["fit"])}
    lt = tables["law"]
    c.unknown(lt, SECTIONS["law"], "law")
    cfg["law"] = {"enabled": c.bool_(lt, "enabled", "[law]", True),
                  "family": c.str_(lt, "family", "[law]", "auto", FAMILIES)}
    cfg["predict"] = _predict(c, tables["predict"], base)
    cfg["compare"] = _compare(c, tables["compare"])
    from .params import BEYOND_SPEC, NOISE_EFFECTS
    dt = tables["discrepancy"]
    c.unknown(dt, SECTIONS["discrepancy"], "discrepancy")
    cfg["discrepancy"] = {"enabled": c.bool_(dt, "enabled", "[discrepancy]", False),
                          "refit": c.bool_(dt, "refit", "[discrepancy]", True),
                          "tests": c.strings(dt, "tests", "[discrepancy]"),
                          "kinds": c.strings(dt, "kinds", "[discrepancy]", KINDS),
                          "extra_effects": c.strings(dt, "extra_effects", "[discrepancy]",
                                                     tuple(sorted(BEYOND_SPEC))),
                          "max_effects": c.num(dt, "max_effects", "[discrepancy]", 1,
                                               integer=True, minimum=1),
                          "check_seeds": c.integers(dt, "check_seeds", "[discrepancy]")}
    if any(s > MAX_SEED for s in cfg["discrepancy"]["check_seeds"]):
        c.fail("[discrepancy].check_seeds", f"entries must be <= {MAX_SEED}, got "
               f"{cfg['discrepancy']['check_seeds']!r}")
    if cfg["workflow"]["seed"] in cfg["discrepancy"]["check_seeds"]:
        c.fail("[discrepancy].check_seeds", f"{cfg['workflow']['seed']} is the workflow's own "
               "seed; give other seeds")
    if cfg["fit"]["likelihood"] == "arma":     # held-out scoring integrates AR(1)/iid noise only
        for sec in ("compare", "discrepancy"):
            if cfg[sec]["enabled"]:
                c.fail("[fit].likelihood", f"'arma' cannot be used with [{sec}] enabled (its "
                       "held-out scoring supports ar1 and iid); use ar1 or disable the stage")
    if cfg["fit"]["force_offset"] == "per_test":   # the closed form covers iid and ar1 noise only
        if cfg["fit"]["likelihood"] == "arma":
            c.fail("[fit].force_offset", "'per_test' works with the ar1 and iid likelihoods, not "
                   "'arma'")
        if set(cfg["fit"]["effects"]) & NOISE_EFFECTS:
            c.fail("[fit].force_offset", f"'per_test' works with no noise effect, and [fit].effects "
                   f"has {sorted(set(cfg['fit']['effects']) & NOISE_EFFECTS)[0]}")
        noise = set(cfg["discrepancy"]["extra_effects"] or ()) & NOISE_EFFECTS
        if cfg["discrepancy"]["enabled"] and noise:
            c.fail("[fit].force_offset", f"'per_test' cannot be screened with the noise effect "
                   f"{sorted(noise)[0]} of [discrepancy].extra_effects; drop it or use 'shared'")
    rt = tables["report"]
    c.unknown(rt, SECTIONS["report"], "report")
    cfg["report"] = {"enabled": c.bool_(rt, "enabled", "[report]", True),
                     "title": c.str_(rt, "title", "[report]", f"frictionuq report: {name}"),
                     "published": c.str_(rt, "published", "[report]", "none", PUBLISHED)}
    return Workflow(path=path.resolve(), sha256=hashlib.sha256(raw).hexdigest(), config=cfg,
                    campaign=campaign, out=out, report_dir=rep)
