"""HTML of the result objects for Jupyter: the best fit and its χ², the region of equivalence, a
study (every other result shows a table of its fields, :func:`fe.display.fields_html`).

The result objects of the numerics draw nothing and write no HTML: each mixes in
:class:`podkrig.display.Displayed`, whose ``_repr_html_`` calls the renderer registered for its
class in :mod:`podkrig.display` (a registry at the bottom of the layers). This module registers its
renderers there (:data:`RENDERERS`) when it is imported: ``import podkrig`` in a running IPython
imports it, and so does loading a study; ``%load_ext podkrig.reports.jupyter`` does it explicitly.
"""

import html
import math

from podkrig.display import register_html
from podkrig.online.findings import RESIDUAL_CONVENTION, chi2_basis

#: "module.Class" → name of the function of this module that renders it
RENDERERS = {
    "podkrig.online.calibrate.CalibrationResult": "calibration_html",
    "podkrig.online.invert.InverseResult": "inverse_result_html",
    "podkrig.online.region.Region": "region_html",
}


def number(value, digits=4):
    """``value`` with ``digits`` significant digits; an em dash for None or a non-finite one."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    return f"{value:.{digits}g}" if isinstance(value, float) else str(value)


def html_table(header, rows, caption=None):
    """An HTML table: ``header`` cells, ``rows`` of cells (every cell escaped)."""
    e = html.escape
    cap = f"<caption style='text-align:left'><b>{e(caption)}</b></caption>" if caption else ""
    head = "".join(f"<th>{e(str(h))}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{e(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>{cap}<thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def inverse_result_html(result):
    """The best fit and its χ² (with what it includes) of an
    :class:`~podkrig.online.invert.InverseResult` as two HTML tables."""
    params = html_table(["parameter", "unit", "best fit", "on a bound"],
                        [[n, u, number(float(v), 6), "yes" if n in result.at_bound else ""]
                         for n, u, v in zip(result.free, result.units, result.x)],
                        caption=f"Inversion: {len(result.free)} free parameters, "
                                f"{result.measurement.get('n_obs', '?')} readings")
    rows = [["surrogate", number(result.chi2, 4), result.dof, number(result.chi2_dof, 3), result.chi2_basis]]
    if result.fe_check is not None:
        rows.append(["FE check", "—", result.dof, number(result.fe_check.chi2_dof_fe, 3), chi2_basis("fe_check")])
    fit = html_table(["model", "χ² (-)", "dof", "χ²/dof (-)", "χ² includes"], rows,
                     caption=f"Misfit ω = {number(result.misfit)}; {result.n_evaluations} evaluations in "
                             f"{result.seconds:.2f} s; residuals {RESIDUAL_CONVENTION}")
    return params + fit


def calibration_html(calibration):
    """A :class:`~podkrig.online.calibrate.CalibrationResult`: the identified parameters with their
    region (:func:`podkrig.reports.inverse.render_parameters`, as in the reports), the fit's χ²
    and the findings in words."""
    from podkrig.reports.findings import words
    from podkrig.reports.html import Page
    from podkrig.reports.inverse import render_parameters

    page = Page("calibration")
    render_parameters(page, calibration)
    for f in words(calibration.findings, "cli"):
        page.warning(f.message, f.remedy)
    return page.markup() + inverse_result_html(calibration.inversion)


def region_html(region):
    """The intervals and their identifiability of a :class:`~podkrig.online.region.Region` as an
    HTML table."""
    rows = [[n, u, number(float(region.intervals[n][0])), number(float(region.intervals[n][1])),
             f"{100 * region.identifiability[n]['share']:.0f}",
             "yes" if region.identifiability[n]["identifiable"] else "NO"]
            for n, u in zip(region.names, region.units)]
    return html_table(["parameter", "unit", "low", "high", "share of search range (%)", "identified"], rows,
                      caption=f"Region of equivalence ({region.method}, {100 * region.confidence:.0f} %): "
                              f"{len(region.samples)} members of {region.n_evaluated} evaluations")


def study_html(study):
    """A :class:`~podkrig.study.settings.Study` before it runs: each test's scenario and designs,
    the free parameters with their search ranges and the fixed ones, as HTML tables."""
    tests = html_table(["test", "scenario", "training design", "held-out design"],
                       [["—" if t.name is None else t.name, t.spec.scenario,
                         f"{t.train.n} FE runs ({t.train.method}, seed {t.train.seed})",
                         f"{t.held_out.n} FE runs ({t.held_out.method}, seed {t.held_out.seed})"]
                        for t in study.calibration_tests],
                       caption=f"Study {study.name} ({study.path}); diagnosis "
                               f"{'on' if study.diagnosis.enabled else 'off'}")
    free = html_table(["parameter", "unit", "low", "high", "scale"],
                      [[p.name, p.unit, number(float(p.lower)), number(float(p.upper)), p.scale]
                       for p in study.free_parameters], caption="Free parameters (search range)")
    fixed = html_table(["parameter", "value"], [[n, number(float(v))] for n, v in study.fixed.items()],
                       caption="Fixed parameters") if study.fixed else ""
    return tests + free + fixed


def register():
    """Register the renderers of this module with :mod:`podkrig.display` (done on import)."""
    for name, function in RENDERERS.items():
        register_html(name, globals()[function])


def load_ipython_extension(ipython):
    """``%load_ext podkrig.reports.jupyter``: :func:`register` (the results then show as HTML)."""
    register()


register()

__all__ = ["RENDERERS", "calibration_html", "html_table", "inverse_result_html", "load_ipython_extension", "number",
           "region_html", "register", "study_html"]
