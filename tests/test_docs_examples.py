"""Every ``podkrig`` command shown in the README and in docs/ works as written.

The examples are read from the ``bash`` blocks of the pages (a line ending in ``\\`` continues on
the next; ``> FILE`` sends the output to FILE). Each one names a command and only options that
command has (fast); and in a scratch folder, in the order a reader meets them, each runs and
ends with exit code 0 (slow), except those that need what only the reader has (:data:`BRING`).
docs/nonlinear.md's commands run in ``tests/test_cli_simulate.py``.
"""

import shlex
import shutil
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from podkrig.cli import app

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), ROOT / "examples" / "README.md"]

#: fragment of an example → what the reader brings for it (such an example is only checked for its
#: command and options)
BRING = {
    "my_study.toml": "their own study file",
    "my_panel.toml": "their own scenario spec",
    "wall3_log.xlsx": "their own lab log",
    "tcp://": "a running Dask cluster",
    "...": "the options of the command before it (an elision)",
    "serve ": "a browser: the page runs until Ctrl-C (tests/test_serve_api.py and test_serve_browser.py start it)",
}


def examples(path):
    """``(line, args, stdout)`` of every ``podkrig`` command in the bash blocks of ``path``: its
    first line number, the arguments after ``podkrig`` and the file its output goes to (or None)."""
    found, in_bash, pending = [], False, None
    for number, line in enumerate(path.read_text().splitlines(), 1):
        if line.startswith("```"):
            in_bash = line.strip() == "```bash"
            continue
        if not in_bash:
            continue
        text = line.split(" #")[0].rstrip() if pending is None else pending[1] + " " + line.split(" #")[0].strip()
        start = number if pending is None else pending[0]
        if text.endswith("\\"):
            pending = (start, text[:-1].rstrip())
            continue
        pending = None
        if not text.startswith("podkrig"):
            continue
        args = shlex.split(text, comments=True)[1:]
        stdout = None
        if ">" in args:
            i = args.index(">")
            args, stdout = args[:i], args[i + 1]
        found.append((start, args, stdout))
    return found


def _command(args):
    """The command an example calls (its subcommand path walked) and the arguments after it."""
    command = typer.main.get_command(app)
    path = []
    while hasattr(command, "commands") and args and args[0] in command.commands:
        command = command.commands[args[0]]
        path.append(args[0])
        args = args[1:]
    return command, path


def _needs(args):
    text = shlex.join(args)
    return next((what for fragment, what in BRING.items() if fragment in text), None)


ALL = [(page.relative_to(ROOT).as_posix(), line, args, stdout) for page in PAGES for line, args, stdout in examples(page)]


def test_the_pages_show_examples():
    """The reader finds the commands where this test looks for them (a change of fence or prefix
    would silently check nothing)."""
    pages = {page for page, *_ in ALL}
    assert {"README.md", "docs/scenarios.md", "docs/nonlinear.md", "docs/diagnosis.md"} <= pages
    assert sum(page == "README.md" for page, *_ in ALL) >= 20


@pytest.mark.parametrize(("page", "line", "args", "stdout"), ALL, ids=[f"{p}:{n}" for p, n, *_ in ALL])
def test_every_example_names_a_command_and_its_options(page, line, args, stdout):
    """Each example calls a command that exists with options that command has (``--version`` is
    the program's own)."""
    command, path = _command(args)
    if args == ["--version"]:
        return
    assert path and not hasattr(command, "commands"), f"{page}:{line}: no command in {args}"
    options = {opt for param in command.params for opt in (*param.opts, *param.secondary_opts)}
    for token in args[len(path):]:
        if token.startswith("-") and token != "...":
            assert token.split("=")[0] in options, f"{page}:{line}: {' '.join(path)} has no option {token}"


RUNNABLE = [(page, line, args, stdout) for page, line, args, stdout in ALL
            if page != "docs/nonlinear.md" and _needs(args) is None]


@pytest.mark.slow
def test_every_example_runs_as_written(tmp_path, monkeypatch, demo_run, triplet_series_run):
    """In a scratch folder (a fresh checkout's view: ``examples/`` beside it), the examples run one
    after the other as a reader runs them — later ones use the files earlier ones wrote — and each
    ends with exit code 0. The demo runs first (``podkrig sensitivity out/demo/...`` reads it)
    without its diagnosis.

    The two study runs (the demo and docs/strength.md's ``podkrig run
    examples/triplet_series.toml``) are the session's (conftest.py: one fresh run each, in a scratch
    folder of the same layout, shared with the other tests that need them): each must have ended
    with exit code 0, and its folder is copied here, where the command then runs as written and
    resumes it (every stage cached by its inputs' contents)."""
    for folder, exit_code, output in (demo_run, triplet_series_run):
        assert exit_code == 0, output[-2000:]
        shutil.copytree(folder / "out", tmp_path / "out", dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    runner = CliRunner()
    setup = runner.invoke(app, ["demo", "--skip-diagnosis"])
    assert setup.exit_code == 0, setup.output[-2000:]
    for page, line, args, stdout in RUNNABLE:
        result = runner.invoke(app, args)
        assert result.exit_code == 0, (f"{page}:{line}", args, result.output[-2000:])
        if stdout is not None:
            Path(stdout).write_text(result.stdout)
