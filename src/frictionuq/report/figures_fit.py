"""Figures of one fit: residuals, the corner plot of the model parameters and the rank plot of
the walkers (PNG bytes, see report.figures)."""
from __future__ import annotations

import numpy as np

from .. import params as P
from .. import units
from .figures import DPI, KN, MM, WIDTH, decimate, plt, png

MAX_CORNER_DRAWS = 2000
MAX_RANK_PARAMS = 16


def residual_figure(per_test: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]], title: str) -> bytes:
    """Data minus the predictive median (kN) against time (s) and displacement (mm), one colour
    per test; per_test: (test id, t, x, residual) in SI."""
    pyplot = plt()
    fig, (a1, a2) = pyplot.subplots(1, 2, figsize=(WIDTH, 3.2), gridspec_kw={"width_ratios": [1.6, 1]})
    for k, (tid, t, x, r) in enumerate(per_test):
        t, x, r = decimate(t, x, r)
        a1.plot(t, r * KN, lw=0.6, color=f"C{k % 10}", label=tid)
        a2.plot(x * MM, r * KN, lw=0.4, color=f"C{k % 10}", label=tid)
    for ax, xl in ((a1, "time (s)"), (a2, "displacement (mm)")):
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_xlabel(xl)
        ax.set_ylabel("residual: data - median (kN)")
        ax.grid(alpha=0.3)
    a1.set_title("residual against time", fontsize=9)
    a2.set_title("residual against displacement", fontsize=9)
    a1.legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return png(fig)


def corner_columns(draws: dict[str, np.ndarray]) -> tuple[np.ndarray, list[str]]:
    """(samples (M, k), axis labels) for the corner plot, in the parameter table's display units
    (kN, mm, mm/s, kN/mm, kN s/m: units.display): log10 of positive parameters that span orders of
    magnitude (log-scale parameters, or values above 1e3 in that unit); at most MAX_CORNER_DRAWS
    draws (evenly thinned)."""
    cols, labels = [], []
    for n, v in draws.items():
        meta = P.PARAMS.get(n)
        unit, fac = units.display(meta.unit if meta else "?")
        v = np.asarray(v, float).ravel() * fac
        positive = bool(np.all(v > 0))
        if positive and ((meta is not None and meta.log_scale) or np.max(v) > 1e3):
            cols.append(np.log10(v))
            labels.append(f"log10 {n}\n({unit})")
        else:
            cols.append(v)
            labels.append(f"{n}\n({unit})")
    X = np.column_stack(cols)
    step = max(1, -(-X.shape[0] // MAX_CORNER_DRAWS))
    return X[::step], labels


def corner_figure(draws: dict[str, np.ndarray], title: str) -> bytes:
    """Corner plot (package `corner`) of the named posterior draws; constant columns get a
    small range so that corner accepts them."""
    import corner
    pyplot = plt()
    X, labels = corner_columns(draws)
    k = X.shape[1]
    ranges = []
    for j in range(k):
        lo, hi = float(np.min(X[:, j])), float(np.max(X[:, j]))
        if not hi > lo:
            pad = max(abs(lo) * 1e-3, 1e-12)
            lo, hi = lo - pad, hi + pad
        ranges.append((lo, hi))
    size = min(WIDTH, max(5.0, 0.85 * k))
    fig = pyplot.figure(figsize=(size, size))
    import logging
    logging.disable(logging.WARNING)   # corner's "Too few points to create valid contours" (a
    try:                               # short run's panels show their points without contours)
        fig = corner.corner(X, labels=labels, range=ranges, fig=fig, bins=20, smooth=None,
                            quantiles=[0.025, 0.5, 0.975], show_titles=False,
                            label_kwargs={"fontsize": 7}, plot_datapoints=True,
                            data_kwargs={"alpha": 0.15, "ms": 1.0}, max_n_ticks=2, labelpad=0.12)
    finally:
        logging.disable(logging.NOTSET)
    for ax in fig.axes:
        ax.tick_params(labelsize=6)
    fig.subplots_adjust(top=0.92, bottom=0.1, left=0.1, right=0.98)
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color="k", lw=1, label="posterior draws: 1-D histograms, 2-D densities"),
               Line2D([], [], color="k", ls="--", lw=1, label="2.5, 50, 97.5 % quantiles")]
    fig.legend(handles=handles, loc="upper right", fontsize=8, frameon=False)
    fig.suptitle(f"{title}\n{X.shape[0]} posterior draws; wide-ranging parameters as log10; "
                 "units as in the parameter table", fontsize=10, x=0.02, ha="left")
    return png(fig)


RANK_CHAINS = 8


def rank_figure(dt, names: list[str], title: str, max_chains: int = RANK_CHAINS) -> bytes:
    """Rank plot (ArviZ, through frictionuq.azadapter) of the first `max_chains` chains (the
    stored run's independent chains, or its ensemble's walkers)."""
    from .. import azadapter
    names = list(names)[:MAX_RANK_PARAMS]
    fig = azadapter.rank_figure(dt, names, max_chains=max_chains)
    ncols = 4
    rows = -(-len(names) // ncols)
    fig.set_size_inches(WIDTH, 1.0 + 1.9 * rows)
    for ax in fig.axes:
        ax.tick_params(labelsize=7)
        if ax.get_xlabel():
            ax.set_xlabel("fractional rank (dimensionless)", fontsize=7)
            ax.set_ylabel("ECDF minus uniform", fontsize=7)
        ax.title.set_fontsize(8)
    fig.suptitle(f"{title}\nrank ECDF minus uniform per chain (first {max_chains} chains; "
                 "a well-mixed chain stays inside the envelope)", fontsize=10)
    try:
        fig.set_layout_engine("constrained")
    except Exception:      # a figure with a fixed layout engine: keep ArviZ's own
        pass
    return png(fig, dpi=DPI)
