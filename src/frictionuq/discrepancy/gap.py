"""The gap before and after (discover's last stage): per test of a level, the residual
diagnostics (diagnostics.py) and their figures at the baseline's MAP and at the MAP of the model
with the named effects, the loops of both over the data, each model's RMSE; and the level's
tests taken together (combine.py). Its tasks run side by side in discover's worker processes
(workers.Workers), each seeded by its arguments: the serial run's numbers."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import atomic
from ..wording import count
from ..workers import Workers
from . import fits


def _model_forces(level_tests, cfg, effects, map_values: dict) -> list[tuple]:
    """[(fit record, simulated force at the MAP point incl. the load-cell offset (N), the noise
    gain of a noise effect there or None)] per test."""
    lp, _ = fits.logpost_for(level_tests, effects, cfg)
    th = lp.space.to_theta({n: map_values[n] for n in lp.space.names})[None, :]
    out = []
    for j, rec in enumerate(lp.records):
        g = lp.noise_gain(th, j)
        # per-test offsets (FitConfig.force_offset): each test's own zero, profiled at the MAP
        out.append((rec, lp.fitted_force(th, rec)[0], None if g is None else g[0]))
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


#: the permutation seeds of a level's tests are seed, seed + this, seed + 2 x this, ...
PERM_SEED_STRIDE = 7919


def _gap_task(args):
    """One task of the gap's stage (workers.Workers.map; seeded by its arguments, so the serial
    run's numbers): ("residuals", ...) one test's residual diagnostics under one model and their
    figure -> (diagnostics, PNG); ("loops", ...) one test's loops figure -> PNG."""
    from .plots import loop_figure, residual_figure
    if args[0] == "loops":
        t, x, y, forces, title = args[1:]
        return loop_figure(t, x, y, forces, title=title)
    from .diagnostics import diagnose
    t, x, r, F, eps, applied, seed, bursts, title = args[1:]
    d = diagnose(t, x, r, force_model=F, eps=eps, applied=applied, seed=seed, bursts=bursts)
    return d, residual_figure(d, None, title=title)


def level_gap(level_tests, cfg, base_map: dict, named: list, named_map: dict, seed: int,
              fig_dir: Path, log, workers=None) -> list[dict]:
    """The gap before and after, per test of a level: residual diagnostics (diagnostics.diagnose)
    at the baseline's MAP (base_map) and, when effects are named, at the MAP of the model with all
    of them (named_map) (figures residuals-<model>-<test>.png), and the loops of both models over
    the data with their residuals (loops-<test>.png); RMSE (offset removed) of each. The figures
    are most of this stage's time (matplotlib); with `workers` (a workers.Workers) each test and
    model's diagnostics and figures are made side by side in its processes."""
    from .plots import centred_rmse
    pool = workers or Workers(1)
    models = [("baseline", (), base_map)] + ([(f"with {' + '.join(named)}", tuple(named), named_map)]
                                              if named else [])
    forces = {tag: _model_forces(level_tests, cfg, eff, m) for tag, eff, m in models}
    tasks, rows = [], []
    for tag, _, _ in models:
        for j, (rec, F, g) in enumerate(forces[tag]):
            # with a noise effect (chatter) the residual in units of its noise model, which the
            # likelihood takes as stationary: what the effect leaves unexplained
            r = rec.y - F if g is None else (rec.y - F) / g
            title = f"{rec.id}: residuals, {tag}" + ("" if g is None else " (divided by the noise gain)")
            # each test its own permutations (seed + PERM_SEED_STRIDE j): the level's tests
            # combined (combine.py) need independent p-values; both models of a test share them
            tasks.append(("residuals", rec.t, rec.x, r, F, rec.eps, rec.applied,
                          seed + PERM_SEED_STRIDE * j, rec.kind != "earthquake",  # chatter.py: why
                          title))
            rows.append((tag, rec, F, g))
    tasks += [("loops", rec.t, rec.x, rec.y, {tag: forces[tag][i][1] for tag, _, _ in models},
               f"{rec.id}: measured and modelled force, "
               + (f"baseline and {models[-1][0]}" if named else "baseline (none named)"))
              for i, (rec, _, _) in enumerate(forces["baseline"])]
    done = pool.map(_gap_task, tasks)
    out = []
    for (tag, rec, F, g), (d, png) in zip(rows, done):
        d["scaled_by_noise_gain"] = g is not None
        name = f"residuals-{tag.replace(' ', '-')}-{rec.id}.png"
        atomic.write_bytes(fig_dir / name, png)
        sig = [_label(k, d) for k in d["significant"]]
        log(f"diagnostics {tag} {rec.id}: significant structure in {', '.join(sig) or 'none'}")
        # the RMSE about the residual's own mean (the shape of the misfit), and that mean: the
        # test's zero against the model's
        out.append({"test": rec.id, "model": tag, "figure": name, "significant_views": sig,
                    "rmse": centred_rmse(rec.y - F), "mean_residual": float(np.mean(rec.y - F)),
                    "diagnostics": d})
    for (rec, _, _), png in zip(forces["baseline"], done[len(rows):]):
        name = f"loops-{rec.id}.png"
        atomic.write_bytes(fig_dir / name, png)
        for g in out:
            if g["test"] == rec.id:
                g["loop_figure"] = name
    return out


def combined(level: str, gap: list[dict], log) -> list[dict]:
    """The level's tests' diagnostics taken together (combine.py), per model, with 2+ tests."""
    from .combine import combine
    out = []
    for tag in dict.fromkeys(g["model"] for g in gap):
        gs = [g for g in gap if g["model"] == tag]
        if len(gs) < 2:
            continue
        c = {"level": level, "model": tag,
             **combine([g["diagnostics"] for g in gs], [g["test"] for g in gs])}
        if len(c["tests"]) >= 2:
            log(f"diagnostics {tag}, level {level}, its tests combined: significant structure in "
                f"{', '.join(c['significant']) or 'none'}"
                + (f" (not combined: {', '.join(c['excluded'])})" if c["excluded"] else ""))
        else:
            log(f"diagnostics {tag}, level {level}: fewer than two tests to combine (left out "
                f"for too few blocks in their null: {', '.join(c['excluded'])})")
        out.append(c)
    return out


def tests_made_worse(doc: dict) -> list[dict]:
    """The tests whose RMSE rises with the named effects (discrepancy.json's diagnostics, at the
    MAP points): [{"test", "before", "after"}] (N). A name that makes a test worse rests on the
    others: on the real 25 lb pair of arts-d1 eccentricity was named while the 1 Hz test went
    from 1,013 to 1,023 N, and another seed named none."""
    base = {g["test"]: g["rmse"] for g in doc.get("diagnostics") or [] if g["model"] == "baseline"}
    return [{"test": g["test"], "before": base[g["test"]], "after": g["rmse"]}
            for g in doc.get("diagnostics") or []
            if g["model"] != "baseline" and g["test"] in base and g["rmse"] > base[g["test"]]]


def worse_sentence(doc: dict) -> str | None:
    """One sentence on the tests made worse, or None (the console's note and the page's)."""
    worse = tests_made_worse(doc)
    if not worse:
        return None
    each = ", ".join(f"{w['test']} {w['before']:.4g} -> {w['after']:.4g} N" for w in worse)
    check = ("" if doc.get("seed_check") else
             "; `--check-seed N` screens again with another seed and says whether it names the same")
    return (f"with {' + '.join(doc.get('named_effects') or [doc['named_effect']])} the RMSE of "
            f"{count(len(worse), 'test')} rises ({each}): the name rests on the other tests{check}")
