"""Ctrl-C (SIGINT) handled so that a long run stops cleanly: noted as well as raised, so that a
KeyboardInterrupt Python swallows (one raised inside a finaliser) is raised again at the next
check; and only noted, never raised, inside code that must not see it (emcee's steps). Used by
the sampler (between steps and chunks) and the workflow runner (between tasks)."""
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
