"""The page of a nonlinear run that stopped early tells which limit ended it and which option
raises it (podkrig.reports.nonlinear)."""

import dataclasses
import re

import pytest

from fe.scenarios import build_scenario
from fe.solvers.nonlinear import BUDGET, LIMITS, PathSettings
from podkrig.reports import nonlinear as report


def test_every_limit_of_the_solver_is_named_by_an_option_that_exists():
    """Fails if the solver gains or renames a limit, or a budget option, without the report's
    remedy following it."""
    options = {f.name for f in dataclasses.fields(PathSettings)}
    assert set(report.LIMITS) == set(LIMITS)
    assert {option for _, option in report.LIMITS.values()} <= options
    assert set(report.BUDGET_OPTIONS.split(", ")) <= options


@pytest.mark.parametrize("spec, limit, words, option", [
    ({"max_steps": 5}, "steps", "step limit", "max_steps"),
    ({"max_total_iterations": 7}, "iterations", "iteration limit", "max_total_iterations"),
])
def test_a_run_stopped_by_its_budget_names_the_limit_and_its_option(tmp_path, spec, limit, words, option):
    sc = build_scenario({"scenario": "couplet_tension", **spec})
    r = sc.run()
    assert r.status == BUDGET and r.limit == limit
    page = report.write_nonlinear_report(sc, r, sc.resolve(None), tmp_path).read_text(encoding="utf-8")
    # the warning itself (the page's solver table lists every option anyway)
    warning = re.search(r'<div class="warn">(.*?)</div>', page, re.DOTALL).group(1)
    for fragment in (words, f"raise {option}", "max_cpu_seconds", "max_total_iterations", "max_steps"):
        assert fragment in warning
