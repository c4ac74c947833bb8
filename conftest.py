"""Pytest set-up for the docstring examples of ``podkrig`` and ``fe`` (``--doctest-modules``).

The examples write and read files with paths relative to the project root, as a user types them
there (``load_study("examples/diagonal_compression.toml")``, ``run_snapshots("snapshots/demo.h5",
...)``). Each runs in a fresh temporary folder holding a copy of ``examples/``, so that nothing is
written into the checkout and no example sees another's files.
"""

import shutil
from pathlib import Path

import pytest
from _pytest.doctest import DoctestItem

EXAMPLES = Path(__file__).resolve().parent / "examples"


@pytest.fixture(autouse=True)
def _doctest_in_a_scratch_folder(request):
    if isinstance(request.node, DoctestItem):  # other tests ask for tmp_path themselves
        tmp_path = request.getfixturevalue("tmp_path")
        shutil.copytree(EXAMPLES, tmp_path / "examples")
        request.getfixturevalue("monkeypatch").chdir(tmp_path)
