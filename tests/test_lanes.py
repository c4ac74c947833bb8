"""The two test lanes: the fast lane (``pytest -m "not slow"``) runs some test of every test module.

A module whose every test is ``slow`` would be checked only by the full suite, and a change that
breaks it would pass the fast lane. What each lane costs is measured, not asserted (a timing
assertion fails on a loaded machine): ``scripts/lane_durations.py`` prints it.

The marks are read from the source (no import, no collection): a test is slow when it, its class
or its module (``pytestmark``) carries ``pytest.mark.slow``.
"""

import ast
import textwrap
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
FUNCTIONS = (ast.FunctionDef, ast.AsyncFunctionDef)


def _is_slow_mark(node):
    """``pytest.mark.slow`` or ``mark.slow``, called or not."""
    if isinstance(node, ast.Call):
        node = node.func
    if not (isinstance(node, ast.Attribute) and node.attr == "slow"):
        return False
    owner = node.value
    return (isinstance(owner, ast.Attribute) and owner.attr == "mark") or (
        isinstance(owner, ast.Name) and owner.id == "mark")


def _any_slow(marks):
    return any(_is_slow_mark(m) for m in marks)


def _module_marks(tree):
    """The marks of ``pytestmark = ...`` (one mark or a list)."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == "pytestmark" for t in node.targets):
            return node.value.elts if isinstance(node.value, (ast.List, ast.Tuple)) else [node.value]
    return []


def _tests_of(source):
    """``(name, slow)`` of every test function and test method in a test module's source."""
    tree = ast.parse(source)
    module_slow = _any_slow(_module_marks(tree))
    found = []
    for node in tree.body:
        if isinstance(node, FUNCTIONS) and node.name.startswith("test"):
            found.append((node.name, module_slow or _any_slow(node.decorator_list)))
        elif isinstance(node, ast.ClassDef) and node.name.startswith("Test"):
            class_slow = module_slow or _any_slow(node.decorator_list)
            for f in node.body:
                if isinstance(f, FUNCTIONS) and f.name.startswith("test"):
                    found.append((f"{node.name}.{f.name}", class_slow or _any_slow(f.decorator_list)))
    return found


CASES = [
    ("""
     import pytest
     @pytest.mark.slow
     def test_a(): pass
     def test_b(): pass
     """, [("test_a", True), ("test_b", False)]),
    ("""
     import pytest
     pytestmark = [pytest.mark.peers, pytest.mark.slow]
     def test_a(): pass
     """, [("test_a", True)]),
    ("""
     from pytest import mark
     @mark.slow
     class TestX:
         def test_a(self): pass
     class TestY:
         @mark.slow()
         def test_b(self): pass
         def test_c(self): pass
         def helper(self): pass
     """, [("TestX.test_a", True), ("TestY.test_b", True), ("TestY.test_c", False)]),
    ("""
     import pytest
     @pytest.mark.parametrize("x", [1])
     def test_a(x): pass
     def _helper(): pass
     """, [("test_a", False)]),
]


@pytest.mark.parametrize("source, expected", CASES)
def test_marks_are_read_from_the_source(source, expected):
    assert _tests_of(textwrap.dedent(source)) == expected


def test_every_test_module_has_a_test_in_the_fast_lane():
    modules = sorted(TESTS.glob("test_*.py"))
    assert len(modules) > 50  # the glob found the suite
    only_slow = []
    for path in modules:
        tests = _tests_of(path.read_text(encoding="utf-8"))
        assert tests, f"{path.name}: no test functions found"
        if all(slow for _, slow in tests):
            only_slow.append(path.name)
    assert not only_slow, (f"every test of {only_slow} is marked slow: add a fast test of what the module "
                           "checks (a smaller case, a coarser mesh), so that `pytest -m 'not slow'` runs it")
