"""`frictionuq run`: the make-like pipeline on a tiny real workflow (two short ARTS d2 sines at
36 lb and 0 lb, a few hundred sampler steps): first run, no-op rerun, only what depends on a
changed test or setting reruns, a corrupted output is recomputed, a failed fit loses nothing else
and is the only thing retried, a killed run resumes, and fits run on a Dask LocalCluster."""
from __future__ import annotations

import gzip
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from frictionuq.pipeline import plan, plan_status, run
from frictionuq.pipeline import cache, tasks as T
from frictionuq.workflow import load_workflow

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[1]

WF = """
[workflow]
name = "tiny"
campaign = "campaign"
seed = 3
output = "out"

[fit]
tests = ["sine-2Hz-36lb-0.5in", "sine-2Hz-0lb-1in"]
samples_per_cycle = 40

[fit.sampler]
max_steps = {steps}
min_steps = 100
burn_steps = 100
burn_rounds = 1
burn_max_rounds = 1
n_random_starts = 1
n_prior_starts = 1

[predict]
n_draws = 50

[[predict.harmonic]]
name = "h36"
amplitude_m = 0.01
frequency_hz = 2.0
applied = 36

[report]
enabled = false
"""


def _workflow(folder: Path, steps: int = 200) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    camp = folder / "campaign"
    if not camp.exists():
        shutil.copytree(ROOT / "data" / "brfd-arts-d2", camp)
    p = folder / "wf.toml"
    p.write_text(WF.format(steps=steps))
    return p


@pytest.fixture(scope="module")
def first_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("pipe")
    wf = load_workflow(_workflow(folder))
    res = run(wf, jobs=2)
    return folder, wf, res


def _stale(wf):
    return {n for n, runs, _ in plan_status(wf) if runs}


def test_first_run_then_noop(first_run):
    folder, wf, res = first_run
    assert res.ok, (res.failed, res.skipped)
    assert set(res.ran) == set(plan(wf)), res.ran
    for f in ("fit/summary.json", "fit/applied-36lb/posterior.nc", "advantage/advantage.csv",
              "predict/h36/bands.csv", "run.json"):
        assert (wf.out / f).is_file(), f
    assert res.log_file.is_file() and "log of fit:applied-36lb" in res.log_file.read_text()
    prov = json.loads((wf.out / "run.json").read_text())
    assert prov["workflow"]["sha256"] == wf.sha256 and prov["seed"] == 3
    assert {t["status"] for t in prov["tasks"]} == {"ran"}
    again = run(load_workflow(wf.path))
    assert again.ran == [] and set(again.cached) == set(plan(wf))


def test_changing_one_test_or_one_setting_reruns_only_its_dependents(first_run):
    folder, wf, _ = first_run
    # the 0 lb record re-compressed: same data, new bytes -> its level and what follows
    rec = folder / "campaign" / "records" / "2Hz0lbtension1amplitude.json.gz"
    data = gzip.decompress(rec.read_bytes())
    saved = rec.read_bytes()
    os.chmod(rec, 0o644)
    rec.write_bytes(gzip.compress(data, mtime=12345))
    try:
        stale = _stale(load_workflow(wf.path))
        assert stale == {"ingest", "fit:applied-0lb", "fit/summary", "predict:h36"}, stale
    finally:
        rec.write_bytes(saved)
    assert _stale(load_workflow(wf.path)) == set()
    # one setting of the predictions: only the predictions
    text = wf.path.read_text()
    wf.path.write_text(text.replace("n_draws = 50", "n_draws = 60"))
    try:
        assert _stale(load_workflow(wf.path)) == {"predict:h36"}
    finally:
        wf.path.write_text(text)
    # the dry run prints the plan and runs nothing
    wf.path.write_text(text.replace("n_draws = 50", "n_draws = 60"))
    try:
        r = subprocess.run([sys.executable, "-m", "frictionuq.cli", "run", str(wf.path), "--dry-run"],
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        assert "run   predict:h36" in r.stdout and "skip  fit:applied-36lb" in r.stdout
        assert "1 of" in r.stdout
    finally:
        wf.path.write_text(text)
    assert _stale(load_workflow(wf.path)) == set()


def test_corrupted_output_is_detected_and_recomputed(first_run):
    folder, wf, _ = first_run
    p = wf.out / "predict" / "h36" / "bands.csv"
    good = p.read_bytes()
    p.write_bytes(good[: len(good) // 2])
    ok, why = cache.state(wf.out, plan(wf)["predict:h36"])
    assert not ok and "changed since it was written" in why
    res = run(load_workflow(wf.path), ["predict"])
    assert res.ran == ["predict:h36"] and p.read_bytes() == good    # same seed, same numbers
    # an unreadable manifest is a stale entry, not a crash
    cache.manifest_path(wf.out, "predict:h36").write_text("{not json")
    assert "unreadable" in cache.state(wf.out, plan(wf)["predict:h36"])[1]
    run(load_workflow(wf.path), ["predict"])
    assert _stale(load_workflow(wf.path)) == set()


def test_a_failed_fit_loses_nothing_and_only_it_is_retried(first_run, monkeypatch):
    folder, wf, _ = first_run
    real = T.RUNNERS["fit"]

    def flaky(wf_, task, log):
        if task.args["fit_id"] == "applied-0lb":
            raise ValueError("simulated failure of the 0 lb fit")
        return real(wf_, task, log)
    monkeypatch.setitem(T.RUNNERS, "fit", flaky)
    wf = load_workflow(wf.path)
    res = run(wf, ["fit", "predict"], force=True)          # inline (-j 1): the patch applies
    assert set(res.failed) == {"fit:applied-0lb"}
    assert "simulated failure" in res.failed["fit:applied-0lb"]
    assert set(res.skipped) == {"fit/summary", "predict:h36"}
    assert "fit:applied-36lb" in res.ran and not res.ok
    monkeypatch.setitem(T.RUNNERS, "fit", real)
    retry = run(load_workflow(wf.path))
    assert set(retry.ran) == {"fit:applied-0lb", "fit/summary", "predict:h36"}, retry.ran
    assert "fit:applied-36lb" in retry.cached and retry.ok


def test_cli_run_status_clean(first_run):
    folder, wf, _ = first_run
    cli = [sys.executable, "-m", "frictionuq.cli"]
    r = subprocess.run(cli + ["run", str(wf.path)], capture_output=True, text=True)
    assert r.returncode == 0 and "nothing to do" in r.stdout, r.stdout + r.stderr
    r = subprocess.run(cli + ["status", str(wf.path)], capture_output=True, text=True)
    assert r.returncode == 0 and "0 stale" in r.stdout
    other = folder / "copy"
    shutil.copytree(wf.out, other)
    r = subprocess.run(cli + ["clean", str(wf.path)], capture_output=True, text=True)
    assert r.returncode == 0 and not wf.out.exists()
    shutil.move(other, wf.out)                   # put the run back for the other tests
    assert _stale(load_workflow(wf.path)) == set()


def test_killed_run_resumes_its_fit(tmp_path):
    """SIGKILL the whole run while a fit samples: finished tasks keep their cache entries, and
    the next run resumes the fit from its HDF5 chain instead of starting again."""
    p = _workflow(tmp_path, steps=3000)
    wf = load_workflow(p)
    proc = subprocess.Popen([sys.executable, "-m", "frictionuq.cli", "run", str(p), "fit:applied-36lb"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    log = T.task_log_path(wf.out, "fit:applied-36lb")
    deadline = time.time() + 240
    while time.time() < deadline:
        if log.is_file() and "step 500" in log.read_text():
            break
        time.sleep(0.5)
    else:
        os.killpg(proc.pid, signal.SIGKILL)
        pytest.fail("the fit did not reach step 500 in time")
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert cache.state(wf.out, plan(wf)["ingest"])[0]            # the finished task is intact
    assert not cache.state(wf.out, plan(wf)["fit:applied-36lb"])[0]
    assert (wf.out / "fit" / "applied-36lb" / "chain.h5").is_file()
    p.write_text(WF.format(steps=3000))                           # same key
    res = run(load_workflow(p), ["fit:applied-36lb"])
    assert res.ran == ["fit:applied-36lb"], res.failed
    text = log.read_text()
    assert "resuming in" in text, text[:2000]
    # the chain resumes, unless the kill landed inside an HDF5 write and left the file's data
    # unreadable: then the fit says so and starts afresh (it must never fail on it). Only an
    # I/O error counts as unreadable (storage.UNREADABLE): a bug in the resume code raises
    # instead of passing as one
    from frictionuq.infer.storage import UNREADABLE
    io_error = any(f"unreadable ({e.__name__}" in text for e in UNREADABLE)
    assert ("resuming from stored step" in text
            or (io_error and "starting afresh" in text)), text[:3000]


def _ctrl_c_once_the_fits_sample(wf, options, check=lambda: True):
    """`frictionuq run WF OPTIONS` in its own session, Ctrl-C (SIGINT to its process group) once
    both fits have burnt in a round and `check()` holds: exit 130 with the one line."""
    proc = subprocess.Popen([sys.executable, "-m", "frictionuq.cli", "run", str(wf.path), *options],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    logs = [T.task_log_path(wf.out, n) for n in ("fit:applied-36lb", "fit:applied-0lb")]
    deadline = time.time() + 240
    try:
        while not all(f.is_file() and "burn-in round 1" in f.read_text() for f in logs):
            assert time.time() < deadline, "the fits did not reach their burn-in in time"
            time.sleep(0.5)
        assert check()
        os.killpg(proc.pid, signal.SIGINT)
        err = proc.communicate(timeout=120)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err.strip().splitlines()[-1], err


def test_ctrl_c_stops_the_workers_and_starts_no_queued_task(tmp_path):
    """run -j 2 with four sampling tasks (two fits, two comparisons) that would never converge:
    Ctrl-C (SIGINT to the process group) while the fits burn in. Before, the workers took it as
    their own KeyboardInterrupt, went back to the pool's loop and started the queued comparison,
    and the run waited for it to end (64 s after the signal on the quick workflow, for ever here);
    now the workers ignore SIGINT, the parent stops them, and no queued task starts."""
    p = _workflow(tmp_path, steps=100000)
    p.write_text(p.read_text().replace("min_steps = 100\n", "min_steps = 100000\n") + """
[compare]
enabled = true
models = ["three_stage", "lugre"]
tests = ["sine-2Hz-36lb-0.5in", "sine-1Hz-36lb-1in"]

[compare.sampler]
max_steps = 100000
min_steps = 100000
""")
    wf = load_workflow(p)
    assert sum(t.heavy for t in plan(wf).values()) == 4
    _ctrl_c_once_the_fits_sample(wf, ["-j", "2"])
    started = sorted(f.name for f in (wf.out / "logs" / "tasks").iterdir())
    assert not [n for n in started if n.startswith("compare")], started
    assert not any(cache.state(wf.out, plan(wf)[n])[0] for n in ("fit:applied-36lb", "fit:applied-0lb"))


def test_fits_on_a_dask_localcluster(first_run):
    import logging
    from dask.distributed import LocalCluster
    folder, wf, _ = first_run
    before = json.loads((wf.out / "fit" / "summary.json").read_text())
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster:
        res = run(load_workflow(wf.path), ["fit"], scheduler=cluster.scheduler_address, force=True)
    assert res.ok and {"fit:applied-36lb", "fit:applied-0lb"} <= set(res.ran)
    after = json.loads((wf.out / "fit" / "summary.json").read_text())
    # reproducible: the same seed gives the same posterior on the cluster as locally
    for a, b in zip(before["fits"], after["fits"]):
        assert a["parameters"]["fc_fwd"]["mean"] == b["parameters"]["fc_fwd"]["mean"]


def test_ctrl_c_stops_the_fits_running_on_a_dask_cluster(tmp_path):
    """Ctrl-C of `run --scheduler` while two never-converging fits sample on the cluster. Until
    2026-12-05 the runner closed its client and exited, and the cluster's workers fitted on (no
    signal reaches a Dask task, and cancelling a running future only drops its result): here for
    ever. Now the runner sets the run's stop event and each sampler stops between two steps, so
    the workers go idle within seconds."""
    import logging
    from dask.distributed import Client, LocalCluster
    p = _workflow(tmp_path, steps=100000)
    p.write_text(p.read_text().replace("min_steps = 100\n", "min_steps = 100000\n"))
    wf = load_workflow(p)

    def busy(client) -> float:
        """CPU seconds the cluster's workers used in the next 3 s."""
        def cpu():
            import psutil
            t = psutil.Process().cpu_times()
            return t.user + t.system
        a = sum(client.run(cpu).values())
        time.sleep(3.0)
        return sum(client.run(cpu).values()) - a

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        # both fits sample before the Ctrl-C (about 6 CPU seconds in 3 s)
        _ctrl_c_once_the_fits_sample(wf, ["--scheduler", cluster.scheduler_address],
                                     check=lambda: busy(client) > 2.0)
        deadline = time.time() + 60
        while (used := busy(client)) > 1.0:
            assert time.time() < deadline, f"the cluster still fits: {used:.1f} CPU s in 3 s"
    assert not any(cache.state(wf.out, plan(wf)[n])[0] for n in ("fit:applied-36lb", "fit:applied-0lb"))


def test_a_ground_motion_from_the_users_own_file(first_run):
    """[[predict.ground_motion]] file = your own accelerogram (one value per line, dt and unit
    given), relative to the workflow file: on the first run's fits only the new prediction
    runs; the drive is written beside it and scaled to peak_m; editing the file makes that
    prediction, and nothing else, stale."""
    import numpy as np
    folder, wf, _ = first_run
    rng = np.random.default_rng(7)
    t = np.arange(0, 12, 0.01)
    acc = 0.2 * np.sin(2 * np.pi * 1.3 * t) * np.exp(-((t - 5) / 2.5) ** 2) \
        + 0.02 * rng.standard_normal(t.size)
    own = folder / "my-quake.txt"
    own.write_text("".join(f"{a:.6g}\n" for a in acc))
    wf2 = folder / "wf-own.toml"
    wf2.write_text(WF.format(steps=200) + '\n[[predict.ground_motion]]\nfile = "my-quake.txt"\n'
                   'dt = 0.01\nunit = "g"\npeak_m = 0.005\napplied = 36\n')
    run(load_workflow(wf.path))          # up to date first (a test before may have forced the fits)
    w = load_workflow(wf2)
    e = w.config["predict"]["ground_motion"][0]
    assert e["name"] == "my-quake-36" and e["file"] == str(own.resolve())
    res = run(w, jobs=1)
    assert res.ok and res.ran == ["predict:my-quake-36"], (res.ran, res.failed)
    drive = np.loadtxt(w.out / "predict" / "inputs" / "my-quake-36.csv", delimiter=",", skiprows=1)
    assert np.max(np.abs(drive[:, 1])) == pytest.approx(0.005, rel=1e-6)      # peak |x| = peak_m
    assert (w.out / "predict" / "my-quake-36" / "bands.csv").is_file()
    own.write_text("".join(f"{a:.6g}\n" for a in 1.1 * acc))
    try:
        assert _stale(load_workflow(wf2)) == {"predict:my-quake-36"}
    finally:
        own.write_text("".join(f"{a:.6g}\n" for a in acc))
    assert _stale(load_workflow(wf.path)) == set()       # the first workflow is untouched
