"""Mutation score per module from the results of a ``mutmut run`` (issue 12).

mutmut is a developer tool, not a CI step::

    pip install "mutmut>=3.8"
    NUMBA_THREADING_LAYER=forksafe mutmut run --max-children 1   # selection: [tool.mutmut] in pyproject.toml
    python scripts/mutation_score.py     # this table; --survivors lists the surviving mutants

``NUMBA_THREADING_LAYER=forksafe``: mutmut forks each mutant from a warmed-up process, and numba's
default GNU-OpenMP threading layer terminates such a child (exit code -15, "other" below) as soon
as a kriging kernel runs; the fork-safe layer (workqueue here) does not.

mutmut writes one ``mutants/<module path>.meta`` JSON file per mutated module with the exit code
of the test run of each mutant. The score is ``(killed + timeout) / checked``: a mutant that makes
the tests hang is detected. "no tests" mutants (no test of the selection called the mutated
function) count as survivors.

``--baseline DIR`` (a copy of an earlier ``mutants/``) fills in the mutants the latest run did not
check (e.g. ``mutmut run NAME ...`` re-ran only the earlier survivors after tests were added): a
mutant killed then is still killed, since tests were only added.
"""

import argparse
import json
import os
from collections import Counter
from pathlib import Path

# Exit codes of the test run of a mutant, as mutmut 3 records them (mutmut.stats).
STATUS_BY_EXIT_CODE = {
    None: "not checked",
    0: "survived",
    1: "killed",
    3: "killed",
    5: "no tests",
    33: "no tests",
    34: "skipped",
    36: "timeout",
    -24: "timeout",
    24: "timeout",
    152: "timeout",
    255: "timeout",
}
COLUMNS = ("killed", "timeout", "survived", "no tests", "not checked", "other")


def module_results(mutants_dir, baseline=None):
    """``{module path: {mutant name: status}}`` from the ``*.meta`` files under ``mutants_dir``;
    mutants not checked there take their status under ``baseline`` (an earlier ``mutants/``)."""
    results = {}
    old = module_results(baseline) if baseline else {}
    for meta in sorted(Path(mutants_dir).rglob("*.py.meta")):
        module = str(meta.relative_to(mutants_dir))[: -len(".meta")]
        exit_codes = json.loads(meta.read_text())["exit_code_by_key"]
        results[module] = {
            name: STATUS_BY_EXIT_CODE.get(code, "other") for name, code in exit_codes.items()
        }
        for name, status in results[module].items():
            if status == "not checked":
                results[module][name] = old.get(module, {}).get(name, status)
    return results


def score_table(results):
    """Markdown table: mutants per status and the score ``(killed + timeout) / checked`` (%)."""
    lines = [
        "| module | mutants | " + " | ".join(COLUMNS) + " | score |",
        "|---|---:|" + "---:|" * len(COLUMNS) + "---:|",
    ]
    total = Counter()
    for module, statuses in list(results.items()) + [("**all**", None)]:
        counts = total if statuses is None else Counter(statuses.values())
        if statuses is not None:
            total.update(counts)
        n = sum(counts.values())
        checked = n - counts["not checked"]
        detected = counts["killed"] + counts["timeout"]
        score = f"{100.0 * detected / checked:.1f} %" if checked else "–"
        cells = " | ".join(str(counts[c]) for c in COLUMNS)
        lines.append(f"| {module} | {n} | {cells} | {score} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=__doc__.split("\n\n", 1)[1])
    parser.add_argument("--mutants", default="mutants", help="mutmut's work directory")
    parser.add_argument("--baseline", help="an earlier mutants/ directory for the mutants not re-run")
    parser.add_argument("--survivors", action="store_true",
                        help="also list the mutants that survived or had no tests")
    args = parser.parse_args()
    results = module_results(args.mutants, args.baseline)
    if not results:
        raise SystemExit(f"no mutmut results (*.py.meta) under {args.mutants!r}: run `mutmut run`")
    print(f"machine load (1, 5, 15 min): {', '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(score_table(results))
    if args.survivors:
        for statuses in results.values():
            for name, status in statuses.items():
                if status in ("survived", "no tests"):
                    print(f"{status:9s} {name}")


if __name__ == "__main__":
    main()
