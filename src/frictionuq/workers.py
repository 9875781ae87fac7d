"""Independent fits on several cores: a map over spawned worker processes.

Used by the calibration (infer.fit.fit_campaign with jobs > 1: one fit per applied force or per
test, each in its own process) and by the discrepancy screening (discrepancy/screen.py: every
candidate effect fitted from the baseline's MAP, each side refitted from the other's solutions,
each scored model's leave-one-out folds). Those fits do not depend on each other. Run one after
the other they already keep part of the second core busy (the simulator's numba threads run the
walkers' or the Jacobian's simulations side by side), but the rest of each fit (the sampler's
moves, the decimation, the noise model, scipy's optimisers) runs on one core: two processes cut
the screening of the item-6 campaign by 14 % (docs/log-discrepancy.md) and the six level fits of
brfd-arts-d1 by 16 % (984 -> 825 s; each fit ran 1.4-1.8 times slower beside another: the two
cores of these machines do not double the throughput; docs/log-calibration.md, 2026-11-29).
`Workers(jobs).map(fn, items)` runs them in `jobs` processes (spawn, not fork: numba's threading
layer and fork do not mix; one numba thread each) and returns the results in the order of
`items`. Every fit is deterministic given its inputs (each fit's random numbers come from its own
seeded generator, and the simulations of a batch do not depend on how many threads run them), so
the results are those of the serial map, bit for bit (tested). With jobs=1 (the library's
default, and inside a pipeline task, which has its own processes) the map runs here, in order,
with no process started.

The functions mapped must be importable (module level) and their arguments picklable: the
log-posteriors (records, prior box) or fit specifications travel whole. The pipeline's own
process pool (pipeline.runner) runs whole tasks, this one fits.
"""
from __future__ import annotations

import os


def _init_worker():
    """One numba thread, and no automatic sampler progress bar: several processes' bars would
    overwrite each other's line (infer.sampler reads FRICTIONUQ_PROGRESS; this process only).
    Ctrl-C is the parent's to handle (interrupts.worker_initializer): the interrupted parent
    stops its workers (Workers.__exit__, interrupts.stop_pool)."""
    import numba
    from .interrupts import worker_initializer
    worker_initializer()
    numba.set_num_threads(1)
    os.environ["FRICTIONUQ_PROGRESS"] = "0"


def stderr_log(msg: str) -> None:
    """The log of a worker process whose caller logs: a line on standard error."""
    import sys
    print(msg, file=sys.stderr, flush=True)


def default_jobs() -> int:
    """All cores (the issue's speed target is on 2)."""
    return max(1, os.cpu_count() or 1)


class Workers:
    """map(fn, items) in `jobs` spawned processes, started at the first map with more than one
    item and kept until close() (a context manager); jobs=1 maps here."""

    def __init__(self, jobs: int = 1):
        if not (isinstance(jobs, int) and jobs >= 1):
            raise ValueError(f"jobs must be an integer >= 1, got {jobs!r}")
        self.jobs = jobs
        self._pool = None

    def map(self, fn, items) -> list:
        items = list(items)
        if self.jobs == 1 or len(items) < 2:
            return [fn(x) for x in items]
        from concurrent.futures import FIRST_EXCEPTION, wait
        from .interrupts import call_in_worker, interrupts, sigint_held
        if self._pool is None:
            import multiprocessing
            from concurrent.futures import ProcessPoolExecutor
            self._pool = ProcessPoolExecutor(self.jobs, mp_context=multiprocessing.get_context("spawn"),
                                             initializer=_init_worker)
        with sigint_held():       # the workers start (in submit) holding Ctrl-C from birth
            futures = [self._pool.submit(call_in_worker, fn, x) for x in items]
        # wait in short slices, so that a Ctrl-C or SIGTERM the pool's internals swallowed (one
        # landing in a finaliser) still stops the map at once: interrupts() notes it, check()
        # raises it, and the caller's `with Workers` terminates the processes
        with interrupts() as intr:
            while wait(futures, timeout=0.5, return_when=FIRST_EXCEPTION).not_done:
                intr.check()
                if any(f.done() and f.exception() is not None for f in futures):
                    break
            intr.check()
        return [f.result() for f in futures]

    def close(self, terminate: bool = False) -> None:
        """Shut the processes down: after their running tasks, or at once (terminate: an
        interrupted or failed parent does not wait for work it will not use)."""
        if self._pool is not None:
            if terminate:
                from .interrupts import stop_pool
                stop_pool(self._pool)
            else:
                self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        self.close(terminate=exc_type is not None and issubclass(exc_type, KeyboardInterrupt))
        return False
