"""What the command line prints outside a terminal: help texts with their brackets, tables whole
when piped, a progress line at least every 20 s (checked with a fake clock), the serial-run hint
only when it is worth saying, and no Dask traceback at the end of a run on a local cluster."""

import io
import logging
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import typer.main
from typer.testing import CliRunner

import podkrig.cli._terminal as terminal
import podkrig.io.surrogate_file as surrogate_file
import podkrig.online.problem as problem
import podkrig.online.sensitivity as sensitivity
from podkrig import parallel
from podkrig.cli import app
from podkrig.cli._terminal import HEARTBEAT_S, LINE_INTERVAL_S, Progress, console
from podkrig.parallel import quiet_loggers
from podkrig.reports.sensitivity import NEGATIVE_INDEX

runner = CliRunner()


# --- help texts: brackets are text, not markup --------------------------------------------------

def _commands(group, path=()):
    """Every command of the app: (argv path, click command)."""
    for name, cmd in group.commands.items():
        if hasattr(cmd, "commands"):
            yield from _commands(cmd, (*path, name))
        else:
            yield (*path, name), cmd


def test_bracketed_words_of_every_help_text_survive_in_help_output():
    """``[kN]``, ``[µm]``, ``[scenario]``, ``[[scenario.sensors]]``: rich markup took them for style
    tags and dropped them."""
    root = typer.main.get_command(app)
    checked = 0
    for path, cmd in _commands(root):
        texts = [cmd.help or ""] + [getattr(p, "help", None) or "" for p in cmd.params]
        tokens = {t for text in texts for t in re.findall(r"\[[^\]\s]+\]", text)}
        if not tokens:
            continue
        result = runner.invoke(app, [*path, "--help"], terminal_width=200)
        assert result.exit_code == 0, result.output
        for token in tokens:
            assert token in result.output, (path, token)
        checked += len(tokens)
    assert checked >= 3  # the premise: help texts with brackets exist ([kN], [µm], [scenario] at least)
    help_text = runner.invoke(app, ["invert", "--help"], terminal_width=200).output
    assert "[kN]" in help_text and "[µm]" in help_text


# --- tables are printed whole outside a terminal ------------------------------------------------

def test_console_outside_a_terminal_is_wide():
    c = console()
    assert not c.is_terminal and c.width > 1000


def test_a_wide_table_is_printed_whole_when_piped():
    """45 load steps × 6 gauges of the flat-jack test: every reading in full, no ellipsis."""
    args = ["simulate", "flat_jack", "--option", "layout=L6"]
    table = runner.invoke(app, args, terminal_width=80)
    assert table.exit_code == 0, table.output
    data = runner.invoke(app, [*args, "--format", "csv"])
    lines = data.stdout.strip().splitlines()
    sensors = [c.split(" [")[0] for c in lines[0].split(",")[1:]]  # "G1 [mm]" → "G1"
    readings = np.array([[float(v) for v in line.split(",")[1:]] for line in lines[1:]])
    assert "…" not in table.stdout
    for j, name in enumerate(sensors):
        row = next(line for line in table.stdout.splitlines() if re.search(rf"\b{name}\b", line))
        cells = re.findall(r"[+-]\d+\.\d{5}", row)
        assert cells == [f"{v:+.5f}" for v in readings[:, j]], name


# --- progress lines outside a terminal ----------------------------------------------------------

class FakeClock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def _progress(clock, **kwargs):
    stream = io.StringIO()
    return Progress("sensors", terminal=False, stream=stream, clock=clock, **kwargs), stream


def test_progress_writes_a_line_once_the_interval_has_passed_and_not_before():
    clock = FakeClock()
    progress, stream = _progress(clock)
    for t in np.arange(0.0, LINE_INTERVAL_S, HEARTBEAT_S):  # the heartbeat's ticks within the first interval
        clock.now = 1000.0 + t
        progress.tick()
    assert stream.getvalue() == ""  # a short command prints no progress
    clock.now = 1000.0 + LINE_INTERVAL_S
    progress.tick()
    lines = stream.getvalue().splitlines()
    assert len(lines) == 1 and lines[0].startswith("sensors:") and f"{LINE_INTERVAL_S:.0f} s" in lines[0]


def test_progress_silent_work_still_gets_a_line_every_interval():
    """No update for 7 minutes (one long computation): the heartbeat's ticks write a line at
    least every LINE_INTERVAL_S + HEARTBEAT_S, and at most one per interval."""
    clock = FakeClock()
    progress, stream = _progress(clock)
    progress.update("sensitivities", 3, 64)
    times = []
    for t in np.arange(0.0, 420.0 + HEARTBEAT_S, HEARTBEAT_S):
        clock.now = 1000.0 + t
        before = stream.getvalue().count("\n")
        progress.tick()
        if stream.getvalue().count("\n") > before:
            times.append(t)
    gaps = np.diff([0.0] + times)
    assert len(times) >= 420.0 // (LINE_INTERVAL_S + HEARTBEAT_S)
    assert gaps.max() <= 30.0 and gaps.min() >= LINE_INTERVAL_S
    assert all(line.startswith("sensitivities: 3/64 (5 %)") for line in stream.getvalue().splitlines())


def test_progress_updates_are_rate_limited_and_name_the_task_and_count():
    clock = FakeClock()
    progress, stream = _progress(clock, rate="snapshots/s")
    for done in range(1, 101):  # a report every 0.5 s over 50 s
        clock.now += 0.5
        progress.update("snapshots", done, 100)
    lines = stream.getvalue().splitlines()
    assert len(lines) == 2  # at 20 s and 40 s
    assert lines[0].startswith("snapshots: 40/100 (40 %), ")
    rate = float(re.search(r"([\d.]+) snapshots/s", lines[0]).group(1))
    assert rate == pytest.approx(40 / 19.5, abs=0.05)  # the task started at its first report, 0.5 s in


def test_progress_finish_prints_its_line_and_returns_to_the_command_task():
    clock = FakeClock()
    progress, stream = _progress(clock)
    progress.update("Training snapshots (FE)", 10, 10)
    progress.finish("✓ Training snapshots (FE): 3.0 s")
    clock.now += LINE_INTERVAL_S
    progress.tick()
    lines = stream.getvalue().splitlines()
    assert lines[0] == "✓ Training snapshots (FE): 3.0 s" and lines[1].startswith("sensors:")


def test_progress_heartbeat_thread_runs_inside_the_block_only():
    progress, _ = _progress(FakeClock())
    with progress:
        assert progress._thread.is_alive()
    assert progress._thread is None
    bar = Progress("x", terminal=True, stream=io.StringIO())
    with bar:
        assert bar._thread is None  # a terminal gets a bar, redrawn by rich: no heartbeat


def test_piped_long_command_reports_progress_on_stderr(tmp_path, monkeypatch):
    """``podkrig snapshots run`` not on a terminal: plain progress lines on stderr (the interval set
    to 0 so that every report writes one), the result on stdout."""
    monkeypatch.setattr(terminal, "LINE_INTERVAL_S", 0.0)
    spec = tmp_path / "coarse.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    result = runner.invoke(app, ["snapshots", "run", "--store", str(tmp_path / "s.h5"), "--spec", str(spec),
                                 "--param", "E_b=5000:20000", "--n", "4", "--seed", "0", "--workers", "1"])
    assert result.exit_code == 0, result.output
    counts = re.findall(r"^snapshots: (\d+)/4 ", result.stderr, re.MULTILINE)
    assert counts and counts[-1] == "4" and [int(c) for c in counts] == sorted(int(c) for c in counts)
    assert "snapshots:" not in result.stdout


# --- a local Dask cluster ends without tracebacks or warnings -----------------------------------

class _ListHandler(logging.Handler):
    def __init__(self):
        super().__init__()
        self.records = []

    def emit(self, record):
        self.records.append(record)


def _listen(name, level=None):
    lg = logging.getLogger(name)
    handler = _ListHandler()
    lg.addHandler(handler)
    if level is not None:
        lg.setLevel(level)
    return lg, handler


def test_quiet_loggers_silences_dask_loggers_only_inside_the_block():
    nanny, heard = _listen("distributed.podkrig_test_nanny")
    own_level, heard_own = _listen("tornado.podkrig_test_application", logging.ERROR)  # a level of its own
    ours, heard_ours = _listen("podkrig.podkrig_test")
    try:
        with quiet_loggers():
            nanny.warning("Worker process still alive after 4.0 seconds, killing")
            own_level.error("CommClosedError")
            ours.warning("kept")
        assert heard.records == [] and heard_own.records == []
        assert len(heard_ours.records) == 1  # podkrig's own loggers are never silenced
        nanny.warning("after the close")
        own_level.error("after the close")
        assert len(heard.records) == 1 and len(heard_own.records) == 1  # restored
        with pytest.raises(RuntimeError), quiet_loggers():
            raise RuntimeError("a failed close")
        assert not nanny.disabled  # restored on an exception too
    finally:
        for lg, h in ((nanny, heard), (own_level, heard_own), (ours, heard_ours)):
            lg.removeHandler(h)


def test_close_local_cluster_silences_workers_then_closes_client_then_cluster():
    calls = []
    nanny, heard = _listen("distributed.podkrig_test_close")

    class Client:
        def run(self, fun):
            calls.append(("run", fun))

        def close(self):
            calls.append("client")
            nanny.error("CommClosedError: in <TCP (closed)>")

    class Cluster:
        def close(self):
            calls.append("cluster")
            nanny.warning("Worker process still alive after 4.0 seconds, killing")

    try:
        parallel.close_local_cluster(Client(), Cluster())
        assert calls == [("run", parallel._silence_shutdown), "client", "cluster"]
        assert heard.records == [] and not nanny.disabled
    finally:
        nanny.removeHandler(heard)


SLOW_EXIT_RUN = """
import pathlib, sys, tempfile

def slow_exit():  # run on each worker: its process outlives the nanny's 4 s wait, as on a loaded machine
    import atexit, time
    atexit.register(time.sleep, 6.0)

from fe.scenarios import build_scenario
from podkrig.offline import runner
from podkrig.parameters import ParameterSpace

runner.LOCAL_CLUSTER_STARTUP_S = 0.0  # a cluster however small the job
start = runner.start_local_cluster

def start_slow(workers):
    client, cluster = start(workers)
    client.run(slow_exit)
    return client, cluster

runner.start_local_cluster = start_slow
spec = {"scenario": "diagonal_compression", "nx": 2, "ny": 1}
space = ParameterSpace.from_scenario(build_scenario(spec), {"E_b": (5000, 20000)})
summary = runner.run_snapshots(pathlib.Path(tempfile.mkdtemp()) / "s.h5", spec, space, n=8, seed=1, workers=2,
                               chunk_size=4)
print(summary.executor, summary.done)
"""


@pytest.mark.slow
def test_a_run_on_a_local_cluster_ends_without_dask_noise_on_stderr(tmp_path):
    """8 coarse runs on 2 local workers whose processes exit slower than the nanny waits (the
    warnings and tracebacks of a loaded machine, made certain): stdout has the result, stderr
    nothing. ≈ 20 s wall (cluster start-up and the nanny's wait), ≈ 5 s CPU."""
    result = subprocess.run([sys.executable, "-c", SLOW_EXIT_RUN], capture_output=True, text=True, timeout=300,
                            cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])})
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["local", "Dask", "cluster,", "2", "workers", "8"]
    assert result.stderr == ""


# --- podkrig sensitivity: a negative index is explained in its table ----------------------------

def test_sensitivity_table_explains_a_negative_first_order_index(tmp_path, monkeypatch):
    """The command's table for indices where r_hj's first-order estimate is −0.0009 inside its
    interval: a note column, the noise words on r_hj's row only (the indices are injected: the
    table is what is tested, not the estimator)."""
    indices = sensitivity.SensitivityResult(
        ("E_b", "r_hj"), ("D1@100",), first=np.array([[0.9, -0.0009]]), total=np.array([[0.95, 0.02]]),
        first_low=np.array([[0.85, -0.004]]), first_high=np.array([[0.95, 0.003]]),
        total_low=np.array([[0.9, 0.01]]), total_high=np.array([[0.99, 0.03]]), variance=np.array([1e-6]),
        confidence=0.95, n_base=256, seconds=0.1)
    monkeypatch.setattr(surrogate_file, "load_surrogate", lambda path: None)
    monkeypatch.setattr(problem, "SurrogateModel", lambda surrogate: None)
    monkeypatch.setattr(sensitivity, "reading_sensitivity", lambda model, **kwargs: indices)
    result = runner.invoke(app, ["sensitivity", str(tmp_path / "s.h5"), "--out", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert any("note" in line for line in lines)
    rows = {name: next(line for line in lines if re.search(rf"\b{name}\b", line) and "[" in line)
            for name in ("E_b", "r_hj")}
    assert NEGATIVE_INDEX["noise"] in rows["r_hj"] and "negative" not in rows["E_b"]


def test_every_command_reports_that_it_is_alive_when_piped(monkeypatch):
    """A command without progress reports of its own (``simulate``) still writes progress lines
    on stderr outside a terminal: the heartbeat every command runs in (interval and heartbeat
    shortened so that the short run writes some)."""
    monkeypatch.setattr(terminal, "LINE_INTERVAL_S", 0.0)
    monkeypatch.setattr(terminal, "HEARTBEAT_S", 0.001)
    result = runner.invoke(app, ["simulate", "diagonal_compression", "--option", "nx=2", "--option", "ny=1",
                                 "--format", "csv"])
    assert result.exit_code == 0, result.output
    assert re.search(r"^podkrig: .*elapsed$", result.stderr, re.MULTILINE)
    assert result.stdout.startswith("load [kN],")  # the output itself is untouched


def test_an_inner_display_speaks_for_the_command():
    """``podkrig run``'s stage display inside the command's heartbeat: one line per interval, the
    inner one's, and a line of either counts for both."""
    clock = FakeClock()
    outer_stream, inner_stream = io.StringIO(), io.StringIO()
    with Progress("podkrig run", terminal=False, stream=outer_stream, clock=clock) as outer:
        with Progress("study", terminal=False, stream=inner_stream, clock=clock) as inner:
            inner.update("Training snapshots (FE)", 3, 256)
            clock.now += LINE_INTERVAL_S
            outer.tick()
            inner.tick()
            outer.tick()
        clock.now += LINE_INTERVAL_S - 1
        outer.tick()  # the inner line was written LINE_INTERVAL_S - 1 ago: nothing yet
        clock.now += 1
        outer.tick()
    assert inner_stream.getvalue().splitlines()[0].startswith("Training snapshots (FE): 3/256")
    assert len(inner_stream.getvalue().splitlines()) == 1
    assert len(outer_stream.getvalue().splitlines()) == 1 and outer_stream.getvalue().startswith("podkrig run:")
