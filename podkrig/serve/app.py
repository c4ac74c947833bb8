"""The Starlette application of ``podkrig serve``: the page, its files and the JSON API.

Routes (the contract the page and the tests share; JSON in and out, errors as
``{"error": message, "field": key or null}`` with a 4xx status, never a traceback):

=====================================  ===============================================================
``GET /``                              the page (``static/index.html``)
``GET /static/...``                    the page's scripts, styles and the vendored chart bundle
``GET /files/PATH``                    a file under the served folder (report figures), sandboxed; nothing outside
``GET /api/study``                     the study: parameters, tests, state, last calibration, settings
``POST /api/predict``                  the surrogate at the sliders' values against the measurements
``POST /api/calibrate``                a calibration run (:mod:`podkrig.serve.runs`) → 202, its id
``GET /api/runs``, ``/api/runs/ID``    the session's runs; one run's state and result
``GET /api/runs/ID/summary.json``      a run's result as ``podkrig invert --format json`` writes it
``POST /api/fe``, ``GET /api/fe/ID``   an FE run on demand (:mod:`podkrig.serve.model`)
``POST /api/jobs``, ``GET /api/jobs``  a study job in a background process (:mod:`podkrig.serve.jobs`)
``GET|DELETE /api/jobs/ID``            a job's state; cancel it
``POST /api/measurement?test=NAME``    a measurement log (raw body) for a test of this session
=====================================  ===============================================================

Safety (:class:`Guard`): the ``Host`` header must name the bound address (a page of another site
that rebinds its DNS name to 127.0.0.1 is refused); a request that carries an ``Origin`` must come
from the served address; with a token, every request must carry it (``?token=`` once, which sets a
cookie, or the ``X-Podkrig-Token`` header). Request bodies are JSON (``Content-Type:
application/json``) or, for a measurement log, raw bytes (``application/octet-stream``): types a
page of another site cannot send without a preflight this server never answers. Bodies are capped
in size (:data:`MAX_JSON_BODY`, :data:`MAX_UPLOAD_BYTES`).
"""

import dataclasses
import hmac
import http.cookies
import ipaddress
import json
import logging
import math
import urllib.parse
from pathlib import Path

import numpy as np
from starlette.applications import Starlette
from starlette.concurrency import run_in_threadpool
from starlette.exceptions import HTTPException
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from podkrig.exceptions import InUseError, PodkrigError
from podkrig.serve.jobs import Jobs
from podkrig.serve.model import FEViews
from podkrig.serve.runs import Runs, result_view
from podkrig.serve.session import RequestError, check_keys, upload_name
from podkrig.study import StudyError

logger = logging.getLogger(__name__)

#: the page's folder inside the package
STATIC = Path(__file__).resolve().parent / "static"
#: largest JSON request body, bytes
MAX_JSON_BODY = 1 << 20
#: largest measurement log uploaded, bytes (a lab log of a few thousand rows is well under 1 MiB)
MAX_UPLOAD_BYTES = 16 << 20
#: the measurement logs an upload may be (the reader of ``podkrig invert``)
UPLOAD_SUFFIXES = (".csv", ".tsv", ".txt", ".xlsx")
#: the cookie that carries the token after a first ``?token=``
TOKEN_COOKIE = "podkrig_token"
#: the header that may carry the token
TOKEN_HEADER = "x-podkrig-token"
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")
#: headers of every file served from the study's folder: an HTML or SVG file there (a report, or a
#: file of a folder received from someone else) runs in a sandbox with an opaque origin, so its
#: scripts cannot read the page's cookie, and their requests to the API carry ``Origin: null``,
#: which :class:`Guard` refuses; the type is never sniffed
FILE_HEADERS = {"Content-Security-Policy": "sandbox allow-scripts allow-popups allow-downloads",
                "X-Content-Type-Options": "nosniff"}
#: headers of the page itself: the browser runs only podkrig's own scripts and asks no other host
#: for anything (scripts, styles, images, fonts, requests), no page of another site may frame it,
#: and no address leaves in a Referer header
PAGE_HEADERS = {"Cache-Control": "no-cache", "X-Content-Type-Options": "nosniff", "Referrer-Policy": "no-referrer",
                "Content-Security-Policy": "default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
                                           "img-src 'self' data: blob:; font-src 'self'; connect-src 'self'; "
                                           "object-src 'none'; base-uri 'none'; form-action 'self'; "
                                           "frame-ancestors 'none'"}


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
        refused = field = None
        host = headers.get("host", "")
        if not self.allowed_host(host):
            refused, field = f"host {host!r} is not the address this server is bound to", "host"
        origin = headers.get("origin")
        if refused is None and origin is not None and urllib.parse.urlsplit(origin).netloc != host:
            refused, field = f"requests from origin {origin!r} are refused: open the page at http://{host}/", "host"
        set_cookie = False
        if refused is None and self.token is not None:
            query = urllib.parse.parse_qs(scope.get("query_string", b"").decode("latin-1"))
            cookies = http.cookies.SimpleCookie(headers.get("cookie", ""))
            given = (query.get("token", [None])[0] or headers.get(TOKEN_HEADER)
                     or (cookies[TOKEN_COOKIE].value if TOKEN_COOKIE in cookies else None))
            if given is None or not hmac.compare_digest(given.encode(), self.token.encode()):
                refused, field = "a token is required: open the address podkrig serve printed (it carries ?token=)", \
                    "token"
            set_cookie = "token" in query
        if refused is not None:
            return await error_response(refused, field, 403)(scope, receive, send)
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
    except RecursionError:  # a few hundred kB of '[': deeper than any request of the page
        raise RequestError("the body is not valid JSON: nested too deeply") from None
    if not isinstance(data, dict):
        raise RequestError(f"the body must be a JSON object; got {type(data).__name__}")
    return data


def _finite(value):
    """``value`` with every non-finite float as None and NumPy scalars and arrays as plain JSON."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k) if k is not None else "": _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    if isinstance(value, np.ndarray | np.generic):
        return _finite(value.tolist())
    return value


class JSON(JSONResponse):
    """A JSON response of plain data: NaN and ±inf as null (JSON has neither), NumPy as lists."""

    def render(self, content):
        return json.dumps(_finite(content), ensure_ascii=False, allow_nan=False, separators=(",", ":")).encode()


@dataclasses.dataclass
class Services:
    """The workers of a session: calibration runs, FE views and study jobs."""

    runs: Runs
    views: FEViews
    jobs: Jobs

    @classmethod
    def of(cls, session):
        return cls(Runs(session), FEViews(session), Jobs(session))

    def close(self):
        """Stop the workers: queued calibrations and FE runs are dropped, running jobs cancelled."""
        self.jobs.close()
        self.runs.close()
        self.views.close()


def create_app(session, *, host="127.0.0.1", port=None, token=None):
    """The ASGI application serving ``session``.

    Parameters
    ----------
    session : Session
    host, port, token
        See :class:`Guard` (``port`` None: any port, e.g. for starlette's test client).

    Returns
    -------
    Guard
        The Starlette app wrapped in the guard; the app is ``.app``, its workers
        ``.app.state.services`` (:class:`Services`).
    """
    services = Services.of(session)

    async def index(request):
        page = STATIC / "index.html"
        if not page.is_file():
            return error_response("the page (static/index.html) is not installed with this podkrig", None, 404)
        return FileResponse(page, headers=PAGE_HEADERS)

    async def files(request):  # a file of the folder is data, never a page of this server (FILE_HEADERS)
        return FileResponse(session.file(request.path_params["path"]), headers=FILE_HEADERS)

    def study(request):  # reads the study's calibration back when it changed: in the thread pool
        cal = session.calibration()
        return JSON(session.study_view(calibration=None if cal is None else result_view(cal)))

    async def predict(request):  # the slider's path: a millisecond on the event loop, no thread hop
        body = await read_json(request)
        check_keys(body, ("values",), "predict")
        return JSON(session.predict(body.get("values")))

    async def calibrate(request):
        body = await read_json(request, required=False)
        return JSON({"run": await run_in_threadpool(services.runs.start, body)}, status_code=202)

    async def runs(request):
        return JSON(services.runs.rows())

    async def run(request):
        return JSON(services.runs.get(request.path_params["id"]).to_dict())

    def summary(request):
        rid = request.path_params["id"]
        return JSON(services.runs.summary(rid),
                    headers={"Content-Disposition": f'attachment; filename="summary-{rid}.json"'})

    async def fe_start(request):
        body = await read_json(request, required=False)
        return JSON({"fe": await run_in_threadpool(services.views.start, body)}, status_code=202)

    async def fe_get(request):
        return JSON(services.views.get(request.path_params["id"]))

    async def jobs(request):
        if request.method == "POST":
            body = await read_json(request, required=False)
            return JSON({"job": await run_in_threadpool(services.jobs.start, body)}, status_code=202)
        return JSON(services.jobs.rows())

    def job(request):  # a cancel waits for the process to end (seconds): in the thread pool
        jid = request.path_params["id"]
        one = services.jobs.cancel(jid) if request.method == "DELETE" else services.jobs.get(jid)
        return JSON(one.to_dict())

    async def measurement(request):
        kind = request.headers.get("content-type", "").split(";")[0].strip().lower()
        if kind != "application/octet-stream":
            raise RequestError("send the measurement log as the raw body with Content-Type: application/octet-stream; "
                               f"got {kind or 'none'!r}", None, 415)
        name = upload_name(request.query_params.get("name"))
        if Path(name).suffix.lower() not in UPLOAD_SUFFIXES:
            raise RequestError(f"name {name!r}: a measurement log is one of {', '.join(UPLOAD_SUFFIXES)}", "name")
        data = await read_body(request, MAX_UPLOAD_BYTES, f"the measurement log {name}")
        if not data:
            raise RequestError(f"the measurement log {name} is empty", "measurement")
        test = request.query_params.get("test")
        return JSON(await run_in_threadpool(session.replace_measurement, test, data, name))

    async def on_request_error(request, exc):
        return error_response(str(exc), exc.field, exc.status)

    async def on_study_error(request, exc):
        return error_response(str(exc), None, 422)

    async def on_http_error(request, exc):
        return error_response(exc.detail, None, exc.status_code)

    async def on_error(request, exc):
        if isinstance(exc, ValueError | PodkrigError | OSError):  # the library's own message
            return error_response(str(exc), None, 409 if isinstance(exc, InUseError) else 422)
        logger.exception("%s %s failed", request.method, request.url.path)
        return error_response(f"internal error ({type(exc).__name__}): see the server's log", None, 500)

    routes = [
        Route("/", index),
        Mount("/static", StaticFiles(directory=STATIC), name="static"),
        Route("/files/{path:path}", files),
        Route("/api/study", study),
        Route("/api/predict", predict, methods=["POST"]),
        Route("/api/calibrate", calibrate, methods=["POST"]),
        Route("/api/runs", runs),
        Route("/api/runs/{id}", run),
        Route("/api/runs/{id}/summary.json", summary),
        Route("/api/fe", fe_start, methods=["POST"]),
        Route("/api/fe/{id}", fe_get),
        Route("/api/jobs", jobs, methods=["GET", "POST"]),
        Route("/api/jobs/{id}", job, methods=["GET", "DELETE"]),
        Route("/api/measurement", measurement, methods=["POST"]),
    ]
    app = Starlette(routes=routes, exception_handlers={RequestError: on_request_error, StudyError: on_study_error,
                                                       HTTPException: on_http_error, Exception: on_error})
    app.state.session = session
    app.state.services = services
    return Guard(app, host=host, port=port, token=token)


__all__ = ["FILE_HEADERS", "JSON", "MAX_JSON_BODY", "MAX_UPLOAD_BYTES", "STATIC", "UPLOAD_SUFFIXES", "Guard", "Services", "create_app",
           "is_loopback", "read_body", "read_json"]
