"""How an FE result shows itself: a short text repr and, in Jupyter, an HTML table of its fields.

:class:`Displayed` is mixed into the results a user gets (:class:`~fe.response.Response`,
:class:`~fe.solvers.nonlinear.PathResult`, ...): ``repr`` is a few lines — the class name and a
summary of each field (a number, a short string, an array's shape and dtype, a table's length),
never a whole array — and at most :data:`MAX_REPR` characters; ``_repr_html_`` is a table of the
same summaries, every cell escaped. ``podkrig`` builds its results' display on these helpers.
"""

import dataclasses
import html
import math

import numpy as np

#: the longest text repr, characters
MAX_REPR = 600


def summary(value, width=60):
    """``value`` in a few characters: numbers with 4 significant digits (positional from 0.001 to
    10⁷: 20000, not 2e+04), strings cut to ``width``,
    arrays as shape and dtype (their values when they have at most 4), sequences and mappings by
    length (their items when short), other objects by class name."""
    if value is None or isinstance(value, (bool, np.bool_)):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value) or not (value == 0 or 1e-3 <= abs(value) < 1e7):
            return f"{value:.4g}"
        return np.format_float_positional(value, precision=4, unique=True, fractional=False, trim="-")
    if isinstance(value, str):
        return repr(value) if len(value) <= width else repr(value[:width - 1] + "…")
    if isinstance(value, np.ndarray):
        if value.size <= 4 and value.dtype.kind in "biuf":
            return "[" + ", ".join(summary(v) for v in value.ravel().tolist()) + "]"
        return f"array{value.shape} {value.dtype}"
    if isinstance(value, (list, tuple)):
        text = "(" + ", ".join(summary(v, 20) for v in value[:6]) + ")"
        if len(value) <= 6 and len(text) <= width:
            return text
        return f"{len(value)} items"
    if isinstance(value, dict):
        text = "{" + ", ".join(f"{k}: {summary(v, 20)}" for k, v in list(value.items())[:6]) + "}"
        if len(value) <= 6 and len(text) <= width:
            return text
        keys = ", ".join(str(k) for k in list(value)[:4])
        return f"{len(value)} entries ({keys}{', …' if len(value) > 4 else ''})"
    return type(value).__name__


def bounded(lines, limit=MAX_REPR):
    """``lines`` joined by newlines, cut to at most ``limit`` characters at a line end (``…`` and
    the number of lines left out when cut)."""
    text = ""
    for i, line in enumerate(lines):
        line = line if len(line) <= 120 else line[:119] + "…"
        candidate = line if i == 0 else text + "\n" + line
        tail = f"\n  … {len(lines) - i} more lines"
        if len(candidate) + (len(tail) if i < len(lines) - 1 else 0) > limit:
            return (text + tail)[:limit]
        text = candidate
    return text


def field_lines(obj, fields=None):
    """``name: summary`` lines of the dataclass fields ``fields`` of ``obj`` (all when None)."""
    names = fields if fields is not None else [f.name for f in dataclasses.fields(obj)]
    return [f"  {name}: {summary(getattr(obj, name))}" for name in names]


def fields_html(obj):
    """A table of the dataclass fields of ``obj`` and their :func:`summary`, captioned with its
    class name (every cell escaped)."""
    e = html.escape
    rows = "".join(f"<tr><td>{e(f.name)}</td><td>{e(summary(getattr(obj, f.name)))}</td></tr>"
                   for f in dataclasses.fields(obj))
    return (f"<table><caption style='text-align:left'><b>{e(type(obj).__name__)}</b></caption>"
            f"<thead><tr><th>field</th><th>value</th></tr></thead><tbody>{rows}</tbody></table>")


class Displayed:
    """Mixin of the result objects: a bounded text repr and Jupyter's ``_repr_html_`` (module
    docstring). A dataclass that mixes it in is declared with ``repr=False`` (else the dataclass
    writes its own repr); a class lists the fields worth a line in ``_repr_fields`` (all when None)
    or writes its own :meth:`_repr_lines`."""

    _repr_fields = None

    def _repr_lines(self):
        """The lines of the text repr: the class name, then one line per field."""
        return [type(self).__name__, *field_lines(self, self._repr_fields)]

    def __repr__(self):
        return bounded(self._repr_lines())

    def _repr_html_(self):
        return fields_html(self)


__all__ = ["MAX_REPR", "Displayed", "bounded", "field_lines", "fields_html", "summary"]
