"""Storage of a sampler run: emcee's HDF5 backend kept open during the run, the coordinates
tag that says a stored chain can be resumed, and the independence proposal kept in the file's
attributes (so a resumed run uses the same proposal). The sampler controller (sampler.py) only
calls open_backend, store_proposal and load_proposal."""
from __future__ import annotations

from pathlib import Path

import emcee
import numpy as np

from .proposal import Proposal


class _Flushing:
    """Context manager over an open h5py file: flushes on exit instead of closing."""

    def __init__(self, f):
        self.f = f

    def __enter__(self):
        return self.f

    def __exit__(self, *exc):
        self.f.flush()
        return False


class OpenHDFBackend(emcee.backends.HDFBackend):
    """emcee's HDF5 backend with the file kept open during a run: emcee opens and closes the
    file on every step (about 3 ms a step, an eighth of a twin fit's time); here each step is
    written and flushed to the open file, so an interruption still loses no finished step.

    While the file is open, save_step writes the step itself (_StepWriter) to the datasets and
    attributes emcee's own save_step writes, the same values, so emcee's HDFBackend reads the
    file as its own (tested). emcee's version reads the run's shape back from the file and looks
    every dataset up again on each step: 1.9 ms a step with 16 walkers and 16 parameters on the
    2-core AMD EPYC of 2026-12-05, a fifth of a stored step of the item-6 campaign's refit; with
    the datasets and counts read once, 0.8 ms (benchmarks/bench_storage.py prints both)."""

    _handle = None
    _writer = None

    def open(self, mode="r"):
        if self._handle is not None:
            return _Flushing(self._handle)
        return super().open(mode)

    def keep_open(self):
        if self._handle is None:
            import h5py
            self._handle = h5py.File(self.filename, "a")
            self._writer = None

    def close(self):
        self._writer = None
        if self._handle is not None:
            self._handle.close()
            self._handle = None

    def grow(self, ngrow, blobs):
        super().grow(ngrow, blobs)
        self._writer = None           # the blobs dataset may have just been created

    def save_step(self, state, accepted):
        if self._handle is None:
            return super().save_step(state, accepted)
        if self._writer is None:
            self._writer = _StepWriter(self._handle[self.name])
        self._writer.write(state, accepted)
        self._handle.flush()


class _StepWriter:
    """emcee's HDFBackend.save_step (its checks, then the step's coordinates, log-probabilities,
    blobs, the acceptance counts, the random state and the iteration count) on an open group
    whose shape, datasets and counts are read once."""

    def __init__(self, g):
        self.g = g
        a = g.attrs
        self.shape = (int(a["nwalkers"]), int(a["ndim"]))
        self.has_blobs = bool(a["has_blobs"])
        self.iteration = int(a["iteration"])
        self.chain, self.log_prob = g["chain"], g["log_prob"]
        self.blobs = g["blobs"] if self.has_blobs else None
        self.accepted = g["accepted"]
        self.n_accepted = self.accepted[...]

    def write(self, state, accepted):
        nw, ndim = self.shape
        if state.coords.shape != (nw, ndim):
            raise ValueError(f"invalid coordinate dimensions; expected {(nw, ndim)}")
        if state.log_prob.shape != (nw,):
            raise ValueError(f"invalid log probability size; expected {nw}")
        if (state.blobs is not None) != self.has_blobs:
            raise ValueError("expected blobs, but none were given" if self.has_blobs
                             else "unexpected blobs")
        if state.blobs is not None and len(state.blobs) != nw:
            raise ValueError(f"invalid blobs size; expected {nw}")
        if accepted.shape != (nw,):
            raise ValueError(f"invalid acceptance size; expected {nw}")
        it = self.iteration
        self.chain[it] = state.coords
        self.log_prob[it] = state.log_prob
        if self.blobs is not None:
            self.blobs[it] = state.blobs
        self.n_accepted = self.n_accepted + accepted
        self.accepted[...] = self.n_accepted
        for i, v in enumerate(state.random_state):
            self.g.attrs[f"random_state_{i}"] = v
        self.g.attrs["iteration"] = it + 1
        self.iteration = it + 1


COORDS = ("frictionuq unbounded logit-of-box coordinates v2 (independence proposal v2, Johnson SU "
          "marginals, in attrs); "
          "blobs v3: per-record log-likelihood, then per-record residual statistics")


#: what reading a damaged HDF5 file raises (h5py's errors derive from these): such a chain is
#: started afresh; any other exception is a bug and is raised
UNREADABLE = (OSError, KeyError, ValueError, RuntimeError)


def open_backend(backend_path, nw, ndim, resume, log=None, key: str | None = None):
    """(backend, steps already stored). A stored chain is resumed only when it was written in the
    same coordinates (attribute `coordinates` of the backend's group), with the same shape, by
    the same run (attribute `run_key` equal to `key`, when one is given: the fit's configuration,
    priors and data; a chain of another seed or likelihood would otherwise be continued under
    the new one's name), and every stored array reads back: a process killed in the middle of an
    HDF5 write can leave a file whose metadata opens but whose data does not, and such a file is
    started afresh."""
    if backend_path is None:
        return None, 0
    backend_path = Path(backend_path)
    backend_path.parent.mkdir(parents=True, exist_ok=True)
    if backend_path.exists() and resume:
        try:
            be = OpenHDFBackend(str(backend_path))
            with be.open() as f:
                coords = f[be.name].attrs.get("coordinates", "")
                stored_key = f[be.name].attrs.get("run_key", "")
            if key is not None and stored_key != key and be.iteration > 0:
                if log is not None:
                    log(f"stored chain {backend_path.name} was made by another configuration or "
                        "data (seed, likelihood, priors, sampler, records): starting afresh")
            elif be.initialized and be.shape == (nw, ndim) and be.iteration > 0 and coords == COORDS:
                be.get_chain(), be.get_log_prob(), be.get_blobs(), be.get_last_sample()
                load_proposal(be)
                return be, int(be.iteration)
        except UNREADABLE as e:      # unreadable / corrupted file: start again
            if log is not None:
                log(f"stored chain {backend_path.name} unreadable ({type(e).__name__}: "
                    f"{' '.join(str(e).split())[:120]}): starting afresh")
    if backend_path.exists():
        backend_path.unlink()
    be = OpenHDFBackend(str(backend_path))
    be.reset(nw, ndim)
    with be.open("a") as f:
        f[be.name].attrs["coordinates"] = COORDS
        if key is not None:
            f[be.name].attrs["run_key"] = key
    return be, 0


def store_proposal(backend, proposal):
    if backend is None or proposal is None:
        return
    with backend.open("a") as f:
        for k, v in proposal.to_attrs().items():
            f[backend.name].attrs[k] = v


def load_proposal(backend):
    with backend.open() as f:
        a = f[backend.name].attrs
        if "proposal_marginals" not in a:
            return None
        return Proposal.from_attrs(a)


def store_count(backend, key: str, n: int) -> None:
    """Keep one of the fit's counts (restart's polishes, stuck's searches) in the chain file's
    attributes, so that a resumed fit goes on from it; no backend: nothing kept."""
    if backend is None:
        return
    with backend.open("a") as f:
        f[backend.name].attrs[key] = int(n)


def load_count(backend, key: str) -> int:
    """A count kept by store_count (0 when none was kept)."""
    if backend is None:
        return 0
    with backend.open() as f:
        return int(f[backend.name].attrs.get(key, 0))


def load_account(backend) -> dict:
    """The fit's bookkeeping over the sessions that wrote the chain so far (a resumed fit
    continues it): {burn_in_steps (the burn-in phase, run once before the stored run),
    evaluations, seconds, resumed_from: [the stored step each later session began at]}."""
    if backend is None:
        return {"burn_in_steps": 0, "evaluations": 0, "seconds": 0.0, "resumed_from": []}
    with backend.open() as f:
        a = f[backend.name].attrs
        return {"burn_in_steps": int(a.get("account_burn_in_steps", 0)),
                "evaluations": int(a.get("account_evaluations", 0)),
                "seconds": float(a.get("account_seconds", 0.0)),
                "resumed_from": [int(v) for v in a.get("account_resumed_from", [])]}


def store_account(backend, account: dict, package_version: str | None = None,
                  seed: int | None = None) -> None:
    """Write the bookkeeping (load_account's dict) and what made the chain into the file."""
    if backend is None:
        return
    with backend.open("a") as f:
        a = f[backend.name].attrs
        a["account_burn_in_steps"] = int(account["burn_in_steps"])
        a["account_evaluations"] = int(account["evaluations"])
        a["account_seconds"] = float(account["seconds"])
        a["account_resumed_from"] = np.asarray(account["resumed_from"], dtype=np.int64)
        if package_version is not None:
            a["frictionuq_version"] = package_version
        if seed is not None:
            a["seed"] = int(seed)
