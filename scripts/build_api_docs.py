"""Build the API reference of ``fe`` and ``podkrig`` as HTML, from their numpydoc docstrings.

Usage: python scripts/build_api_docs.py [--out out/api]

Needs pdoc (``pip install -e '.[docs]'``). Writes one page per module, ``OUT/index.html`` with a
search box and, e.g., ``OUT/podkrig/online.html`` and ``OUT/fe.html``; open ``OUT/index.html`` in a
browser. ``out/`` is git-ignored. Every module is imported (nothing is run): a module that fails to
import stops the build with its error.
"""

import argparse
import importlib
import pkgutil
import sys
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("fe", "podkrig")


def public_modules(packages=PACKAGES):
    """Every public module of ``packages``, packages first, sorted.

    pdoc follows a package's ``__all__``, which names functions and classes, not submodules; so
    each module is passed by name. Modules whose name starts with ``_`` are private.

    Parameters
    ----------
    packages : tuple of str
        Importable package names.

    Returns
    -------
    list of str
        Dotted module names, e.g. ``["fe", "fe.assembly", ..., "podkrig.online.region", ...]``.
    """
    names = []
    for package in packages:
        module = importlib.import_module(package)
        names.append(package)
        for info in pkgutil.walk_packages(module.__path__, prefix=f"{package}."):
            if not any(part.startswith("_") for part in info.name.split(".")):
                names.append(info.name)
    return sorted(names)


def build(out):
    """Render the API reference of every public module of :data:`PACKAGES` into ``out``.

    Parameters
    ----------
    out : str or Path
        Output folder (created; existing pages are overwritten).

    Returns
    -------
    Path
        ``out/index.html``.
    """
    import pdoc
    import pdoc.render

    out = Path(out)
    pdoc.render.configure(
        docformat="numpy",
        footer_text="podkrig API reference",
        math=False,  # the docstrings write their formulas in plain Unicode
        search=True,
        show_source=True,
    )
    with warnings.catch_warnings():
        # a package whose __all__ lists its submodules adds them itself: passing them again is harmless
        warnings.filterwarnings("ignore", message="The module specification .* adds a module named")
        # pydantic's generated __init__ annotations name a type that exists only for type checkers:
        # shown as written
        warnings.filterwarnings("ignore", message="(Error parsing|Failed to run TYPE_CHECKING code).*PydanticDataclass")
        pdoc.pdoc(*public_modules(), output_directory=out)
    return out / "index.html"


def main(argv=None):
    sys.path.insert(0, str(ROOT))  # this checkout's fe and podkrig, not another installed copy
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="out/api", help="output folder (default: out/api)")
    args = parser.parse_args(argv)
    index = build(args.out)
    print(f"API reference: {index}")


if __name__ == "__main__":
    main()
