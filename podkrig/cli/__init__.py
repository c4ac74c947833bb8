"""The ``podkrig`` command line: a thin layer that parses arguments, calls the library, writes
outputs and turns domain errors into one-line messages with a hint and a non-zero exit code.

Each command module imports the stage it drives inside its command function, not at the top:
importing every stage (Dask, matplotlib, the study pipeline) would take several times as long as
``podkrig --help`` does now (measured 2026-11-24: ``import podkrig.cli`` about half the time of
``import podkrig.study``, and matplotlib alone ≈ 0.5 s on an idle core), and every command would
pay it.
"""

import sys

import typer

from podkrig import __version__
from podkrig.cli import diagnose, invert, run, scenarios, sensitivity, sensors, serve, simulate, snapshots, surrogate
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
    # help texts are plain text: rich markup would take "[kN]", "[µm]" or "[scenario.sensors]" for
    # style tags and drop them (every command and sub-app inherits this)
    rich_markup_mode=None,
)
simulate.register(app)
snapshots.register(app)
surrogate.register(app)
invert.register(app)
diagnose.register(app)
run.register(app)
scenarios.register(app)
sensors.register(app)
sensitivity.register(app)
serve.register(app)


def _print_version(value: bool):
    if value:
        typer.echo(f"podkrig {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: bool = typer.Option(False, "--version", callback=_print_version, is_eager=True,
                                 help="Print the version and exit."),
):
    """Surrogate-first inverse analysis of mesoscale masonry FE models (units: N, mm, MPa)."""
