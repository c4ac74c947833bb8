"""The offline stage's result in words: the rows of a snapshot store, for ``podkrig snapshots run``
and for the study report's offline section (:class:`~podkrig.offline.results.OfflineResult`)."""

from podkrig.reports.html import fmt

__all__ = ["failure_lines", "offline_table", "rows_text"]


def rows_text(result):
    """``"15 done, 1 failed, 0 pending of 16 rows"``."""
    return f"{result.done} done, {result.failed} failed, {result.pending} pending of {result.total} rows"


def failure_lines(report):
    """The failed FE runs of a store in words (``report``: a
    :class:`~podkrig.offline.failures.FailureReport`): their share and reasons, then where in the
    box they fail — the parameters that drive failure and towards which end, from the classifier —
    one sentence a line."""
    reasons = ", ".join(f"{n} {_REASONS.get(reason, reason)}" for reason, n in sorted(report.reasons.items()))
    lines = [f"{report.n_failed} of {report.n_run} FE runs ({100 * report.share:.0f} %) failed or stopped early: "
             f"{reasons}; the store keeps them as failed rows (with the readings they reached), and a surrogate drops "
             "or refuses them, saying so (setting failed_rows)."]
    region = report.region
    if region is None:
        lines.append("Too few runs of one outcome to say where in the box runs fail.")
        return lines
    where = " and ".join(f"{region.direction(n)} {n}" for n in region.driving())
    weights = ", ".join(f"{n} {w:+.3g}" for n, w in zip(region.names, region.weights))
    lines.append(f"Runs fail towards {where} (logistic classifier on the design's unit cube, agreeing with "
                 f"{100 * region.accuracy:.0f} % of the runs; change of the log-odds of failure across each "
                 f"parameter's range: {weights}).")
    return lines


#: reasons of failed rows (:attr:`~podkrig.offline.failures.FailureReport.reasons`) in words
_REASONS = {"steps": "ran out of their step budget", "iterations": "ran out of their iteration budget",
            "cpu": "ran out of their CPU-time budget", "wall": "hit the wall-clock guard",
            "not converged": "did not converge", "error": "raised an error"}


def _ms(value):
    if value is None:
        return "—"
    text = fmt(value, 3)
    return f"{value:.0f}" if "e+" in text and abs(value) < 1e6 else text


def offline_table(page, entries):
    """The stores of a study's offline stages as one table on ``page``, then their notes.

    Parameters
    ----------
    page : podkrig.reports.html.Page
    entries : sequence of (str, OfflineResult, str)
        The stage's title, its result and what this run did (``"cached"``, ``"ran 16 FE runs"``).
    """
    page.table(["stage", "done", "failed", "rows", "FE time per run (ms)", "dofs", "this run"],
               [[title, r.done, r.failed, r.total, _ms(r.fe_ms_per_run), r.n_dofs, this_run]
                for title, r, this_run in entries])
    for title, r, _ in entries:
        for note in r.notes:
            page.paragraph(f"{title}: {note}", "meta")
        for line in failure_lines(r.failure) if r.failure is not None else ():
            page.paragraph(f"{title}: {line}")
