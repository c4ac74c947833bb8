"""Run the two test lanes and print what each costs: tests, wall time, CPU time, slowest tests.

The lanes (README, "Set up and run the tests"):

- ``fast``: ``python -m pytest -m "not slow" -n 2`` — every test module, no FE-heavy test;
- ``full``: ``python -m pytest -q -n 2`` — the README's test command, what CI runs;
- ``slow`` (on request): ``-m slow``, what the full lane adds to the fast one.

For the record, not a gate: speed is measured here, not asserted in tests (a timing assertion
fails on a loaded machine). Wall time depends on the load of the machine; CPU time (user + system
of pytest, its xdist workers and every other child process it waited for) much less so. Each test's
CPU time is its own process's (``time.process_time``, all threads) plus that of the child processes
it reaped (Dask workers), recorded by the plugin in this file.

Usage::

    python scripts/lane_durations.py                         # both lanes, -n 2
    python scripts/lane_durations.py --lanes fast --top 10
    python scripts/lane_durations.py --workers 0 --lanes full tests/test_study.py   # one file, one process

Paths after the options narrow both lanes to those files (default: the configured ``testpaths``).
"""

import argparse
import json
import os
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LANES = {"fast": ["-m", "not slow"], "full": [], "slow": ["-m", "slow"]}  # slow: what full adds to fast
LOG_ENV = "LANE_DURATIONS_LOG"


# ------------------------------------------------------------------------------- pytest plugin
# loaded into pytest (and its xdist workers) by ``-p lane_durations``; records each test's cost

def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


_STARTS = {}  # nodeid -> (wall, CPU, children's CPU) when the test's setup began


def pytest_runtest_protocol(item, nextitem):
    _STARTS[item.nodeid] = (time.perf_counter(), time.process_time(), _children_cpu())


def _record(item):
    log = os.environ.get(LOG_ENV)
    start = _STARTS.pop(item.nodeid, None)
    if not log or start is None:
        return
    wall0, cpu0, child0 = start
    line = {"test": item.nodeid, "wall": time.perf_counter() - wall0,
            "cpu": time.process_time() - cpu0 + _children_cpu() - child0,
            "slow": item.get_closest_marker("slow") is not None}
    with open(log, "a") as f:  # one short line per write: appends from several workers do not mix
        f.write(json.dumps(line) + "\n")


def pytest_runtest_makereport(item, call):
    if call.when == "teardown":
        _record(item)


# ------------------------------------------------------------------------------- the runner

def _summary_counts(output):
    """{'passed': 1234, 'skipped': 5, ...} from pytest's last summary line."""
    lines = [ln for ln in output.splitlines() if re.search(r"\d+ (passed|failed|error)", ln)]
    if not lines:
        return {}
    return {word: int(n) for n, word in re.findall(r"(\d+) (\w+)", lines[-1])}


def run_lane(name, workers, paths, top):
    """Run one lane; returns (row, per-test records)."""
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "tests.jsonl"
        path = [str(ROOT / "scripts")] + ([os.environ["PYTHONPATH"]] if os.environ.get("PYTHONPATH") else [])
        env = {**os.environ, LOG_ENV: str(log), "PYTHONPATH": os.pathsep.join(path)}  # finds this plugin
        xdist = ["-p", "no:xdist"] if workers == 0 else ["-n", str(workers)]
        cmd = [sys.executable, "-m", "pytest", "-q", "-p", "lane_durations", *xdist, *LANES[name],
               f"--durations={top}", *paths]
        print("$", " ".join(cmd), flush=True)
        before = _children_cpu()
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        cpu = _children_cpu() - before
        records = [json.loads(ln) for ln in log.read_text().splitlines()] if log.exists() else []
    counts = _summary_counts(proc.stdout)
    tail = "\n".join(proc.stdout.splitlines()[-(top + 8):])
    print(tail, flush=True)
    failed = sum(counts.get(k, 0) for k in ("failed", "error", "errors"))
    tests = failed + sum(counts.get(k, 0) for k in ("passed", "skipped", "xfailed", "xpassed"))
    row = {"lane": name, "tests": tests, "passed": counts.get("passed", 0), "failed": failed,
           "wall": wall, "cpu": cpu, "exit": proc.returncode}
    return row, records


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lanes", default="fast,full",
                        help="comma-separated: fast, full (default both); slow: the slow tests alone")
    parser.add_argument("--workers", type=int, default=2, help="xdist workers; 0 runs in one process")
    parser.add_argument("--top", type=int, default=30, help="slowest tests to list per lane (by CPU)")
    parser.add_argument("paths", nargs="*", help="test files or folders (default: the configured testpaths)")
    args = parser.parse_args(argv)
    rows = []
    for name in args.lanes.split(","):
        if name not in LANES:
            parser.error(f"unknown lane {name!r}; choose from {', '.join(LANES)}")
        row, records = run_lane(name, args.workers, args.paths, args.top)
        rows.append(row)
        print(f"\n{name} lane, {args.top} most expensive tests by CPU (s):")
        print(f"{'CPU':>8} {'wall':>8}  test")
        for r in sorted(records, key=lambda r: -r["cpu"])[: args.top]:
            print(f"{r['cpu']:8.2f} {r['wall']:8.2f}  {r['test']}{'  [slow]' if r['slow'] else ''}")
    load = os.getloadavg()[0]
    print(f"\nmachine: {os.cpu_count()} cores, load {load:.1f}; workers: {args.workers or 'one process'}")
    print("| lane  |  tests | passed | failed |  wall (s) |  CPU (s) |")
    print("|-------|--------|--------|--------|-----------|----------|")
    for r in rows:
        print(f"| {r['lane']:<5} | {r['tests']:>6} | {r['passed']:>6} | {r['failed']:>6} "
              f"| {r['wall']:>9.1f} | {r['cpu']:>8.1f} |")
    return max(r["exit"] for r in rows)


if __name__ == "__main__":
    sys.exit(main())
