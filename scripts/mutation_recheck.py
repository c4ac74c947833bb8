"""Re-run surviving mutants of one module against whole test files (issue 12).

mutmut 3 runs each mutant only against the tests its call statistics attribute to the mutated
function, and it records a function's calls at the teardown of the test that made them: a
module-scoped fixture built during the first test of a file is attributed to that test alone, so
the other tests that use the fixture's surrogate or store are never run against the mutant, and a
test file left out of ``pytest_add_cli_args_test_selection`` is never run at all. This script takes
the survivors (and "no tests") from a ``mutants/<module>.meta`` file and runs each one against the
given test files in full, ``MUTANT_UNDER_TEST=NAME python -m pytest -x`` in ``mutants/``, one fresh
process per mutant. Results go to a JSON file, written after every mutant, so an interrupted run
resumes where it stopped::

    cd mutants
    python ../scripts/mutation_recheck.py podkrig/surrogate/podkriging.py.meta /tmp/recheck.json \\
        tests/test_surrogate.py tests/test_bitflips.py

A developer tool, not a CI step (the finished campaign: docs/benchmarks/mutation-testing.md).
"""

import argparse
import json
import os
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

from rich.progress import track

SURVIVOR_EXIT_CODES = (0, 5, 33)  # survived, or no test of the selection called the function


def survivors(meta):
    """Names of the surviving and "no tests" mutants recorded in a mutmut ``.meta`` file."""
    codes = json.loads(Path(meta).read_text())["exit_code_by_key"]
    return [name for name, code in codes.items() if code in SURVIVOR_EXIT_CODES]


def recheck(name, tests, timeout):
    """Run one mutant against ``tests``; returns (status, first failing test or "")."""
    env = dict(os.environ, MUTANT_UNDER_TEST=name, NUMBA_THREADING_LAYER="forksafe", PYTHONPATH=os.getcwd())
    try:
        run = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:xdist", "-p", "no:cacheprovider",
                              *tests], env=env, capture_output=True, text=True, timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return "timeout", ""
    failed = next((line for line in run.stdout.splitlines() if line.startswith("FAILED")), "")
    status = {0: "survived", 1: "killed"}.get(run.returncode, f"exit code {run.returncode}")
    return status, failed


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("meta", help="mutants/<module path>.meta written by mutmut run")
    ap.add_argument("out", help="JSON file of results (resumed if it exists)")
    ap.add_argument("tests", nargs="+", help="test files or node ids to run against each mutant")
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per mutant (default 600)")
    args = ap.parse_args(argv)
    out = Path(args.out)
    done = json.loads(out.read_text()) if out.exists() else {}
    todo = [name for name in survivors(args.meta) if name not in done]
    for name in track(todo, description="mutants"):
        t0 = time.perf_counter()
        status, failed = recheck(name, args.tests, args.timeout)
        done[name] = {"status": status, "failed": failed, "seconds": round(time.perf_counter() - t0, 1)}
        out.write_text(json.dumps(done, indent=1, ensure_ascii=False))
    counts = Counter(result["status"] for result in done.values())
    print(f"{len(done)} mutants: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    for name, result in done.items():
        if result["status"] != "killed":
            print(f"  {result['status']:<9} {name}")


if __name__ == "__main__":
    main()
