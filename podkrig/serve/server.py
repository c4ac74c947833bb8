"""Start ``podkrig serve``: bind, print the address, open the browser, serve until stopped.

Binds 127.0.0.1 by default; any other address needs a token (:func:`check_binding`), which every
request must then carry. Port 0 takes a free port (the socket is bound before the server starts,
so the printed address is the one served).
"""

import logging
import socket
import threading
import time
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
    """A listening TCP socket on ``host:port`` (``port`` 0: a free one).

    Made with ``proto=IPPROTO_TCP``, not 0 as :func:`socket.create_server` does: asyncio switches
    Nagle's algorithm off (``TCP_NODELAY``) only on connections of a socket that says it is TCP, and
    with Nagle on, a response written as headers then body waits for the client's delayed ACK —
    44 ms per request on loopback (measured 2026-11-27), the whole slider budget.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM, socket.IPPROTO_TCP)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(128)
    except OSError:
        sock.close()
        raise
    return sock


def address(host, port, token=None):
    """The URL of the page (with ``?token=`` when there is one); for a server on every interface
    (``0.0.0.0``, ``::``) its loopback address, which this machine's browser opens."""
    host = {"0.0.0.0": "127.0.0.1", "::": "::1"}.get(host, host)
    shown = f"[{host}]" if ":" in host else host
    return f"http://{shown}:{port}/" + (f"?token={token}" if token else "")


def serve(session, sock, *, host="127.0.0.1", token=None, open_browser=True, say=print):
    """Serve ``session`` on the listening socket ``sock`` (:func:`bind`) until interrupted (Ctrl-C).

    Parameters
    ----------
    session : Session
    sock : socket.socket
        Bound to ``host`` (:func:`check_binding` passed).
    host : str
        The address ``sock`` is bound to (the Host header every request must name).
    token : str, optional
    open_browser : bool
        Open the page in the default browser once the server is up.
    say : callable
        Prints the address (one line).
    """
    import uvicorn

    port = sock.getsockname()[1]
    session.warm()
    app = create_app(session, host=host, port=port, token=token)
    url = address(host, port, token)
    server = uvicorn.Server(uvicorn.Config(app, log_level="warning", lifespan="off", access_log=False))
    say(f"podkrig serve: {session.study.name} ({session.folder}) at {url}  (Ctrl-C stops)")
    if open_browser:
        def open_when_up():
            while not server.started and not server.should_exit:
                time.sleep(0.05)
            if server.started:
                webbrowser.open(url)
        threading.Thread(target=open_when_up, daemon=True).start()
    try:
        server.run(sockets=[sock])
    finally:
        app.app.state.services.close()
        session.close()
        sock.close()


__all__ = ["address", "bind", "check_binding", "serve"]
