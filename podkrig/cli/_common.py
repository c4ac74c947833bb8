"""Helpers shared by CLI commands: error reporting and logging set-up."""

import contextlib
import logging

import typer

from fe.exceptions import FEError

from podkrig.exceptions import PodkrigError


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
