"""Screenshots of each screen of ``podkrig serve`` for the docs (``docs/img/serve-*.png``).

Serves a copy of a finished demo folder (``podkrig demo --out DIR``), drives the page in headless
Chromium (selenium) and saves one picture per screen:

- ``serve-explore.png``: sliders, predicted readings against the measured ones, residuals;
- ``serve-calibrate.png``: a calibration with ``kV_bj`` frozen, its table and region, two runs compared;
- ``serve-model.png``: the FE model at the best fit, deformed, with its load–displacement curve;
- ``serve-jobs.png``: the study rerun as a background job (it resumes: nothing left to compute).

The pictures are quantized to a 256-colour palette (Pillow) to keep them small. Needs Debian's
``chromium`` and ``chromium-driver`` and selenium (the project's ``test`` extra)::

    python scripts/serve_screenshots.py --folder out/diagonal_compression_demo
"""

import argparse
import io
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"


def chrome(width, height):
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 f"--window-size={width},{height}", "--hide-scrollbars", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-extensions",
                 "--force-device-scale-factor=1"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def start_server(folder):
    code = "import sys; from podkrig.cli import app; sys.argv[0] = 'podkrig'; app()"
    proc = subprocess.Popen([sys.executable, "-c", code, "serve", str(folder), "--no-browser"],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        found = re.search(r"http://127\.0\.0\.1:\d+/", line)
        if found:
            return proc, found.group(0)
    proc.wait()
    sys.exit("podkrig serve printed no address:\n" + "".join(lines))


def wait_for(driver, script, timeout=300.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if driver.execute_script(script):
            return
        time.sleep(0.05)
    raise TimeoutError(script)


def save(driver, path, width, max_height):
    """A screenshot of the page's content (at most ``max_height`` px tall) as a 256-colour PNG."""
    from PIL import Image

    content = driver.execute_script(
        "return Math.ceil(Math.max(...Array.from(document.querySelectorAll('main > .screen:not([hidden]) > *'))"
        ".map(e => e.getBoundingClientRect().bottom + window.scrollY)) + 12)")
    height = min(int(content), max_height)
    driver.execute_script("document.activeElement && document.activeElement.blur()")
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
    time.sleep(0.4)  # the plots follow the new size
    driver.execute_script("window.scrollTo(0, 0)")
    picture = Image.open(io.BytesIO(driver.get_screenshot_as_png())).convert("RGB")
    picture.quantize(colors=256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    driver.execute_cdp_cmd("Emulation.clearDeviceMetricsOverride", {})
    print(f"{path} ({path.stat().st_size / 1024:.0f} KiB, {picture.width}×{picture.height})")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--folder", type=Path, required=True, help="a finished demo folder (copied, not changed)")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "img", help="where the PNGs go (default docs/img)")
    parser.add_argument("--width", type=int, default=1280)
    args = parser.parse_args(argv)
    if not (args.folder / "summary.json").is_file():
        sys.exit(f"{args.folder} is not a finished study folder (no summary.json): run `podkrig demo --out DIR`")
    args.out.mkdir(parents=True, exist_ok=True)
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys
    from selenium.webdriver.support.ui import Select

    with tempfile.TemporaryDirectory(prefix="serve-shots-") as scratch:
        folder = Path(scratch) / "demo"
        shutil.copytree(args.folder, folder)
        driver = chrome(args.width, 820)
        proc = None
        try:
            proc, url = start_server(folder)
            driver.get(url)
            wait_for(driver, "return document.body.dataset.ready === '1'")
            # Explore: move kN_bj off the best fit so that the residuals show something
            slider = driver.find_element(By.ID, "param-kN_bj")
            for _ in range(60):
                slider.send_keys(Keys.RIGHT)
            wait_for(driver, "return window.podkrigLatency.length >= 61")
            save(driver, args.out / "serve-explore.png", args.width, 820)

            # Calibrate: a free run, then one with kV_bj frozen at a value off its best; compare them
            driver.find_element(By.ID, "reset-best").click()
            driver.find_element(By.ID, "tab-calibrate").click()
            for lock in (False, True):
                if lock:
                    driver.find_element(By.ID, "tab-explore").click()
                    box = driver.find_element(By.ID, "value-kV_bj")
                    box.clear()
                    box.send_keys("40", Keys.ENTER)
                    driver.find_element(By.ID, "lock-kV_bj").click()
                    driver.find_element(By.ID, "tab-calibrate").click()
                count = driver.execute_script("return window.podkrigCalibration.length")
                driver.find_element(By.ID, "calibrate").click()
                wait_for(driver, f"return window.podkrigCalibration.length > {count}")
            for pick in driver.find_elements(By.CSS_SELECTOR, "#runs .compare-pick"):
                pick.click()
            wait_for(driver, "return document.querySelectorAll('#compare tr[data-param]').length > 0")
            save(driver, args.out / "serve-calibrate.png", args.width, 1700)

            # Model: the FE model at the best fit
            driver.find_element(By.ID, "tab-model").click()
            Select(driver.find_element(By.ID, "fe-source")).select_by_value("best")
            driver.find_element(By.ID, "fe-run").click()
            wait_for(driver, "return document.querySelector('#mesh polygon') !== null")
            save(driver, args.out / "serve-model.png", args.width, 1000)

            # Jobs: the study rerun in the background
            driver.find_element(By.ID, "tab-jobs").click()
            driver.find_element(By.ID, "job-start").click()
            wait_for(driver, "return ['done', 'failed', 'cancelled'].includes("
                             "document.getElementById('job-status').dataset.status)")
            save(driver, args.out / "serve-jobs.png", args.width, 700)
        finally:
            driver.quit()
            if proc is not None:
                proc.terminate()
                proc.wait(timeout=30)


if __name__ == "__main__":
    main()
