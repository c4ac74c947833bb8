"""Helpers shared by CLI commands: error reporting, logging set-up and the choices of options.

Options with a fixed set of values are typed with the enumerations below, so ``--help`` lists
the choices (those of a stage's settings generated from the settings class, the words of the
study file) and a wrong value is refused by the command line parser (exit code 2) with the
allowed values. They are :class:`enum.StrEnum`, so a member compares equal to its text and
library functions receive plain strings in effect.
"""

import contextlib
import csv
import errno
import logging
import sys
from enum import StrEnum

import typer

from fe.exceptions import FEError
from podkrig.cli._terminal import Progress
from podkrig.config import choices, make_settings
from podkrig.exceptions import PodkrigError
from podkrig.limits import CONFIRM_FE_HOURS, CONFIRM_ROWS, CONFIRM_STORE_BYTES
from podkrig.offline.settings import Design
from podkrig.online.data_check import MeasurementCheckError
from podkrig.online.rigid_body import RIGID_BODY_CHOICES
from podkrig.online.settings import RegionSettings
from podkrig.reports.findings import refusal
from podkrig.sensors.settings import SearchSettings
from podkrig.surrogate.settings import SurrogateSettings

__all__ = [
    "KrigingCriterion",
    "LinearSolver",
    "FailedRows",
    "PlacementCriterion",
    "RegionMethod",
    "ResponseFormat",
    "RigidBody",
    "SamplingMethod",
    "SensitivitySource",
    "SurrogateBackend",
    "TableFormat",
    "TextFormat",
    "Variogram",
    "configure_logging",
    "confirm_large_job",
    "error_message",
    "os_error_message",
    "parse_rigid_groups",
    "print_findings",
    "settings_from_options",
    "user_errors",
]


def _words_enum(name, words, doc):
    """A :class:`enum.StrEnum` of ``words``: members named by the words with ``-`` as ``_``."""
    members = StrEnum(name, {word.replace("-", "_"): word for word in words})
    members.__doc__ = doc
    members.__module__ = __name__
    return members


def _choices_enum(name, cls, field, doc):
    """A :class:`enum.StrEnum` of the choices of settings field ``cls.field``
    (:func:`podkrig.config.choices`): members named by the words with ``-`` as ``_``."""
    return _words_enum(name, choices(cls, field), doc)


SamplingMethod = _choices_enum("SamplingMethod", Design, "method",
                               "Sampling design of FE runs (``--sampling``); ``lhs-ese``: SMT's optimised LHS.")
Variogram = _choices_enum("Variogram", SurrogateSettings, "variogram",
                          "Semivariogram model of the kriging (``--variogram``).")
KrigingCriterion = _choices_enum("KrigingCriterion", SurrogateSettings, "criterion",
                                 "Hyperparameters by likelihood or by leave-one-out (``--criterion``).")
SurrogateBackend = _choices_enum("SurrogateBackend", SurrogateSettings, "backend", "Surrogate backend (``--backend``).")
FailedRows = _choices_enum("FailedRows", SurrogateSettings, "failed_rows",
                           "What a surrogate fit does with a store's failed rows (``--failed-rows``).")
PlacementCriterion = _choices_enum("PlacementCriterion", SearchSettings, "criterion",
                                   "Criterion of the sensor layout (``podkrig sensors --criterion``).")


RegionMethod = _choices_enum("RegionMethod", RegionSettings, "method",
                             "Region of equivalence method (``--region-method``).")


class SensitivitySource(StrEnum):
    """Where ``podkrig sensors`` takes the sensitivities from (``--sensitivities``); the same words
    as :data:`podkrig.sensors.placement.SENSITIVITY_SOURCES`."""

    auto = "auto"
    exact = "exact"
    fe = "fe"


class LinearSolver(StrEnum):
    """Linear solver of the FE model (``--solver``)."""

    auto = "auto"
    pardiso = "pardiso"
    superlu = "superlu"


#: removal of the rigid-body motion of absolute displacement readings (``--rigid-body``; the study
#: file's ``[measurement] rigid_body``)
RigidBody = _words_enum("RigidBody", RIGID_BODY_CHOICES, "Removal of the rigid-body motion of absolute displacement "
                        "readings (``--rigid-body``).")


#: help of ``--rigid-body`` and ``--rigid-group`` (invert, diagnose)
RIGID_BODY_HELP = ("Rigid-body motion (translation and rotation, least squares per load level) removed from data and "
                   "model: auto = of each DIC grid (and each --rigid-group), remove = also of all other point "
                   "displacement sensors together, keep = none.")
RIGID_GROUP_HELP = ("NAME=S1,S2,...: point displacement sensors whose rigid-body motion is fitted and removed together "
                    "(repeatable).")


def parse_rigid_groups(items):
    """``["top=P1,P2", ...]`` (``--rigid-group``) → ``{"top": ("P1", "P2")}``; None for none."""
    groups = {}
    for text in items:
        name, sep, members = text.partition("=")
        names = tuple(n.strip() for n in members.split(",") if n.strip())
        if not sep or not name.strip() or not names:
            raise ValueError(f"--rigid-group {text!r}: expected NAME=SENSOR,SENSOR,..., e.g. --rigid-group top=P1,P2")
        if name.strip() in groups:
            raise ValueError(f"--rigid-group: group {name.strip()!r} given twice; list its sensors once")
        groups[name.strip()] = names
    return groups or None


class TableFormat(StrEnum):
    """Output of a command that prints a table, or JSON (``--format``)."""

    table = "table"
    json = "json"


class TextFormat(StrEnum):
    """Output of a command that prints text, or JSON (``--format``)."""

    text = "text"
    json = "json"


class ResponseFormat(StrEnum):
    """Output of ``podkrig simulate``: a table, JSON or a measurement-layout CSV (``--format``)."""

    table = "table"
    json = "json"
    csv = "csv"


_OS_HINTS = {
    errno.EACCES: "permission denied: choose a folder you can write to, or fix its permissions",
    errno.EPERM: "operation not permitted: choose another folder, or fix its permissions",
    errno.EROFS: "read-only file system: choose a writable folder (e.g. --out or --store elsewhere)",
    errno.ENOSPC: "disk full: free some space and rerun the same command (finished work is kept)",
    errno.EDQUOT: "disk quota exceeded: free some space and rerun the same command (finished work is kept)",
    errno.ENOENT: "no such file or folder: check the path",
    errno.EISDIR: "is a folder: give a file",
    errno.ENOTDIR: "a part of the path is a file, not a folder: check the path",
    errno.EEXIST: "already exists and is in the way: choose another path",
    errno.ENAMETOOLONG: "file name too long: choose a shorter path",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n) or use fewer workers",
}


def os_error_message(e):
    """One line for an OSError: the path, what went wrong and what to do."""
    where = " -> ".join(str(p) for p in (e.filename, e.filename2) if p is not None)
    what = _OS_HINTS.get(e.errno) or f"{e.strerror or type(e).__name__}: {e}"
    return f"{where}: {what}" if where else what


def error_message(e):
    """The one-line message for an exception the CLI reports instead of a traceback, or None."""
    if isinstance(e, MeasurementCheckError):
        return refusal(e, "cli")
    if isinstance(e, (FEError, PodkrigError, ValueError, FileNotFoundError)) and not isinstance(e, UnicodeError):
        return str(e)
    if isinstance(e, OSError):
        return os_error_message(e)
    if isinstance(e, UnicodeDecodeError):
        return (f"a file is not UTF-8 text (byte {e.start}: {e.object[e.start:e.start + 4]!r}); save it as "
                "UTF-8")
    if isinstance(e, csv.Error):
        return f"malformed CSV ({e}); check the file's quoting and cell sizes"
    if isinstance(e, RecursionError):
        return "input nested too deeply; simplify it"
    if isinstance(e, OverflowError):
        return f"a number is too large ({e}); use values of ordinary size"
    if isinstance(e, MemoryError):
        return "not enough memory for this input or setting; reduce its size"
    return None


@contextlib.contextmanager
def user_errors():
    """Turn domain, OS and format errors into ``error: <message>`` on stderr and exit code 2; while
    the block runs outside a terminal, a progress line on stderr at least every 20 s
    (:class:`podkrig.cli._terminal.Progress`)."""
    try:
        with Progress("podkrig"):
            yield
    except (FEError, PodkrigError, ValueError, OSError, csv.Error, RecursionError, OverflowError,
            MemoryError) as e:
        typer.echo(f"error: {error_message(e)}", err=True)
        raise typer.Exit(code=2) from None


def settings_from_options(cls, options):
    """Settings ``cls`` built from command-line options, a wrong value named by its option.

    Parameters
    ----------
    cls : settings class (:func:`podkrig.config.settings`)
    options : dict of str to (str, object)
        ``{field: (option, value)}``, e.g. ``{"modes": ("--modes", 4)}``; a value None is an option
        not given (the field keeps its default).

    Raises
    ------
    ValueError
        ``OPTION VALUE: what is wrong; allowed: ...`` (the settings' own words and allowed values).
    """
    return make_settings(cls, {k: v for k, (_, v) in options.items()}, {k: o for k, (o, _) in options.items() if o})


def print_findings(console, findings):
    """Print each finding in words (:class:`~podkrig.reports.findings.FindingText`) as
    ``warning: MESSAGE`` and ``what to do: REMEDY`` on a rich ``console``, the texts literally: rich
    markup would take a bracketed word such as ``[fixed]`` (a study-file table) for a style tag and
    drop it."""
    from rich.markup import escape  # rich is imported by the caller's console already

    for f in findings:
        console.print(f"[bold yellow]warning:[/] {escape(f.message)}\n  what to do: {escape(f.remedy)}")


def configure_logging(verbose):
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")


def confirm_large_job(estimate, large, yes):
    """Ask before a large FE job, or refuse it when nobody can answer.

    Parameters
    ----------
    estimate : str
        The job in words (from :func:`podkrig.limits.fe_job_estimate`).
    large : bool
        Above the thresholds of :mod:`podkrig.limits` (``CONFIRM_*``).
    yes : bool
        ``--yes`` was given: start without asking.

    Raises
    ------
    ValueError
        A large job without ``--yes`` and no terminal to ask on (a script, a batch job).
    typer.Abort
        The user answered no.
    """
    if not large or yes:
        return
    if sys.stdin.isatty():
        typer.confirm(f"this job is {estimate}; start it? (--yes skips this question)", abort=True, err=True)
        return
    raise ValueError(
        f"this job is {estimate}: above {CONFIRM_ROWS} runs, {CONFIRM_FE_HOURS:g} h of FE work or "
        f"{CONFIRM_STORE_BYTES // 2**30} GiB on disk, so it starts only with --yes (nothing was run)"
    )
