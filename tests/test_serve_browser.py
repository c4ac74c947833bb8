"""``podkrig serve`` used as a user uses it: headless Chromium drives the page.

The server runs as a subprocess (``podkrig serve FOLDER --no-browser``) over a tiny finished study;
selenium loads the page, moves a slider, freezes a parameter, runs a calibration, reads the results
table, and starts and cancels a job on a study whose offline stage has not run. After every test
Chrome's performance log (DevTools ``Network`` events) proves that no request left 127.0.0.1.

Needs Debian's ``chromium`` and ``chromium-driver`` (``.ci/run`` installs them); skipped without.
"""

import json
import math
import re
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

import httpx
import numpy as np
import pytest
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.io.measurement_log import write_measurement_csv
from podkrig.online.measurement import Measurement

from serve_studies import TRUTH, measured, write_joint_study

CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
pytestmark = pytest.mark.skipif(
    not (CHROMIUM.exists() and CHROMEDRIVER.exists()),
    reason="needs Debian's chromium and chromium-driver (/usr/bin/chromium, /usr/bin/chromedriver); "
           "apt-get install chromium chromium-driver")

webdriver = pytest.importorskip("selenium.webdriver")
from selenium.common.exceptions import TimeoutException  # noqa: E402
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.support.ui import WebDriverWait  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: a tiny finished study: a coarse mesh, three free parameters (two on a log scale), 16 FE runs
TINY = """\
name = "tiny_serve"

[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1

[parameters]
E_b = {{ lower = 6000.0, upper = 18000.0, scale = "log" }}
kN_bj = {{ lower = 30.0, upper = 300.0, scale = "log" }}
r_hj = {{ lower = 0.2, upper = 1.0 }}

[fixed]
kV_bj = 35.0

[sampling]
train = {{ n = {n_train}, seed = 0 }}
held_out = {{ n = 4, seed = 1, method = "random" }}
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
region_samples = 1024
"""

def write_study(folder, n_train):
    """A tiny study file and its measurement (1 % noise on the FE response at TRUTH)."""
    folder.mkdir(parents=True, exist_ok=True)
    measured(folder / "measured.csv")
    (folder / "study.toml").write_text(TINY.format(n_train=n_train))
    return folder / "study.toml"


class Server:
    """``podkrig serve`` in a subprocess; ``url`` is the address it prints."""

    def __init__(self, target, *options):
        code = "import sys; from podkrig.cli import app; sys.argv[0] = 'podkrig'; app()"
        self.process = subprocess.Popen(
            [sys.executable, "-c", code, "serve", str(target), "--no-browser", *options],
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.url = None
        lines = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = self.process.stdout.readline()
            if not line:
                break
            lines.append(line)
            found = re.search(r"http://127\.0\.0\.1:\d+/?\S*", line)
            if found:
                self.url = found.group(0).rstrip(".,")
                break
        if self.url is None:
            self.stop()
            raise RuntimeError("podkrig serve printed no address:\n" + "".join(lines))

    def api(self, method, path, **kwargs):
        parts = urlsplit(self.url)
        return httpx.request(method, f"{parts.scheme}://{parts.netloc}{path}", timeout=30, **kwargs)

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


def chrome():
    """Headless Chromium with DevTools network events in its performance log."""
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--window-size=1400,1000", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-default-apps", "--disable-sync",
                 "--disable-extensions", "--metrics-recording-only", "--no-default-browser-check"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
    return webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)


def requested_hosts(driver):
    """Hosts of every request the page made since the last call (DevTools Network events)."""
    hosts = set()
    for entry in driver.get_log("performance"):
        message = json.loads(entry["message"])["message"]
        if message["method"] in ("Network.requestWillBeSent", "Network.webSocketCreated"):
            url = message["params"].get("request", {}).get("url") or message["params"].get("url", "")
            parts = urlsplit(url)
            if parts.scheme in ("data", "blob", "about", "chrome", "devtools"):
                continue
            hosts.add(parts.hostname)
    return hosts


def console_errors(driver):
    """The page's errors since the last call: script errors and refusals by the page's
    Content-Security-Policy (an answer of the API with a 4xx status, which some tests ask for, is
    logged as a failed resource and is not one)."""
    return [e["message"] for e in driver.get_log("browser")
            if e["level"] == "SEVERE" and "Failed to load resource" not in e["message"]]


def wait(driver, condition, timeout=30, message=""):
    return WebDriverWait(driver, timeout, poll_frequency=0.05).until(lambda d: condition(d), message)


def load(driver, url):
    driver.get(url)
    wait(driver, lambda d: d.execute_script("return document.body.dataset.ready === '1'"), message="page ready")


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A tiny study run to the end (``podkrig run``): the served folder."""
    folder = tmp_path_factory.mktemp("serve")
    study = write_study(folder, n_train=16)
    out = folder / "out"
    result = CliRunner().invoke(app, ["run", str(study), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return out


@pytest.fixture(scope="module")
def server(finished):
    srv = Server(finished)
    yield srv
    srv.stop()


@pytest.fixture(scope="module")
def browser():
    driver = chrome()
    yield driver
    driver.quit()


@pytest.fixture(autouse=True)
def only_loopback(request):
    """After each test: every request the page made went to 127.0.0.1, and the page raised no
    script error and broke no rule of its Content-Security-Policy."""
    yield
    if "browser" in request.fixturenames:
        driver = request.getfixturevalue("browser")
        hosts = requested_hosts(driver)
        assert hosts <= {"127.0.0.1"}, f"requests left 127.0.0.1: {sorted(map(str, hosts))}"
        assert not console_errors(driver)


def slider_values(driver, names):
    return {n: float(driver.find_element(By.ID, f"value-{n}").get_attribute("value")) for n in names}


def test_page_shows_the_study_with_units_and_log_sliders(server, browser):
    load(browser, server.url)
    study = server.api("GET", "/api/study").json()
    names = [p["name"] for p in study["parameters"]]
    assert names == ["E_b", "kN_bj", "r_hj"]
    for p in study["parameters"]:
        row = browser.find_element(By.CSS_SELECTOR, f'.param[data-param="{p["name"]}"]')
        assert p["unit"].replace("-", "[-]") in row.text
        slider = browser.find_element(By.ID, f"param-{p['name']}")
        assert slider.get_attribute("type") == "range"
        # the slider's position is the value's place on the parameter's scale (log or linear)
        f = math.log if p["scale"] == "log" else (lambda v: v)
        t = (f(p["value"]) - f(p["lower"])) / (f(p["upper"]) - f(p["lower"]))
        assert int(slider.get_attribute("value")) == pytest.approx(1000 * t, abs=1)
    assert browser.find_element(By.ID, "chi2").text.startswith("χ²/dof")
    assert browser.find_element(By.ID, "plot-0").find_elements(By.TAG_NAME, "canvas")
    # the performance log sees the page's requests (so the after-test check is not vacuous)
    assert requested_hosts(browser) == {"127.0.0.1"}


def test_moving_a_slider_redraws_the_plot_with_the_servers_prediction(server, browser):
    load(browser, server.url)
    canvas = browser.find_element(By.CSS_SELECTOR, "#plot-0 canvas")
    picture = browser.execute_script("return arguments[0].toDataURL()", canvas)
    chi2 = browser.find_element(By.ID, "chi2").text
    before = browser.execute_script("return window.podkrigLatency.length")
    slider = browser.find_element(By.ID, "param-kN_bj")
    for _ in range(25):
        slider.send_keys(Keys.RIGHT)
    # every input gets a latency once a plot at least as new as it has been drawn
    wait(browser, lambda d: d.execute_script("return window.podkrigLatency.length") >= before + 25,
         message="latencies recorded")
    assert browser.execute_script("return arguments[0].toDataURL()", canvas) != picture
    assert browser.find_element(By.ID, "chi2").text != chi2
    latencies = browser.execute_script("return window.podkrigLatency")
    assert all(0 < ms < 30_000 for ms in latencies)
    # the page shows what the server predicts for the sliders' values
    values = slider_values(browser, ["E_b", "kN_bj", "r_hj"])
    answer = server.api("POST", "/api/predict", json={"values": values}).json()
    shown = float(re.search(r"χ²/dof = ([-\d.e+]+)", browser.find_element(By.ID, "chi2").text).group(1))
    # the page shows 3 significant digits, and its values box 5 (the slider holds more)
    assert shown == pytest.approx(answer["chi2_dof"], rel=5e-3, abs=1e-3)


def test_an_out_of_bounds_value_shows_the_library_message_next_to_its_input(server, browser):
    load(browser, server.url)
    box = browser.find_element(By.ID, "value-kN_bj")
    box.clear()
    box.send_keys("5000", Keys.ENTER)
    error = browser.find_element(By.ID, "err-kN_bj")
    wait(browser, lambda d: error.text, message="error shown")
    assert "kN_bj" in error.text and "5000" in error.text
    assert browser.find_element(By.ID, "explore-error").text == ""


def test_a_frozen_parameter_stays_put_through_a_calibration(server, browser):
    load(browser, server.url)
    slider = browser.find_element(By.ID, "param-E_b")
    for _ in range(40):
        slider.send_keys(Keys.LEFT)
    browser.find_element(By.ID, "lock-E_b").click()
    assert not slider.is_enabled()
    frozen = slider_values(browser, ["E_b"])["E_b"]
    browser.find_element(By.ID, "tab-calibrate").click()
    assert "E_b" in browser.find_element(By.ID, "frozen-list").text
    browser.find_element(By.ID, "calibrate").click()
    status = browser.find_element(By.ID, "calib-status")
    wait(browser, lambda d: status.get_attribute("data-status") in ("done", "failed"), timeout=60,
         message="calibration finished")
    assert status.get_attribute("data-status") == "done", browser.find_element(By.ID, "calib-error").text
    rows = {r.get_attribute("data-param"): [c.text for c in r.find_elements(By.TAG_NAME, "td")]
            for r in browser.find_elements(By.CSS_SELECTOR, "#results tr[data-param]")}
    assert sorted(rows) == ["E_b", "kN_bj", "r_hj"]
    run_id = browser.find_element(By.CSS_SELECTOR, "#runs tr.selected").get_attribute("data-run")
    run = server.api("GET", f"/api/runs/{run_id}").json()
    # the page sent the frozen value as the sliders hold it (the values box shows 5 digits)
    assert run["frozen"]["E_b"] == pytest.approx(frozen, rel=1e-4)
    found = {p["name"]: p for p in run["result"]["parameters"]}
    assert found.keys() <= {"kN_bj", "r_hj", "E_b"} and {"kN_bj", "r_hj"} <= found.keys()
    for name, p in found.items():
        cells = rows[name]
        # the table writes 4 significant digits and the unit
        assert float(cells[1].split()[0]) == pytest.approx(p["value"], rel=1e-3), name
        assert cells[1].endswith(p["unit"] if p["unit"] != "-" else "[-]")
        assert cells[3] == ("yes" if p["identified"] else "no")
    # the frozen parameter is listed at its frozen value
    assert float(rows["E_b"][1].split()[0]) == pytest.approx(run["frozen"]["E_b"], rel=1e-3)
    if "E_b" not in found:
        assert rows["E_b"][3] == "frozen"
    href = browser.find_element(By.ID, "export").get_attribute("href")
    assert href.endswith(f"/api/runs/{run_id}/summary.json")
    assert server.api("GET", urlsplit(href).path).status_code == 200


def test_two_runs_compare_side_by_side(server, browser):
    load(browser, server.url)
    browser.find_element(By.ID, "tab-calibrate").click()
    for seed in ("3", "4"):
        box = browser.find_element(By.ID, "inv-seed")
        box.clear()
        box.send_keys(seed)
        n_runs = len(server.api("GET", "/api/runs").json())
        browser.find_element(By.ID, "calibrate").click()
        wait(browser, lambda d: len(d.find_elements(By.CSS_SELECTOR, "#runs tr[data-run]")) > n_runs
             and d.find_element(By.ID, "calib-status").get_attribute("data-status") == "done",
             timeout=60, message="run listed")
    picks = browser.find_elements(By.CSS_SELECTOR, "#runs .compare-pick")
    picks[-1].click()
    picks[-2].click()
    wait(browser, lambda d: d.find_elements(By.CSS_SELECTOR, "#compare tr[data-param]"), message="comparison")
    header = browser.find_element(By.CSS_SELECTOR, "#compare tr").text
    ids = [p.get_attribute("value") for p in picks[-2:]]
    assert all(f"run {i}" in header for i in ids)


def test_invalid_settings_show_the_settings_message_beside_the_field(server, browser):
    load(browser, server.url)
    browser.find_element(By.ID, "tab-calibrate").click()
    box = browser.find_element(By.ID, "inv-population_size")
    box.clear()
    box.send_keys("1")
    browser.find_element(By.ID, "calibrate").click()
    wait(browser, lambda d: d.find_element(By.ID, "err-population_size").text
         or d.find_element(By.ID, "calib-error").text, message="error shown")
    text = browser.find_element(By.ID, "err-population_size").text
    assert "population_size" in text and "1" in text
    box.clear()
    box.send_keys("20")
    # a noise setting's refusal (field "noise.noise_rel") lands beside the noise field of its test
    noise = browser.find_element(By.ID, "noise-0-noise_rel")
    noise.clear()
    noise.send_keys("-1")
    browser.find_element(By.ID, "calibrate").click()
    wait(browser, lambda d: d.find_element(By.ID, "err-noise-0-noise_rel").text
         or d.find_element(By.ID, "calib-error").text, message="error shown")
    text = browser.find_element(By.ID, "err-noise-0-noise_rel").text
    assert "noise_rel" in text and "-1" in text
    assert browser.find_element(By.ID, "err-population_size").text == ""


def test_a_measurement_upload_is_checked_and_replaces_the_data(server, browser, finished, tmp_path):
    load(browser, server.url)
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run(TRUTH).readings
    # readings written in µm instead of mm: refused with the reader's words, shown beside the upload
    wrong = tmp_path / "in_micrometres.csv"
    write_measurement_csv(wrong, Measurement(1000 * clean, sc.sensor_names, sc.load_levels))
    expected = server.api("POST", "/api/measurement?test=&name=in_micrometres.csv", content=wrong.read_bytes(),
                          headers={"Content-Type": "application/octet-stream"})
    assert expected.status_code == 422
    browser.find_element(By.ID, "upload-0").send_keys(str(wrong))
    box = browser.find_element(By.ID, "err-upload-0")
    wait(browser, lambda d: box.text, message="upload refused")
    # the same words as the API's answer, naming the file chosen (never the server's copy of it)
    assert box.text == expected.json()["error"] and box.text.startswith("in_micrometres.csv: ")
    # another measurement of the same wall (other noise): accepted, the page predicts against it
    other = tmp_path / "second_series.csv"
    noisy = clean * (1 + 0.05 * np.random.default_rng(7).standard_normal(clean.shape))
    write_measurement_csv(other, Measurement(noisy, sc.sensor_names, sc.load_levels))
    chi2 = browser.find_element(By.ID, "chi2").text
    count = browser.execute_script("return window.podkrigPredictions")
    browser.find_element(By.ID, "upload-0").send_keys(str(other))
    wait(browser, lambda d: d.execute_script("return window.podkrigPredictions") > count, message="predicted again")
    assert "second_series.csv" in browser.find_element(By.ID, "upload-note-0").text
    assert box.text == ""
    assert browser.find_element(By.ID, "chi2").text != chi2
    # a study job (every stage cached) rebuilds the server's problem from the folder: the upload is
    # read again and stays in use, named beside its test, and the plot still shows it
    chi2 = browser.find_element(By.ID, "chi2").text
    browser.find_element(By.ID, "tab-jobs").click()
    browser.find_element(By.ID, "job-start").click()
    status = browser.find_element(By.ID, "job-status")
    wait(browser, lambda d: status.get_attribute("data-status") in ("done", "failed", "cancelled"), timeout=180,
         message="job ended")
    assert status.get_attribute("data-status") == "done", status.text
    browser.find_element(By.ID, "tab-explore").click()
    assert server.api("GET", "/api/study").json()["uploads"][""]["file"] == "second_series.csv"
    assert "second_series.csv" in browser.find_element(By.ID, "upload-note-0").text
    wait(browser, lambda d: d.find_element(By.ID, "chi2").text == chi2, message="the upload's χ² after the job")
    # put the study's own measurement back for the other tests of this module
    original = finished.parent / "measured.csv"
    assert server.api("POST", "/api/measurement?test=&name=measured.csv", content=original.read_bytes(),
                      headers={"Content-Type": "application/octet-stream"}).status_code == 200


def test_the_page_works_behind_a_token(finished, browser):
    """With --token the printed address carries it once; the page's own requests then pass on the
    cookie the server set, and a request without it is refused."""
    srv = Server(finished, "--token", "page-token-1234")
    try:
        assert "token=page-token-1234" in srv.url
        load(browser, srv.url)
        count = browser.execute_script("return window.podkrigPredictions")
        browser.find_element(By.ID, "param-kN_bj").send_keys(Keys.RIGHT)
        wait(browser, lambda d: d.execute_script("return window.podkrigPredictions") > count, message="predicted")
        assert browser.find_element(By.ID, "explore-error").text == ""
        assert srv.api("GET", "/api/study").status_code == 403
    finally:
        srv.stop()


@pytest.fixture(scope="module")
def unfinished(tmp_path_factory):
    """A study file whose offline stage has not run (enough FE runs to be cancelled mid-way)."""
    return write_study(tmp_path_factory.mktemp("serve-job"), n_train=256)


def test_a_job_starts_from_the_page_and_is_cancelled(unfinished, browser):
    srv = Server(unfinished, "--out", str(unfinished.parent / "out"))
    try:
        load(browser, srv.url)
        assert browser.execute_script("return document.body.dataset.state") == "needs_offline"
        assert not browser.find_element(By.ID, "screen-jobs").get_attribute("hidden")
        browser.find_element(By.ID, "job-start").click()
        status = browser.find_element(By.ID, "job-status")
        wait(browser, lambda d: status.get_attribute("data-status") == "running", message="job running")
        cancel = browser.find_element(By.ID, "job-cancel")
        wait(browser, lambda d: cancel.is_enabled(), message="cancel enabled")
        cancel.click()
        try:
            wait(browser, lambda d: status.get_attribute("data-status") in ("cancelled", "done", "failed"),
                 timeout=60, message="job ended")
        except TimeoutException:
            pytest.fail(f"the job was not cancelled: {status.text}")
        assert status.get_attribute("data-status") == "cancelled"
        jobs = srv.api("GET", "/api/jobs").json()
        assert [j["status"] for j in jobs] == ["cancelled"]
        wait(browser, lambda d: "cancelled" in d.find_element(By.CSS_SELECTOR, "#jobs tr[data-job]").text,
             message="jobs table updated")
    finally:
        srv.stop()


@pytest.mark.slow
def test_a_joint_study_shows_its_tests_side_by_side(tmp_path, browser):
    """Two tests sharing kN_bj and kV_bj (tests/serve_studies.py): one slider set, the tests side by side."""
    write_joint_study(tmp_path)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "study.toml"), "--out", str(tmp_path / "out"),
                                      "--skip-diagnosis"])
    assert result.exit_code == 0, result.output
    srv = Server(tmp_path / "out")
    try:
        load(browser, srv.url)
        assert [s.get_attribute("id") for s in browser.find_elements(By.CSS_SELECTOR, "#sliders input[type=range]")] \
            == ["param-kN_bj", "param-kV_bj", "param-r_hj"]
        panels = [browser.find_element(By.ID, f"test-{i}") for i in range(2)]
        assert "diagonal" in panels[0].text and "shear" in panels[1].text
        # side by side: same row, the second to the right of the first
        assert panels[0].rect["y"] == panels[1].rect["y"] and panels[1].rect["x"] > panels[0].rect["x"]
        values = slider_values(browser, ["kN_bj", "kV_bj", "r_hj"])
        answer = srv.api("POST", "/api/predict", json={"values": values}).json()
        for i, t in enumerate(answer["tests"]):
            shown = browser.find_element(By.ID, f"chi2-{i}").text
            assert float(shown.split("=")[1]) == pytest.approx(t["chi2_dof"], rel=5e-3, abs=1e-3)
        # a noise setting of the second test is refused beside that test's field
        browser.find_element(By.ID, "tab-calibrate").click()
        keys = browser.execute_script(
            "return Array.from(document.querySelectorAll('#noise-fields input')).map(i => [i.id, i.dataset.noiseKey])")
        shear_rel = next(i for i, key in keys if key == "shear" and i.endswith("noise_rel"))
        box = browser.find_element(By.ID, shear_rel)
        box.clear()
        box.send_keys("-1")
        browser.find_element(By.ID, "calibrate").click()
        error = browser.find_element(By.ID, f"err-{shear_rel}")
        wait(browser, lambda d: error.text, message="noise error beside the shear test's field")
        assert "noise_rel" in error.text
    finally:
        srv.stop()
