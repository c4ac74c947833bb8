"""Helpers shared by CLI commands: error reporting, logging set-up and the choices of options.

Options with a fixed set of values are typed with the enumerations below, so ``--help`` lists
the choices and a wrong value is refused by the command line parser (exit code 2) with the
allowed values. They are :class:`enum.StrEnum`, so a member compares equal to its text and
library functions receive plain strings in effect.
"""

import contextlib
import logging
from enum import StrEnum

import typer

from fe.exceptions import FEError
from podkrig.exceptions import PodkrigError

__all__ = [
    "KrigingCriterion",
    "LinearSolver",
    "RegionMethod",
    "ResponseFormat",
    "SamplingMethod",
    "SurrogateBackend",
    "TableFormat",
    "TextFormat",
    "Variogram",
    "configure_logging",
    "user_errors",
]

# The same words as the study file's (podkrig.study.settings; tests/test_cli_choices.py checks
# they agree). Spelt out rather than imported: importing the study package (pydantic, the
# pipeline) made `import podkrig.cli` take 4.4 s instead of 2.4 s (measured on the loaded machine).


class SamplingMethod(StrEnum):
    """Sampling design of FE runs (``--sampling``); ``lhs-ese``: SMT's optimised LHS."""

    sobol = "sobol"
    lhs = "lhs"
    random = "random"
    lhs_ese = "lhs-ese"


class Variogram(StrEnum):
    """Semivariogram model of the kriging (``--variogram``)."""

    exponential = "exponential"
    power = "power"


class KrigingCriterion(StrEnum):
    """Hyperparameters by likelihood or by leave-one-out (``--criterion``)."""

    ml = "ml"
    loo = "loo"


class RegionMethod(StrEnum):
    """Region of equivalence method (``--region-method``)."""

    likelihood_ratio = "likelihood-ratio"
    noise_mc = "noise-mc"


class SurrogateBackend(StrEnum):
    """Surrogate backend (``--backend``)."""

    podkrig = "podkrig"
    smt_krg = "smt-krg"
    smt_kpls = "smt-kpls"
    sklearn_gpr = "sklearn-gpr"


class LinearSolver(StrEnum):
    """Linear solver of the FE model (``--solver``)."""

    auto = "auto"
    pardiso = "pardiso"
    superlu = "superlu"


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


@contextlib.contextmanager
def user_errors():
    """Turn domain errors into ``error: <message>`` on stderr and exit code 2."""
    try:
        yield
    except (FEError, PodkrigError, ValueError, FileNotFoundError) as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(code=2) from None


def configure_logging(verbose):
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
