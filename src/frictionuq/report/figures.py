"""Figure helpers of the report: matplotlib (Agg) figures to PNG bytes and data URIs, decimation
of long records, and posterior bands drawn along a time axis or along a loop.

Every figure of the report goes through `png()`: saved at `DPI` and closed, so a long report
never keeps figures alive. Plots are in display units (kN, mm, mm/s, s), converted here from the
SI arrays the package writes.
"""
from __future__ import annotations

import base64
import io
import math

import numpy as np

from ..environment import png_metadata

DPI = 90
WIDTH = 11.0                 # inches: 990 px at DPI, the report's content width
MAX_POINTS = 5000            # at most this many points per plotted line
KN, MM = 1e-3, 1e3           # SI -> display factors: N -> kN, m -> mm (and m/s -> mm/s)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

BAND95 = dict(color="C0", alpha=0.22)
BAND50 = dict(color="C0", alpha=0.45)


def plt():
    """matplotlib.pyplot with the Agg backend (no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot


def png(fig, dpi: int = DPI) -> bytes:
    """The figure as PNG bytes; the figure is closed in any case."""
    pyplot = plt()
    try:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi, metadata=png_metadata())
        return buf.getvalue()
    finally:
        pyplot.close(fig)


def data_uri(png_bytes: bytes) -> str:
    if not png_bytes.startswith(PNG_SIGNATURE):
        raise ValueError("not PNG data")
    return "data:image/png;base64," + base64.b64encode(png_bytes).decode("ascii")


def stride(n: int, max_points: int = MAX_POINTS) -> int:
    """Slicing step that leaves at most `max_points` of `n` samples."""
    return max(1, math.ceil(n / max_points))


def decimate(*arrays, max_points: int = MAX_POINTS):
    """Every array sliced with the same step (at most `max_points` samples each)."""
    n = len(arrays[0])
    s = stride(n, max_points)
    return tuple(None if a is None else np.asarray(a)[::s] for a in arrays)


def velocity(t, x) -> np.ndarray:
    """Central-difference velocity (units of x per s)."""
    t, x = np.asarray(t, float), np.asarray(x, float)
    if t.size < 2:
        return np.zeros_like(x)
    return np.gradient(x, t)


def band_along_time(ax, t, lo, hi, label, **style):
    ax.fill_between(t, lo, hi, lw=0, label=label, **style)


def band_along_path(ax, u, lo, hi, label, **style):
    """A band over a path that is not monotone in u (a hysteresis loop): one vertical segment
    per sample from lo to hi, which renders as a shaded band following the loop."""
    from matplotlib.collections import LineCollection
    u = np.asarray(u, float)
    segs = np.stack([np.column_stack([u, lo]), np.column_stack([u, hi])], axis=1)
    lc = LineCollection(segs, linewidths=1.2, label=label, **style)
    ax.add_collection(lc)
    ax.update_datalim(np.vstack([np.column_stack([u, lo]), np.column_stack([u, hi])]))
    ax.autoscale_view()


def quantile_bands(samples: np.ndarray) -> dict:
    """Pointwise 2.5/25/50/75/97.5 % of draws (S, N) as the keys of `band_panels`."""
    q = np.percentile(np.asarray(samples, float), [2.5, 25, 50, 75, 97.5], axis=0)
    return {"lo95": q[0], "lo50": q[1], "median": q[2], "hi50": q[3], "hi95": q[4]}


def band_panels(t, x, bands: dict, *, measured=None, title: str, panels=("fx", "fv", "ft"),
                median_label: str = "posterior predictive median", height: float = 3.4) -> bytes:
    """Force against displacement, velocity and/or time (panels "fx", "fv", "ft"), in kN, mm,
    mm/s and s, with the 95 % and 50 % bands, the median and the measured force (all SI
    arrays of one record; `bands` with keys lo95, lo50, median, hi50, hi95)."""
    pyplot = plt()
    keys = ("lo95", "lo50", "median", "hi50", "hi95")
    t, x = np.asarray(t, float), np.asarray(x, float)
    v = velocity(t, x)
    arrs = decimate(t, x, v, None if measured is None else np.asarray(measured, float),
                    *[np.asarray(bands[k], float) for k in keys])
    t, x, v, y = arrs[:4]
    b = {k: a * KN for k, a in zip(keys, arrs[4:])}
    y = None if y is None else y * KN
    widths = [1.0 if p != "ft" else 1.6 for p in panels]
    fig, axes = pyplot.subplots(1, len(panels), figsize=(WIDTH, height),
                                gridspec_kw={"width_ratios": widths})
    axes = np.atleast_1d(axes)
    for ax, p in zip(axes, panels):
        if p == "ft":
            u, xlabel, along = t, "time (s)", band_along_time
        else:
            u = x * MM if p == "fx" else v * MM
            xlabel = "displacement (mm)" if p == "fx" else "velocity (mm/s)"
            along = band_along_path
        along(ax, u, b["lo95"], b["hi95"], "95 % band", **BAND95)
        along(ax, u, b["lo50"], b["hi50"], "50 % band", **BAND50)
        if y is not None:
            ax.plot(u, y, color="k", lw=0.6, label="measured")
        ax.plot(u, b["median"], color="C3", lw=0.9, label=median_label)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("force (kN)")
        ax.set_title({"fx": "force-displacement", "fv": "force-velocity",
                      "ft": "force-time"}[p], fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return png(fig)
