"""``scripts/bench_serve_peers.py`` (BENCHMARKS.md "Front end stack"): imports without running,
says how to install the peers, refuses clearly without them, and writes apps that are Python.

The measurement itself needs the peers' environments, a finished demo folder and Chromium: it is
run by hand (the script's ``--help``), not here."""

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import load_file

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_serve_peers.py"


@pytest.fixture(scope="module")
def bench():
    return load_file(SCRIPT)


def test_help_says_how_to_install_the_peers():
    result = subprocess.run([sys.executable, str(SCRIPT), "--help"], capture_output=True, text=True, timeout=60,
                            check=False)
    assert result.returncode == 0, result.stderr
    for fragment in ("--install", "/work/venv-peers-NAME", "pip install -e .", "--stacks"):
        assert fragment in result.stdout


def test_a_missing_peer_environment_names_the_install_command(bench, monkeypatch, tmp_path):
    monkeypatch.setattr(bench, "VENV_PREFIX", str(tmp_path / "venv-peers-"))
    with pytest.raises(SystemExit, match=r"no environment for the dash stack.*--install dash") as caught:
        bench.main(["--stacks", "starlette", "dash"])
    assert "--install starlette" in str(caught.value)


def test_every_app_and_the_shared_model_are_python(bench):
    compile(bench.MODEL, "peer_model.py", "exec")
    assert set(bench.STACKS) == {"starlette", "dash", "panel", "streamlit"}
    for stack in bench.STACKS.values():
        compile(stack.source, f"{stack.name}/{stack.app_file}", "exec")
        assert "peer_model" in stack.source  # every stack predicts with the same demo problem
    assert (bench.UPLOT / "uPlot.iife.min.js").is_file()  # the Starlette page's chart bundle


def test_moves_take_the_sliders_in_turn_and_stay_within_five_steps(bench):
    from selenium.webdriver.common.keys import Keys

    moves = [bench.key_for(i, 4) for i in range(68)]
    assert [k for k, _ in moves[:8]] == [0, 1, 2, 3, 0, 1, 2, 3]
    for slider in range(4):
        steps = [1 if key == Keys.ARROW_RIGHT else -1 for k, key in moves if k == slider]
        positions = [sum(steps[:n + 1]) for n in range(len(steps))]
        assert min(positions) >= 0 and max(positions) == 5  # 50 … 55 of 0 … 100: never at an end


def test_table_gives_a_failed_stack_a_full_row(bench):
    row = {"stack": "dash", "version": "4.4.1", "added": 28, "serving": 3.4, "first_plot_first": 1.7,
           "first_plot_reload": 0.8, "start_to_plot": 5.9, "median": 113.0, "p90": 133.0, "burst": 150.0,
           "cpu": 0.08, "browser_cpu": 2.0, "moves": 60, "failed": 0, "foreign": []}
    text = bench.table([row, {"stack": "panel", "error": "panel: found 0 sliders | see log"}])
    lines = text.splitlines()
    assert len({line.count("|") for line in lines}) == 1  # every row has the header's columns
    assert "| 113 | 133 | 150 |" in lines[2] and "found 0 sliders / see log" in lines[3]
