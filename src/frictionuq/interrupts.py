"""Ctrl-C (SIGINT) handled so that a long run stops cleanly: noted as well as raised, so that a
KeyboardInterrupt Python swallows (one raised inside a finaliser) is raised again at the next
check; and only noted, never raised, inside code that must not see it (emcee's steps). Used by
the sampler (between steps and chunks) and the workflow runner (between tasks); the worker pools
(workers.Workers, the runner's) stop their processes with worker_initializer, call_in_worker and
stop_pool; a task on a Dask cluster, where no signal reaches it, with call_stoppable."""
from __future__ import annotations

import contextlib
import threading

#: stop requests of tasks running on a Dask worker's threads (call_stoppable): thread id -> event
_STOPS: dict[int, threading.Event] = {}


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
        self._hit = False
        self.defer = False
        self._stop = _STOPS.get(threading.get_ident())     # set when run by call_stoppable

    @property
    def hit(self) -> bool:
        """A Ctrl-C or SIGTERM was noted, or (a task on a Dask worker) its run asked it to stop."""
        return self._hit or (self._stop is not None and self._stop.is_set())

    def handler(self, signum, frame):
        self._hit = True
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
def sigint_held():
    """SIGINT blocked on the main thread for the block (elsewhere a no-op). A process started in
    it inherits the blocked signal (fork and exec keep the mask), so a Ctrl-C while a spawned
    worker imports stays pending there until worker_initializer ignores it: no traceback from the
    worker (workers.Workers, the runner's pool). In this process a Ctrl-C during the block is
    held, not lost: it is delivered when the block ends. Until 2026-12-05 SIGINT was ignored
    (SIG_IGN) for the block instead, and the kernel dropped a Ctrl-C that came while the workers
    started: the command then ran to its end (tests/test_interrupts.py)."""
    import signal
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if signal.SIGINT not in old:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def worker_initializer():
    """A spawned pool worker ignores SIGINT: Ctrl-C at a terminal reaches the whole process group,
    and it is the parent's to handle (an idle worker printed a KeyboardInterrupt traceback); the
    interrupted parent stops its workers with SIGTERM (stop_pool). A Ctrl-C held while the worker
    started (it was born with SIGINT blocked, sigint_held) is discarded here."""
    import signal
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


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


class Stopped(RuntimeError):
    """A task on a Dask worker stopped by its run's stop event (call_stoppable)."""


def call_stoppable(fn, *args, stop: str):
    """fn(*args) on a Dask worker thread, stopped when the cluster's Event named `stop` is set
    (the interrupted runner sets it, pipeline.runner._Pool). No signal reaches a task on a Dask
    worker, and cancelling its future only drops the result: the thread ran on, a sampler to its
    step cap (for ever with no convergence), holding the cluster's worker. A watcher thread turns
    the event into the stop request that Interrupts.check() raises between two sampler steps,
    every finished step stored; the MAP search before the sampling runs to its end."""
    from distributed import Event, get_client
    event = Event(stop, client=get_client())    # resolved here: the watcher's thread has no client
    request, finished = threading.Event(), threading.Event()
    me = threading.get_ident()

    def watch():
        while not finished.is_set():
            try:
                if event.wait(timeout=1.0):
                    request.set()
                    return
            except Exception:          # the scheduler went away: nothing left to wait for
                return

    _STOPS[me] = request
    threading.Thread(target=watch, name=f"frictionuq-stop-{stop}", daemon=True).start()
    try:
        return fn(*args)
    except KeyboardInterrupt:
        raise Stopped(f"stopped: the run was interrupted ({stop})") from None
    finally:
        finished.set()
        _STOPS.pop(me, None)
