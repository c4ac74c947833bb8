"""How a podkrig result shows itself: a short text repr and, in Jupyter, HTML from the reports.

Every result a user gets (:class:`~podkrig.online.invert.InverseResult`,
:class:`~podkrig.online.region.Region`, the stage results, ...) mixes in :class:`Displayed`:

- ``repr(result)`` is a few lines, never a whole array, at most :data:`~fe.display.MAX_REPR`
  characters (the helpers of :mod:`fe.display`);
- ``result._repr_html_()`` (what Jupyter shows) is the HTML of the renderer registered for the
  result's class (or a class it derives from). The renderers are the words of the reports layer
  (:mod:`podkrig.reports.jupyter` registers them when imported, which ``import podkrig`` does in a
  running IPython); this module, at the bottom of the layers, only keeps the registry, so the
  numerics never import the reports. With nothing registered the HTML is a table of the fields
  (:func:`fe.display.fields_html`).
"""

from fe import display as _fe_display
from fe.display import MAX_REPR, bounded, field_lines, summary

#: "module.QualName" of a class → function(obj) → HTML
_RENDERERS = {}


def register_html(cls_name, function):
    """Show the instances of the class ``cls_name`` (``"module.QualName"``) as ``function(obj)`` (a
    string of HTML) in Jupyter."""
    _RENDERERS[cls_name] = function


class Displayed(_fe_display.Displayed):
    """Mixin of the result objects (:class:`fe.display.Displayed`) whose HTML is the registered
    renderer of its class (module docstring)."""

    def _repr_html_(self):
        for cls in type(self).__mro__:
            function = _RENDERERS.get(f"{cls.__module__}.{cls.__qualname__}")
            if function is not None:
                return function(self)
        return super()._repr_html_()


__all__ = ["MAX_REPR", "Displayed", "bounded", "field_lines", "register_html", "summary"]
