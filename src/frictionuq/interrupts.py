"""Ctrl-C (SIGINT) handled so that a long run stops cleanly: noted as well as raised, so that a
KeyboardInterrupt Python swallows (one raised inside a finaliser) is raised again at the next
check; and only noted, never raised, inside code that must not see it (emcee's steps). Used by
the sampler (between steps and chunks) and the workflow runner (between tasks); the worker pools
(workers.Workers, the runner's) stop their processes with worker_initializer, call_in_worker and
stop_pool."""
from __future__ import annotations

import contextlib


class Interrupts:
    """Ctrl-C (SIGINT) during a run. While `defer` is set (the sampler sets it once its MAP
    search is done) it is only noted, and the sampler (infer.sampler.run_steps) raises
    KeyboardInterrupt between two steps or chunks: raised inside the log-probability it went
    through emcee's wrapper, which prints the walkers' whole parameter arrays and a traceback
    (about 90 lines) before the CLI's one-line "interrupted", and raised between chunks it could
    land in a finaliser, where Python prints "Exception ignored in ..." with a traceback and goes
    on (the fit ran to the end). Otherwise it raises at once and is noted too, and `check()`
    raises it again at the next step, chunk or task (in `run` one was swallowed 1 time in 4)."""

    def __init__(self):
        self.hit = False
        self.defer = False

    def handler(self, signum, frame):
        self.hit = True
        if not self.defer:
            raise KeyboardInterrupt

    def check(self):
        if self.hit:
            raise KeyboardInterrupt


@contextlib.contextmanager
def interrupts():
    """An Interrupts handling SIGINT and SIGTERM for the block (off the main thread, e.g. in a
    Dask worker, signals cannot be set: then it never notes anything)."""
    import signal
    intr = Interrupts()
    try:
        old = {s: signal.signal(s, intr.handler) for s in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:
        yield intr
        return
    try:
        yield intr
    finally:
        for s, h in old.items():
            signal.signal(s, h)


@contextlib.contextmanager
def sigint_ignored():
    """SIGINT ignored for the block (on the main thread; elsewhere a no-op): processes started in
    it inherit SIG_IGN, and Python leaves an ignored SIGINT ignored at start-up, so a Ctrl-C
    while a spawned worker imports cannot print its traceback (workers.Workers)."""
    import signal
    try:
        old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


def worker_initializer():
    """A spawned pool worker ignores SIGINT: Ctrl-C at a terminal reaches the whole process group,
    and it is the parent's to handle (an idle worker printed a KeyboardInterrupt traceback); the
    interrupted parent stops its workers with SIGTERM (stop_pool)."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def call_in_worker(fn, *args):
    """fn(*args) in a pool worker process, which ends when fn is interrupted. The parent's
    SIGTERM reaches a sampler as a KeyboardInterrupt between two steps (interrupts(), every
    finished step stored); returned to concurrent.futures' worker loop, it was sent back as the
    call's result and the process took the next queued call (a pool queues one more than it has
    processes), which then ran to its end, so that an interrupted `fit --jobs 2` of three levels,
    or `run -j 2`, went on fitting after Ctrl-C. Ending the process here stops it."""
    try:
        return fn(*args)
    except KeyboardInterrupt:
        import os
        import sys
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(130)


def stop_pool(pool, grace: float = 20.0) -> None:
    """Stop a ProcessPoolExecutor of interrupted work at once: its queued calls cancelled, SIGTERM
    to each process (a sampler stops between two steps, other work at once), SIGKILL to any still
    running after `grace` seconds, then the pool shut down."""
    import time
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        if p.is_alive():
            p.terminate()
    end = time.monotonic() + grace
    for p in procs:
        p.join(max(0.0, end - time.monotonic()))
        if p.is_alive():
            p.kill()
            p.join(5.0)
    pool.shutdown(wait=True, cancel_futures=True)
