"""``podkrig serve``: the local web front end over a study's output folder or study file."""

from pathlib import Path

import typer

from podkrig.cli._common import configure_logging, user_errors


def register(app):
    @app.command()
    def serve(
        target: Path = typer.Argument(..., help="A finished study's output folder, or a study file (TOML); a "
                                                "study whose stages have not run is offered to run from the page."),
        out: Path = typer.Option(None, "--out", help="Output folder of a study file (default: out/NAME with the "
                                                     "study's name, as 'podkrig run')."),
        host: str = typer.Option("127.0.0.1", "--host", help="Address to bind; other than loopback needs --token."),
        port: int = typer.Option(0, "--port", help="Port; 0 takes a free port."),
        no_browser: bool = typer.Option(False, "--no-browser", help="Print the address only; do not open a browser."),
        token: str = typer.Option(None, "--token", help="Every request must carry it (?token= once, then a cookie); "
                                                        "required with a --host other than loopback."),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Serve a study in the browser: sliders over the surrogate, calibrations, the FE model, study jobs.

        Binds 127.0.0.1 on a free port by default, prints the address and opens it in the browser. Serves
        only files under the study's folder; the page asks no other host for anything. Ctrl-C stops it.
        """
        from podkrig.serve.server import bind, check_binding, serve as run_server
        from podkrig.serve.session import Session

        configure_logging(verbose)
        with user_errors():
            check_binding(host, port, token)
            session = Session.open(target, out)
            sock = bind(host, port)  # a port in use is refused here, with the OS's words
        run_server(session, sock, host=host, token=token, open_browser=not no_browser, say=typer.echo)
