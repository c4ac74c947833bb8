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
from podkrig.io.measurement_log import write_measurement_csv
from podkrig.online.measurement import Measurement
from podkrig.serve.app import MAX_JSON_BODY, create_app
from podkrig.serve.server import check_binding
from podkrig.serve.session import RequestError, Session
from podkrig.study import load_study, run_study

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

TRUTH = {"E_b": 11000.0, "r_hj": 0.6, "kN_bj": 90.0, "kV_bj": 35.0}
ORIGIN = "http://127.0.0.1:8000"


def measured(path, seed=0, scale=1.0):
    """Pseudo-measured readings of the tiny study's scenario at :data:`TRUTH` with 1 % noise."""
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run(TRUTH).readings
    noisy = clean * (1 + 0.01 * np.random.default_rng(seed).standard_normal(clean.shape)) * scale
    write_measurement_csv(path, Measurement(noisy, sc.sensor_names, sc.load_levels))
    return noisy


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
    if page.is_file():
        assert r.status_code == 200 and r.content == page.read_bytes()
    else:
        error_of(r, 404, "index.html")
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
