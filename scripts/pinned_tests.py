"""Count the test functions that pin wording or bookkeeping instead of behaviour.

A test function is *pinned* when it asserts a whole message, a verbatim log line or recorded
optimiser calls: rewording a message or improving a search then breaks it, and none of that
protects a user. The rule, per test function (its body, its ``parametrize`` values and the
module-level helpers it calls)::

    anchored   a ``match=`` / ``.match()`` pattern anchored at both ends (``^...$``), or anchored
               at one end with a sentence (SENTENCE_WORDS or more words) behind the anchor
    sentence   a ``match=`` pattern, or ``re.escape(...)`` of a literal, with a sentence between
               its wildcards (``A.*B`` asserts the fragments A and B); or a literal sentence
               compared with ``==`` / ``!=`` / ``in`` against anything (``str(err.value) ==
               "..."``, ``"..." in result.output``, ``caplog.messages == [...]``,
               ``describe() == "..."``)
    optimiser  an optimiser (``minimize``, ``fmin*``, ``least_squares``,
               ``differential_evolution``, ``minimize_scalar``) replaced with ``monkeypatch``

A *sentence* is a string literal (an f-string counts its literal words, each ``{...}`` as one)
of at least SENTENCE_WORDS (7) whitespace-separated words. Fragments -- a parameter name, a
value, an option, a short phrase such as "must be positive" -- are what tests should match, as
``pytest.raises(ValueError, match="kN_bj")``; log records are checked by logger, level and
``record.args``. The rule is a heuristic: a whole message shorter than 7 words is not counted, and
fragments passed to a helper are not inspected.

Usage::

    python scripts/pinned_tests.py            # table per file and the total
    python scripts/pinned_tests.py --list     # also each pinned test and why
    python scripts/pinned_tests.py tests/test_kriging_estimator.py --list
"""

import argparse
import ast
import re
import sys
from pathlib import Path

SENTENCE_WORDS = 7
OPTIMISERS = re.compile(r"^(minimize|minimize_scalar|fmin\w*|least_squares|differential_evolution|dual_annealing"
                        r"|basinhopping|shgo)$")


WILDCARD = re.compile(r"\.[*+]\??")


def literal_text(node):
    """The literal text of a ``str`` constant or f-string (each ``{...}`` as the word ``{}``),
    ``re.escape(<literal>)`` unwrapped; ``None`` for anything else."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.JoinedStr):
        return "".join(v.value if isinstance(v, ast.Constant) else " {} " for v in node.values)
    if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Add):  # "..." "..." + f"..."
        left, right = literal_text(node.left), literal_text(node.right)
        if left is not None or right is not None:
            return (left or " {} ") + (right or " {} ")
    if is_call(node, "escape") and node.args:
        return literal_text(node.args[0])
    return None


def words(text):
    return len(text.split())


def is_sentence(text):
    """A literal of SENTENCE_WORDS or more words between regex wildcards (``A.*B`` holds the
    fragments A and B)."""
    return text is not None and any(words(piece) >= SENTENCE_WORDS for piece in WILDCARD.split(text))


def is_call(node, name):
    if not isinstance(node, ast.Call):
        return False
    f = node.func
    return (isinstance(f, ast.Name) and f.id == name) or (isinstance(f, ast.Attribute) and f.attr == name)


def pattern_reason(node, bound):
    """Why a ``match`` pattern pins a whole message, or ``None``."""
    if isinstance(node, ast.Name) and node.id in bound:
        return bound[node.id]
    text = literal_text(node)
    if text is None:
        return None
    head = text.startswith("^")
    tail = text.endswith("$") and not text.endswith("\\$")
    if head and tail:
        return "anchored"
    if is_sentence(text):
        return "anchored" if head or tail else "sentence"
    return None


def sentences_in(node, bound):
    """True when ``node`` is, or contains (a list, tuple, set or call argument), a sentence."""
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name) and sub.id in bound:
            return True
        if isinstance(sub, (ast.Constant, ast.JoinedStr)) and is_sentence(literal_text(sub)):
            return True
    return False


def parametrized_sentences(func):
    """Parameter names of ``func`` whose ``parametrize`` values include a sentence."""
    names = {}
    for dec in func.decorator_list:
        if not (is_call(dec, "parametrize") and len(dec.args) >= 2):
            continue
        argnames = literal_text(dec.args[0])
        if argnames is None:
            continue
        argnames = [a.strip() for a in argnames.split(",") if a.strip()]
        rows = dec.args[1].elts if isinstance(dec.args[1], (ast.List, ast.Tuple)) else []
        for row in rows:
            if is_call(row, "param"):
                row = row.args[0] if len(row.args) == 1 else ast.Tuple(elts=row.args)
            cells = row.elts if isinstance(row, ast.Tuple) and len(argnames) > 1 else [row]
            for name, cell in zip(argnames, cells):
                if sentences_in(cell, {}):
                    names[name] = "sentence"
    return names


def reasons(func):
    """The reasons ``func`` (a test or a helper) pins wording or bookkeeping: ``{reason: lines}``."""
    bound = parametrized_sentences(func)
    for sub in ast.walk(func):  # local names bound to a sentence: message = "..."
        if isinstance(sub, ast.Assign) and is_sentence(literal_text(sub.value)):
            for target in sub.targets:
                if isinstance(target, ast.Name):
                    bound[target.id] = "sentence"
    found = {}
    for sub in ast.walk(func):
        if isinstance(sub, ast.Call):
            patterns = [kw.value for kw in sub.keywords if kw.arg == "match"]
            if isinstance(sub.func, ast.Attribute) and sub.func.attr == "match" and sub.args:
                patterns.append(sub.args[0])  # excinfo.match(...)
            for pattern in patterns:
                why = pattern_reason(pattern, bound)
                if why:
                    found.setdefault(why, set()).add(pattern.lineno)
            if is_call(sub, "setattr") and isinstance(sub.func, ast.Attribute) and len(sub.args) >= 2:
                owner = sub.func.value
                if isinstance(owner, ast.Name) and owner.id == "monkeypatch":
                    target = literal_text(sub.args[1]) if len(sub.args) >= 3 else literal_text(sub.args[0])
                    if target and OPTIMISERS.match(target.rsplit(".", 1)[-1]):
                        found.setdefault("optimiser", set()).add(sub.lineno)
        elif isinstance(sub, ast.Compare) and any(isinstance(op, (ast.Eq, ast.NotEq, ast.In, ast.NotIn))
                                                  for op in sub.ops):
            if any(sentences_in(side, bound) for side in [sub.left, *sub.comparators]):
                found.setdefault("sentence", set()).add(sub.lineno)
    return found


def scan(path):
    """``[(test name, {reason: lines})]`` for the pinned test functions of ``path``, and the number
    of test functions. A test inherits the reasons of the module-level helpers it calls."""
    tree = ast.parse(Path(path).read_text(), filename=str(path))
    functions = {}
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            functions.setdefault(node.name, node)
    helpers = {name: reasons(f) for name, f in functions.items() if not name.startswith("test_")}
    tests = [f for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
             and f.name.startswith("test_")]
    pinned = []
    for test in tests:
        why = reasons(test)
        called = {n.func.id for n in ast.walk(test) if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)}
        for name in called & helpers.keys():
            for reason, lines in helpers[name].items():
                why.setdefault(reason, set()).update(lines)
        if why:
            pinned.append((test.name, why))
    return pinned, len(tests)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 1)[1])
    parser.add_argument("paths", nargs="*", type=Path, help="test files (default: tests/test_*.py)")
    parser.add_argument("--list", action="store_true", help="list each pinned test and its reasons")
    args = parser.parse_args(argv)
    root = Path(__file__).resolve().parent.parent
    paths = args.paths or sorted((root / "tests").glob("test_*.py"))
    rows, total_pinned, total_tests = [], 0, 0
    for path in paths:
        pinned, n = scan(path)
        total_pinned += len(pinned)
        total_tests += n
        if pinned:
            rows.append((path, pinned, n))
    width = max([len(p.name) for p, _, _ in rows] + [5])
    print(f"{'file':<{width}}  pinned  tests  anchored  sentence  optimiser")
    for path, pinned, n in sorted(rows, key=lambda r: (-len(r[1]), r[0].name)):
        count = {k: sum(k in why for _, why in pinned) for k in ("anchored", "sentence", "optimiser")}
        print(f"{path.name:<{width}}  {len(pinned):>6}  {n:>5}  {count['anchored']:>8}  {count['sentence']:>8}"
              f"  {count['optimiser']:>9}")
        if args.list:
            for name, why in pinned:
                print(f"    {name}  (" + "; ".join(f"{k}: line {', '.join(map(str, sorted(v)))}"
                                                  for k, v in sorted(why.items())) + ")")
    print(f"{'total':<{width}}  {total_pinned:>6}  {total_tests:>5}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
