"""podkrig — surrogate-first inverse analysis of mesoscale FE models of brick masonry.

Stages: offline snapshots of the bundled FE solver (:mod:`fe`) → POD + ordinary kriging
surrogate → online genetic-algorithm inversion, region of equivalence, RVC → model diagnosis.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("podkrig")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0.0.0+unknown"
