"""The stored run in chunks (infer.sampler runs it): after every `chunk` steps the checks of the
MAP (infer.restart) and of stuck chains (infer.stuck), then the stopping rule (infer.convergence:
tau, R-hat and ESS, held at `confirm_checks` checks in a row), until the rule holds or the step
cap. A resumed run first replays the stored chain's last checks, so that it checks and stops
where the uninterrupted run would. The sampler module's docstring says why each piece is there."""
from __future__ import annotations

import numpy as np

from .burnin import progress_bar, run_steps
from .convergence import check, replay, rule_met
from .tempering import swap_rates


def cold_walkers(cfg, n_walkers: int) -> slice:
    """The stored run's walkers that sample the posterior: all, or with tempering the first
    run_walkers (level beta = 1; infer.tempering)."""
    return slice(0, cfg.run_walkers if cfg.temperatures > 1 else n_walkers)


def run_chunks(sampler, state, cfg, sp, n_done, history, log, intr=None, moves=(),
               map_check=None, stuck_check=None):
    """The stored run in chunks until the convergence criteria or the step cap. The checks fall
    on multiples of `chunk` stored steps; a resumed run (n_done > 0) first replays the stored
    chain's checks (convergence.replay) to restore the rule's state (the last max tau and the
    checks in a row it held at), so that it checks and stops where the uninterrupted run would.
    With `map_check` (restart.MapCheck), each chunk's states are also checked against the MAP:
    returns (steps, converged, None), or (steps, False, (theta, log-posterior, how)) at once when
    the check finds a point above it; with `stuck_check` (stuck.StuckCheck), (steps, False,
    Proposal) at once when chains stick where the proposal underweights the posterior and the
    search adds components."""
    cold = cold_walkers(cfg, sampler.nwalkers)
    prev_tau, passes = _replayed(sampler, cfg, sp, cold, n_done, log)
    converged = passes >= cfg.confirm_checks
    while n_done < cfg.max_steps and not converged:
        n = min(cfg.chunk - n_done % cfg.chunk, cfg.max_steps - n_done)
        run_steps(sampler, state, n, progress=progress_bar(cfg), intr=intr)
        state = None
        chunk_start, n_done = n_done, int(sampler.iteration)
        found = map_check(sampler, cold, chunk_start) if map_check is not None else None
        if found is None and stuck_check is not None:
            found = stuck_check(sampler, cold, chunk_start)
        if found is not None:
            return n_done, False, found
        if n_done < cfg.min_steps:
            continue
        burn = int(n_done * cfg.discard_fraction)
        c = check(sampler.get_chain(discard=burn)[:, cold], cfg, sp)
        h = {"steps": n_done, "tau_max": c["tau_max"],
             "acceptance": float(np.mean(sampler.acceptance_fraction[cold])),
             "r_hat_max": c["r_hat_max"], "ess_min": c["ess_min"],
             "worst": sp.names[int(np.argmax(c["r_hat"]))]}
        rates = swap_rates(moves)
        if rates is not None:
            h["swap_acceptance"] = [float(r) for r in rates]
        history.append(h)
        log(f"step {n_done}: max tau {c['tau_max']:.1f} steps, R-hat max {h['r_hat_max']:.3f} "
            f"({h['worst']}), ESS min {h['ess_min']:.0f}, acceptance {h['acceptance']:.2f}"
            + ("" if rates is None else ", swaps accepted " + " / ".join(f"{r:.2f}" for r in rates)))
        met = rule_met(c, prev_tau, n_done - burn, cfg)
        prev_tau = c["tau_max"]
        passes = passes + 1 if met else 0
        h["rule_met"] = bool(met)
        if met and passes < cfg.confirm_checks and n_done < cfg.max_steps:
            log(f"step {n_done}: stopping rule met ({passes} of {cfg.confirm_checks} checks in a "
                f"row); running {min(cfg.chunk, cfg.max_steps - n_done)} more steps to confirm")
        converged = passes >= cfg.confirm_checks
    return n_done, converged, None


def _replayed(sampler, cfg, sp, cold, n_done, log) -> tuple[float | None, int]:
    """The stopping rule's state after the first `n_done` stored steps (a resumed run): the max
    tau of the last check and the checks in a row the rule held at, replayed on the stored
    chain; (None, 0) for a fresh run. Only the last confirm_checks + 1 checks are replayed: the
    first of them gives the previous tau, and a longer run of passes than confirm_checks
    changes nothing (a long chain has hundreds of checks, each a few tenths of a second)."""
    if not n_done:
        return None, 0
    last_check = n_done - n_done % cfg.chunk
    rows = replay(sampler.get_chain()[:n_done, cold], cfg, sp,
                  from_step=last_check - cfg.confirm_checks * cfg.chunk)
    if not rows:
        return None, 0
    last = rows[-1]
    log(f"stopping rule replayed on the {n_done} stored steps ({len(rows)} checks up to step "
        f"{last['steps']}: max tau {last['tau_max']:.1f} steps, R-hat max "
        f"{last['r_hat_max']:.3f}, ESS min {last['ess_min']:.0f}); held at the last "
        f"{last['in_a_row']} in a row")
    return last["tau_max"], last["in_a_row"]
