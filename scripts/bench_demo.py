"""Time ``podkrig demo`` end to end: a cold run (empty output folder, no numba cache) and a cached rerun.

The cold run starts with a fresh output folder and empty numba and bytecode caches
(``NUMBA_CACHE_DIR`` and ``PYTHONPYCACHEPREFIX`` point to new temporary folders), as after a fresh
install; the cached run repeats the same command with those caches and the output folder kept.
Each run is a separate ``podkrig demo`` process with the process-default thread settings, as a
user runs it. Targets (issue 8): cold under 5 min, cached under 15 s, on 2 cores.

``--fresh-venv`` also creates a new virtual environment, installs this checkout into it
(``pip install -e``, from the package index; the install time is reported separately) and times
the demo with that environment's ``podkrig``.

Prints a Markdown table (for BENCHMARKS.md)::

    python scripts/bench_demo.py
    python scripts/bench_demo.py --fresh-venv
"""

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _podkrig(venv=None):
    """The ``podkrig`` executable of ``venv`` (default: the one beside this Python)."""
    folder = Path(venv) / "bin" if venv else Path(sys.executable).parent
    exe = folder / "podkrig"
    if not exe.is_file():
        sys.exit(f"no podkrig executable at {exe}: install the project first (pip install -e .)")
    return exe


def _cpu():
    """The processor's model name (Linux), else the machine type."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return f"{line.split(':', 1)[1].strip()} ({platform.machine()})"
    except OSError:
        pass
    return platform.machine()


def _time(cmd, env):
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
    return seconds


def _stages(out):
    summary = json.loads((out / "summary.json").read_text())
    stages = summary["stages"].values()
    return sum(s["fe_runs"] for s in stages), sum(s["cached"] for s in stages), len(stages)


def _fresh_venv(folder):
    """Create a virtual environment in ``folder`` and install this checkout; returns the install time, s."""
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True)
    pip = [str(folder / "bin" / "python"), "-m", "pip", "install", "-q"]
    subprocess.run([*pip, "--upgrade", "pip"], check=True)
    subprocess.run([*pip, "-e", str(REPO)], check=True)
    return time.perf_counter() - t0


def main(argv=None):
    parser = argparse.ArgumentParser(description="Time 'podkrig demo': cold (fresh caches) and fully cached.")
    parser.add_argument("--fresh-venv", action="store_true",
                        help="Also create a new virtual environment and install the project into it first.")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_demo_") as tmp:
        tmp = Path(tmp)
        venv = None
        if args.fresh_venv:
            venv = tmp / "venv"
            rows.append(("fresh virtual environment: pip install -e .", _fresh_venv(venv), None))
        env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / "numba"), PYTHONPYCACHEPREFIX=str(tmp / "pycache"))
        out = tmp / "demo"
        cmd = [str(_podkrig(venv)), "demo", "--out", str(out)]
        rows.append(("cold: empty output folder, numba and bytecode caches", _time(cmd, env), _stages(out)))
        rows.append(("cached: the same command again", _time(cmd, env), _stages(out)))
    print(f"**podkrig demo** ({datetime.date.today().isoformat()}; {_cpu()}, {os.cpu_count()} cores, "
          f"Python {platform.python_version()}; process-default threads)\n")
    print("| run | wall time (s) | FE runs | stages cached |")
    print("|---|---:|---:|---:|")
    for label, seconds, stages in rows:
        fe, cached, total = stages if stages else ("", "", "")
        print(f"| {label} | {seconds:.1f} | {fe} | {cached}{f' of {total}' if stages else ''} |")


if __name__ == "__main__":
    main()
