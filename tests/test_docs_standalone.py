"""The user's documentation stands alone: it points at no file the user does not have, every
choice it marks INFERRED says where that word is explained, and the commands the prose names
(not only the ``bash`` blocks, which ``tests/test_docs_examples.py`` runs) exist with the options
they are shown with.

User text here is what a user reads: the README, ``docs/``, ``examples/``, BENCHMARKS.md, the
docstrings and strings of ``podkrig`` and ``fe`` (the API reference, reports, messages), the
``--help`` of every command and of the scripts the docs tell users to run, and ``podkrig
scenarios NAME``. The project's tests and code comments are not user text.
"""

import ast
import re
import shlex
import shutil
import tomllib
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from fe.scenarios import SCENARIOS, build_scenario
from podkrig.cli import app
from podkrig.online.settings import NoiseSettings
from podkrig.study import load_study

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").rglob("*.md")),
         ROOT / "examples" / "README.md"]
EXAMPLES = ROOT / "examples"
EXAMPLE_FILES = sorted(p for p in (ROOT / "examples").iterdir() if p.suffix in (".toml", ".py"))

#: a path or a section of the project's private reference notes (never in the repository)
PRIVATE = re.compile(r"shared/|reference/[\w-]+\.md|[Rr]eference §|[Rr]eference notes")

runner = CliRunner()


def _strings(path, module_only=False):
    """``(line, text)`` of the docstrings and string constants of a Python file (its module
    docstring only if ``module_only``: what a script's ``--help`` prints)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    if module_only:
        return [(1, ast.get_docstring(tree, clean=False) or "")]
    return [(node.lineno, node.value) for node in ast.walk(tree)
            if isinstance(node, ast.Constant) and isinstance(node.value, str)]


def _code_texts():
    for folder in ("podkrig", "fe"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            for line, text in _strings(path):
                yield f"{path.relative_to(ROOT)}:{line}", text
    for path in sorted((ROOT / "scripts").glob("*.py")):
        yield f"{path.relative_to(ROOT)} --help", _strings(path, module_only=True)[0][1]


def _paragraphs(path):
    """``(line, paragraph)`` of a text page, paragraphs split at blank lines."""
    out, start, lines = [], 1, []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if line.strip():
            start = number if not lines else start
            lines.append(line)
        elif lines:
            out.append((start, "\n".join(lines)))
            lines = []
    if lines:
        out.append((start, "\n".join(lines)))
    return out


def _commands(group=None, path=()):
    group = group or typer.main.get_command(app)
    yield list(path)
    for name, command in getattr(group, "commands", {}).items():
        yield from _commands(command, (*path, name))


def _cli_texts():
    for path in _commands():
        yield "podkrig " + " ".join([*path, "--help"]), runner.invoke(app, [*path, "--help"], terminal_width=200).output
    for name in sorted(SCENARIOS):
        yield f"podkrig scenarios {name}", runner.invoke(app, ["scenarios", name], terminal_width=200).output


def _page_texts():
    for page in [*PAGES, *EXAMPLE_FILES]:
        for line, text in _paragraphs(page):
            yield f"{page.relative_to(ROOT)}:{line}", text


def test_no_user_text_points_at_files_the_user_does_not_have():
    found = [where for where, text in [*_page_texts(), *_code_texts(), *_cli_texts()] if PRIVATE.search(text)]
    assert not found


def test_references_page_explains_inferred():
    text = (ROOT / "docs" / "references.md").read_text(encoding="utf-8")
    assert "\n## INFERRED choices\n" in text
    section = text.split("\n## INFERRED choices\n")[1]
    assert "named option" in section and "default" in section  # what it means to a user: a choice they can change


def test_every_inferred_in_user_text_says_where_it_is_explained():
    """Each paragraph, docstring, string or command output that marks a choice INFERRED also names
    docs/references.md (the page with the "INFERRED choices" section), which itself is exempt."""
    texts = [*_page_texts(), *_code_texts(), *_cli_texts()]
    marked = [(where, text) for where, text in texts
              if "INFERRED" in text and not where.startswith("docs/references.md")]
    assert len(marked) > 10  # the check looks where the word is used
    assert [where for where, text in marked if "references.md" not in text] == []


@pytest.mark.parametrize("instrument", ["lvdt", "dic"])
def test_the_noise_model_a_report_prints_says_where_inferred_is_explained(instrument):
    """The demo's report and summary show the instrument noise in words (``describe``)."""
    text = NoiseSettings(instrument=instrument).describe()
    assert "INFERRED" in text and "docs/references.md" in text


def _inline_commands():
    """``(page, line, args)`` of each ``podkrig ...`` code span in the prose of the pages."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        prose = re.sub(r"```.*?```", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.DOTALL)
        for m in re.finditer(r"`podkrig ([^`]+)`", prose):
            found.append((page.relative_to(ROOT).as_posix(), prose.count("\n", 0, m.start()) + 1,
                          shlex.split(m.group(1))))
    return found


INLINE = _inline_commands()


def test_the_prose_names_commands():
    assert sum(page == "README.md" for page, *_ in INLINE) >= 5
    assert ["demo", "--skip-diagnosis"] in [args for page, _, args in INLINE if page == "README.md"]


@pytest.mark.parametrize(("page", "line", "args"), INLINE, ids=[f"{p}:{n}" for p, n, _ in INLINE])
def test_every_command_the_prose_names_exists_with_its_options(page, line, args):
    """A code span such as `podkrig run --skip-diagnosis STUDY.toml` names a command (or a group
    of commands) and only options that command has."""
    command, rest = typer.main.get_command(app), list(args)
    while hasattr(command, "commands") and rest and rest[0] in command.commands:
        command, rest = command.commands[rest[0]], rest[1:]
    assert rest == [] or not hasattr(command, "commands"), f"{page}:{line}: no command in {args}"
    options = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
    unknown = [t for t in rest if t.startswith("-") and t != "..." and t.split("=")[0] not in options]
    assert not unknown, f"{page}:{line}: {' '.join(args)}"


def test_readme_gives_the_test_suite_and_the_demo_their_time_and_a_shorter_way():
    """A newcomer reads how long the tests take and the fast lane (a registered marker), and how
    long the demo takes, how much of it is the diagnosis and how to leave it out."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    tests = text[text.index("Set up and run the tests"):text.index("## A five-minute tour")]
    assert re.search(r'python -m pytest -m "not slow"[^\n]*under \d+ min', tests)
    assert re.search(r"everything[^\n]*about \d+ min", tests)
    assert '"slow:' in (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    demo = text[text.index("## The two commands"):text.index("Set up and run the tests")]
    assert re.search(r"diagnosis: [\d ]+ of the demo's [\d ]+ FE runs", demo)
    assert "`podkrig demo --skip-diagnosis`" in demo


# ----------------------------------------------------------------------------- Python examples
#: fragment of a Python example → what the reader brings for it (such an example is only compiled)
PY_BRING = {
    '"wall3.csv"': "their own lab log and the README's model",
    "dask_jobqueue": "a batch cluster",
}


def _python_examples(page):
    """``(line, code)`` of each ``python`` block of a page."""
    found, code, start = [], None, 0
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if code is None and line.strip() == "```python":
            code, start = [], number + 1
        elif code is not None and line.startswith("```"):
            found.append((start, "\n".join(code) + "\n"))
            code = None
        elif code is not None:
            code.append(line)
    return found


PYTHON = [(page.relative_to(ROOT).as_posix(), line, code) for page in PAGES for line, code in _python_examples(page)]


def test_every_python_example_is_valid_python():
    assert sum(page == "README.md" for page, *_ in PYTHON) >= 3
    for page, line, code in PYTHON:
        compile(code, f"{page}:{line}", "exec")


@pytest.mark.slow
def test_the_python_examples_run_as_written(tmp_path, monkeypatch, demo_run):
    """In a scratch folder beside ``examples/``, after ``podkrig demo --skip-diagnosis`` (the
    README's first command; its Python then adds the diagnosis, every other stage cached), each
    page's Python blocks run one after the other in one namespace, as a reader pastes them into
    one session, except those that need what only the reader has (:data:`PY_BRING`).

    The demo's first run is the session's (conftest.py: one fresh run in a scratch folder of the
    same layout, shared): it must have ended with exit code 0; its folder is copied here, where the
    command then runs as written and resumes it (every stage cached by its inputs' contents)."""
    folder, exit_code, output = demo_run
    assert exit_code == 0, output[-2000:]
    shutil.copytree(folder / "out", tmp_path / "out")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    setup = runner.invoke(app, ["demo", "--skip-diagnosis"])
    assert setup.exit_code == 0, setup.output[-2000:]
    namespaces = {}
    ran = []
    for page, line, code in PYTHON:
        if any(fragment in code for fragment in PY_BRING):
            continue
        exec(compile(code, f"{page}:{line}", "exec"), namespaces.setdefault(page, {"__name__": "__example__"}))
        ran.append(f"{page}:{line}")
    assert sum(where.startswith("README.md") for where in ran) >= 3


# ----------------------------------------------------------------------------- TOML examples
def _toml_blocks(page):
    return re.findall(r"```toml\n(.*?)```", page.read_text(encoding="utf-8"), re.DOTALL)


def test_every_toml_example_is_valid_toml():
    blocks = [block for page in PAGES for block in _toml_blocks(page)]
    assert len(blocks) >= 5
    for block in blocks:
        tomllib.loads(block)


def test_the_readmes_study_file_is_the_demos_study(tmp_path):
    """The README shows the demo's study file "as it is": beside its measurement log, it loads to
    the very settings of ``examples/diagonal_compression.toml``."""
    (tmp_path / "study.toml").write_text(_toml_blocks(ROOT / "README.md")[0], encoding="utf-8")
    (tmp_path / "diagonal_compression_measured.csv").symlink_to(EXAMPLES / "diagonal_compression_measured.csv")
    shown, demo = load_study(tmp_path / "study.toml"), load_study(EXAMPLES / "diagonal_compression.toml")
    for key in ("name", "spec", "space", "fixed", "train", "held_out", "surrogate", "inversion", "validation",
                "diagnosis", "sensitivity", "workers", "scheduler"):
        assert getattr(shown, key) == getattr(demo, key), key


def test_the_scenario_pages_spec_builds_its_scenario():
    spec = tomllib.loads(_toml_blocks(ROOT / "docs" / "scenarios.md")[0])
    scenario = build_scenario(spec)
    assert scenario.sensor_names == ("D1",) and list(scenario.load_levels) == spec["load_levels"]
