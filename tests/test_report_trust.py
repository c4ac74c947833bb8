"""Reports that must not contradict their own results: the GA figure marks the reported optimum,
one significance level α in the diagnosis section, flat-jack fits against the jack pressure with
the phase, units on the nonlinear report's tables, negative Sobol' indices explained, and a
nonlinear run that stopped early saying so in the first line of its report. Each test reads the
drawn coordinates or the table structure, not the sentences."""

import dataclasses
import re
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from fe.solvers.nonlinear import PathSettings
from podkrig.cli import app
from podkrig.diagnosis.results import CHI2_ALPHA_SHARE
from podkrig.diagnosis.settings import DiagnosisSettings
from podkrig.ga.options import GAOptions
from podkrig.online.invert import invert
from podkrig.online.measurement import NoiseModel
from podkrig.online.problem import InverseProblem
from podkrig.reports import inverse as inverse_report
from podkrig.reports.figures import load_label, pyplot
from podkrig.reports.flat_jack import jack_pressures
from podkrig.reports.ga import plot_parameters
from podkrig.reports.html import Page
from podkrig.reports.nonlinear import SETTING_UNITS, write_nonlinear_report
from podkrig.reports.sensitivity import NEGATIVE_INDEX, index_notes, negative_index
from podkrig.reports.study import _diagnosis, _sensitivity
from tests.test_online_results import SIGMA
from tests.test_problem import TwoBasinModel, _zero_data


@pytest.fixture(scope="module")
def polished():
    """An inversion whose least-squares polish moved the optimum away from the GA's best: the
    two-basin model (exact minima at m = 0.2 and 0.8), the GA's own polish off, so the GA's best
    (0.175 with seed 0) is rough and the reported optimum is 0.2."""
    model = TwoBasinModel()
    problem = InverseProblem(model, _zero_data(model), NoiseModel(sigma=SIGMA))
    result = invert(problem, rng=0, population_size=6, generations=2, n_starts=1, options=GAOptions(polish="none"))
    assert abs(result.ga.x[0] - result.x[0]) > 0.01  # the premise: the polish moved the point
    return result


def _line(ax, label):
    lines = [ln for ln in ax.lines if ln.get_label() == label]
    assert len(lines) == 1, [ln.get_label() for ln in ax.lines]
    return lines[0]


def test_ga_parameter_figure_marks_the_reported_optimum_not_the_ga_best(polished, tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(inverse_report, "save", lambda fig, path, dpi=110: drawn.setdefault("fig", fig))
    inverse_report.plot_ga_parameters(polished, tmp_path / "ga_parameters.png")
    ax = drawn["fig"].axes[0]
    star = _line(ax, "reported optimum")
    assert star.get_xdata()[0] == polished.x[0] and star.get_ydata()[0] == polished.misfit
    dashed = [ln for ln in ax.lines if ln.get_linestyle() == "--"]
    assert [ln.get_xdata()[0] for ln in dashed] == [polished.x[0]]  # the dashed line is the optimum
    assert _line(ax, "GA best before the polish").get_xdata()[0] == polished.ga.x[0]
    pyplot().close("all")


def test_ga_history_figure_shows_the_reported_optimum_misfit(polished, tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(inverse_report, "save", lambda fig, path, dpi=110: drawn.setdefault("fig", fig))
    inverse_report.plot_ga_history(polished, tmp_path / "ga_history.png")
    line = _line(drawn["fig"].axes[0], "reported optimum")
    assert set(line.get_ydata()) == {polished.misfit}
    pyplot().close("all")


def test_ga_parameters_without_an_optimum_marks_the_ga_best_only(polished):
    axes = plot_parameters(polished.ga)
    star = _line(axes[0], "reported optimum")
    assert star.get_xdata()[0] == polished.ga.x[0] and star.get_ydata()[0] == polished.ga.fun
    assert not [ln for ln in axes[0].lines if ln.get_label() == "GA best before the polish"]
    with pytest.raises(ValueError, match="optimum x must hold 1 values"):
        plot_parameters(polished.ga, optimum=(np.zeros(3), 0.0))
    pyplot().close("all")


# --- the diagnosis section: one α, the settings' -----------------------------------------------

def _diagnosis_report(alpha):
    """A diagnosis's report numbers (``DiagnosisResult.to_dict`` keys the section reads) with the
    settings' ``alpha``; the χ² test ran at α × CHI2_ALPHA_SHARE, as the diagnosis records it."""
    candidate = {"name": "weak_joint", "applicable": True, "location": "bed joint 3", "delta_chi2": 0.4,
                 "p_corrected": 0.7, "parameter": {"name": "f", "value": 0.5, "unit": "-"}}
    return {"verdict": "adequate", "alpha": alpha, "cause": None, "detail": None, "gain": None,
            "n_fe_runs": 10, "seconds": 1.0, "candidates": [candidate],
            "adequacy": {"chi2_dof": 1.1, "p_value": 0.3, "alpha": alpha * CHI2_ALPHA_SHARE, "basis": "noise"}}


def test_diagnosis_section_states_one_alpha_the_settings_value():
    alpha = DiagnosisSettings().alpha
    page = Page("t")
    _diagnosis(page, _diagnosis_report(alpha))
    text = page.markup()
    cells = re.findall(r"<td>significance level α \(-\)</td><td[^>]*>([^<]+)</td>", text)
    assert [float(c) for c in cells] == [alpha]
    stated = {float(v) for v in re.findall(r"α = ([0-9.eE+-]+[0-9])", text)}
    assert stated == {alpha}, stated  # the text's α (the candidates' level) is the table's
    assert f"{alpha * CHI2_ALPHA_SHARE:g}" not in text  # the χ² test's level appears only as a share of α


# --- negative Sobol' indices: noise or flagged -------------------------------------------------

def test_a_negative_index_is_noise_inside_its_interval_and_flagged_beyond_it():
    assert negative_index(-0.0009, -0.004, 0.003) == "noise"
    assert negative_index(-0.05, -0.08, -0.02) == "suspect"  # the whole interval below 0
    assert negative_index(0.2, 0.1, 0.3) is None and negative_index(float("nan"), None, None) is None
    assert negative_index(-0.01, None, None) == "suspect"  # no interval: cannot be called noise
    assert index_notes((0.2, 0.1, 0.3), (-0.0009, -0.004, 0.003)) == NEGATIVE_INDEX["noise"]
    both = index_notes((-0.0009, -0.004, 0.003), (-0.05, -0.08, -0.02))
    assert both.startswith(NEGATIVE_INDEX["suspect"]) and NEGATIVE_INDEX["noise"] in both
    assert index_notes((0.2, 0.1, 0.3)) == ""


def _sensitivity_report(first, first_low, first_high):
    """The study's sensitivity numbers for one test with two parameters: the misfit's indices."""
    misfit = {"parameters": ["E_b", "r_hj"], "total": [[0.9, 0.01]], "total_low": [[0.85, 0.0]],
              "total_high": [[0.95, 0.02]], "first": [[0.85, first]], "first_low": [[0.8, first_low]],
              "first_high": [[0.9, first_high]]}
    readings = {"parameters": ["E_b", "r_hj"], "total": [[0.9, 0.05]]}
    return {"misfit": misfit, "readings": {None: readings}, "propose_fixing": [], "threshold": 0.01}


def _table(markup):
    head = re.findall(r"<th>([^<]*)</th>", markup)
    rows = [re.findall(r"<td[^>]*>([^<]*)</td>", row) for row in re.findall(r"<tr>(<td.*?)</tr>", markup)]
    return head, rows


def test_study_sensitivity_table_explains_a_negative_first_order_index():
    study = SimpleNamespace(calibration_tests=[], tests=[])
    page = Page("t")
    _sensitivity(page, study, _sensitivity_report(-0.0009, -0.004, 0.003))
    head, rows = _table(page.markup())
    assert head[-1] == "note"
    notes = {row[0]: row[-1] for row in rows}
    assert notes == {"E_b": "", "r_hj": NEGATIVE_INDEX["noise"]}
    assert float(rows[1][3]) == pytest.approx(-0.0009, rel=1e-12)  # the estimate is shown as it is

    page = Page("t")
    _sensitivity(page, study, _sensitivity_report(-0.05, -0.08, -0.02))
    head, rows = _table(page.markup())
    assert rows[1][-1] == NEGATIVE_INDEX["suspect"]

    page = Page("t")
    _sensitivity(page, study, _sensitivity_report(0.004, -0.001, 0.01))
    head, rows = _table(page.markup())
    assert "note" not in head and all(len(row) == len(head) for row in rows)


# --- flat-jack fits against the jack pressure, phase by phase ----------------------------------

@pytest.fixture(scope="module")
def flat_jack_steps():
    """The steps of the example flat-jack study's test (chisari preset, phases 0b, 1 and 2)."""
    sc = build_scenario({"scenario": "flat_jack", "phases": ["0b", "1", "2"], "layout": "L6"})
    return sc.steps


def test_jack_pressures_follow_the_jack_each_phase_raises(flat_jack_steps):
    levels = np.arange(1.0, 21.0)
    pressure, phases, labels = jack_pressures(flat_jack_steps, levels)
    assert list(labels) == ["0b", "1", "2"]
    assert list(phases) == ["0b"] + ["1"] * 10 + ["2"] * 9
    # phase 1 raises p_H 0.1 → 1.0 MPa with the vertical jacks seated; phase 2 raises p_V1 = p_V2 0.1 → 0.5
    np.testing.assert_allclose(pressure, [0.0] + list(np.arange(1, 11) / 10) + list(np.arange(2, 11) / 20),
                               rtol=0, atol=1e-12)  # the schedule's decimal pressures, exactly as written
    assert "p_H" in labels["1"] and "p_V1" in labels["2"] and "p_V2" in labels["2"]
    subset, _, _ = jack_pressures(flat_jack_steps, [3.0, 12.0])  # measured at some steps only
    np.testing.assert_allclose(subset, [0.2, 0.1], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="load levels .*21"):
        jack_pressures(flat_jack_steps, [21.0])


class _FlatJackFit:
    """What ``plot_fit`` reads of an inversion: measurement, noise and prediction, two gauges."""

    def __init__(self, n_levels):
        levels = np.arange(1.0, n_levels + 1)
        self.values = np.column_stack([levels, -levels]) * 1e-3
        sd = np.full_like(self.values, 1e-4)
        measurement = SimpleNamespace(sensor_names=("G1", "G2"), load_levels=levels, values=self.values,
                                      grid=lambda flat: sd)
        self.problem = SimpleNamespace(measurement=measurement, misfit=SimpleNamespace(noise_std=sd.ravel()))

    def predicted(self):
        return self.values * 1.01, None


def test_flat_jack_fit_is_drawn_against_the_jack_pressure_with_each_phase(flat_jack_steps, tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(inverse_report, "save", lambda fig, path, dpi=110: drawn.setdefault("fig", fig))
    fit = _FlatJackFit(20)
    inverse_report.plot_fit(fit, tmp_path / "fit.png", load_unit="step", steps=flat_jack_steps)
    ax = drawn["fig"].axes[0]
    assert ax.get_ylabel() == "jack pressure (MPa)"
    pressure, phases, labels = jack_pressures(flat_jack_steps, np.arange(1.0, 21.0))
    measured = {c.get_label(): c.lines[0] for c in ax.containers}
    assert len(measured) == 3  # one series per phase
    for phase, label in labels.items():
        line = next(ln for lab, ln in measured.items() if lab.startswith(label))
        np.testing.assert_array_equal(line.get_ydata(), pressure[phases == phase])
        np.testing.assert_array_equal(line.get_xdata(), fit.values[phases == phase, 0])
    drawn.clear()
    inverse_report.plot_residuals(fit, tmp_path / "residuals.png", load_unit="step", steps=flat_jack_steps)
    ticks = [t.get_text() for t in drawn["fig"].axes[0].get_yticklabels()]
    assert [f"phase {ph}," in t and f"{p:g} MPa" in t for t, ph, p in zip(ticks, phases, pressure)] == [True] * 20
    pyplot().close("all")


def test_fit_of_a_load_test_keeps_the_load_axis(tmp_path, monkeypatch):
    drawn = {}
    monkeypatch.setattr(inverse_report, "save", lambda fig, path, dpi=110: drawn.setdefault("fig", fig))
    inverse_report.plot_fit(_FlatJackFit(4), tmp_path / "fit.png", load_unit="kN")
    ax = drawn["fig"].axes[0]
    assert ax.get_ylabel() == "load (kN)"
    np.testing.assert_array_equal(ax.containers[0].lines[0].get_ydata(), [1.0, 2.0, 3.0, 4.0])
    pyplot().close("all")


# --- the nonlinear report: units everywhere, and the first line of a run that stopped early -----

def test_every_solver_setting_has_a_unit():
    """Fails when the solver gains a setting the report's table would show without a unit."""
    assert set(SETTING_UNITS) == {f.name for f in dataclasses.fields(PathSettings)}
    assert all(SETTING_UNITS.values())


@pytest.fixture(scope="module")
def stopped_run():
    """couplet_tension ended by its step limit (5 increments) before its last control level."""
    sc = build_scenario({"scenario": "couplet_tension", "max_steps": 5})
    r = sc.run(field=True)
    assert r.status == "budget_exhausted" and r.limit == "steps" and r.reached < r.load_levels[-1]
    return sc, r


def _tables(page):
    """Every table of an HTML page: (caption, header, rows)."""
    out = []
    for body in re.findall(r"<table>(.*?)</table>", page, re.DOTALL):
        caption = re.search(r"<caption>(.*?)</caption>", body)
        head = re.findall(r"<th>([^<]*)</th>", body)
        rows = [re.findall(r"<td[^>]*>([^<]*)</td>", row) for row in re.findall(r"<tr>(<td.*?)</tr>", body)]
        out.append((caption.group(1) if caption else None, head, rows))
    return out


def test_nonlinear_page_says_first_how_far_a_stopped_run_got(stopped_run, tmp_path):
    sc, r = stopped_run
    page = write_nonlinear_report(sc, r, sc.resolve(None), tmp_path).read_text(encoding="utf-8")
    first = re.search(r"</h1>\s*(<[^>]+>.*?)</div>", page, re.DOTALL).group(1)
    assert first.startswith('<div class="warn">')
    for fragment in (r.status, "max_steps", f"{r.reached:.4g}", f"{r.load_levels[-1]:.4g} {r.load_unit}"):
        assert fragment in first, fragment


def test_nonlinear_page_tables_carry_units_and_no_raw_dicts(stopped_run, tmp_path):
    sc, r = stopped_run
    values = sc.resolve(None)
    tables = {cap: (head, rows) for cap, head, rows in
              _tables(write_nonlinear_report(sc, r, values, tmp_path).read_text(encoding="utf-8"))}
    head, rows = tables["Parameters"]
    assert head == ["parameter", "value", "unit"]
    assert {row[0]: row[2] for row in rows} == {k: sc.parameters[k].unit for k in values}
    head, rows = next(v for k, v in tables.items() if k.startswith("Solver settings"))
    assert head == ["setting", "value", "unit"]
    assert {row[0] for row in rows} == set(PathSettings().to_dict())
    assert all(row[2] == SETTING_UNITS[row[0]] for row in rows)
    settings = r.path.settings
    assert {row[0]: row[1] for row in rows if type(settings[row[0]]) is int} == \
        {k: str(v) for k, v in settings.items() if type(v) is int}  # counts in full, not 3e+04
    head, rows = tables["Readings at the response levels"]
    assert all(cell == "—" for row in rows[1:] for cell in row[1:])  # the levels it did not reach
    head, rows = tables["Path following"]
    assert head[-1] == "unit" and all(row[2] for row in rows)
    cells = [c for head, rows in tables.values() for row in rows for c in row]
    assert not [c for c in cells if "{" in c or "&#x27;" in c]  # no Python dict or repr in a cell


def test_simulate_table_output_says_first_that_the_run_stopped(stopped_run):
    _, r = stopped_run
    result = CliRunner().invoke(app, ["simulate", "couplet_tension", "--option", "max_steps=5"])
    assert result.exit_code == 1
    first = result.stdout.splitlines()[0]
    for fragment in (r.status, "max_steps", f"{r.reached:.4g}", f"{r.load_levels[-1]:.4g} {r.load_unit}"):
        assert fragment in first, fragment


def test_a_step_axis_is_not_labelled_as_a_load():
    assert load_label("step") == "step" and load_label("kN") == "load (kN)"
