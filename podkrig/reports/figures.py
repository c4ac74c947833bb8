"""Matplotlib for report figures: the non-interactive Agg backend, imported only when drawing
(``matplotlib.pyplot`` takes ≈ 0.5 s to import on an idle core, more than the rest of a report
module; commands that draw nothing do not pay it), and :func:`save`, which every report figure
goes through.

:func:`save` writes the PNG with a description of its panels in a PNG text chunk
(``podkrig:panels``, JSON; :func:`describe`): per panel its title, axis labels and scales, whether
it draws anything, whether it holds a colour-mapped artist and whether that has a colour bar. The
structural report test (``tests/test_report_structure.py``) reads it back with :func:`read_panels`
to check every figure of a generated report without re-running the drawing code.
"""

import json

import numpy as np

PANELS_KEY = "podkrig:panels"


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (unless the user already chose one)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _is_colourbar(ax):
    return hasattr(ax, "_colorbar") or ax.get_label() == "<colorbar>"


def _colour_mapped(ax):
    """Artists of ``ax`` whose colours come from a colour map (scatter with ``c=``, images,
    collections with an array)."""
    out = []
    for artist in list(ax.collections) + list(ax.images):
        array = artist.get_array() if hasattr(artist, "get_array") else None
        if array is not None and np.size(array) > 0:
            out.append(artist)
    return out


def _draws_something(ax):
    """Whether ``ax`` shows data: a line in data coordinates (reference lines such as ``axvline``
    do not count), a bar of non-zero size, a non-empty collection or an image; a panel with its
    axes switched off counts when it holds text (a text box)."""
    from matplotlib.patches import Rectangle  # matplotlib is imported by the figure being described

    lines = [ln for ln in ax.lines if ln.get_transform() == ax.transData and len(ln.get_xdata())]
    patches = [pt for pt in ax.patches
               if not isinstance(pt, Rectangle) or (pt.get_width() != 0 and pt.get_height() != 0)]
    collections = [c for c in ax.collections if len(c.get_paths()) or len(c.get_offsets())]
    if lines or patches or collections or ax.images:
        return True
    return not ax.axison and any(t.get_text().strip() for t in ax.texts)


def describe(fig):
    """The panels of ``fig`` (colour bars excluded), each a dict: ``title``, ``xlabel``,
    ``ylabel``, ``xscale``, ``yscale``, ``empty`` (visible but draws nothing), ``colour_mapped``
    (holds a colour-mapped artist), ``colourbar`` (one of its colour-mapped artists, or a
    ScalarMappable drawn for its panel, has a colour bar)."""
    colourbar_of = set()
    for ax in fig.axes:
        if _is_colourbar(ax):
            cb = getattr(ax, "_colorbar", None)
            mappable = getattr(cb, "mappable", None)
            colourbar_of.add(id(mappable))
            parents = getattr(cb, "_podkrig_panels", None)
            for p in parents or ():
                colourbar_of.add(id(p))
    panels = []
    for ax in fig.axes:
        if _is_colourbar(ax) or not ax.get_visible() or not ax.axison and not _draws_something(ax):
            continue
        mapped = _colour_mapped(ax)
        panels.append({
            "title": ax.get_title() or ax.get_title("left"),
            "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
            "xscale": ax.get_xscale(), "yscale": ax.get_yscale(),
            "empty": not _draws_something(ax),
            "colour_mapped": bool(mapped),
            "colourbar": any(id(a) in colourbar_of for a in mapped) or id(ax) in colourbar_of,
        })
    return panels


def load_label(unit):
    """The label of a load axis in ``unit``: ``"load (kN)"``; ``"step"`` for a test whose levels are
    the steps of a loading sequence (a flat-jack test's ``load_unit``: a step is no load)."""
    return "step" if unit == "step" else f"load ({unit})"


def colourbar(fig, mappable, axes, **kwargs):
    """``fig.colorbar(mappable, ax=axes)`` for a colour scale shared by ``axes`` whose artists
    took their colours from ``mappable`` by hand (e.g. lines coloured with ``cmap(norm(v))``):
    records the panels it belongs to for :func:`describe`."""
    cb = fig.colorbar(mappable, ax=axes, **kwargs)
    cb._podkrig_panels = list(np.ravel(axes))
    return cb


def save(fig, path, dpi=110):
    """Save ``fig`` as PNG at ``path`` with its :func:`describe` in the ``podkrig:panels`` text
    chunk, close it, and return ``path``."""
    fig.savefig(path, dpi=dpi, metadata={PANELS_KEY: json.dumps(describe(fig), ensure_ascii=False)})
    pyplot().close(fig)
    return path


def read_panels(path):
    """The panels :func:`save` recorded in the PNG at ``path`` (list of dicts), or None for a PNG
    saved otherwise."""
    from PIL import Image  # matplotlib's own dependency; only the report test reads figures back

    with Image.open(path) as im:
        text = getattr(im, "text", {}).get(PANELS_KEY)
    return None if text is None else json.loads(text)
