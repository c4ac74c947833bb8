"""The HTTP API of ``podkrig serve`` (starlette's test client; one real uvicorn start).

The study served is a tiny one (coarse mesh, three free parameters, 16 training runs) run once per
session into a scratch folder; its numbers are checked against the library computing the same
quantities directly (the surrogate, the noise model, the calibration stage).
"""

import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import httpx
import numpy as np
import pytest

with warnings.catch_warnings():  # starlette's test client asks for httpx2 over httpx; both work
    warnings.simplefilter("ignore")
    from starlette.testclient import TestClient

from fe.scenarios import build_scenario
from podkrig.serve.app import MAX_JSON_BODY, create_app
from podkrig.serve.server import check_binding
from podkrig.serve.session import RequestError, Session
from podkrig.study import load_study, run_study

from serve_studies import TRUTH, measured, write_joint_study

ROOT = Path(__file__).resolve().parents[1]

#: three free parameters (two log-scaled), a coarse mesh, a few FE runs, a small GA and region
TINY = """\
name = "tiny_serve"

[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1

[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }
r_hj = { lower = 0.2, upper = 1.0 }

[fixed]
E_b = 11000.0

[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1

[surrogate]
beta = "fit-shared"

[measurement]
file = "measured.csv"
noise_rel = 0.01

[inversion]
population_size = 20
generations = 10
n_starts = 2
region_samples = 4096
"""

ORIGIN = "http://127.0.0.1:8000"


@pytest.fixture(scope="session")
def tiny_study(tmp_path_factory):
    """The tiny study run once: (study file, output folder)."""
    d = tmp_path_factory.mktemp("serve_study")
    (d / "study.toml").write_text(TINY)
    measured(d / "measured.csv")
    run_study(load_study(d / "study.toml"), d / "out")
    return d / "study.toml", d / "out"


@pytest.fixture(scope="module")
def session(tiny_study):
    s = Session.open(tiny_study[1])
    yield s
    s.close()


@pytest.fixture
def client(session):
    with TestClient(create_app(session), base_url=ORIGIN) as c:
        yield c


def error_of(response, status, *fragments, field=...):
    """Assert an error response: its status, the fragments of its message, its field."""
    assert response.status_code == status, response.text
    body = response.json()
    assert set(body) == {"error", "field"}
    for fragment in fragments:
        assert fragment in body["error"], body["error"]
    if field is not ...:
        assert body["field"] == field
    assert "Traceback" not in body["error"]
    return body


# ------------------------------------------------------------------------------------- the page


def test_page_and_static_files(client):
    page = Path(__file__).resolve().parents[1] / "podkrig" / "serve" / "static" / "index.html"
    r = client.get("/")
    assert r.status_code == 200 and r.content == page.read_bytes()
    # the browser runs podkrig's own scripts only and asks no other host for anything
    policy = dict(rule.strip().split(" ", 1) for rule in r.headers["content-security-policy"].split(";"))
    assert policy["default-src"] == policy["script-src"] == policy["connect-src"] == "'self'"
    assert policy["frame-ancestors"] == "'none'" and r.headers["x-content-type-options"] == "nosniff"
    r = client.get("/static/vendor/uplot-1.6.32/uPlot.iife.min.js")
    assert r.status_code == 200 and b"uPlot" in r.content
    assert client.get("/static/vendor/nothing.js").status_code == 404


def test_files_only_under_the_folder(client, session, tmp_path):
    r = client.get("/files/report/index.html")
    assert r.status_code == 200 and r.content == (session.folder / "report" / "index.html").read_bytes()
    error_of(client.get("/files/report/no_such.png"), 404, "no_such.png", field="path")
    error_of(client.get("/files/.podkrig.lock"), 403, ".podkrig.lock", field="path")  # hidden files: never
    error_of(client.get("/files/report/%2e%2e/%2e%2e/secret"), 403, "not a path inside", field="path")
    outside = tmp_path / "secret.txt"
    outside.write_text("outside")
    link = session.folder / "report" / "link_out.txt"
    link.symlink_to(outside)
    try:
        error_of(client.get("/files/report/link_out.txt"), 403, "outside the served folder", field="path")
    finally:
        link.unlink()
    with pytest.raises(RequestError, match="not a path inside"):
        session.file("/etc/passwd")


def test_files_are_sandboxed(client):
    """An HTML file of the folder (a report, or a file planted in a folder received from someone
    else) runs without this server's origin: its scripts' requests carry Origin "null" (refused)."""
    r = client.get("/files/report/index.html")
    assert r.status_code == 200
    assert r.headers["content-security-policy"].startswith("sandbox") and "allow-same-origin" not in \
        r.headers["content-security-policy"]
    assert r.headers["x-content-type-options"] == "nosniff"
    error_of(client.post("/api/jobs", json={"kind": "study"}, headers={"origin": "null"}), 403, "null", field="host")


def test_files_refuse_every_escape(client, session, tmp_path):
    """A hostile page or user asking /files for anything but a file under the folder."""
    error_of(client.get("/files//etc/passwd"), 403, "not a path inside", field="path")  # absolute
    error_of(client.get("/files/report%2f..%2f..%2f..%2fetc%2fpasswd"), 403, "not a path inside", field="path")
    error_of(client.get("/files/%2E%2E/summary.json"), 403, "not a path inside", field="path")
    error_of(client.get("/files/report/%00.png"), 403, "not a path inside", field="path")  # NUL: no OS error
    error_of(client.get("/files/report"), 404, "report", field="path")  # a directory: no listing
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    (outside / "secret.txt").write_text("outside")
    link = session.folder / "report" / "dir_out"
    link.symlink_to(outside, target_is_directory=True)
    try:
        error_of(client.get("/files/report/dir_out/secret.txt"), 403, "outside the served folder", field="path")
    finally:
        link.unlink()


# ------------------------------------------------------------------------------------- the study


def test_study_view(client, tiny_study):
    study = client.get("/api/study").json()
    manifest = json.loads((tiny_study[1] / "stages" / "calibration.json").read_text())["result"]
    assert study["name"] == "tiny_serve" and study["state"] == "ready"
    assert study["study_file"] == str(tiny_study[0])
    params = {p["name"]: p for p in study["parameters"]}
    assert list(params) == ["kN_bj", "kV_bj", "r_hj"]
    assert params["kN_bj"]["scale"] == "log" and params["r_hj"]["scale"] == "linear"
    assert params["kN_bj"]["unit"] == "N/mm³" and params["r_hj"]["unit"] == "-"
    for name, p in params.items():  # the study's best fit and interval, as its calibration stage wrote them
        assert p["best"] == p["value"] == manifest["inversion"]["parameters"][name]
        assert p["interval"] == manifest["region"]["intervals"][name]
        assert (p["lower"], p["upper"]) == {"kN_bj": (30.0, 300.0), "kV_bj": (10.0, 120.0), "r_hj": (0.2, 1.0)}[name]
    (test,) = study["tests"]
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    assert test["name"] is None and test["scenario"] == "diagonal_compression"
    assert test["control"] == "load" and test["load_unit"] == "kN"
    assert test["load_levels"] == sc.load_levels.tolist()
    assert [s["name"] for s in test["sensors"]] == list(sc.sensor_names)
    assert test["free"] == ["kN_bj", "kV_bj", "r_hj"]
    assert study["noise"] == {"": {"noise_abs": None, "noise_rel": 0.01, "instrument": None}}
    assert study["inversion"] == {"seed": 0, "population_size": 20, "generations": 10, "n_starts": 2}
    cal = study["calibration"]
    assert cal["chi2_dof"] == pytest.approx(manifest["inversion"]["chi2_dof"], rel=1e-12, abs=0)  # same numbers
    assert [p["name"] for p in cal["parameters"]] == ["kN_bj", "kV_bj", "r_hj"]
    assert len(cal["region"]["samples"]) == manifest["region"]["n_members"] <= 2000
    assert cal["fe_check"][0]["unit"] == "mm"


def test_midpoint_without_a_calibration(tiny_study, tmp_path):
    """A study file whose calibration has not run starts every slider at the box's midpoint (the
    geometric mean of the bounds on a log scale)."""
    s = Session(load_study(tiny_study[0]), tmp_path / "empty")
    assert s.state == "needs_offline"
    d = s.defaults()
    np.testing.assert_allclose([d["kN_bj"], d["kV_bj"], d["r_hj"]], [np.sqrt(30 * 300), np.sqrt(10 * 120), 0.6],
                               rtol=1e-12, atol=0)  # closed forms of the unit cube's centre
    with pytest.raises(RequestError, match="run the study first") as e:
        s.predict({})
    assert e.value.status == 409


def test_open_refuses_a_folder_without_summary(tmp_path):
    with pytest.raises(RequestError, match="summary.json") as e:
        Session.open(tmp_path)
    assert "STUDY.toml" in str(e.value)


# ------------------------------------------------------------------------------------- predict


def test_predict_is_the_surrogate_against_the_data(client, session):
    values = {"kN_bj": 120.0, "kV_bj": 40.0, "r_hj": 0.5}
    r = client.post("/api/predict", json={"values": values})
    assert r.status_code == 200, r.text
    out = r.json()
    problem = session.problem
    full = np.array([[{**TRUTH, **values}[n] for n in problem.model.space.names]])
    mean, std = problem.model.predict(full, return_std=True)
    meas = problem.measurement
    mean, std = mean[0].reshape(meas.values.shape), std[0].reshape(meas.values.shape)
    sigma = np.sqrt((0.01 * meas.values) ** 2 + std**2)  # noise_rel = 0.01 and the surrogate's variance (C_D)
    (test,) = out["tests"]
    for j, series in enumerate(test["series"]):
        assert series["sensor"] == meas.sensor_names[j] and series["x_unit"] == "kN"
        # tolerances: the same arithmetic in another order
        np.testing.assert_allclose(series["mean"], mean[:, j], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(series["std"], std[:, j], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(series["measured"], meas.values[:, j], rtol=0, atol=0)
        np.testing.assert_allclose(series["residual"], (meas.values[:, j] - mean[:, j]) / sigma[:, j], rtol=1e-10,
                                   atol=1e-12)
    z = np.array([s["residual"] for s in test["series"]])
    n_obs = meas.values.size
    assert out["dof"] == test["dof"] == n_obs - 3
    np.testing.assert_allclose(out["chi2"], np.sum(z**2), rtol=1e-10, atol=0)  # diagonal C_D: χ² = Σ z²
    np.testing.assert_allclose(out["chi2_dof"], out["chi2"] / (n_obs - 3), rtol=1e-12, atol=0)
    np.testing.assert_allclose(out["omega"], out["chi2"] / 2, rtol=1e-12, atol=0)  # thesis eq. 2.13, no prior


def test_predict_at_the_best_fit_gives_the_studys_chi2(client, tiny_study):
    manifest = json.loads((tiny_study[1] / "stages" / "calibration.json").read_text())["result"]
    out = client.post("/api/predict", json={"values": {}}).json()  # every slider at the study's best fit
    np.testing.assert_allclose(out["chi2_dof"], manifest["inversion"]["chi2_dof"], rtol=1e-9, atol=0)


def test_predict_refuses_bad_values(client):
    error_of(client.post("/api/predict", json={"values": {"kN_bj": 1000.0}}), 422, "kN_bj", "1000", "[30, 300]",
             field="kN_bj")
    error_of(client.post("/api/predict", json={"values": {"E_b": 9000.0}}), 422, "E_b", "free parameters", field="E_b")
    error_of(client.post("/api/predict", json={"values": {"r_hj": "0.5"}}), 422, "r_hj", "'0.5'", field="r_hj")
    error_of(client.post("/api/predict", json={"values": [1, 2]}), 422, "values", field="values")
    error_of(client.post("/api/predict", content=b'{"values": {}}'), 415, "application/json")
    error_of(client.post("/api/predict", content=b"{not json", headers={"content-type": "application/json"}), 422,
             "not valid JSON")
    big = b'{"values": {}, "pad": "' + b"x" * MAX_JSON_BODY + b'"}'
    error_of(client.post("/api/predict", content=big, headers={"content-type": "application/json"}), 413,
             str(MAX_JSON_BODY))


# ------------------------------------------------------------------------------------- safety


def test_host_origin_and_token(session):
    with TestClient(create_app(session), base_url="http://attacker.example") as c:  # DNS rebinding
        error_of(c.get("/api/study"), 403, "attacker.example", field="host")
    with TestClient(create_app(session, port=8000), base_url="http://127.0.0.1:9000") as c:
        error_of(c.get("/api/study"), 403, "127.0.0.1:9000", field="host")
    with TestClient(create_app(session), base_url=ORIGIN) as c:
        error_of(c.post("/api/predict", json={}, headers={"origin": "http://attacker.example"}), 403,
                 "attacker.example")
        assert c.post("/api/predict", json={}, headers={"origin": ORIGIN}).status_code == 200
    app = create_app(session, host="0.0.0.0", token="s3cret-token")
    with TestClient(app, base_url="http://192.0.2.7:8000") as c:
        error_of(c.get("/api/study"), 403, "token", field="token")
        error_of(c.get("/api/study?token=wrong-token"), 403, "token", field="token")
        assert c.get("/api/study", headers={"X-Podkrig-Token": "s3cret-token"}).status_code == 200
        r = c.get("/api/study?token=s3cret-token")  # once in the address: then a cookie
        assert r.status_code == 200 and "podkrig_token" in r.headers["set-cookie"]
        assert c.get("/api/study").status_code == 200


def test_dns_rebinding_and_foreign_origins(session):
    """A page of another site whose name was rebound to 127.0.0.1 sends its own name (and the
    server's port) as Host; a sandboxed or file:// page sends Origin "null"."""
    for name in ("evil.example:8000", "localhost.evil.example:8000", "127.0.0.1.nip.io:8000"):
        with TestClient(create_app(session, port=8000), base_url=f"http://{name}") as c:
            error_of(c.get("/api/study"), 403, name.split(":")[0], field="host")
            error_of(c.post("/api/predict", json={}), 403, name.split(":")[0], field="host")
    with TestClient(create_app(session, port=8000), base_url="http://127.0.0.1:8000") as c:
        for origin in ("null", "http://127.0.0.1:8001", "http://evil.example:8000"):
            error_of(c.post("/api/predict", json={}, headers={"origin": origin}), 403, origin, field="host")
        assert c.get("/api/study", headers={"host": "localhost:8000"}).status_code == 200


def test_hostile_json_bodies(client):
    """Bodies a script could send: nested, non-finite, out of a float's range, wrong types, unknown keys."""
    as_json = {"content-type": "application/json"}
    deep = b'{"values": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    error_of(client.post("/api/predict", content=deep, headers=as_json), 422, "nested too deeply", field=None)
    for literal in (b"NaN", b"Infinity", b"-Infinity", b"1" + b"0" * 400, b'"90"', b"true", b"null", b"[90]"):
        r = client.post("/api/predict", content=b'{"values": {"kN_bj": ' + literal + b"}}", headers=as_json)
        error_of(r, 422, "kN_bj", "finite number", field="kN_bj")
    r = client.post("/api/calibrate", content=b'{"frozen": {"r_hj": 1' + b"0" * 400 + b"}}", headers=as_json)
    error_of(r, 422, "r_hj", "finite number", field="r_hj")
    error_of(client.post("/api/predict", json={"valuez": {}}), 422, "valuez", "values", field="valuez")
    error_of(client.post("/api/fe", json={"values": {}, "tst": None}), 422, "tst", "test", field="tst")
    error_of(client.post("/api/jobs", json={"kind": "study", "skip": True}), 422, "skip", "skip_diagnosis",
             field="skip")
    error_of(client.post("/api/jobs", json={"kind": ["study"]}), 422, "study", field="kind")
    error_of(client.post("/api/fe", json={"test": {"name": None}}), 404, "no test", field="test")
    error_of(client.post("/api/predict", json=[1, 2]), 422, "JSON object")


def test_an_unexpected_error_answers_without_its_traceback(session, monkeypatch):
    def broken(values=None):
        raise RuntimeError("secret internals at /home/someone")

    monkeypatch.setattr(session, "predict", broken)
    with TestClient(create_app(session), base_url=ORIGIN, raise_server_exceptions=False) as c:
        body = error_of(c.post("/api/predict", json={}), 500, "internal error", "RuntimeError")
    assert "secret" not in body["error"]


def test_printed_address():
    from podkrig.serve.server import address

    assert address("127.0.0.1", 8765) == "http://127.0.0.1:8765/"
    assert address("::1", 8765) == "http://[::1]:8765/"
    assert address("0.0.0.0", 8765, "long-enough-token") == "http://127.0.0.1:8765/?token=long-enough-token"


def test_binding_needs_a_token_off_loopback():
    check_binding("127.0.0.1", 0, None)
    check_binding("::1", 8080, None)
    with pytest.raises(RequestError, match="--token") as e:
        check_binding("0.0.0.0", 0, None)
    assert e.value.status == 403 and "0.0.0.0" in str(e.value)
    check_binding("0.0.0.0", 0, "long-enough-token")
    with pytest.raises(RequestError, match="--port 70000"):
        check_binding("127.0.0.1", 70000, None)
    with pytest.raises(RequestError, match="8 characters"):
        check_binding("0.0.0.0", 0, "short")


def test_bound_socket_says_it_is_tcp():
    """asyncio turns Nagle off only on connections of a socket whose proto is TCP: without it every
    response waits ~40 ms for the client's delayed ACK."""
    import socket

    from podkrig.serve.server import bind

    sock = bind("127.0.0.1", 0)
    try:
        assert sock.proto == socket.IPPROTO_TCP and sock.getsockname()[1] > 0
        with pytest.raises(OSError):  # the same port twice: refused by the OS
            bind("127.0.0.1", sock.getsockname()[1])
    finally:
        sock.close()


def test_real_server_on_a_free_port(tiny_study):
    """``podkrig serve DIR --no-browser --port 0`` prints its address, serves the study, and stops."""
    cmd = [sys.executable, "-c", "from podkrig.cli import app; app()", "serve", str(tiny_study[1]), "--no-browser"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    try:
        line = proc.stdout.readline()
        assert "http://127.0.0.1:" in line, line + proc.stderr.read() if proc.poll() is not None else line
        url = line.split(" at ")[1].split()[0]
        deadline = time.monotonic() + 60
        while True:
            try:
                r = httpx.get(url + "api/study", timeout=10)
                break
            except httpx.TransportError:
                assert time.monotonic() < deadline, "the server did not answer"
                time.sleep(0.1)
        assert r.status_code == 200 and r.json()["name"] == "tiny_serve"
        r = httpx.post(url + "api/predict", json={"values": {"r_hj": 0.7}}, timeout=10)
        assert r.status_code == 200 and len(r.json()["tests"][0]["series"]) == 6
        error_of(httpx.get(url + "api/study", headers={"host": "evil.example"}, timeout=10), 403, "evil.example")
    finally:
        proc.terminate()
        proc.wait(timeout=30)


def test_cli_refuses_other_hosts_without_a_token(tiny_study):
    from typer.testing import CliRunner

    from podkrig.cli import app

    result = CliRunner().invoke(app, ["serve", str(tiny_study[1]), "--host", "0.0.0.0", "--no-browser"])
    assert result.exit_code == 2
    assert "--token" in result.output and "0.0.0.0" in result.output


# ------------------------------------------------------------------------------------- calibrate


def wait_for(client, url, timeout=120):
    """Poll ``url`` until its status is no longer running; its last answer."""
    deadline = time.monotonic() + timeout
    while True:
        body = client.get(url).json()
        if body["status"] != "running":
            return body
        assert time.monotonic() < deadline, f"{url} still running after {timeout} s"
        time.sleep(0.05)


GA = {"seed": 3, "population_size": 16, "generations": 8, "n_starts": 2}


def test_calibration_is_the_library_stage_with_the_frozen_parameter_fixed(client, session):
    r = client.post("/api/calibrate", json={"frozen": {"r_hj": 0.6}, "noise": None, "inversion": GA,
                                            "diagnosis": False})
    assert r.status_code == 202
    rid = r.json()["run"]
    run = wait_for(client, f"/api/runs/{rid}")
    assert run["status"] == "done", run["error"]
    assert run["frozen"] == {"r_hj": 0.6} and run["progress"]["done"] == run["progress"]["total"]
    assert run["settings"]["calibration"]["inversion"] == GA
    # the same stage called directly on the same problem with r_hj fixed
    import dataclasses as dc

    from podkrig.online.calibrate import calibrate
    from podkrig.online.settings import InversionSettings

    p = session.problem
    direct_problem = dc.replace(p, free=("kN_bj", "kV_bj"), fixed={**p.fixed, "r_hj": 0.6})
    settings = dc.replace(session.study.calibration_settings(), inversion=InversionSettings(**GA))
    direct = calibrate(direct_problem, settings, check_measurement=False, range_check=False)
    result = run["result"]
    assert [q["name"] for q in result["parameters"]] == ["kN_bj", "kV_bj"]  # r_hj frozen: not identified
    # the same seeded computation in the same process: equal up to summation order
    np.testing.assert_allclose([q["value"] for q in result["parameters"]], direct.inversion.x, rtol=1e-9, atol=0)
    np.testing.assert_allclose(result["chi2_dof"], direct.inversion.chi2_dof, rtol=1e-9, atol=0)
    assert result["dof"] == direct.inversion.dof == p.n_obs - 2
    for q in result["parameters"]:
        lo, hi = direct.region.intervals[q["name"]]
        np.testing.assert_allclose(q["interval"], [lo, hi], rtol=1e-9, atol=0)
        assert q["identified"] == direct.region.identifiability[q["name"]]["identifiable"]
        assert q["name"] in q["words"]
    region = result["region"]
    assert region["names"] == ["kN_bj", "kV_bj"] and len(region["samples"]) == min(region["n_members"], 2000)
    assert len(region["omega"]) == len(region["samples"]) and region["best"] == [q["value"] for q in result["parameters"]]
    assert result["fe_check"][0]["test"] is None and result["fe_check"][0]["max_diff"] >= 0
    assert all(set(f) == {"code", "level", "message"} for f in result["findings"])
    # the history and the export
    rows = client.get("/api/runs").json()
    assert rows[-1]["id"] == rid and rows[-1]["frozen"] == {"r_hj": 0.6}
    assert rows[-1]["chi2_dof"] == result["chi2_dof"]
    r = client.get(f"/api/runs/{rid}/summary.json")
    assert r.status_code == 200 and "attachment" in r.headers["content-disposition"]
    summary = r.json()
    expected = json.loads(json.dumps(direct.to_dict()))
    assert summary["inversion"]["parameters"].keys() == expected["inversion"]["parameters"].keys()
    assert summary["settings"] == expected["settings"]
    assert {"warnings", "region", "rvc", "findings"} <= set(summary)


def test_calibration_noise_from_the_page(client, session):
    """A noise model given on the page replaces the study's: the run's χ² is that of the problem
    with the page's noise at the run's optimum."""
    import dataclasses as dc

    from podkrig.online.settings import NoiseSettings

    r = client.post("/api/calibrate", json={"noise": {"": {"noise_rel": 0.02}}, "inversion": GA})
    run = wait_for(client, f"/api/runs/{r.json()['run']}")
    assert run["status"] == "done", run["error"]
    assert run["settings"]["noise"] == {"": {"noise_abs": None, "noise_rel": 0.02, "instrument": None}}
    p = session.problem
    doubled = dc.replace(p, noise=NoiseSettings(noise_rel=0.02).noise_model(p.measurement.sensor_names))
    x = np.array([[q["value"] for q in run["result"]["parameters"]]])
    np.testing.assert_allclose(run["result"]["chi2"], doubled.chi2(x)[0], rtol=1e-9, atol=0)  # same arithmetic
    # with the study's σ (half the page's) the same residuals weigh up to 4× more (less where the
    # surrogate's own variance dominates C_D)
    assert 2.0 < p.chi2(x)[0] / run["result"]["chi2"] <= 4.0


@pytest.mark.slow
def test_calibration_with_the_diagnosis(client):
    """Asked for, the model diagnosis runs after the calibration; the data were made by this very
    model (1 % noise), so it finds the model adequate and names no cause."""
    rid = client.post("/api/calibrate", json={"inversion": GA, "diagnosis": True}).json()["run"]
    run = wait_for(client, f"/api/runs/{rid}", timeout=600)
    assert run["status"] == "done", run["error"]
    (diagnosis,) = run["result"]["diagnosis"].values()
    assert diagnosis["verdict"] == "adequate" and diagnosis["causes"] == []
    assert run["settings"]["diagnosis"] is True


@pytest.mark.slow
def test_diagnosis_holds_the_frozen_parameters(client, session):
    """The diagnosis asked with a calibration is that calibration's: r_hj frozen on the page at 0.45
    (the data were made with 0.6) stays at 0.45 in the diagnosis's base fit, which fits the other two."""
    rid = client.post("/api/calibrate", json={"frozen": {"r_hj": 0.45}, "inversion": GA, "diagnosis": True}).json()
    run = wait_for(client, f"/api/runs/{rid['run']}", timeout=600)
    assert run["status"] == "done", run["error"]
    (diagnosis,) = run["result"]["diagnosis"].values()
    assert diagnosis["held"] == {"r_hj": 0.45}  # the value its FE fits ran with, as the calibration's
    assert set(diagnosis["base"]["parameters"]) == {"kN_bj", "kV_bj"} == set(diagnosis["surrogate"]["parameters"])
    assert diagnosis["adequacy"]["dof"] == session.problem.n_obs - 2


def test_calibration_refuses_bad_settings(client):
    post = lambda body: client.post("/api/calibrate", json=body)  # noqa: E731
    error_of(post({"inversion": {**GA, "population_size": 2}}), 422, "population_size", "2", "[4,",
             field="inversion.population_size")
    error_of(post({"inversion": {**GA, "generations": "10"}}), 422, "generations", "an integer",
             field="inversion.generations")
    error_of(post({"inversion": {"pop": 10}}), 422, "pop", "population_size", field="inversion.pop")
    error_of(post({"noise": {"": {"noise_rel": 0.01, "instrument": "lvdt"}}}), 422, "instrument", "noise_rel",
             field="noise.instrument")
    error_of(post({"noise": {"": {"instrument": "laser"}}}), 422, "laser", "lvdt", field="noise.instrument")
    error_of(post({"noise": {"": {}}}), 422, "give a noise model", field="noise")
    error_of(post({"noise": {"wall": {"noise_rel": 0.01}}}), 422, "wall", field="noise.wall")
    error_of(post({"noise": {"": {"noise_abs": {"D9": 0.001}}}}), 422, "D9", "D1", field="noise..noise_abs")
    error_of(post({"frozen": {"r_hj": 2.0}}), 422, "r_hj", "2", "[0.2, 1]", field="r_hj")
    error_of(post({"frozen": {"kN_bj": 90.0, "kV_bj": 35.0, "r_hj": 0.6}}), 422, "free at least one", field="frozen")
    error_of(post({"diagnosis": "yes"}), 422, "diagnosis", field="diagnosis")
    error_of(post({"frozn": {"r_hj": 0.6}}), 422, "frozn", "frozen", field="frozn")  # never ignored silently
    error_of(post({"inversion": {**GA, "population_size": -5}}), 422, "population_size", "-5",
             field="inversion.population_size")
    error_of(post({"inversion": {**GA, "generations": 0}}), 422, "generations", "0", field="inversion.generations")
    error_of(post({"inversion": {**GA, "generations": 10**9}}), 422, "generations", "GA evaluations",
             field="inversion.generations")
    error_of(post({"inversion": {**GA, "n_starts": 10**6}}), 422, "n_starts", field="inversion.n_starts")
    error_of(client.get("/api/runs/r999"), 404, "r999", field="run")
    error_of(client.get("/api/runs/r999/summary.json"), 404, "r999", field="run")


def test_calibrations_and_fe_runs_wait_in_a_bounded_queue(session):
    """Many calibrations or FE runs asked at once: a few wait, the next is refused (409) until one
    is done, so a script cannot queue hours of work behind the page."""
    import threading

    from podkrig.serve.model import MAX_PENDING_FE
    from podkrig.serve.runs import MAX_PENDING_RUNS

    app = create_app(session)
    services = app.app.state.services
    gate = threading.Event()
    services.runs._pool.submit(gate.wait)  # the worker busy: every run waits behind it
    services.views._pool.submit(gate.wait)
    try:
        with TestClient(app, base_url=ORIGIN) as c:
            ids = [c.post("/api/calibrate", json={"inversion": GA}).json()["run"] for _ in range(MAX_PENDING_RUNS)]
            body = error_of(c.post("/api/calibrate", json={"inversion": GA}), 409, "running or waiting", ids[0])
            assert all(i in body["error"] for i in ids)
            assert [c.get(f"/api/runs/{i}").json()["progress"]["step"] for i in ids] == ["queued"] * MAX_PENDING_RUNS
            fe = [c.post("/api/fe", json={}).json()["fe"] for _ in range(MAX_PENDING_FE)]
            error_of(c.post("/api/fe", json={}), 409, "running or waiting", fe[0])
            gate.set()
            assert all(wait_for(c, f"/api/runs/{i}")["status"] == "done" for i in ids)
            assert all(wait_for(c, f"/api/fe/{i}")["status"] == "done" for i in fe)
            assert c.post("/api/calibrate", json={"inversion": GA}).status_code == 202  # room again
            assert c.post("/api/fe", json={}).status_code == 202
    finally:
        gate.set()
        services.close()


# ------------------------------------------------------------------------------------- the FE model


def test_fe_view_of_a_linear_test(client, session):
    values = {"kN_bj": 90.0, "kV_bj": 35.0, "r_hj": 0.6}
    r = client.post("/api/fe", json={"values": values, "test": None})
    assert r.status_code == 202
    view = wait_for(client, f"/api/fe/{r.json()['fe']}")
    assert view["status"] == "done", view["error"]
    assert view["parameters"] == values  # E_b is fixed in the study's scenario spec
    res = view["result"]
    sc = build_scenario(session.tests[0].spec)
    field = sc.run(values, field=True).field
    corners = np.unique(np.asarray(sc.mesh.quads)[:, :4])
    nodes, outline, u = np.array(res["nodes"]), np.array(res["outline"]), np.array(res["displacement"])
    np.testing.assert_allclose(nodes, sc.mesh.nodes[corners], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(nodes[outline], sc.mesh.nodes[np.asarray(sc.mesh.quads)[:, :4]])
    assert res["steps"] == sc.load_levels.tolist() and res["x_unit"] == "kN"
    top = np.abs(field).max()
    np.testing.assert_allclose(u, field[:, corners], rtol=0, atol=1e-5 * top)  # rounded to 6 significant digits
    # a linear test: the field grows in proportion to the load (closed form)
    ratio = u / np.asarray(res["steps"])[:, None, None]
    np.testing.assert_allclose(ratio, np.broadcast_to(ratio[-1], ratio.shape), rtol=0, atol=1e-4 * np.abs(ratio).max())
    # the largest displacement drawn as 5 % of the specimen's larger side
    largest = np.linalg.norm(field[-1], axis=-1).max()
    np.testing.assert_allclose(res["scale"] * largest, 0.05 * max(sc.mesh.width, sc.mesh.height), rtol=1e-9, atol=0)
    assert res["curve"] is None and res["joints"] is None


def test_fe_view_refusals(client):
    error_of(client.post("/api/fe", json={"values": {"kV_bj": 500.0}}), 422, "kV_bj", "500", "[10, 120]",
             field="kV_bj")
    error_of(client.post("/api/fe", json={"test": "wall"}), 404, "wall", field="test")
    error_of(client.get("/api/fe/f999"), 404, "f999", field="fe")


@pytest.mark.slow
def test_fe_view_of_a_nonlinear_run():
    """Joints' opening and slip and the load–displacement curve of a coarse triplet pushed past its
    peak (the run of the step slider's tests)."""
    from podkrig.reports.step_slider import MAX_FRAMES
    from podkrig.serve.model import model_view

    sc = build_scenario({"scenario": "triplet_shear", "nx": 2, "ny": 1, "precompression": 0.2,
                         "load_levels": [0.05, 0.3, 1.0], "increment": 0.005, "max_increment": 0.02})
    r = sc.run(field=True)
    view = model_view(sc, r)
    path = r.path
    control = np.flatnonzero(path.of_phase(path.phase[-1]))
    n = len(view["steps"])
    assert n == min(MAX_FRAMES, len(control))
    np.testing.assert_allclose(view["curve"]["x"], sc.control_sign * np.asarray(path.path)[control], rtol=1e-12, atol=0)
    np.testing.assert_allclose(view["curve"]["y"], np.asarray(path.load)[control], rtol=1e-12, atol=0)
    assert view["curve"]["y_unit"] == r.force_unit and max(view["curve"]["y"]) in np.asarray(path.load)[control]
    # each shown step's point on the curve (the page marks it there): the same control value
    at = np.asarray(view["curve"]["step_index"])
    assert len(control) > n  # the curve has more points than shown steps: the index is not k
    np.testing.assert_allclose(np.asarray(view["curve"]["x"])[at], view["steps"], rtol=0, atol=0)
    joints = view["joints"]
    points = sc.mesh.nodes[np.asarray(sc.model.point_nodes())]
    n_elements = len(sc.model.interface_elements)
    assert len(joints) == n_elements and all(len(j["opening"]) == len(j["slip"]) == n for j in joints)
    per = len(points) // n_elements
    last = np.asarray(path.states[control[-1]]["opening"], float).reshape(n_elements, per).mean(axis=1)
    opening = np.array([j["opening"][-1] for j in joints])
    np.testing.assert_allclose(opening, last, rtol=0, atol=1e-5 * np.abs(last).max())  # rounded to 6 digits
    for e in (0, n_elements - 1):  # the ends are two of the element's own integration points
        own = points[e * per:(e + 1) * per].tolist()
        assert joints[e]["a"] in own and joints[e]["b"] in own and joints[e]["a"] != joints[e]["b"]
    assert np.shape(view["displacement"])[:2] == (n, len(view["nodes"]))


# ------------------------------------------------------------------------------------- jobs


@pytest.fixture
def fresh_study(tiny_study, tmp_path):
    """A copy of the tiny study file whose stages have not run: (session, client)."""
    study = tmp_path / "study.toml"
    study.write_text(TINY)
    (tmp_path / "measured.csv").write_bytes((tiny_study[0].parent / "measured.csv").read_bytes())
    s = Session.open(study, tmp_path / "out")
    with TestClient(create_app(s), base_url=ORIGIN) as c:
        yield s, c
    c.app.app.state.services.close()
    s.close()


def test_study_file_before_its_stages(fresh_study):
    s, c = fresh_study
    study = c.get("/api/study").json()
    assert study["state"] == "needs_offline" and study["calibration"] is None
    assert [p["value"] for p in study["parameters"]] == pytest.approx([np.sqrt(9000), np.sqrt(1200), 0.6], rel=1e-12)
    assert study["tests"][0]["sensors"][0] == {"name": "D1", "unit": "mm"}
    error_of(c.post("/api/predict", json={}), 409, "run the study first")
    error_of(c.post("/api/calibrate", json={}), 409, "run the study first")


def test_job_cancel_and_a_busy_folder(fresh_study):
    from podkrig.locks import folder_lock

    s, c = fresh_study
    error_of(c.post("/api/jobs", json={"kind": "sweep"}), 422, "sweep", "study", field="kind")
    with folder_lock(s.folder):  # another job holds the folder
        error_of(c.post("/api/jobs", json={"kind": "study"}), 409, "in use", str(s.folder))
    r = c.post("/api/jobs", json={"kind": "study"})
    assert r.status_code == 202
    jid = r.json()["job"]
    error_of(c.post("/api/jobs", json={"kind": "study"}), 409, jid, "cancel")
    job = c.delete(f"/api/jobs/{jid}").json()
    assert job["status"] == "cancelled" and "resume" in job["log"][-1]
    assert c.get("/api/jobs").json()[-1]["status"] == "cancelled"
    with folder_lock(s.folder):  # the job's process is gone: its lock with it
        pass
    again = c.delete(f"/api/jobs/{jid}")  # cancelling an ended job leaves it as it ended
    assert again.status_code == 200 and again.json()["status"] == "cancelled"
    error_of(c.get("/api/jobs/j999"), 404, "j999", field="job")
    error_of(c.delete("/api/jobs/j999"), 404, "j999", field="job")


@pytest.mark.slow
def test_study_job_runs_the_study_then_resumes_cached(fresh_study):
    s, c = fresh_study
    jid = c.post("/api/jobs", json={"kind": "study"}).json()["job"]
    job = wait_for(c, f"/api/jobs/{jid}", timeout=600)
    assert job["status"] == "done", job
    assert any("Training snapshots" in line for line in job["log"])
    study = c.get("/api/study").json()
    assert study["state"] == "ready" and study["calibration"] is not None
    out = c.post("/api/predict", json={}).json()  # at the job's best fit: its χ²/dof
    np.testing.assert_allclose(out["chi2_dof"], study["calibration"]["chi2_dof"], rtol=1e-9, atol=0)
    again = wait_for(c, f"/api/jobs/{c.post('/api/jobs', json={}).json()['job']}", timeout=600)
    assert again["status"] == "done" and "0 FE runs" in again["log"][-1]  # every stage cached
    assert sum("cached" in line for line in again["log"]) >= 6


# ------------------------------------------------------------------------------------- uploads


def test_measurement_upload_replaces_the_data(tiny_study, tmp_path, monkeypatch):
    s = Session.open(tiny_study[1])
    with TestClient(create_app(s), base_url=ORIGIN) as c:
        log = tmp_path / "new.csv"
        values = measured(log, seed=7)
        headers = {"content-type": "application/octet-stream"}
        r = c.post("/api/measurement?test=&name=new.csv", content=log.read_bytes(), headers=headers)
        assert r.status_code == 200, r.text
        assert r.json()["name"] is None and len(r.json()["sensors"]) == 6
        series = c.post("/api/predict", json={}).json()["tests"][0]["series"]
        # the uploaded readings as they were written (CSV text: 6 significant digits or more)
        np.testing.assert_allclose([x["measured"] for x in series], values.T, rtol=1e-6, atol=0)
        error_of(c.post("/api/measurement", content=log.read_bytes(), headers={"content-type": "text/plain"}), 415,
                 "application/octet-stream")
        error_of(c.post("/api/measurement?name=log.pdf", content=b"x", headers=headers), 422, ".csv", field="name")
        error_of(c.post("/api/measurement?test=wall", content=log.read_bytes(), headers=headers), 404, "wall",
                 field="test")
        no_load = log.read_text().replace("load", "force", 1)
        error_of(c.post("/api/measurement", content=no_load.encode(), headers=headers), 422, "load",
                 field="measurement")
        micrometres = tmp_path / "um.csv"
        measured(micrometres, seed=7, scale=1000.0)  # µm written as mm: refused against the training runs
        error_of(c.post("/api/measurement", content=micrometres.read_bytes(), headers=headers), 422, "D1", "larger",
                 field="measurement")
        import podkrig.serve.app as app_module

        monkeypatch.setattr(app_module, "MAX_UPLOAD_BYTES", 100)
        error_of(c.post("/api/measurement", content=log.read_bytes(), headers=headers), 413, "100 bytes")
    s.close()


def test_upload_refusals_name_the_users_file(tiny_study, tmp_path):
    """A refused upload, and a later message about its data, name the file the user chose, never
    the server's temporary copy of it."""
    s = Session.open(tiny_study[1])
    headers = {"content-type": "application/octet-stream"}
    with TestClient(create_app(s), base_url=ORIGIN) as c:
        micrometres = tmp_path / "um.csv"
        measured(micrometres, seed=7, scale=1000.0)  # µm written as mm: refused against the training runs
        r = c.post("/api/measurement?name=lab_um.csv", content=micrometres.read_bytes(), headers=headers)
        body = error_of(r, 422, "lab_um.csv", "D1", field="measurement")
        assert "podkrig-serve" not in body["error"] and "/tmp" not in body["error"]
        r = c.post("/api/measurement?name=C%3A%5Cfakepath%5Cshort.csv", content=b"load,D1\n", headers=headers)
        body = error_of(r, 422, "short.csv", "no data rows", field="measurement")  # the browser's fake folder dropped
        assert "fakepath" not in body["error"] and "podkrig-serve" not in body["error"]
        # a log with a missing cell is accepted for the calibration; the diagnosis, which needs every
        # reading, refuses it naming the file
        log = tmp_path / "gap.csv"
        measured(log, seed=7)
        lines = log.read_text().splitlines()
        cells = lines[1].split(",")
        lines[1] = ",".join([cells[0], "", *cells[2:]])
        r = c.post("/api/measurement?name=lab_gap.csv", content="\n".join(lines).encode(), headers=headers)
        assert r.status_code == 200, r.text
        run = wait_for(c, f"/api/runs/{c.post('/api/calibrate', json={'inversion': GA, 'diagnosis': True}).json()['run']}")
        assert run["status"] == "failed" and "lab_gap.csv" in run["error"] and "podkrig-serve" not in run["error"]
    s.close()


def test_an_upload_outlives_a_job(tiny_study, tmp_path):
    """When a study job ends the session rebuilds its problem from the folder and reads each upload
    again: it stays in use (the page says which file), or, refused now, is dropped with the reason."""
    s = Session.open(tiny_study[1])
    headers = {"content-type": "application/octet-stream"}
    with TestClient(create_app(s), base_url=ORIGIN) as c:
        assert c.get("/api/study").json()["uploads"] == {}
        log = tmp_path / "new.csv"
        values = measured(log, seed=7)
        assert c.post("/api/measurement?test=&name=lab.csv", content=log.read_bytes(), headers=headers).status_code == 200
        s.reload()  # what the end of a study job does
        study = c.get("/api/study").json()
        assert study["uploads"] == {"": {"file": "lab.csv", "state": "in use", "message": None}}
        series = c.post("/api/predict", json={}).json()["tests"][0]["series"]
        np.testing.assert_allclose([x["measured"] for x in series], values.T, rtol=1e-6, atol=0)  # CSV's digits
        s._uploads[None].path.unlink()  # the copy lost (a cleaned /tmp): the rebuilt problem cannot read it
        s.reload()
        upload = c.get("/api/study").json()["uploads"][""]
        assert upload["state"] == "dropped" and upload["file"] == "lab.csv"
        assert "lab.csv" in upload["message"] and "dropped" in upload["message"]
        assert "podkrig-serve" not in upload["message"]
        study_values = load_study(tiny_study[0])
        series = c.post("/api/predict", json={}).json()["tests"][0]["series"]
        assert not np.allclose([x["measured"] for x in series], values.T, rtol=1e-6, atol=0)  # the study's log
        assert study_values.name == "tiny_serve"
    s.close()


# ------------------------------------------------------------------------------------- a joint study


@pytest.mark.slow
def test_joint_study_side_by_side(tmp_path):
    """Two tests sharing kN_bj and kV_bj, the shear test with its own r_hj: one slider set (the
    union, in the joint order), one series set per test, χ² summed over the tests."""
    write_joint_study(tmp_path)
    run_study(load_study(tmp_path / "study.toml"), tmp_path / "out")
    s = Session.open(tmp_path / "out")
    with TestClient(create_app(s), base_url=ORIGIN) as c:
        study = c.get("/api/study").json()
        assert [p["name"] for p in study["parameters"]] == ["kN_bj", "kV_bj", "r_hj"]
        assert [(t["name"], t["free"]) for t in study["tests"]] == [("diagonal", ["kN_bj", "kV_bj"]),
                                                                     ("shear", ["kN_bj", "kV_bj", "r_hj"])]
        assert set(study["noise"]) == {"diagonal", "shear"}
        out = c.post("/api/predict", json={"values": {"kN_bj": 90.0, "kV_bj": 35.0, "r_hj": 0.45}}).json()
        assert [t["name"] for t in out["tests"]] == ["diagonal", "shear"]
        np.testing.assert_allclose(out["chi2"], sum(t["chi2"] for t in out["tests"]), rtol=1e-12, atol=0)
        n_obs = sum(len(t["series"]) * len(t["series"][0]["x"]) for t in out["tests"])
        assert out["dof"] == n_obs - 3
        for t in out["tests"]:  # noise-free data at the truth: the residuals are the surrogate's error
            z = np.array([x["residual"] for x in t["series"]])
            np.testing.assert_allclose(t["chi2"], np.sum(z**2), rtol=1e-10, atol=0)
        error_of(c.post("/api/calibrate", json={"frozen": {"kN_bj": 90.0, "kV_bj": 35.0}}), 422, "diagonal",
                 "free", field="frozen")
        rid = c.post("/api/calibrate", json={"frozen": {"r_hj": 0.45}}).json()["run"]
        run = wait_for(c, f"/api/runs/{rid}")
        assert run["status"] == "done", run["error"]
        assert [q["name"] for q in run["result"]["parameters"]] == ["kN_bj", "kV_bj"]
        assert [f["test"] for f in run["result"]["fe_check"]] == ["diagonal", "shear"]
        error_of(c.post("/api/calibrate", json={"noise": {"shear": {"noise_rel": -1.0}}}), 422, "noise_rel",
                 field="noise.shear.noise_rel")
    s.close()
