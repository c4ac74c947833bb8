"""A minimal self-contained HTML page writer for podkrig reports (no template engine).

A :class:`Page` collects sections of headings, paragraphs, warnings (with what to do), tables
(numbers with units in the headers) and figures (PNG files beside ``index.html``); ``write``
produces one HTML file with inline CSS.
"""

import html
from pathlib import Path

import numpy as np

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em;border-bottom:2px solid #444}h2{font-size:1.25em;margin-top:2em;border-bottom:1px solid #bbb}
table{border-collapse:collapse;margin:1em 0;font-size:.92em}th,td{border:1px solid #ccc;padding:.3em .6em;text-align:left}
th{background:#f0f0f0}td.num{text-align:right;white-space:nowrap}
figure{margin:1em 0}figure img{max-width:100%;border:1px solid #ddd}figcaption{font-size:.9em;color:#555}
.warn{background:#fff4e0;border-left:4px solid #e69500;padding:.6em 1em;margin:1em 0}
.ok{background:#eaf6ea;border-left:4px solid #3a3;padding:.6em 1em;margin:1em 0}
.meta{color:#666;font-size:.85em}
"""


def _e(text):
    return html.escape(str(text))


class Page:
    """An HTML report page.

    Parameters
    ----------
    title : str
    """

    def __init__(self, title):
        self.title = title
        self._parts = []

    def heading(self, text, level=2, anchor=None):
        a = f' id="{_e(anchor)}"' if anchor else ""
        self._parts.append(f"<h{level}{a}>{_e(text)}</h{level}>")

    def paragraph(self, text, css_class=None):
        c = f' class="{css_class}"' if css_class else ""
        self._parts.append(f"<p{c}>{_e(text)}</p>")

    def warning(self, what, remedy):
        """A warning in plain words and what to do about it."""
        self._parts.append(f'<div class="warn"><b>Warning:</b> {_e(what)}<br><b>What to do:</b> {_e(remedy)}</div>')

    def success(self, text):
        self._parts.append(f'<div class="ok">{_e(text)}</div>')

    def table(self, header, rows, caption=None):
        """A table; ``header`` are column titles (with units), ``rows`` lists of cells."""
        cap = f"<caption>{_e(caption)}</caption>" if caption else ""
        head = "".join(f"<th>{_e(h)}</th>" for h in header)
        body = "".join("<tr>" + "".join(_cell(c) for c in row) + "</tr>" for row in rows)
        self._parts.append(f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>")

    def details(self, summary, text):
        """A collapsed block of preformatted text (e.g. the JSON behind the page)."""
        self._parts.append(f"<details><summary>{_e(summary)}</summary><pre>{_e(text)}</pre></details>")

    def links(self, entries):
        """A list of links, ``entries`` of (href, text): ``"#anchor"`` for a section of this page,
        or a path relative to the page."""
        items = "".join(f'<li><a href="{_e(href)}">{_e(text)}</a></li>' for href, text in entries)
        self._parts.append(f"<ul>{items}</ul>")

    def fragment(self, markup):
        """Trusted markup built by podkrig's own report code (e.g. an inline SVG with its script,
        :mod:`podkrig.reports.step_slider`); inserted as is, not escaped."""
        self._parts.append(markup)

    def figure(self, filename, caption):
        """A figure already saved beside the page (``filename`` relative to the page)."""
        self._parts.append(f'<figure><img src="{_e(filename)}" alt="{_e(caption)}"><figcaption>{_e(caption)}</figcaption></figure>')

    def markup(self):
        """The page's body so far, as an HTML fragment."""
        return "\n".join(self._parts)

    def write(self, path):
        """Write the page to ``path`` (its folder is created); returns the path."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        body = "\n".join(self._parts)
        path.write_text(
            f"<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{_e(self.title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{_e(self.title)}</h1>\n{body}\n</body></html>\n",
            encoding="utf-8",
        )
        return path


def _cell(value):
    """A table cell; numbers (and [low, high] intervals) are right-aligned."""
    text = str(value)
    numeric = isinstance(value, (int, float)) or text.lstrip("[-+").replace(".", "", 1)[:1].isdigit()
    return f'<td class="num">{_e(text)}</td>' if numeric else f"<td>{_e(text)}</td>"


def fmt(value, digits=4):
    """A number for a table: 4 significant digits, or the text as is."""
    if isinstance(value, (int, float)):
        return f"{value:.{digits}g}"
    return str(value)


def num(value, digits=4):
    """A number for a table: ``digits`` significant digits, no exponent below 10⁶ (``15934``, not
    ``1.593e+04``, so that the two ends of an interval read alike), an em dash for a missing or
    non-finite one."""
    if value is None or (isinstance(value, float) and not np.isfinite(value)):
        return "—"
    text = fmt(value, digits)
    return f"{value:.0f}" if "e+" in text and abs(value) < 1e6 else text


def pct(value, digits=3):
    """A share (-) in per cent for a table, ``digits`` significant digits; an em dash for a missing
    or non-finite one."""
    return "—" if value is None or not np.isfinite(value) else f"{100 * value:.{digits}g}"


def unit_cell(unit):
    """A unit for a table's unit column: ``-`` for a dimensionless one."""
    return "-" if not unit else unit
