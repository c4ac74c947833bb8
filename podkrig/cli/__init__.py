"""The ``podkrig`` command line: a thin layer that parses arguments, calls the library, writes
outputs and turns domain errors into one-line messages with a hint and a non-zero exit code."""

import typer

from podkrig.cli import diagnose, invert, run, sensors, simulate, snapshots, surrogate

app = typer.Typer(
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
sensors.register(app)


@app.callback()
def main():
    """Surrogate-first inverse analysis of mesoscale masonry FE models (units: N, mm, MPa)."""
