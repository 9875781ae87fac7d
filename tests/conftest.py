"""Shared fixtures: a small but complete workflow run folder built with the library (ingest, fit,
mechanical advantage, validation, a harmonic prediction, model comparison) and its rendered
HTML report, built once per session for tests/test_report.py.

The run: 3 tests of data/brfd-arts-d2 (the two 2 Hz sines, fitted per applied force: 36 lb and
0 lb; the 1 Hz / 36 lb sine held out for validation), with the smallest sampler settings that
still run: the fits are NOT converged, which the report must say. About 20-30 s on 2 cores.
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy: see frictionuq/__init__.py
# Under pytest-xdist each worker gets its share of the cores for numba (set before numba is
# imported; xdist sets PYTEST_XDIST_WORKER_COUNT before it loads this file). Two workers with
# numba's default of one thread per core put 4 OpenMP threads on 2 cores, whose idle threads spin:
# measured, two processes simulating batches ran at 480 batches/s each with 2 threads and 1,090
# with 1 (the same numbers either way; only the speed differs).
if int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1")) > 1:
    os.environ.setdefault("NUMBA_NUM_THREADS", str(max(1, (os.cpu_count() or 1)
                                                        // int(os.environ["PYTEST_XDIST_WORKER_COUNT"]))))

import signal

# The Ctrl-C tests start commands as a terminal would, SIGINT at its default action. A suite run
# in the background of a non-interactive shell (`nohup bash .ci/run &`) inherits SIGINT ignored,
# Python keeps an inherited SIG_IGN, and so did every command the tests started: a Ctrl-C sent
# before the command set its own handler was dropped (test_ctrl_c_with_worker_processes_is_one_line
# failed twice on a 2-core Intel host, 2026-12-05; it passed where the signal came later).
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)

from pathlib import Path

import pytest

#: the test files with the most work, longest first (seconds summed over each file's tests in the
#: CI run of 2026-12-03 night, --durations=150: 592, 480, 226, 165, 105, 72, 71, 58, 49, 89 before
#: nullperm.py halved it, 41, 40, 65 before nullperm.py, 28, 26, 24; every other file under 17 s).
#: xdist's loadfile scheduler hands out whole files in collection order and by default reorders
#: them by their number of tests, which put the few-test discover files last, where two of them
#: ran side by side at the end of the run; with these first (and --no-loadscope-reorder in
#: pyproject's addopts) the many short files fill in behind them (longest first, the classic rule
#: for balancing two workers). With only the first six listed, one worker sat idle for the last
#: 65 s of the CI run of 2026-12-03, morning (vmstat), while the other finished its last file.
SLOW_FIRST = ("test_discrepancy_discover_rounds.py", "test_discrepancy_discover.py",
              "test_quick_workflow.py", "test_pipeline.py", "test_report.py",
              "test_discrepancy_screen.py", "test_stat_recovery.py", "test_infer_fit.py",
              "test_infer_law.py", "test_discrepancy_combine.py", "test_infer_compare.py",
              "test_stat_sbc.py", "test_discrepancy_diagnostics.py", "test_infer_arma.py",
              "test_cli_fit.py", "test_infer_likelihood.py", "test_discrepancy_gap.py")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(SLOW_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(SLOW_FIRST)))   # stable


REPO = Path(__file__).resolve().parent.parent
ARTS = REPO / "data" / "brfd-arts-d2"
FIT_TESTS = ("sine-2Hz-36lb-0.5in", "sine-2Hz-0lb-1in")
HELD_OUT = "sine-1Hz-36lb-1in"
PREDICTION = "harmonic-25mm-2Hz-36lb"

WORKFLOW = {
    "workflow": {"name": "tiny-report", "description": "Report test run: 2 short BRFD tests, tiny sampler",
                 "campaign": str(ARTS), "seed": 1},
    "fit": {"by": "applied", "model": "three_stage", "tests": list(FIT_TESTS)},
    "predict": {"validate": [HELD_OUT], "harmonic": [
        {"name": PREDICTION, "amplitude_m": 0.025, "frequency_hz": 2.0, "applied": 36}]},
    "compare": {"models": ["three_stage", "lugre"]},
    "report": {"title": "Tiny report test", "published": "brfd"},
}


def provenance(run_dir) -> dict:
    return {"package_version": "0.1.0",
            "workflow": {"name": "tiny-report", "file": str(REPO / "workflows" / "tiny.toml"),
                         "sha256": "f" * 64, "config": WORKFLOW},
            "seed": 1, "started": "2026-01-01T00:00:00+00:00", "finished": "2026-01-01T00:01:00+00:00",
            "inputs": [{"path": "data/brfd-arts-d2/campaign.toml", "sha256": "a" * 64}],
            "tasks": [{"name": "ingest", "stage": "ingest", "status": "ran", "seconds": 0.5, "key": "k1",
                       "error": None},
                      {"name": "fit", "stage": "fit", "status": "cached", "seconds": 0.0, "key": "k2",
                       "error": None}]}


def tiny_campaign(dest: Path, keep) -> Path:
    """A campaign folder with only the tests `keep` of data/brfd-arts-d2 (records symlinked)."""
    dest.mkdir(parents=True)
    (dest / "records").symlink_to(ARTS / "records")
    head, *blocks = (ARTS / "campaign.toml").read_text().split("[[tests]]")
    blocks = [b for b in blocks if any(f'id = "{k}"' in b for k in keep)]
    assert len(blocks) == len(keep), "data/brfd-arts-d2 lost a test the report fixture needs"
    (dest / "campaign.toml").write_text(head + "".join("[[tests]]" + b for b in blocks))
    return dest


def build_run(root: Path, compare: bool = True) -> Path:
    from frictionuq.advantage import write_advantage
    from frictionuq.infer.compare import compare_campaign
    from frictionuq.infer.fit import FitConfig, fit_campaign
    from frictionuq.infer.sampler import SamplerConfig
    from frictionuq.ingest import ingest
    from frictionuq.predict import write_prediction
    from frictionuq.validate import validate
    camp = tiny_campaign(root / "campaign", FIT_TESTS + (HELD_OUT,))
    run = root / "run"
    ingest(camp, run / "ingest")
    sc = SamplerConfig(max_steps=300, min_steps=200, burn_steps=100, burn_rounds=1, burn_max_rounds=1,
                       n_random_starts=1, n_prior_starts=1, progress=False)
    cfg = FitConfig(tests=FIT_TESTS, samples_per_cycle=60, sampler=sc, n_predictive=50)
    fit_campaign(run / "ingest", run / "fit", config=cfg, resume=False)
    write_advantage(run / "fit", run / "advantage")
    validate(run / "fit", run / "ingest", [HELD_OUT], run / "predict" / "validation", n_draws=40)
    write_prediction(run / "fit", run / "predict" / PREDICTION, harmonic=(0.025, 2.0), applied=36, n_draws=40)
    if compare:
        cfgs = {m: FitConfig(model=m, samples_per_cycle=60, sampler=sc, n_predictive=50)
                for m in ("three_stage", "lugre")}
        compare_campaign(run / "ingest", run / "compare", cfgs, tests=FIT_TESTS,
                         work_dir=root / "compare-chains")
    return run


class FigureSpy:
    """Records, for every figure the report saves, its title, axis labels and legends."""

    def __init__(self):
        self.figures = []

    def wrap(self, png):
        def spy(fig, *a, **kw):
            titles = [fig.get_suptitle()] if fig.get_suptitle() else []
            axes = [{"title": ax.get_title(), "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
                     "has_data": bool(ax.lines or ax.collections or ax.patches), "visible": ax.axison,
                     "legend": ax.get_legend() is not None} for ax in fig.axes]
            self.figures.append({"titles": titles, "axes": axes, "fig_legend": bool(fig.legends)})
            return png(fig, *a, **kw)
        return spy


@pytest.fixture(scope="session")
def report_run(tmp_path_factory):
    """{"run_dir", "workflow", "provenance"} of the shared run folder."""
    root = tmp_path_factory.mktemp("report-run")
    run = build_run(root)
    return {"run_dir": run, "workflow": WORKFLOW, "provenance": provenance(run), "root": root}


@pytest.fixture(scope="session")
def rendered_report(report_run, tmp_path_factory):
    """The run's report rendered once: {"path", "html", "seconds", "figures"} (figures: what
    FigureSpy saw)."""
    import time
    from unittest import mock
    from frictionuq.report import figures, figures_fit, figures_levels, render_report
    spy = FigureSpy()
    wrapped = spy.wrap(figures.png)
    out = tmp_path_factory.mktemp("report-html") / "tiny.html"
    t0 = time.perf_counter()
    with mock.patch.object(figures, "png", wrapped), mock.patch.object(figures_fit, "png", wrapped), \
            mock.patch.object(figures_levels, "png", wrapped):
        path = render_report(report_run["run_dir"], out, workflow=report_run["workflow"],
                             provenance=report_run["provenance"])
    return {"path": path, "html": path.read_text(encoding="utf-8"),
            "seconds": time.perf_counter() - t0, "figures": spy.figures}


@pytest.fixture
def partial_run(report_run, tmp_path):
    """partial_run(*names): a run folder holding only those sub-folders of the shared run
    (symlinked), e.g. partial_run("ingest", "fit") for a workflow without the optional stages."""
    def make(*keep) -> Path:
        dest = tmp_path / ("run-" + "-".join(keep or ("empty",)))
        dest.mkdir()
        for name in keep:
            (dest / name).symlink_to(report_run["run_dir"] / name, target_is_directory=True)
        return dest
    return make

