"""HTML tables for the ``_repr_html_`` of result objects (Jupyter shows them instead of the
dataclass ``repr``). Plain strings, escaped; no plotting (the numerics layer draws nothing)."""

import html
import math


def number(value, digits=4):
    """``value`` with ``digits`` significant digits; an em dash for None or a non-finite one."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value:.{digits}g}" if isinstance(value, float) else str(value)


def html_table(header, rows, caption=None):
    """An HTML table: ``header`` cells, ``rows`` of cells (every cell escaped)."""
    e = html.escape
    cap = f"<caption style='text-align:left'><b>{e(caption)}</b></caption>" if caption else ""
    head = "".join(f"<th>{e(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"
