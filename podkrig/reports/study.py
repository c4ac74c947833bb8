"""The one-page HTML report of a study: a section per stage, numbers with units, warnings in plain
words with what to do about them, and the figures the stages drew beside the page.

Presentation only: :func:`write_study_report` reads the stage manifests of
:func:`podkrig.study.run_study` (their JSON results), the calibration as its result object
(:class:`~podkrig.online.calibrate.CalibrationResult`, rendered by the same functions as the
inversion report of ``podkrig invert``: :mod:`podkrig.reports.inverse`) and the study settings;
it computes nothing and draws nothing (the figures are stage outputs, already in the report folder).
"""

import base64
import html
import json
import math
from pathlib import Path

from podkrig.diagnosis.results import CHI2_ALPHA_SHARE
from podkrig.online.findings import RESIDUAL_CONVENTION, chi2_basis
from podkrig.offline.results import OfflineResult
from podkrig.reports.diagnosis import chi2_level_text, fitted_parameter_text, unnamed_significant
from podkrig.reports.html import Page, num, pct, unit_cell
from podkrig.reports.inverse import (distribution_file, render_fit, render_ga, render_joint, render_parameters,
                                     render_region, render_rvc)
from podkrig.reports.offline import offline_table
from podkrig.reports.sensitivity import index_notes
from podkrig.reports.surrogate import fit_tables, held_out_tables, layout_table
from podkrig.surrogate.results import HeldOutResult, SurrogateFitResult, ValidationModelResult

#: report sections: (anchor, heading), in page order
SECTIONS = (
    ("summary", "Summary"),
    ("study", "The study"),
    ("offline", "Offline stage: FE snapshots"),
    ("surrogate", "Surrogate: POD + kriging"),
    ("held-out", "Surrogate check on held-out FE runs"),
    ("sensitivity", "Global sensitivity: which parameters can the data inform?"),
    ("inversion", "Inversion"),
    ("region", "Region of equivalence"),
    ("rvc", "Response variability (RVC)"),
    ("diagnosis", "Model diagnosis"),
    ("provenance", "Provenance and cache"),
)


def _finite(obj):
    """``obj`` with non-finite floats replaced by None (for the JSON shown on the page)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def write_study_report(path, study, records, calibration, warnings):
    """Write the study report page; returns its path.

    Parameters
    ----------
    path : str or Path
        ``index.html`` in the folder holding the stages' figures.
    study : podkrig.study.Study
    records : sequence of podkrig.study.pipeline.StageRecord
        Every stage of the run, in order.
    calibration : podkrig.online.calibrate.CalibrationResult
        The calibration stage's result, read back (with the region's members).
    warnings : sequence of FindingText
        The study's findings in words (:func:`podkrig.reports.findings.words` of
        :func:`podkrig.study.pipeline.study_findings`).
    """
    stages = {r.name: r for r in records}
    res = {name: r.result for name, r in stages.items()}
    tests = study.calibration_tests
    page = Page(f"podkrig study: {study.name}")
    units = sorted({res[t.stage("measurement")]["load_unit"] for t in tests})
    page.paragraph(f"Study file {study.path}. Units: N, mm, MPa; interface stiffness N/mm³; loads in "
                   f"{', '.join(units)}." + (f" A joint calibration over {len(tests)} tests: "
                                             f"{', '.join(t.name for t in tests)}." if study.tests else ""), "meta")
    page.links([(f"#{anchor}", title) for anchor, title in SECTIONS])
    by_section = {}
    for w in warnings:
        by_section.setdefault(w.section, []).append(w)

    def section(anchor):
        page.heading(dict(SECTIONS)[anchor], anchor=anchor)
        for w in by_section.get(anchor, ()):
            page.warning(w.message, w.remedy)

    _summary(page, study, res, calibration, warnings)
    section("study")
    _study(page, study)
    section("offline")
    _offline(page, stages)
    section("surrogate")
    for t in tests:
        _test_heading(page, t)
        _surrogate(page, study, res[t.stage("surrogate")], t.file(""))
    section("held-out")
    for t in tests:
        _test_heading(page, t)
        _held_out(page, res[t.stage("held_out_validation")], t.file(""))
    section("sensitivity")
    _sensitivity(page, study, res.get("sensitivity"))
    section("inversion")
    inv = calibration.inversion
    if study.tests:
        render_joint(page, inv)
    outputs = stages["calibration"].manifest["outputs"]
    for t in tests:
        _test_heading(page, t)
        render_fit(page, calibration.tests[t.name], t.file(""), f"report/{t.file('deformed.png')}" in outputs)
    render_ga(page)
    section("region")
    render_region(page, calibration.region, calibration.posterior)
    section("rvc")
    render_rvc(page, calibration.rvc, "" if study.validation else " No validation model is configured: add a "
               "[[validation]] table to propagate the calibration to another test.",
               figures={m.name: distribution_file(m.name) for m in study.validation
                        if f"report/{distribution_file(m.name)}" in outputs})
    for m in study.validation:
        fit = res[f"validation_model.{m.name}"]["surrogate"]
        if fit.get("excluded_rows"):
            page.paragraph(f"Validation model {m.name}: {len(fit['excluded_rows'])} of its {m.design.n} snapshots over "
                           f"the search box ({fit['excluded_why']}) are left out of its surrogate, which learns the "
                           "capacity of the runs that have one; the FE runs at region members above measure how many "
                           "fail within the region.", "meta")
    section("diagnosis")
    _diagnosis_intro(page)
    for t in tests:
        _test_heading(page, t)
        _diagnosis(page, res.get(t.stage("diagnosis")), t.file(""))
    section("provenance")
    _provenance(page, records)
    return page.write(path)


def study_summary_html(name, calibration, diagnoses, warnings, report, figures):
    """An HTML fragment summarising a study (Jupyter's view of a StudyResult): the identified
    parameters with their region (:func:`~podkrig.reports.inverse.render_parameters`), every
    χ²/dof with its model and covariance, the warnings, and ``figures`` of the report folder
    inline (base64 PNG). ``diagnoses``: test name → the diagnosis result dict (None when off)."""
    e = html.escape
    page = Page(name)
    render_parameters(page, calibration, caption=None)
    parts = [f"<h3>podkrig study: {e(name)}</h3>", page.markup(),
             "<table><thead><tr><th>χ²/dof of</th><th>value</th><th>χ² includes</th></tr></thead><tbody>"
             + "".join(f"<tr><td>{e(m)}</td><td>{v}</td><td>{e(b)}</td></tr>"
                       for m, v, b, _ in chi2_rows(calibration, diagnoses))
             + "</tbody></table>",
             f"<p>Residuals {e(RESIDUAL_CONVENTION)}. Full report: <code>{e(str(report))}</code></p>"]
    parts += [f"<p><b>warning:</b> {e(w.message)}<br><b>what to do:</b> {e(w.remedy)}</p>" for w in warnings]
    folder = Path(report).parent
    for f in figures:
        if (folder / f).is_file():
            data = base64.b64encode((folder / f).read_bytes()).decode("ascii")
            parts.append(f'<img src="data:image/png;base64,{data}" alt="{e(f)}" style="max-width:100%">')
    return "\n".join(parts)


def _summary(page, study, res, calibration, warnings):
    page.heading("Summary", anchor="summary")
    render_parameters(page, calibration)
    diagnoses = {t.name: res.get(t.stage("diagnosis")) for t in study.calibration_tests}
    numbers = [[f"χ²/dof, {model} (-)", value, f"{basis}; {note}"]
               for model, value, basis, note in chi2_rows(calibration, diagnoses)]
    for t in study.calibration_tests:
        label = "" if t.name is None else f"test {t.name}: "
        held = res[t.stage("held_out_validation")]
        fe = calibration.tests[t.name].fe_check
        numbers += [
            [f"{label}surrogate median error on held-out FE runs (%)", pct(held["rel_error"]["median"]),
             f"{held['n_held_out']} runs, {held['n_train']} training snapshots, {held['n_modes']} POD modes"],
            [f"{label}max |FE − surrogate| at the best fit / noise σ (-)",
             num(fe.max_diff_over_noise, 3) if fe else "—",
             "below 1: the surrogate is as good as the data there" if fe else "FE check switched off"],
        ]
    for model, r in calibration.rvc.items():
        numbers.append([f"largest output CV over the region, {model} (%)", pct(float(max(r.cv))),
                        f"{len(r.outputs)} outputs, {r.n_samples} members of the region"])
        numbers += [[f"{model}: {text}", value, note] for text, value, note in capacity_rows(r)]
    page.table(["quantity", "value", "note"], numbers, caption="Key numbers")
    page.paragraph("Each χ²/dof is about 1 when its model explains the data within what its C_D allows; they differ "
                   "because they compare different models (surrogate or FE, fitted by the inversion or refitted by "
                   "the diagnosis) with the data under different covariances C_D. Residuals everywhere in this report "
                   f"are {RESIDUAL_CONVENTION}: positive where the specimen moved more than the model.", "meta")
    if warnings:
        page.paragraph(f"{len(warnings)} warning(s), each in its section below:")
        for w in warnings:
            page.warning(w.message, w.remedy)
    else:
        page.success("No warnings: the surrogate is accurate enough for the data, the calibrated model explains "
                     "the measurements within the noise, and every free parameter is identified.")


#: the outputs of a validation model summarised among a study's key numbers: its capacity
CAPACITY_OUTPUTS = ("F_peak", "d_peak")


def capacity_rows(rvc_result):
    """Key numbers of one RVC result: rows of (quantity, value, note) for each capacity output
    (:data:`CAPACITY_OUTPUTS`: the peak load and its displacement) — mean with its band and CV —
    and the share of its FE validation runs at region members that failed, when it has runs."""
    r = rvc_result
    lo, hi = r.quantile_levels[0], r.quantile_levels[-1]
    rows = [(f"{out} ({r.units[k]})", f"{num(float(r.mean[k]))} [{num(float(r.quantiles[0, k]))}, "
             f"{num(float(r.quantiles[-1, k]))}]",
             f"mean [{100 * lo:g} %, {100 * hi:g} % quantiles] over the region; CV {pct(float(r.cv[k]))} %")
            for k, out in enumerate(r.outputs) if out.split("@")[0] in CAPACITY_OUTPUTS]
    if r.runs is not None:
        runs = r.runs
        rows.append(("failed validation runs (%)", pct(r.failed_share),
                     f"{int(runs.failed.sum())} of {runs.n_runs} FE runs at region members: {int(runs.stopped.sum())} "
                     f"stopped early, {int(runs.no_peak.sum())} without a load maximum"))
    return rows


def chi2_rows(calibration, diagnoses=None):
    """The χ²/dof of a study, each with its model and what its covariance includes: rows of
    (model, value text, basis, note) for the inversion (surrogate), the FE check and the
    diagnosis's FE refit (``diagnoses``: test name → its result dict, or None), those that ran —
    in a joint calibration, the joint inversion and then each test's rows."""
    inv = calibration.inversion
    diagnoses = diagnoses or {}
    rows = [("inversion (surrogate)" + (", all tests" if inv.tests else ""), num(inv.chi2_dof, 3), inv.chi2_basis,
             f"dof = {inv.dof}; the number the inversion minimised")]
    if not inv.tests:
        return rows + _test_chi2_rows(inv, diagnoses.get(None), "")
    for name, one in inv.tests.items():
        rows.append((f"test {name}: inversion (surrogate)", num(one.chi2_dof, 3), one.chi2_basis,
                     f"dof = {one.dof} (its readings − the free parameters it depends on)"))
        rows += _test_chi2_rows(one, diagnoses.get(name), f"test {name}: ")
    return rows


def _test_chi2_rows(inv, d, label):
    rows = []
    fe = inv.fe_check
    if fe is not None:
        rows.append((f"{label}FE check", num(fe.chi2_dof_fe, 3), chi2_basis("fe_check"),
                     "no surrogate error: only the FE model against the data"))
    if d is not None:
        a = d["adequacy"]
        rows.append((f"{label}diagnosis (FE refit)", num(a["chi2_dof"], 3),
                     a.get("basis", chi2_basis("diagnosis")), f"dof = {a['dof']}; p = {num(a['p_value'], 3)}"))
    return rows


def _test_heading(page, test):
    """A sub-heading naming the test of a joint calibration (nothing for a single-test study)."""
    if test.name is not None:
        page.heading(f"Test {test.name} ({test.spec.scenario})", level=3)


def _study(page, study):
    if study.tests:
        page.table(["shared free parameter", "unit", "lower", "upper", "scale"],
                   [[p.name, unit_cell(p.unit), num(p.lower), num(p.upper), p.scale] for p in study.space.parameters])
    designs = []
    for t in study.calibration_tests:
        _test_heading(page, t)
        spec = t.spec.to_dict()
        fixed = spec.pop("parameters")
        name = spec.pop("scenario")
        page.paragraph(f"Scenario {name}; options: " + ", ".join(f"{k} = {v}" for k, v in spec.items() if v is not None)
                       + ".")
        page.table(["free parameter", "unit", "lower", "upper", "scale"],
                   [[p.name, unit_cell(p.unit), num(p.lower), num(p.upper), p.scale] for p in t.space.parameters])
        if fixed:
            page.table(["fixed parameter", "value"], [[k, num(v)] for k, v in fixed.items()])
        m = t.measurement
        page.table(["setting", "value"], [["measurement", f"{m.file.name} ({m.file})"], ["noise model", m.noise.describe()]])
        label = "" if t.name is None else f" ({t.name})"
        designs += [[f"training{label}", t.train.n, t.train.method, t.train.seed],
                    [f"held-out{label}", t.held_out.n, t.held_out.method, t.held_out.seed]]
    designs += [[f"validation model {v.name} ({v.spec.scenario})", v.design.n, v.design.method, v.design.seed]
                for v in study.validation]
    page.table(["FE design", "runs", "sampling", "seed"], designs)
    s, i = study.surrogate, study.inversion
    pod = f"{s.modes} modes" if s.modes is not None else f"energy {s.energy}" if s.energy is not None else "default energy"
    page.table(["setting", "value"], [
        ["surrogate", (f"POD ({pod}); kriging: {s.variogram} semivariogram, β {s.beta}, criterion {s.criterion}, "
                       f"nugget {s.nugget}")],
        ["inversion", (f"GA population {i.population_size} × {i.generations} generations, {i.n_starts} "
                       f"least-squares polishes, seed {i.seed}")],
        ["region of equivalence", f"{i.region_method}, confidence {i.confidence}, {i.region_samples} samples per round"],
        ["FE executor", f"Dask scheduler {study.scheduler}" if study.scheduler else
                        "in this process" if study.workers == 1 else f"{study.workers} local worker processes"],
    ])


def _store_result(record):
    """The :class:`OfflineResult` of an offline stage's record (training, held-out or validation
    model store), or None for another stage."""
    kind = record.name.split(".")[0]
    if kind in ("offline", "held_out"):
        return OfflineResult.from_dict(record.result)
    if kind == "validation_model":
        return ValidationModelResult.from_dict(record.result).store
    return None


def _offline(page, stages):
    offline_table(page, [(r.title, result, "cached" if r.cached else f"ran {r.fe_runs} FE runs")
                         for r in stages.values() if (result := _store_result(r)) is not None])


def _surrogate(page, study, r, folder=""):
    fit_tables(page, SurrogateFitResult.from_dict(r))
    page.figure(f"{folder}energy.png", "POD energy decay: share of each mode and the energy left out (log scale).")
    page.figure(f"{folder}modes.png", "First POD modes of the readings: one line per gauge over the load levels.")


def _held_out(page, r, folder=""):
    held = HeldOutResult.from_dict(r)
    held_out_tables(page, held)
    if held.layouts:  # a nonlinear test: both POD layouts on the same snapshots
        layout_table(page, held.layouts, held.layout)
        units = held.layouts[held.layout]["by_unit"]
        better = {unit: min(held.layouts, key=lambda k: held.layouts[k]["by_unit"][unit]["peak_error"]["median"])
                  for unit in units}
        page.paragraph(f"The study's surrogate is the {held.layout.replace('_', ' ')} one ([surrogate] pod = "
                       f"\"{held.layout}\"); the smaller median error "
                       + ", ".join(f"in {unit}: {k.replace('_', ' ')}" for unit, k in better.items()) + ".")
    page.figure(f"{folder}predicted_vs_fe.png", "Surrogate prediction (±2σ) against the FE value for every held-out reading (mm).")


def _sensitivity(page, study, r):
    page.paragraph("Variance-based (Sobol') indices over the search box, on the surrogate: the share of an output's "
                   "variance a parameter explains alone (first order) and with its interactions (total). A parameter "
                   "whose total index stays below the threshold for every reading and for the misfit cannot be "
                   "informed by these data: fix it before the inversion (parameter reduction).")
    if r is None:
        page.paragraph("Switched off for this study: set [sensitivity] enabled = true in the study file to run it.")
        return
    m = r["misfit"]
    rows = []
    for j, name in enumerate(m["parameters"]):
        best = []
        for test, one in r["readings"].items():
            if name in one["parameters"]:
                k = one["parameters"].index(name)
                best.append(max((t[k] for t in one["total"] if t[k] is not None and math.isfinite(t[k])), default=0.0))
        estimates = [(m[k][0][j], m[f"{k}_low"][0][j], m[f"{k}_high"][0][j]) for k in ("total", "first")]
        rows.append([name, num(max(best, default=0.0), 3), num(m["total"][0][j], 3), num(m["first"][0][j], 3),
                     "yes" if name in r["propose_fixing"] else "", index_notes(*estimates)])
    header = ["parameter", "largest total index over the readings (-)", "total index of the misfit (-)",
              "first-order index of the misfit (-)", f"propose fixing (< {r['threshold']:g})", "note"]
    if not any(row[-1] for row in rows):  # the note column only when an index needs one
        header, rows = header[:-1], [row[:-1] for row in rows]
    page.table(header, rows)
    if not r["propose_fixing"]:
        page.success(f"Every free parameter explains at least {r['threshold']:g} of the variance of some reading and "
                     "of the misfit.")
    for t in study.calibration_tests:
        _test_heading(page, t)
        page.figure(f"{t.file('')}sensitivity.png",
                    "Left: per parameter, the largest total and first-order index over the readings"
                    + ("" if study.tests else " and the misfit's total index")
                    + ", with bootstrap intervals and the fixing threshold. Right: the total index of every reading and "
                    "parameter, with its colour scale (-).")


def _diagnosis_intro(page):
    page.paragraph(
        "Does the calibrated model explain the data within the noise? If not, which physical effect does it leave "
        "out? Each candidate cause (softer head joints, a weak joint, compliant supports, a faulty gauge, an "
        "eccentric load, ...) is fitted as an extension of the model and tested, with a correction for the number "
        "of candidates and locations tried."
    )


def _diagnosis(page, r, folder=""):
    if r is None:
        page.paragraph("Switched off for this study: set [diagnosis] enabled = true in the study file to run it.")
        return
    a = r["adequacy"]
    alpha = r.get("alpha", a["alpha"] / CHI2_ALPHA_SHARE)  # the settings' α (older manifests lack it)
    adequacy = f"{num(a['chi2_dof'], 3)} (p = {num(a['p_value'], 3)}; {chi2_level_text()})"
    rows = [["verdict", r["verdict"]], ["significance level α (-)", f"{alpha:g}"],
            ["χ²/dof of the FE model at the base fit (-)", adequacy],
            ["χ² includes", a.get("basis", chi2_basis("diagnosis"))],
            ["cause", r["cause"] or "none"]]
    d = r["detail"]
    if d:
        unit = "" if d["unit"] == "-" else f" {d['unit']}"
        where = f"{d['location']}: {d['parameter']} = {num(d['value'])}{unit} (neutral {num(d['neutral'])}{unit})"
        rows.append(["where, and how strong", where])
    g = r["gain"]
    if g:
        rows.append(["χ²/dof before → after (-)", f"{num(g['chi2_dof_before'], 3)} → {num(g['chi2_dof_after'], 3)}"])
        rows.append(["AIC / BIC drop (-)", f"{num(g['aic_drop'], 3)} / {num(g['bic_drop'], 3)}"])
        if "held_out_rms_before" in g:
            rows.append(["held-out RMS residual before → after (σ)",
                         f"{num(g['held_out_rms_before'], 3)} → {num(g['held_out_rms_after'], 3)}"])
    rows.append(["FE runs, time (s)", f"{r['n_fe_runs']}, {num(r['seconds'], 3)}"])
    page.table(["quantity", "value"], rows)
    if r["verdict"] == "adequate":
        page.success("The calibrated model explains the data within the noise; no candidate cause improves the fit "
                     "significantly.")
    cands = [c for c in r["candidates"] if c["applicable"]]
    if not cands:
        page.paragraph("No candidate cause applies to this scenario and these sensors.")
    else:
        if r["cause"] is None and unnamed_significant(r):
            page.paragraph(f"Significant but not named: a candidate cause improves the fit beyond chance ({unnamed_significant(r)}), "
                           "but "
                           "what is left of its effect after refitting is too small or too diffuse to name as a cause; "
                           "no candidate explains the data.")
        elif r["cause"] is None:
            page.paragraph(f"Nothing significant: no candidate cause improves the fit beyond chance (every corrected "
                           f"p ≥ α = {alpha:g}); the fitted values below only show where each fit went.")
        page.table(["candidate cause", "best location", "fitted parameter", "Δχ² (-)", "corrected p (-)"],
                   [[c["name"], c["location"] or "—", fitted_parameter_text(c, alpha), num(c["delta_chi2"], 3),
                     num(c["p_corrected"], 3)] for c in cands],
                   caption="Candidate causes, as ranked by the diagnosis")
    page.links([(f"{folder}diagnosis/index.html",
                 "The diagnosis report: residuals on the specimen and against load, candidate scores, before and after")])


def _provenance(page, records):
    page.paragraph("Each stage is cached by a hash of its inputs (settings and the files it reads); a cached stage "
                   "was not run again. Manifests: stages/STAGE.json beside this report's folder.")
    page.table(["stage", "this run", "time when run (s)", "FE runs when run", "finished", "input hash"],
               [[r.title, "cached" if r.cached else "ran", num(r.manifest["seconds"], 3), r.manifest["fe_runs"],
                 r.manifest["finished"], r.manifest["input_hash"][:12]] for r in records])
    notes = [f"{r.title}: {n}" for r in records if _store_result(r) is None for n in r.result.get("notes", [])]
    for note in notes:
        page.paragraph(note, "meta")
    data = {r.name: {"result": r.result, "inputs": r.manifest["inputs"]} for r in records}
    page.details("every stage's numbers and inputs (JSON)", json.dumps(_finite(data), indent=2, ensure_ascii=False))
