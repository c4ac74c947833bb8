"""The two test lanes: the fast lane (``pytest -m "not slow"``) runs some test of every test module.

A module whose every test is ``slow`` would be checked only by the full suite, and a change that
breaks it would pass the fast lane. What each lane costs is measured, not asserted (a timing
assertion fails on a loaded machine): ``scripts/lane_durations.py`` prints it.

The marks are read from the source (no import, no collection): a test is slow when it, its class
or its module (``pytestmark``) carries ``pytest.mark.slow``.
"""

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent


def _is_slow_mark(node):
    """``pytest.mark.slow`` or ``mark.slow``, called or not."""
    if isinstance(node, ast.Call):
        node = node.func
    return isinstance(node, ast.Attribute) and node.attr == "slow" and (
        (isinstance(node.value, ast.Attribute) and node.value.attr == "mark")
        or (isinstance(node.value, ast.Name) and node.value.id == "mark"))


def _module_marked_slow(tree):
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in node.targets):
            marks = node.value.elts if isinstance(node.value, (ast.List, ast.Tuple)) else [node.value]
            if any(_is_slow_mark(m) for m in marks):
                return True
    return False


def _tests_of(source):
    """``(name, slow)`` of every test function and method of a test module's source."""
    tree = ast.parse(source)
    module_slow = _module_marked_slow(tree)
    found = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name.startswith("test"):
            found.append((node.name, module_slow or any(_is_slow_mark(d) for d in node.decorator_list)))
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            class_slow = module_slow or any(_is_slow_mark(d) for d in node.decorator_list)
            for f in node.body:
                if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef)) and f.name.startswith("test"):
                    found.append((f"{node.name}.{f.name}", class_slow or any(_is_slow_mark(d) for d in f.decorator_list)))
    return found




@pytest.mark.parametrize("source, expected", [
    ("import pytest\n@pytest.mark.slow\ndef test_a(): pass\ndef test_b(): pass\n",
     [("test_a", True), ("test_b", False)]),
    ("import pytest\npytestmark = [pytest.mark.peers, pytest.mark.slow]\ndef test_a(): pass\n", [("test_a", True)]),
    ("from pytest import mark\n@mark.slow\nclass TestX:\n    def test_a(self): pass\n"
     "class TestY:\n    @mark.slow()\n    def test_b(self): pass\n    def test_c(self): pass\n    def helper(self): pass\n",
     [("TestX.test_a", True), ("TestY.test_b", True), ("TestY.test_c", False)]),
    ("import pytest\n@pytest.mark.parametrize('x', [1])\ndef test_a(x): pass\ndef _helper(): pass\n", [("test_a", False)]),
])
def test_marks_are_read_from_the_source(source, expected):
    assert _tests_of(source) == expected


def test_every_test_module_has_a_test_in_the_fast_lane():
    modules = sorted(TESTS.glob("test_*.py"))
    assert len(modules) > 50  # the glob found the suite
    only_slow = []
    for path in modules:
        tests = _tests_of(path.read_text(encoding="utf-8"))
        assert tests, f"{path.name}: no test functions found"
        if all(slow for _, slow in tests):
            only_slow.append(path.name)
    assert not only_slow, (f"every test of {only_slow} is marked slow: add a fast test of what each module "
                           "checks (a smaller case, a coarser mesh), so that `pytest -m 'not slow'` runs it")
