"""Pick the front end's stack by measurement: the same slider page in four stacks, timed in Chromium.

The task, identical in every stack: one slider per free parameter of the demo study (E_b, kN_bj,
kV_bj, r_hj; 101 positions over the parameter's range, log-spaced where its scale is log) → the
demo surrogate's prediction of the readings → one line plot of the predicted readings against the
measured ones, per sensor, over the load levels. The stacks:

- ``starlette``: Starlette + uvicorn serving a static HTML page that draws with the vendored uPlot
  (``podkrig/serve/static/vendor/uplot-1.6.32``) and asks a JSON route for each prediction;
- ``dash``: a Dash app (``dcc.Slider(updatemode="drag")`` → callback → ``dcc.Graph``, Plotly);
- ``panel``: a Panel app (``pn.widgets.IntSlider`` → ``param.watch`` → the data of a Bokeh figure);
- ``streamlit``: a Streamlit script (``st.slider`` → ``st.line_chart``, Vega-Lite).

Each app is written into a temporary folder and started as a subprocess (``nice -n 5``) on a free
127.0.0.1 port with its own virtual environment's Python, one stack after the other (never two at
once). Every app loads the demo's calibration problem read-only from the finished demo folder
(``podkrig.study.load_study`` + ``StudyRun(...).calibration_problem()``).

What is measured, in headless Chromium (selenium + chromedriver):

- slider → plot latency: the slider is moved by one step with the keyboard (ArrowRight /
  ArrowLeft on the focused slider, which every one of these slider widgets listens to); the time
  runs from that key's event (``KeyboardEvent.timeStamp``, caught before the framework's handlers)
  to the last paint of the plot (a canvas drawing call, or a change inside an SVG) before the
  page stays still for the quiet time (``--quiet``). Median and 90th percentile over ``--moves``
  moves after ``--warmup`` moves, the four sliders in turn;
- after a burst: ten steps 1/60 s apart (input events at a display's rate, as a drag sends them);
  the time from the burst's last key to the plot's last paint, median over ``--bursts`` bursts
  (a stack that queues one update per step falls behind here);
- serving: from the server process's start to its answering HTTP (a static file or a health path,
  which starts no session: Panel and Streamlit load the surrogate in the first session, Starlette
  and Dash before they serve);
- first plot: from the page's navigation start to the first paint of the plot, on the first visit
  (right after the server serves) and on a reload; and from the server process's start to the
  first visit's first plot (what a user waits for after starting the app);
- the server process's CPU seconds (user + system, with its children) during the timed moves, and
  the browser's (chromedriver and every Chromium process);
- the packages each stack adds to a fresh virtual environment: ``pip list`` of the environment
  after ``pip install STACK`` minus that of the bare environment (recorded by ``--install``
  before podkrig itself is installed into it).

The machine's load (``uptime``) is printed before and after.

Install the peers (each in its own environment, never in the project's; a minute or two each)::

    python scripts/bench_serve_peers.py --install            # all four: /work/venv-peers-NAME
    python scripts/bench_serve_peers.py --install dash       # one

which for each stack runs ``python -m venv /work/venv-peers-NAME``, ``pip list`` (bare),
``pip install PACKAGES`` (starlette: ``starlette uvicorn``; dash: ``dash``; panel: ``panel``;
streamlit: ``streamlit``), ``pip list`` again (the count, written to ``peer.json`` in the
environment) and ``pip install -e .`` (this checkout, so that the app can load the surrogate).
Then measure::

    python scripts/bench_serve_peers.py                      # all four, prints a Markdown table
    python scripts/bench_serve_peers.py --stacks starlette dash --moves 60
"""

import argparse
import json
import os
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
UPLOT = ROOT / "podkrig" / "serve" / "static" / "vendor" / "uplot-1.6.32"
DEMO_FOLDER = Path("/work/out-demo")
DEMO_STUDY = ROOT / "examples" / "diagonal_compression.toml"
VENV_PREFIX = "/work/venv-peers-"
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: positions of every slider: 0 … STEPS over the parameter's unit coordinate
STEPS = 100
#: key presses of one burst, 1/60 s apart (a drag's input events at a display's rate)
BURST = 10


@dataclass(frozen=True)
class Stack:
    """One stack of the comparison: what to install, how to write and start its app."""

    name: str
    packages: tuple  # pip install arguments of the stack alone
    distribution: str  # the distribution whose version the table gives
    app_file: str  # the file the app is written to
    source: str  # the app's source
    command: tuple  # argv after the Python executable; {app}, {port} formatted
    path: str = "/"  # the page's path
    probe: str = "/"  # a path that answers once the server serves, without starting a session
    extra_files: dict = field(default_factory=dict)


# --------------------------------------------------------------------------- the shared model
#: Written beside each app: the demo's calibration problem, its sliders and one prediction.
MODEL = '''\
"""The demo's calibration problem for the peer apps: sliders, measured readings, predictions."""
import os
import numpy as np
from podkrig.study import load_study
from podkrig.study.cache import Progress
from podkrig.study.stages import StudyRun

STEPS = {steps}


class Demo:
    def __init__(self):
        study = load_study(os.environ["PEERS_STUDY"])
        self.problem = StudyRun(study, os.environ["PEERS_FOLDER"], Progress()).calibration_problem()
        self.space = self.problem.free_space
        self.names = list(self.space.names)
        self.units = [p.unit for p in self.space.parameters]
        m = self.problem.measurement
        self.sensors = list(m.sensor_names)
        self.loads = [float(v) for v in m.load_levels]
        self.measured = m.values  # (n_loads, n_sensors), mm

    def values(self, positions):
        """Slider positions (0 … STEPS each) → physical parameter values."""
        u = np.asarray(positions, dtype=float)[None, :] / STEPS
        return self.space.from_unit(u)[0]

    def predict(self, positions):
        """The surrogate's mean readings on the measurement's grid, (n_loads, n_sensors) mm."""
        x = self.values(positions)[None, :]
        mean = self.problem.model.predict(self.problem.full(x))
        return self.problem.measurement.grid(self.problem.observation.apply(mean)[0])

    def label(self, i, position):
        return f"{{self.names[i]}} = {{self.values_at(i, position):.4g}} {{self.units[i]}}"

    def values_at(self, i, position):
        u = np.full((1, len(self.names)), 0.5)
        u[0, i] = position / STEPS
        return float(self.space.from_unit(u)[0, i])


_DEMO = []


def demo():
    """The process's one Demo (apps that rerun their script for each session load it once)."""
    if not _DEMO:
        _DEMO.append(Demo())
    return _DEMO[0]
'''.format(steps=STEPS)


# --------------------------------------------------------------------------- environments
def venv_dir(name):
    return Path(VENV_PREFIX + name)


def venv_python(name):
    return venv_dir(name) / "bin" / "python"


def _pip_list(python):
    out = subprocess.run([str(python), "-m", "pip", "list", "--format=json", "--disable-pip-version-check"],
                         check=True, capture_output=True, text=True, timeout=300).stdout
    return {d["name"].lower(): d["version"] for d in json.loads(out)}


def install(stack, log=print):
    """Make ``/work/venv-peers-NAME``: a bare environment, the stack's packages (counted against
    the bare environment's ``pip list``, written to ``peer.json``), then this checkout editable."""
    folder = venv_dir(stack.name)
    if folder.exists():
        shutil.rmtree(folder)
    log(f"[{stack.name}] python -m venv {folder}")
    subprocess.run([sys.executable, "-m", "venv", str(folder)], check=True, timeout=300)
    python = venv_python(stack.name)
    bare = _pip_list(python)
    log(f"[{stack.name}] pip install {' '.join(stack.packages)}")
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", *stack.packages],
                   check=True, timeout=1800)
    after = _pip_list(python)
    added = sorted(set(after) - set(bare))
    record = {"stack": stack.name, "packages": list(stack.packages), "bare": len(bare), "after": len(after),
              "added": len(added), "added_names": added, "version": after.get(stack.distribution),
              "date": time.strftime("%Y-%m-%d", time.gmtime())}
    (folder / "peer.json").write_text(json.dumps(record, indent=1), encoding="utf-8")
    log(f"[{stack.name}] {len(added)} packages added: {', '.join(added)}")
    log(f"[{stack.name}] pip install -e {ROOT}")
    subprocess.run([str(python), "-m", "pip", "install", "-q", "--disable-pip-version-check", "-e", str(ROOT)],
                   check=True, timeout=3600)
    return record


# --------------------------------------------------------------------------- the four apps
STARLETTE_APP = '''\
"""Peer app: Starlette + uvicorn, a static page drawing with uPlot."""
import math
import sys
from pathlib import Path

import uvicorn
from starlette.applications import Starlette
from starlette.responses import FileResponse, JSONResponse
from starlette.routing import Mount, Route
from starlette.staticfiles import StaticFiles

from peer_model import STEPS, Demo

HERE = Path(__file__).parent
demo = Demo()


def _json(a):
    return [[None if math.isnan(v) else v for v in row] for row in a.tolist()]


async def index(request):
    return FileResponse(HERE / "index.html")


async def meta(request):
    return JSONResponse({"names": demo.names, "sensors": demo.sensors, "loads": demo.loads, "steps": STEPS,
                         "measured": _json(demo.measured)})


async def predict(request):
    positions = [int(v) for v in request.query_params["p"].split(",")]
    text = ", ".join(demo.label(i, p) for i, p in enumerate(positions))
    return JSONResponse({"mean": _json(demo.predict(positions)), "text": text})


app = Starlette(routes=[Route("/", index), Route("/api/meta", meta), Route("/api/predict", predict),
                        Mount("/uplot", StaticFiles(directory=sys.argv[2]))])
uvicorn.run(app, host="127.0.0.1", port=int(sys.argv[1]), log_level="warning")
'''

STARLETTE_PAGE = '''\
<!doctype html>
<html><head><meta charset="utf-8"><title>peer: starlette + uPlot</title>
<link rel="stylesheet" href="/uplot/uPlot.min.css"><script src="/uplot/uPlot.iife.min.js"></script></head>
<body><div id="sliders"></div><p id="values"></p><div id="plot"></div>
<script>
(async () => {
  const meta = await (await fetch("/api/meta")).json();
  const box = document.getElementById("sliders");
  const sliders = meta.names.map(name => {
    const label = document.createElement("label");
    label.textContent = name + " ";
    const s = document.createElement("input");
    Object.assign(s, {type: "range", id: "param-" + name, min: 0, max: meta.steps, step: 1, value: meta.steps / 2});
    label.appendChild(s); box.appendChild(label); box.appendChild(document.createElement("br"));
    return s;
  });
  const colors = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
  const series = [{label: "load, kN"}];
  meta.sensors.forEach((s, j) => {
    series.push({label: s + " measured", stroke: colors[j % 6], dash: [4, 4], points: {show: true}});
    series.push({label: s + " predicted", stroke: colors[j % 6], width: 2});
  });
  const column = (rows, j) => rows.map(r => r[j]);
  const data = mean => [meta.loads, ...meta.sensors.flatMap((s, j) => [column(meta.measured, j), column(mean, j)])];
  let plot = null, sent = 0, shown = 0;
  async function update() {
    const id = ++sent;
    const r = await (await fetch("/api/predict?p=" + sliders.map(s => s.value).join(","))).json();
    if (id < shown) return;  // an older answer arriving late
    shown = id;
    document.getElementById("values").textContent = r.text;
    if (plot) plot.setData(data(r.mean));
    else plot = new uPlot({width: 900, height: 500, series, scales: {x: {time: false}},
                           axes: [{label: "load, kN"}, {label: "reading, mm"}]}, data(r.mean),
                          document.getElementById("plot"));
  }
  sliders.forEach(s => s.addEventListener("input", update));
  update();
})();
</script></body></html>
'''

DASH_APP = '''\
"""Peer app: Dash (dcc.Slider → callback → dcc.Graph)."""
import sys

import plotly.graph_objects as go
from dash import Dash, Input, Output, dcc, html

from peer_model import STEPS, Demo

demo = Demo()
app = Dash(__name__)
app.layout = html.Div(
    [html.Div([html.Label(name), dcc.Slider(0, STEPS, 1, value=STEPS // 2, id=f"param-{name}", marks=None,
                                            updatemode="drag")]) for name in demo.names]
    + [html.P(id="values"), dcc.Graph(id="plot")])
COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]


@app.callback(Output("plot", "figure"), Output("values", "children"),
              [Input(f"param-{name}", "value") for name in demo.names])
def update(*positions):
    mean = demo.predict(positions)
    fig = go.Figure()
    for j, s in enumerate(demo.sensors):
        c = COLORS[j % 6]
        fig.add_trace(go.Scatter(x=demo.loads, y=demo.measured[:, j], name=f"{s} measured",
                                 mode="lines+markers", line={"dash": "dash", "color": c}))
        fig.add_trace(go.Scatter(x=demo.loads, y=mean[:, j], name=f"{s} predicted", mode="lines",
                                 line={"color": c}))
    fig.update_layout(width=900, height=500, xaxis_title="load, kN", yaxis_title="reading, mm")
    return fig, ", ".join(demo.label(i, p) for i, p in enumerate(positions))


app.run(host="127.0.0.1", port=int(sys.argv[1]), debug=False)
'''

PANEL_APP = '''\
"""Peer app: Panel (IntSlider → watcher → the data of a Bokeh figure)."""
import panel as pn
from bokeh.models import ColumnDataSource
from bokeh.plotting import figure

from peer_model import STEPS, demo

d = demo()
sliders = [pn.widgets.IntSlider(name=name, start=0, end=STEPS, step=1, value=STEPS // 2) for name in d.names]
COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"]


def columns():
    positions = [s.value for s in sliders]
    mean = d.predict(positions)
    data = {"load": d.loads}
    for j, s in enumerate(d.sensors):
        data[f"m{j}"], data[f"p{j}"] = d.measured[:, j], mean[:, j]
    return data, ", ".join(d.label(i, p) for i, p in enumerate(positions))


data, text = columns()
source = ColumnDataSource(data)
fig = figure(width=900, height=500, x_axis_label="load, kN", y_axis_label="reading, mm")
for j, s in enumerate(d.sensors):
    c = COLORS[j % 6]
    fig.line("load", f"m{j}", source=source, color=c, line_dash="dashed", legend_label=f"{s} measured")
    fig.scatter("load", f"m{j}", source=source, color=c)
    fig.line("load", f"p{j}", source=source, color=c, line_width=2, legend_label=f"{s} predicted")
values = pn.pane.Str(text)


def update(event):
    source.data, values.object = columns()


for s in sliders:
    s.param.watch(update, "value")
pn.Column(*sliders, values, pn.pane.Bokeh(fig)).servable()
'''

STREAMLIT_APP = '''\
"""Peer app: Streamlit (st.slider → rerun → st.line_chart)."""
import pandas as pd
import streamlit as st

from peer_model import STEPS, demo

d = demo()
positions = [st.slider(name, 0, STEPS, STEPS // 2, key=f"param-{name}") for name in d.names]
st.text(", ".join(d.label(i, p) for i, p in enumerate(positions)))
mean = d.predict(positions)
frame = {}
for j, s in enumerate(d.sensors):
    frame[f"{s} measured"], frame[f"{s} predicted"] = d.measured[:, j], mean[:, j]
st.line_chart(pd.DataFrame(frame, index=pd.Index(d.loads, name="load, kN")), width=900, height=500)
'''

STACKS = {
    "starlette": Stack("starlette", ("starlette", "uvicorn"), "starlette", "app.py", STARLETTE_APP,
                       ("{app}", "{port}", str(UPLOT)), extra_files={"index.html": STARLETTE_PAGE},
                       probe="/uplot/uPlot.min.css"),
    "dash": Stack("dash", ("dash",), "dash", "app.py", DASH_APP, ("{app}", "{port}")),
    "panel": Stack("panel", ("panel",), "panel", "app.py", PANEL_APP,
                   ("-m", "panel", "serve", "{app}", "--address", "127.0.0.1", "--port", "{port}",
                    "--allow-websocket-origin", "127.0.0.1:{port}"), path="/app", probe="/static/js/bokeh.min.js"),
    "streamlit": Stack("streamlit", ("streamlit",), "streamlit", "app.py", STREAMLIT_APP,
                       ("-m", "streamlit", "run", "{app}", "--server.address", "127.0.0.1", "--server.port",
                        "{port}", "--server.headless", "true", "--browser.gatherUsageStats", "false",
                        "--server.fileWatcherType", "none"), probe="/_stcore/health"),
}


# --------------------------------------------------------------------------- the browser side
#: Runs in the page before any of its scripts: notes each key event and each paint of a plot (a
#: drawing call on a 2D canvas of at least 300 × 200 px, a change inside an SVG drawing of at least
#: that size: not an icon), in ``performance.now()`` milliseconds.
RECORDER = r'''
(() => {
  const rec = window.__peers = {key: null, first: null, last: null, paints: 0, firstPaint: null};
  const note = () => {
    const t = performance.now();
    if (rec.firstPaint === null) rec.firstPaint = t;
    if (rec.key === null) return;
    rec.paints += 1; rec.last = t; if (rec.first === null) rec.first = t;
  };
  const proto = CanvasRenderingContext2D.prototype;
  for (const name of ["stroke", "fill", "fillRect", "clearRect", "strokeRect", "fillText", "drawImage",
                      "putImageData"]) {
    const original = proto[name];
    proto[name] = function (...args) {
      if (this.canvas.width >= 300 && this.canvas.height >= 200) note();
      return original.apply(this, args);
    };
  }
  const large = n => {
    if (!(n instanceof SVGElement)) return false;
    while (n.ownerSVGElement) n = n.ownerSVGElement;
    const r = n.getBoundingClientRect();
    return r.width >= 300 && r.height >= 200;
  };
  new MutationObserver(records => {
    if (records.some(r => large(r.target) || Array.from(r.addedNodes).some(large))) note();
  }).observe(document, {subtree: true, childList: true, attributes: true, characterData: true});
  window.addEventListener("keydown", e => { rec.key = e.timeStamp; }, true);
  rec.reset = () => { rec.key = null; rec.first = null; rec.last = null; rec.paints = 0; };
})();
'''

#: Every slider of the page, in document order, looking inside shadow roots too (Bokeh's widgets).
FIND_SLIDERS = r'''
const found = [];
const walk = root => {
  for (const el of root.querySelectorAll("*")) {
    if (el.matches('input[type="range"], [role="slider"]')) found.push(el);
    if (el.shadowRoot) walk(el.shadowRoot);
  }
};
walk(document);
return found;
'''

#: Wait until the page has painted after the key and then stayed still for ``quiet`` ms.
WAIT_QUIET = r'''
const [quiet, timeout, done] = [arguments[0], arguments[1], arguments[arguments.length - 1]];
const rec = window.__peers, start = performance.now();
(function poll() {
  const now = performance.now();
  if (rec.key !== null && rec.last !== null && now - rec.last >= quiet)
    return done({key: rec.key, first: rec.first, last: rec.last, paints: rec.paints});
  if (now - start > timeout) return done({key: rec.key, first: null, last: null, paints: rec.paints});
  setTimeout(poll, 10);
})();
'''

WAIT_FIRST_PAINT = r'''
const [timeout, done] = [arguments[0], arguments[arguments.length - 1]];
const start = performance.now();
(function poll() {
  const rec = window.__peers;
  if (rec && rec.firstPaint !== null) return done(rec.firstPaint);
  if (performance.now() - start > timeout) return done(null);
  setTimeout(poll, 20);
})();
'''

#: Requests the page made to hosts other than the server's.
FOREIGN = r'''
return performance.getEntriesByType("resource").map(e => e.name)
  .filter(u => !u.startsWith(location.origin) && !u.startsWith("data:") && !u.startsWith("blob:"));
'''


def browser(chromium=CHROMIUM, chromedriver=CHROMEDRIVER):
    """Headless Chromium driven by selenium, with :data:`RECORDER` in every page."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    for path in (chromium, chromedriver):
        if not Path(path).is_file():
            sys.exit(f"{path} not found: install Debian's chromium and chromium-driver (apt-get install "
                     "chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                "--window-size=1200,1000", "--disable-background-timer-throttling",
                "--disable-renderer-backgrounding", "--disable-extensions"):
        options.add_argument(arg)
    driver = webdriver.Chrome(service=Service(chromedriver), options=options)
    driver.set_page_load_timeout(120)
    driver.set_script_timeout(120)
    driver.execute_cdp_cmd("Page.addScriptToEvaluateOnNewDocument", {"source": RECORDER})
    return driver


# --------------------------------------------------------------------------- one stack's run
def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_serving(url, proc, timeout):
    """Seconds until ``url`` answers 200 (the server process must stay alive meanwhile)."""
    start = time.perf_counter()
    while time.perf_counter() - start < timeout:
        if proc.poll() is not None:
            raise RuntimeError(f"the server exited with code {proc.returncode} before serving {url}")
        try:
            with urllib.request.urlopen(url, timeout=5) as r:
                if r.status == 200:
                    return time.perf_counter() - start
        except (urllib.error.URLError, ConnectionError, TimeoutError, OSError):
            pass
        time.sleep(0.05)
    raise RuntimeError(f"{url} did not answer within {timeout} s")


def cpu_seconds(pid):
    """User + system CPU seconds of a process and its live children."""
    import psutil

    proc = psutil.Process(pid)
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.NoSuchProcess:
            pass
    return total


def stop(proc, timeout=15):
    """SIGTERM to the server's process group, SIGKILL after ``timeout`` s."""
    if proc.poll() is not None:
        return
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout)
    except ProcessLookupError:
        pass


def peer_record(name):
    """The ``peer.json`` written by ``--install``; exits with the command to run if it is missing."""
    python, record = venv_python(name), venv_dir(name) / "peer.json"
    if not python.is_file() or not record.is_file():
        raise MissingPeer(f"no environment for the {name} stack at {venv_dir(name)}: make it with "
                          f"'python scripts/bench_serve_peers.py --install {name}'")
    return json.loads(record.read_text(encoding="utf-8"))


class MissingPeer(RuntimeError):
    """A stack's environment has not been made (``--install``)."""


def key_for(i, n_sliders):
    """Slider and key of move ``i``: the sliders in turn, five steps right then five left each."""
    from selenium.webdriver.common.keys import Keys

    k, j = i % n_sliders, i // n_sliders
    return k, (Keys.ARROW_RIGHT if (j // 5) % 2 == 0 else Keys.ARROW_LEFT)


def measure(stack, args, log=print):
    """Start one stack's app, load its page in Chromium, move its sliders; a dict of figures."""
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.keys import Keys

    record = peer_record(stack.name)
    folder = Path(tempfile.mkdtemp(prefix=f"peers-{stack.name}-"))
    (folder / "peer_model.py").write_text(MODEL, encoding="utf-8")
    (folder / stack.app_file).write_text(stack.source, encoding="utf-8")
    for name, text in stack.extra_files.items():
        (folder / name).write_text(text, encoding="utf-8")
    port = free_port()
    argv = [str(venv_python(stack.name)), *(a.format(app=folder / stack.app_file, port=port) for a in stack.command)]
    env = {**os.environ, "PYTHONPATH": str(folder), "PEERS_STUDY": str(args.study), "PEERS_FOLDER": str(args.folder)}
    env.pop("VIRTUAL_ENV", None)
    out = {"stack": stack.name, "version": record["version"], "added": record["added"]}
    driver = browser()  # before the server: its start-up is no part of the server's figures
    server_log, proc = (folder / "server.log").open("w"), None
    try:
        started = time.perf_counter()
        proc = subprocess.Popen(["nice", "-n", "5", *argv], cwd=folder, env=env, stdout=server_log,
                                stderr=subprocess.STDOUT, start_new_session=True)
        url = f"http://127.0.0.1:{port}{stack.path}"
        out["serving"] = wait_serving(f"http://127.0.0.1:{port}{stack.probe}", proc, args.timeout)
        log(f"[{stack.name}] serving {url} after {out['serving']:.1f} s")
        for visit in ("first", "reload"):
            navigated = time.perf_counter()
            driver.get(url)
            paint = driver.execute_async_script(WAIT_FIRST_PAINT, args.timeout * 1000)
            if paint is None:
                raise RuntimeError(f"no plot painted within {args.timeout} s of loading {url}")
            out[f"first_plot_{visit}"] = paint / 1000
            if visit == "first":
                out["start_to_plot"] = navigated - started + paint / 1000
            log(f"[{stack.name}] first plot ({visit} visit) {paint / 1000:.2f} s after navigation")
        sliders, start = [], time.perf_counter()
        while len(sliders) != args.n_params and time.perf_counter() - start < args.timeout:
            time.sleep(0.2)
            sliders = driver.execute_script(FIND_SLIDERS)
        if len(sliders) != args.n_params:
            raise RuntimeError(f"found {len(sliders)} sliders on the page, expected {args.n_params}")
        time.sleep(args.quiet / 1000 * 2)  # let the first render settle
        driver.execute_script("window.__peers.reset()")
        time.sleep(1.0)
        out["idle_paints"] = driver.execute_script("return window.__peers.paints")
        latencies, firsts, paints, failed, cpu0, browser0 = [], [], [], 0, None, None
        for i in range(args.warmup + args.moves):
            if i == args.warmup:
                cpu0, browser0 = cpu_seconds(proc.pid), cpu_seconds(driver.service.process.pid)
            k, key = key_for(i, len(sliders))
            driver.execute_script("arguments[0].focus(); window.__peers.reset();", sliders[k])
            ActionChains(driver).send_keys(key).perform()
            r = driver.execute_async_script(WAIT_QUIET, args.quiet, args.move_timeout * 1000)
            if i < args.warmup:
                continue
            if r["last"] is None:
                failed += 1
            else:
                latencies.append(r["last"] - r["key"])
                firsts.append(r["first"] - r["key"])
                paints.append(r["paints"])
        out["cpu"] = cpu_seconds(proc.pid) - cpu0
        out["browser_cpu"] = cpu_seconds(driver.service.process.pid) - browser0
        out["moves"], out["failed"], out["latencies"] = len(latencies), failed, latencies
        nan = float("nan")
        out["median"], out["p90"], out["first_paint_median"], out["paints_median"] = nan, nan, nan, 0
        if latencies:
            q = statistics.quantiles(latencies, n=10, method="inclusive")
            out["median"], out["p90"] = statistics.median(latencies), q[8]
            out["first_paint_median"], out["paints_median"] = statistics.median(firsts), statistics.median(paints)
        bursts = []
        for i in range(args.bursts):  # BURST steps at the display's rate, as a drag sends them
            k, key = i % len(sliders), (Keys.ARROW_RIGHT if (i // len(sliders)) % 2 == 0 else Keys.ARROW_LEFT)
            driver.execute_script("arguments[0].focus(); window.__peers.reset();", sliders[k])
            chain = ActionChains(driver)
            for _ in range(BURST):
                chain.send_keys(key).pause(1 / 60)
            chain.perform()
            r = driver.execute_async_script(WAIT_QUIET, args.quiet, args.move_timeout * 1000)
            if r["last"] is not None:
                bursts.append(r["last"] - r["key"])
        out["burst"] = statistics.median(bursts) if bursts else nan
        out["foreign"] = driver.execute_script(FOREIGN)
        log(f"[{stack.name}] {len(latencies)} moves: median {out['median']:.0f} ms, p90 {out['p90']:.0f} ms "
            f"(first paint {out['first_paint_median']:.0f} ms, {out['paints_median']:.0f} paint calls), "
            f"{failed} without a paint, {out['idle_paints']} paint calls in 1 s idle; burst {out['burst']:.0f} ms; "
            f"CPU: server {out['cpu']:.2f} s, browser {out['browser_cpu']:.2f} s")
    except Exception as error:
        raise RuntimeError(f"{stack.name}: {error} (the server's output: {folder / 'server.log'})") from error
    finally:
        driver.quit()
        if proc is not None:
            stop(proc)
        server_log.close()
    if not args.keep:
        shutil.rmtree(folder, ignore_errors=True)
    return out


# --------------------------------------------------------------------------- table and command
def uptime():
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def table(rows):
    """The Markdown table of the measured stacks."""
    head = ("| stack | version | packages added to a fresh venv | serving after start, s | first plot after "
            "navigation, first visit / reload, s | start → first plot, s | slider → plot median, ms | p90, ms "
            "| after a burst of 10 steps, ms | CPU during the moves, server / browser, s | moves (no paint) "
            "| requests to other hosts |")
    n_columns = head.count("|") - 1
    lines = [head, "|" + "---|" * n_columns]
    for r in rows:
        if "error" in r:
            lines.append(f"| {r['stack']} | " + r["error"].replace("|", "/") + " |" + " |" * (n_columns - 2))
            continue
        lines.append(f"| {r['stack']} | {r['version']} | {r['added']} | {r['serving']:.1f} | "
                     f"{r['first_plot_first']:.2f} / {r['first_plot_reload']:.2f} | {r['start_to_plot']:.1f} | "
                     f"{r['median']:.0f} | {r['p90']:.0f} | {r['burst']:.0f} | "
                     f"{r['cpu']:.2f} / {r['browser_cpu']:.1f} | {r['moves']} ({r['failed']}) | {len(r['foreign'])} |")
    return "\n".join(lines)


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="\n\n".join(__doc__.split("\n\n")[1:]))
    parser.add_argument("--install", nargs="*", choices=list(STACKS), metavar="STACK",
                        help="make the stacks' environments /work/venv-peers-STACK (all four if none is named) "
                             "and exit")
    parser.add_argument("--stacks", nargs="+", choices=list(STACKS), default=list(STACKS),
                        help="stacks to measure, one after the other (default: all four)")
    parser.add_argument("--folder", type=Path, default=DEMO_FOLDER,
                        help="the finished demo folder, read only (default: %(default)s; made by 'podkrig demo "
                             "--out FOLDER')")
    parser.add_argument("--study", type=Path, default=DEMO_STUDY, help="its study file (default: the demo's)")
    parser.add_argument("--moves", type=int, default=60, help="timed slider moves per stack (default: %(default)s)")
    parser.add_argument("--warmup", type=int, default=8, help="untimed moves first (default: %(default)s)")
    parser.add_argument("--bursts", type=int, default=12,
                        help=f"bursts of {BURST} steps at 60 per second after the moves (default: %(default)s)")
    parser.add_argument("--quiet", type=float, default=400.0,
                        help="ms without a paint that end a move (default: %(default)s)")
    parser.add_argument("--timeout", type=float, default=180.0,
                        help="s to wait for a server to answer and for its first plot (default: %(default)s)")
    parser.add_argument("--move-timeout", type=float, default=20.0,
                        help="s to wait for the plot after a move (default: %(default)s)")
    parser.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    parser.add_argument("--keep", action="store_true", help="keep each app's temporary folder (app, server log)")
    args = parser.parse_args(argv)
    args.n_params = 4
    return args


def main(argv=None):
    args = parse_args(argv)
    if args.install is not None:
        for name in args.install or list(STACKS):
            try:
                install(STACKS[name])
            except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as error:
                sys.exit(f"making the {name} environment failed: {error} (pip's output is above)")
        return 0
    missing = []
    for name in args.stacks:
        try:
            peer_record(name)
        except MissingPeer as error:
            missing.append(str(error))
    if missing:
        sys.exit("\n".join(missing))
    for path in (args.folder / "surrogate.h5", args.study):
        if not path.is_file():
            sys.exit(f"{path} not found: give the finished demo folder with --folder (made by 'podkrig demo "
                     "--out FOLDER') and its study with --study")
    before = uptime()
    print(f"load before: {before}", flush=True)
    rows = []
    for name in args.stacks:
        try:
            rows.append(measure(STACKS[name], args, log=lambda m: print(m, flush=True)))
        except RuntimeError as error:
            print(error, flush=True)
            rows.append({"stack": name, "error": str(error)})
    after = uptime()
    print(f"load after: {after}\n")
    print(table(rows))
    if args.json:
        args.json.write_text(json.dumps({"rows": rows, "load_before": before, "load_after": after,
                                         "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, indent=1),
                             encoding="utf-8")
    return 1 if any("error" in r for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
