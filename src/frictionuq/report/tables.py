"""HTML tables and number formatting of the report. Cells are escaped unless they are
`markupsafe.Markup`; every table sits in a horizontally scrollable wrapper so a wide table never
widens the page."""
from __future__ import annotations

import math
from typing import Iterable, Sequence

from markupsafe import Markup, escape

DASH = "\u2013"


def num(v, digits: int = 4) -> str:
    """A number with `digits` significant digits; '-' for None / NaN / non-numbers."""
    if v is None or isinstance(v, bool):
        return DASH if v is None else ("yes" if v else "no")
    try:
        f = float(v)
    except (TypeError, ValueError):
        return str(v)
    if not math.isfinite(f):
        return DASH if math.isnan(f) else ("inf" if f > 0 else "-inf")
    if f == 0:
        return "0"
    if 10 ** digits <= abs(f) < 1e7:
        return f"{f:.0f}"          # e.g. 28698 samples, 13001 N: all integer digits
    if 1e-3 <= abs(f) < 10 ** digits:
        return f"{f:.{digits}g}"
    return f"{f:.{max(digits - 1, 1)}e}"


def scaled(v, factor: float, digits: int = 4) -> str:
    """num(v * factor), '-' when v is missing."""
    try:
        return num(None if v is None else float(v) * factor, digits)
    except (TypeError, ValueError):
        return DASH


def interval(lo, hi, digits: int = 4, factor: float = 1.0) -> str:
    """'[lo, hi]' (scaled by factor), '-' when either end is missing."""
    a, b = scaled(lo, factor, digits), scaled(hi, factor, digits)
    return DASH if DASH in (a, b) else f"[{a}, {b}]"


def pct(v, digits: int = 1) -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return DASH
    return f"{100 * f:.{digits}f} %" if math.isfinite(f) else DASH


def cell(v) -> Markup:
    if isinstance(v, Markup):
        return v
    if isinstance(v, int) and not isinstance(v, bool):
        return escape(str(v))
    if isinstance(v, float):
        return escape(num(v))
    return escape(DASH if v is None else str(v))


def nowrap(text) -> Markup:
    """A cell kept on one line (ids, ranges)."""
    return Markup('<span class="nw">{}</span>').format(text)


def badge(text: str, ok: bool) -> Markup:
    """A coloured yes/no label."""
    return Markup('<span class="badge {}">{}</span>').format("ok" if ok else "bad", text)


def table(columns: Sequence[str], rows: Iterable[Sequence], *, caption: str | None = None,
          cls: str = "", row_classes: Sequence[str] | None = None, tid: str | None = None) -> Markup:
    """An HTML table (header `columns`, one row per item of `rows`) in a scrolling wrapper."""
    rows = list(rows)
    out = [Markup('<div class="table-wrap"><table class="{}"{}>').format(
        cls, Markup(' id="{}"').format(tid) if tid else "")]
    if caption:
        out.append(Markup("<caption>{}</caption>").format(caption))
    out.append(Markup("<thead><tr>"))
    out += [Markup("<th>{}</th>").format(c) for c in columns]
    out.append(Markup("</tr></thead><tbody>"))
    for i, r in enumerate(rows):
        rc = row_classes[i] if row_classes and i < len(row_classes) and row_classes[i] else ""
        out.append(Markup('<tr class="{}">').format(rc) if rc else Markup("<tr>"))
        out += [Markup("<td>{}</td>").format(cell(v)) for v in r]
        out.append(Markup("</tr>"))
    out.append(Markup("</tbody></table></div>"))
    return Markup("").join(out)


def kv_table(pairs: Iterable[tuple[str, object]], caption: str | None = None) -> Markup:
    """A two-column table: name, value."""
    return table(["item", "value"], [[k, v] for k, v in pairs], caption=caption, cls="kv")


def bullet_list(items: Iterable) -> Markup:
    return Markup("<ul>{}</ul>").format(Markup("").join(Markup("<li>{}</li>").format(cell(i))
                                                         for i in items))
