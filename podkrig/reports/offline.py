"""The offline stage's result in words: the rows of a snapshot store, for ``podkrig snapshots run``
and for the study report's offline section (:class:`~podkrig.offline.results.OfflineResult`)."""

from podkrig.reports.html import fmt

__all__ = ["offline_table", "rows_text"]


def rows_text(result):
    """``"15 done, 1 failed, 0 pending of 16 rows"``."""
    return f"{result.done} done, {result.failed} failed, {result.pending} pending of {result.total} rows"


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
