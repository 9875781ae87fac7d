"""The sampler's settings (infer.sampler reads them; its module docstring says what each does):
one dataclass, checked at construction, so that a bad value from the CLI, a workflow's
[fit.sampler] table or Python is refused before any work."""
from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from numbers import Integral, Real

from ..errors import InputError


#: the stored run's two designs (SamplerConfig.stored_run; module docstring)
STORED_RUNS = ("chains", "ensemble")


@dataclass
class SamplerConfig:
    nwalkers: int | None = None       # default: max(32, 2 * ndim + 4) rounded up to even
    chunk: int = 500
    max_steps: int = 100000           # stored steps, after the burn-in phase
    min_steps: int = 1000
    burn_rounds: int = 2              # minimum burn-in rounds
    burn_max_rounds: int = 20         # more while the walkers still climb or some are stuck
    burn_steps: int = 250             # short rounds: the proposal is refitted (and widens) sooner
    burn_stable: float = 1.25         # ... and while the proposal still changes (proposal_change)
    burn_shift: float = 0.5
    discard_fraction: float = 0.25    # of the stored run, before the convergence checks
    de_gamma: float | None = None     # DE scale; None: 2.38 / sqrt(2 ndim) (emcee's default)
    tau_factor: float = 50.0
    tau_rtol: float = 0.05
    r_hat_max: float = 1.01
    ess_min: float = 400.0
    confirm_checks: int = 2           # the stopping rule must hold at this many checks in a row
    n_random_starts: int = 6
    n_prior_starts: int = 4
    n_global_starts: int = 2          # differential-evolution runs: at least this many; with 2+,
                                      # more until two agree (optimize._global_searches)
    independence: bool = True         # add the independence move fitted to the burn-in
    independence_weight: float = 0.8  # its share of the stored run's moves
    stored_run: str = "chains"        # "chains": run_walkers independent chains; "ensemble": the
                                      # burn-in's walkers with DE moves beside the independence move
    run_walkers: int = 16             # the chains' number
    temperatures: int = 1             # tempered copies of each chain (1: none; infer.tempering)
    temper_ratio: float | None = None  # the ladder's beta ratio; None: tempering.default_ratio
    start_profile: bool = True        # start ball from 1-D profiles (walkers.profile_sides)
    mode_search: bool | None = None   # proposal components on regions the burn-in visited and
                                      # its proposal misses (infer.modes); None: wherever the
                                      # independence move runs (the default since 2026-12-07,
                                      # stop 87), True: on (needs it), False: off
    mode_weight: float = 0.1          # their total weight in the independence move
    n_map_restarts: int = 1           # burn-in restarts when a chain climbs above the MAP
                                      # (infer.restart; 0: none)
    n_stored_searches: int = 2        # stored runs started again with proposal components where
                                      # stored chains stick (infer.stuck; with the mode search;
                                      # 0: none)
    thin_output: int | None = None    # default: about tau/4
    progress: bool | None = None      # default: on a terminal

    def __post_init__(self):
        """Refuse a setting no run can use (InputError naming it), at construction: from the
        CLI (--max-steps), a workflow's [fit.sampler] table or Python alike."""
        for f in fields(self):
            v, typ = getattr(self, f.name), str(f.type)
            if v is None and "None" in typ or typ.startswith("bool"):
                continue
            if f.name == "stored_run":
                if v not in STORED_RUNS:
                    raise InputError(f"sampler: stored_run must be one of {', '.join(STORED_RUNS)}, "
                                     f"got {v!r}")
                continue
            if typ.startswith("int"):
                low = 0 if f.name.startswith("n_") else 1
                if isinstance(v, bool) or not isinstance(v, Integral) or v < low:
                    raise InputError(f"sampler: {f.name} must be an integer >= {low}, got {v!r}")
            elif isinstance(v, bool) or not isinstance(v, Real) or not v > 0:   # NaN fails too
                raise InputError(f"sampler: {f.name} must be a number > 0 (inf: no limit), "
                                 f"got {v!r}")
        if not self.discard_fraction < 1:
            raise InputError(f"sampler: discard_fraction must be < 1, got {self.discard_fraction!r}")
        if not self.independence_weight <= 1:
            raise InputError(f"sampler: independence_weight must be in (0, 1], got "
                             f"{self.independence_weight!r}")
        if not self.mode_weight < 1:
            raise InputError(f"sampler: mode_weight must be in (0, 1), got {self.mode_weight!r}")
        if self.mode_search is True and not self.independence:
            raise InputError("sampler: mode_search needs the independence move (its components "
                             "are the independence proposal's); set independence = true")
        if self.temper_ratio is not None and not self.temper_ratio < 1:
            raise InputError(f"sampler: temper_ratio must be in (0, 1), got {self.temper_ratio!r}")
        if self.temperatures > 1 and not (self.stored_run == "chains" and self.independence):
            raise InputError("sampler: temperatures > 1 needs stored_run = \"chains\" with the "
                             "independence move (tempering wraps its Metropolis-Hastings moves)")
        if self.run_walkers < 4:
            raise InputError(f"sampler: run_walkers must be >= 4 (R-hat compares chains), got "
                             f"{self.run_walkers!r}")

    @property
    def searches_modes(self) -> bool:
        """Whether the burn-in runs the mode search (mode_search None: wherever the independence
        move runs, whose proposal its components join)."""
        return self.independence and self.mode_search is not False

    def to_json(self) -> dict:
        return asdict(self)
