"""Start ``podkrig serve``: bind, print the address, open the browser, serve until stopped.

Binds 127.0.0.1 by default; any other address needs a token (:func:`check_binding`), which every
request must then carry. Port 0 takes a free port (the socket is bound before the server starts,
so the printed address is the one served).
"""

import logging
import socket
import threading
import webbrowser

from podkrig.serve.app import create_app, is_loopback
from podkrig.serve.session import RequestError

logger = logging.getLogger(__name__)


def check_binding(host, port, token):
    """Refuse a non-loopback ``host`` without a token, a port outside [0, 65535] and an empty token.

    Raises
    ------
    RequestError
        Naming the option and what to give.
    """
    if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
        raise RequestError(f"--port {port!r}: an integer in [0, 65535] (0: a free port)", "port")
    if token is not None and len(token) < 8:
        raise RequestError("--token: at least 8 characters (anyone who guesses it controls the server)", "token")
    if not is_loopback(host) and token is None:
        raise RequestError(f"--host {host}: binding to an address other than this machine's loopback lets other "
                           "machines in; give --token TOKEN as well (every request must then carry it)", "host", 403)


def bind(host, port):
    """A listening TCP socket on ``host:port`` (``port`` 0: a free one)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    return socket.create_server((host, port), family=family)


def address(host, port, token=None):
    """The URL of the page (with ``?token=`` when there is one)."""
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}/" + (f"?token={token}" if token else "")


def serve(session, *, host="127.0.0.1", port=0, token=None, open_browser=True, say=print):
    """Serve ``session`` until interrupted (Ctrl-C).

    Parameters
    ----------
    session : Session
    host : str
        Address to bind (loopback by default; another needs ``token``).
    port : int
        0: a free port.
    token : str, optional
    open_browser : bool
        Open the page in the default browser once the server is up.
    say : callable
        Prints the address (one line).
    """
    import uvicorn

    check_binding(host, port, token)
    sock = bind(host, port)
    port = sock.getsockname()[1]
    session.warm()
    app = create_app(session, host=host, port=port, token=token)
    url = address(host, port, token)
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="off", access_log=False))
    say(f"podkrig serve: {session.study.name} ({session.folder}) at {url}  (Ctrl-C stops)")
    if open_browser:
        def open_when_up():
            while not server.started and not server.should_exit:
                threading.Event().wait(0.05)
            if server.started:
                webbrowser.open(url)
        threading.Thread(target=open_when_up, daemon=True).start()
    try:
        server.run(sockets=[sock])
    finally:
        services = getattr(app.app.state, "services", None)
        if services is not None:
            services.close()
        session.close()
        sock.close()


__all__ = ["address", "bind", "check_binding", "serve"]
