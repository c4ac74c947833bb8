"""The API reference builds from the docstrings (``python scripts/build_api_docs.py``)."""

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import load_file

ROOT = Path(__file__).resolve().parents[1]


def _builder():
    return load_file(ROOT / "scripts" / "build_api_docs.py")


def test_the_reference_covers_every_public_module_and_no_private_one():
    """pdoc follows a package's __all__, which names no submodules: the builder passes each module,
    so a stage's submodules get their pages; private modules (a part starting with _) get none."""
    names = _builder().public_modules()
    for name in ("fe", "fe.model", "podkrig", "podkrig.config", "podkrig.online", "podkrig.online.region",
                 "podkrig.surrogate.kriging.ordinary", "podkrig.study.pipeline"):
        assert name in names
    private = [n for n in names if any(part.startswith("_") for part in n.split("."))]
    assert not private, private
    assert names == sorted(set(names))


@pytest.mark.slow
def test_the_api_reference_builds_with_a_page_per_stage(tmp_path):
    """Every module is imported and rendered (~40 s); the key pages exist and render the numpydoc
    sections as headings."""
    pytest.importorskip("pdoc", reason="needs the docs extra: pip install -e '.[docs]'")
    out = tmp_path / "api"
    subprocess.run([sys.executable, str(ROOT / "scripts" / "build_api_docs.py"), "--out", str(out)],
                   cwd=tmp_path, check=True, capture_output=True, text=True, timeout=600)
    pages = ["index.html", "fe.html", "fe/model.html", "podkrig.html", "podkrig/config.html",
             "podkrig/offline.html", "podkrig/surrogate.html", "podkrig/online.html",
             "podkrig/online/region.html", "podkrig/diagnosis.html", "podkrig/study.html"]
    missing = [p for p in pages if not (out / p).is_file()]
    assert not missing, f"pages not built: {missing}"
    region = (out / "podkrig/online/region.html").read_text(encoding="utf-8")
    assert "likelihood_ratio_region" in region
    assert "Parameters</span>" in region  # the numpydoc section rendered as a heading
