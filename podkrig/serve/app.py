"""The Starlette application of ``podkrig serve``: the page, its files and the JSON API.

Routes (the contract the page and the tests share; JSON in and out, errors as
``{"error": message, "field": key or null}`` with a 4xx status, never a traceback):

==========================  =========================================================================
``GET /``                   the page (``static/index.html``)
``GET /static/...``         the page's scripts, styles and the vendored chart bundle
``GET /files/PATH``         a file under the served folder (report figures); nothing outside it
``GET /api/study``          the study: parameters, tests, state, last calibration, noise, GA settings
``POST /api/predict``       the surrogate at the sliders' values against the measurements
==========================  =========================================================================

Safety (:class:`Guard`): the ``Host`` header must name the bound address (a page of another site
that rebinds its DNS name to 127.0.0.1 is refused); a request that carries an ``Origin`` must come
from the served address; with a token, every request must carry it (``?token=`` once, which sets a
cookie, or the ``X-Podkrig-Token`` header). Request bodies are JSON (``Content-Type:
application/json``, which a page of another site cannot send without a preflight this server never
answers) and capped in size.
"""

import hmac
import http.cookies
import ipaddress
import json
import logging
import urllib.parse
from pathlib import Path

from starlette.applications import Starlette
from starlette.exceptions import HTTPException
from starlette.requests import Request
from starlette.responses import FileResponse, JSONResponse, Response
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from podkrig.serve.session import RequestError
from podkrig.study import StudyError

logger = logging.getLogger(__name__)

#: the page's folder inside the package
STATIC = Path(__file__).resolve().parent / "static"
#: largest JSON request body, bytes
MAX_JSON_BODY = 1 << 20
#: the cookie that carries the token after a first ``?token=``
TOKEN_COOKIE = "podkrig_token"
#: the header that may carry the token
TOKEN_HEADER = "x-podkrig-token"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


def is_loopback(host):
    """Whether ``host`` (a name or an address) is this machine's loopback."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def error_response(message, field=None, status=422):
    return JSONResponse({"error": str(message), "field": field}, status_code=status)


def _split_host(value):
    """``host[:port]`` of a Host header (IPv6 in brackets) → (host, port or None)."""
    parsed = urllib.parse.urlsplit(f"//{value}")
    try:
        port = parsed.port
    except ValueError:
        return value, "invalid"
    return (parsed.hostname or ""), port


class Guard:
    """ASGI middleware: the Host and Origin checks and the token (module docstring).

    Parameters
    ----------
    app : ASGI app
    host : str
        The address the server is bound to.
    port : int or None
        Its port (None: any, for tests without a socket).
    token : str or None
        Required of every request when given.
    """

    def __init__(self, app, host="127.0.0.1", port=None, token=None):
        self.app = app
        self.host = host
        self.port = port
        self.token = token

    def allowed_host(self, value):
        host, port = _split_host(value)
        if self.port is not None and port != self.port:
            return False
        if is_loopback(self.host):
            return host in LOOPBACK_NAMES or is_loopback(host)
        if self.host in ("0.0.0.0", "::"):  # every interface: the token guards it
            return True
        return host == self.host.strip("[]")

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = {k.decode("latin-1"): v.decode("latin-1") for k, v in scope["headers"]}
        refused = None
        host = headers.get("host", "")
        if not self.allowed_host(host):
            refused = f"host {host!r} is not the address this server is bound to"
        origin = headers.get("origin")
        if refused is None and origin is not None and origin != "null":
            netloc = urllib.parse.urlsplit(origin).netloc
            if netloc != host:
                refused = f"requests from origin {origin!r} are refused: open the page at http://{host}/"
        set_cookie = False
        if refused is None and self.token is not None:
            query = urllib.parse.parse_qs(scope.get("query_string", b"").decode("latin-1"))
            cookies = http.cookies.SimpleCookie(headers.get("cookie", ""))
            given = (query.get("token", [None])[0] or headers.get(TOKEN_HEADER)
                     or (cookies[TOKEN_COOKIE].value if TOKEN_COOKIE in cookies else None))
            if given is None or not hmac.compare_digest(given.encode(), self.token.encode()):
                refused = "a token is required: open the address podkrig serve printed (it carries ?token=)"
            set_cookie = "token" in query
        if refused is not None:
            return await error_response(refused, "token" if "token" in refused else "host", 403)(scope, receive, send)
        if not set_cookie:
            return await self.app(scope, receive, send)
        cookie = f"{TOKEN_COOKIE}={self.token}; Path=/; HttpOnly; SameSite=Strict".encode("latin-1")

        async def send_with_cookie(message):
            if message["type"] == "http.response.start":
                message = {**message, "headers": [*message.get("headers", []), (b"set-cookie", cookie)]}
            await send(message)

        return await self.app(scope, receive, send_with_cookie)


async def read_body(request, limit, what="request body"):
    """The request's body, refused (413) past ``limit`` bytes without reading the rest."""
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise RequestError(f"{what} of {int(declared)} bytes is larger than the cap of {limit} bytes", None, 413)
    chunks, size = [], 0
    async for chunk in request.stream():
        size += len(chunk)
        if size > limit:
            raise RequestError(f"{what} is larger than the cap of {limit} bytes", None, 413)
        chunks.append(chunk)
    return b"".join(chunks)


async def read_json(request, *, required=True):
    """The request's JSON object (``Content-Type: application/json``, at most
    :data:`MAX_JSON_BODY` bytes); ``{}`` for an empty body when not ``required``."""
    kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
    body = await read_body(request, MAX_JSON_BODY)
    if not body and not required:
        return {}
    if kind != "application/json":
        raise RequestError(f"the body must be JSON with Content-Type: application/json; got {kind or 'none'!r}",
                           None, 415)
    try:
        data = json.loads(body)
    except (ValueError, UnicodeDecodeError) as e:
        raise RequestError(f"the body is not valid JSON: {e}") from None
    if not isinstance(data, dict):
        raise RequestError(f"the body must be a JSON object; got {type(data).__name__}")
    return data


def create_app(session, *, host="127.0.0.1", port=None, token=None, services=None):
    """The ASGI application serving ``session``.

    Parameters
    ----------
    session : Session
    host, port, token
        See :class:`Guard` (``port`` None: any port, e.g. for starlette's test client).
    services : Services, optional
        The calibration runs, FE views and study jobs (:class:`podkrig.serve.services.Services`);
        default: new ones over ``session``.

    Returns
    -------
    Guard
        The Starlette app wrapped in the guard; the app is ``.app``, the services
        ``.app.state.services``.
    """

    async def index(request):
        page = STATIC / "index.html"
        if not page.is_file():
            return error_response("the page (static/index.html) is not installed with this podkrig", None, 404)
        return FileResponse(page, headers={"Cache-Control": "no-cache"})

    async def files(request):
        relative = request.path_params["path"]
        path = session.file(relative)
        return FileResponse(path)

    async def study(request):
        return JSONResponse(session.study_view(calibration=session_calibration()))

    def session_calibration():
        from podkrig.serve.runs import result_view

        cal = session._calibration_cached()
        return None if cal is None else result_view(cal)

    async def predict(request):
        body = await read_json(request)
        return JSONResponse(session.predict(body.get("values")))

    async def on_request_error(request, exc):
        return error_response(str(exc), exc.field, exc.status)

    async def on_study_error(request, exc):
        return error_response(str(exc), None, 422)

    async def on_http_error(request, exc):
        return error_response(exc.detail, None, exc.status_code)

    async def on_error(request, exc):
        logger.exception("%s %s failed", request.method, request.url.path)
        message = str(exc) if isinstance(exc, ValueError | OSError) else f"internal error ({type(exc).__name__}): " \
                                                                         "see the server's log"
        return error_response(message, None, 422 if isinstance(exc, ValueError) else 500)

    routes = [
        Route("/", index),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
        Route("/files/{path:path}", files),
        Route("/api/study", study),
        Route("/api/predict", predict, methods=["POST"]),
    ]
    app = Starlette(routes=routes, exception_handlers={RequestError: on_request_error, StudyError: on_study_error,
                                                       HTTPException: on_http_error, Exception: on_error})
    app.state.session = session
    return Guard(app, host=host, port=port, token=token)


__all__ = ["MAX_JSON_BODY", "STATIC", "Guard", "create_app", "is_loopback", "read_body", "read_json"]
