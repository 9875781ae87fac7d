"""frictionuq.environment: the software and machine recorded beside the package version in every
result file, so that two outputs that differ say whether they came from the same dependency
versions on the same kind of CPU (numba compiles the kernel for the host CPU)."""
import json
import os
import subprocess
import sys
from importlib import metadata

import numpy as np
import pytest

from frictionuq import environment as E
from frictionuq.cli import main
from frictionuq.published import brfd_params


def test_environment_names_the_versions_and_the_cpu_numba_compiles_for(monkeypatch):
    env = E.environment()
    json.dumps(env)                                  # JSON-ready
    assert env["packages"]["numpy"] == metadata.version("numpy") == np.__version__
    assert env["packages"]["numba"] == metadata.version("numba")
    assert set(env["packages"]) == set(E.PACKAGES)
    import llvmlite.binding as ll
    monkeypatch.delenv("NUMBA_CPU_NAME", raising=False)
    assert E._numba_cpu() == ll.get_host_cpu_name()
    monkeypatch.setenv("NUMBA_CPU_NAME", "generic")
    assert E._numba_cpu() == "generic"
    monkeypatch.setenv("NUMBA_CPU_NAME", "host")            # numba's word for the host's own
    assert E._numba_cpu() == ll.get_host_cpu_name()
    import numba
    assert env["numba_threads"] == numba.get_num_threads() and env["cores"] >= 1


def test_environment_returns_a_fresh_dict():
    a = E.environment()
    a["packages"]["numpy"] = "edited"
    a["python"] = "edited"
    b = E.environment()
    assert b["packages"]["numpy"] == np.__version__ and b["python"] != "edited"


def test_a_result_file_records_it(tmp_path):
    """`frictionuq simulate`'s metadata file, the cheapest result a command writes."""
    t = np.arange(500) / 100.0
    X = tmp_path / "X.csv"
    X.write_text("time,displacement\n" + "\n".join(
        f"{float(u)!r},{float(0.01 * np.sin(2 * np.pi * 0.5 * u))!r}" for u in t))
    P = tmp_path / "P.json"
    P.write_text(json.dumps(brfd_params(133.0)))
    F = tmp_path / "F.csv"
    assert main(["simulate", "--params", str(P), "--input", str(X), "--out", str(F)]) == 0
    meta = json.loads(F.with_name("F.csv.json").read_text())
    assert meta["environment"] == E.environment()


@pytest.mark.parametrize("module", ["frictionuq.infer.fit", "frictionuq.discrepancy.discover",
                                    "frictionuq.validate", "frictionuq.infer.compare",
                                    "frictionuq.infer.law", "frictionuq.predict",
                                    "frictionuq.advantage", "frictionuq.pipeline.provenance"])
def test_every_writer_of_a_result_records_it(module):
    """Each module that writes a result file with a package_version writes the environment
    beside it (read from the source: running each writer is the job of its own test file)."""
    import importlib
    import inspect
    src = inspect.getsource(importlib.import_module(module))
    assert src.count('"package_version": __version__') == src.count('"environment": environment()')


def test_the_reports_provenance_shows_it():
    """The pipeline report's provenance table: the run's environment, or says it was not
    recorded (run folders made before it was)."""
    from types import SimpleNamespace
    from frictionuq.report.sections import provenance as S
    env = E.environment()

    def html(prov):
        ctx = SimpleNamespace(provenance=prov, workflow={}, summary=lambda: {}, run_dir="RUN")
        return "".join(str(b) for b in S.build(ctx, "now"))
    shown = html({"package_version": "0.1.0", "environment": env})
    assert f"numpy {np.__version__}" in shown and f"compiles for {env['numba_cpu']}" in shown
    assert f"BLAS {env['blas_threads']}" in shown
    assert "not recorded (run made before" in html({"package_version": "0.1.0"})


_BLAS_SCRIPT = """
import numpy, scipy.linalg   # both OpenBLAS copies loaded before frictionuq, as a user's script may
from threadpoolctl import threadpool_info, threadpool_limits
# OpenBLAS starts one thread per core it may use: two on a free 2-core machine, but one where the
# process is pinned to one core or OMP_NUM_THREADS=1 (the project's CI host, 2026-12-07). Two,
# as on a free machine, whatever this one is:
threadpool_limits(limits=2, user_api="blas")
before = max(i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas")
import frictionuq.environment as E
print(before, E.environment()["blas_threads"])
"""


def test_numpy_imported_first_still_gets_one_blas_thread():
    """A script that imports numpy (and scipy) before frictionuq: OpenBLAS had already started one
    thread per core, and with two threads the MAP search's SVDs differed in their last bits from
    run to run, so one seed gave two chains (docs/log-calibration.md, stop 81). frictionuq holds
    every loaded BLAS to one thread; a user's own OPENBLAS_NUM_THREADS wins."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}

    def run(**extra):
        out = subprocess.run([sys.executable, "-c", _BLAS_SCRIPT], env={**env, **extra}, check=True,
                             capture_output=True, text=True).stdout.split()
        return int(out[-2]), int(out[-1])
    before, after = run()
    assert before == 2 and after == 1           # numpy had started two; frictionuq made it one
    assert run(OPENBLAS_NUM_THREADS="2") == (2, 2)
