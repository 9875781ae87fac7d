"""Where a fit's stored chains sit in one parameter, and how sticky the independence move is
there (docs/log-calibration.md, 2026-12-06, evening: d3's second mode on dataset 2).

    .venv/bin/python benchmarks/chain_modes.py FIT_DIR/<fit> --param d3 --above 6.1e-3
        [--start 1000]

Reads <fit>/chain.h5 (the stored run; with tempering only the cold chains, the first
`run_walkers` walkers) and <fit>/fit.json (the sampling space). Prints, per chain, the fraction
of its stored steps from --start on with PARAM above the value (SI) and how many times it
entered that region; then the log importance weight log p(x) - log q(x) of the independence
proposal stored with the run (with mode components, the mixture's), for the states above and
below, relative to the median below.
Where the weights above are e^k higher, an independence proposal from there back below is
accepted about e^-k of the time, and a chain that gets there stays.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import h5py
import numpy as np

from frictionuq.infer.proposal import Proposal
from frictionuq.infer.space import Space


def cold_states(fit: Path, param: str, above: float, start: int):
    """A stored run's cold chains and where PARAM > above lies in their coordinate: (column j,
    edge in u, chain (steps, chains, D), log_prob (steps, chains), its stored Proposal, the last
    step). Exits 2 with one line for a parameter the region cannot be read of."""
    rec = json.loads((fit / "fit.json").read_text())
    sp = Space.from_json(rec["space"])
    if param not in sp.names:
        print(f"{Path(sys.argv[0]).stem}: {param!r} is not a free parameter of this fit "
              f"({', '.join(sp.names)})", file=sys.stderr)
        sys.exit(2)
    j = sp.names.index(param)
    if sp.priors[param].ratio_of:
        print(f"{Path(sys.argv[0]).stem}: {param}'s prior is relative to "
              f"{sp.priors[param].ratio_of}; give another parameter", file=sys.stderr)
        sys.exit(2)
    theta = 0.5 * (sp.lo + sp.hi)
    theta[j] = np.log(above) if sp.log[j] else above
    edge = float(sp.to_u(theta)[j])        # the region's edge in the chain's coordinate
    with h5py.File(fit / "chain.h5", "r") as f:
        g = f["mcmc"]
        n = int(g.attrs["iteration"])
        cold = int(rec["config"]["sampler"]["run_walkers"])
        chain = g["chain"][start:n, :cold, :]
        logp = g["log_prob"][start:n, :cold]
        proposal = Proposal.from_attrs(dict(g.attrs))
    return j, edge, chain, logp, proposal, n


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("fit", help="one fit's folder (chain.h5 and fit.json)")
    ap.add_argument("--param", required=True, help="a free parameter (spec name)")
    ap.add_argument("--above", type=float, required=True, help="the region's lower edge (SI)")
    ap.add_argument("--start", type=int, default=1000, help="first stored step read")
    a = ap.parse_args(argv)
    fit = Path(a.fit)
    j, edge, chain, logp, proposal, n = cold_states(fit, a.param, a.above, a.start)
    cold = chain.shape[1]
    move = proposal.move()       # with mode components (--mode-search) their mixture
    inside = chain[:, :, j] > edge
    print(f"{fit}: steps {a.start}-{n}, {cold} chains; {a.param} > {a.above:g} "
          f"(u > {edge:.2f}) in {inside.mean():.1%} of the draws")
    for c in range(cold):
        entries = int(np.sum(np.diff(inside[:, c].astype(int)) == 1))
        print(f"  chain {c:2d}: {inside[:, c].mean():6.1%} of its steps, entered {entries} times")
    x = chain[::5].reshape(-1, chain.shape[2])
    lw = logp[::5].reshape(-1) - move.logq(x)
    up = x[:, j] > edge
    ref = np.median(lw[~up])
    for name, sel in (("below", ~up), ("above", up)):
        if sel.any():
            q = np.percentile(lw[sel] - ref, [5, 50, 95, 99])
            print(f"  log importance weight {name}: 5/50/95/99 % points "
                  + " / ".join(f"{v:+.1f}" for v in q) + f" ({int(sel.sum())} states)")


if __name__ == "__main__":
    main()
