"""The ``podkrig`` command line: a thin layer that parses arguments, calls the library, writes
outputs and turns domain errors into one-line messages with a hint and a non-zero exit code."""

import sys

import typer

from podkrig.cli import diagnose, invert, run, simulate, snapshots, surrogate
from podkrig.cli._common import error_message


class _App(typer.Typer):
    """The ``podkrig`` app: an OS or format error that escapes a command is one line, not a traceback."""

    def __call__(self, *args, **kwargs):
        try:
            return super().__call__(*args, **kwargs)
        except Exception as e:  # noqa: BLE001 - re-raised unless it has a message for the user
            message = error_message(e)
            if message is None:
                raise
            typer.echo(f"error: {message}", err=True)
            sys.exit(2)


app = _App(
    name="podkrig",
    help="Surrogate-first inverse analysis of mesoscale masonry FE models.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
simulate.register(app)
snapshots.register(app)
surrogate.register(app)
invert.register(app)
diagnose.register(app)
run.register(app)


@app.callback()
def main():
    """Surrogate-first inverse analysis of mesoscale masonry FE models (units: N, mm, MPa)."""
