"""Time ``podkrig serve`` as a user feels it, measured in the browser (headless Chromium).

Over a copy of a finished demo folder (``podkrig demo --out DIR``), the script starts
``podkrig serve DIR --no-browser`` as a subprocess and drives the page with selenium:

- **page ready**: from the moment the server prints its address (it is then listening) to the
  page's ``data-ready`` mark (study loaded, first prediction drawn), the browser already started;
- **slider → plot**: the page records, per slider ``input`` event, the time from the event to the end
  of the redraw of every plot that shows a prediction at least as new as that input
  (``window.podkrigLatency``); measured for single moves (one arrow key, then wait for its plot)
  and for a drag (an input every 16 ms, the page keeps one prediction in flight and sends the
  latest values), each over ``--moves`` inputs spread over every free parameter;
- the same single moves **while calibrations run** back to back in the same server;
- **calibration from the page**: click on *Calibrate* to the results table drawn
  (``window.podkrigCalibration``), ``--calibrations`` times.

Also printed: the server's CPU time (user + system, from ``/proc``) per prediction, the machine and
its load. The browser and the server share the machine's cores, as on a user's laptop. Targets:
slider → plot median ≤ 100 ms and p90 ≤ 200 ms on 2 cores, ≤ 2× that during a calibration;
calibration from the page ≤ 1.5 s; page ready ≤ 1 s.

Needs Debian's ``chromium`` and ``chromium-driver`` (``/usr/bin/chromium``, ``/usr/bin/chromedriver``)
and selenium (the project's ``test`` extra)::

    python scripts/bench_serve.py --folder out/diagonal_compression_demo
    python scripts/bench_serve.py            # builds the demo first (podkrig demo, a few minutes)
"""

import argparse
import datetime
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"


def percentile(values, q):
    """The ``q``-th percentile (linear interpolation, as numpy's default)."""
    ordered = sorted(values)
    if not ordered:
        return float("nan")
    k = (len(ordered) - 1) * q / 100
    lo = int(k)
    hi = min(lo + 1, len(ordered) - 1)
    return ordered[lo] + (ordered[hi] - ordered[lo]) * (k - lo)


def cpu_seconds(pid):
    """User + system CPU time of a process and its waited-for children, s (Linux /proc)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    ticks = sum(int(x) for x in fields[11:15])  # utime, stime, cutime, cstime
    return ticks / os.sysconf("SC_CLK_TCK")


def machine():
    cpu = platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start"


def chrome():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--window-size=1400,1000", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-default-apps", "--disable-sync",
                 "--disable-extensions"):
        options.add_argument(flag)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)


def start_server(folder):
    """``podkrig serve FOLDER --no-browser``; returns (process, url, monotonic time of the address)."""
    code = "import sys; from podkrig.cli import app; sys.argv[0] = 'podkrig'; app()"
    proc = subprocess.Popen([sys.executable, "-c", code, "serve", str(folder), "--no-browser"],
                            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    for line in proc.stdout:
        lines.append(line)
        found = re.search(r"http://127\.0\.0\.1:\d+/", line)
        if found:
            return proc, found.group(0), time.monotonic()
    proc.wait()
    sys.exit("podkrig serve printed no address:\n" + "".join(lines))


def wait_for(driver, script, timeout=60.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = driver.execute_script(script)
        if value:
            return value
        time.sleep(0.01)
    raise TimeoutError(script)


def single_moves(driver, names, n_moves):
    """One arrow key per move, waiting for its plot; returns the moves' latencies, ms."""
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    start = driver.execute_script("return window.podkrigLatency.length")
    for i in range(n_moves):
        name = names[i % len(names)]
        # 10 moves one way, 10 back: the sliders wander around the best fit
        key = Keys.RIGHT if (i // (10 * len(names))) % 2 == 0 else Keys.LEFT
        driver.find_element(By.ID, f"param-{name}").send_keys(key)
        wait_for(driver, f"return window.podkrigLatency.length >= {start + i + 1}")
    return driver.execute_script(f"return window.podkrigLatency.slice({start})")


DRAG = """
const [names, n, done] = [arguments[0], arguments[1], arguments[arguments.length - 1]];
const start = window.podkrigLatency.length;
let i = 0;
const timer = setInterval(() => {
  const name = names[Math.floor(i / 20) % names.length];
  const slider = document.getElementById('param-' + name);
  const step = (Math.floor(i / 10) % 2 === 0) ? 1 : -1;
  slider.value = Number(slider.value) + 3 * step;
  slider.dispatchEvent(new Event('input', {bubbles: true}));
  i += 1;
  if (i >= n) {
    clearInterval(timer);
    const check = setInterval(() => {
      if (window.podkrigLatency.length >= start + n) {
        clearInterval(check);
        done(window.podkrigLatency.slice(start));
      }
    }, 10);
  }
}, 16);
"""


def drag(driver, names, n_moves):
    """Inputs every 16 ms (a drag at 60 Hz); returns their latencies, ms."""
    driver.set_script_timeout(120)
    return driver.execute_async_script(DRAG, names, n_moves)


def calibrations_in_background(url, stop, counter):
    """POST /api/calibrate back to back (the demo's settings) until ``stop`` is set."""
    import httpx

    with httpx.Client(base_url=url, timeout=60) as client:
        while not stop.is_set():
            run = client.post("/api/calibrate", json={"frozen": {}, "noise": None, "inversion": None,
                                                      "diagnosis": False})
            run.raise_for_status()
            run_id = run.json()["run"]
            while not stop.is_set():
                status = client.get(f"/api/runs/{run_id}").json()["status"]
                if status != "running":
                    counter.append(status)
                    break
                time.sleep(0.05)


def calibrate_from_page(driver, n):
    from selenium.webdriver.common.by import By

    driver.find_element(By.ID, "tab-calibrate").click()
    times = []
    for _ in range(n):
        count = driver.execute_script("return window.podkrigCalibration.length")
        driver.find_element(By.ID, "calibrate").click()
        wait_for(driver, f"return window.podkrigCalibration.length > {count} || "
                         "['refused', 'failed'].includes(document.getElementById('calib-status').dataset.status)",
                 timeout=300)
        status = driver.execute_script("return document.getElementById('calib-status').dataset.status")
        if status != "done":
            error = driver.execute_script("return document.getElementById('calib-error').textContent")
            sys.exit(f"the calibration from the page ended {status}: {error}")
        times.append(driver.execute_script("return window.podkrigCalibration.at(-1)"))
    driver.find_element(By.ID, "tab-explore").click()
    return times


def row(label, values, unit="ms"):
    return (f"| {label} | {len(values)} | {statistics.median(values):.0f} {unit} | "
            f"{percentile(values, 90):.0f} {unit} | {max(values):.0f} {unit} |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--folder", type=Path, help="a finished demo folder (copied; default: build one "
                                                     "with `podkrig demo` in a temporary folder)")
    parser.add_argument("--moves", type=int, default=120, help="slider inputs per measurement (default 120)")
    parser.add_argument("--calibrations", type=int, default=5, help="calibrations from the page (default 5)")
    args = parser.parse_args(argv)
    if args.moves < 1 or args.calibrations < 1:
        parser.error("--moves and --calibrations must be at least 1")
    for exe in (CHROMIUM, CHROMEDRIVER):
        if not Path(exe).exists():
            sys.exit(f"{exe} is missing: apt-get install chromium chromium-driver")

    with tempfile.TemporaryDirectory(prefix="bench-serve-") as scratch:
        folder = Path(scratch) / "demo"
        if args.folder:
            if not (args.folder / "summary.json").is_file():
                sys.exit(f"{args.folder} is not a finished study folder (no summary.json): "
                         "run `podkrig demo --out DIR` first")
            shutil.copytree(args.folder, folder)
        else:
            print("building the demo folder (podkrig demo) ...", flush=True)
            subprocess.run([sys.executable, "-c", "import sys; from podkrig.cli import app; "
                            "sys.argv[0] = 'podkrig'; app()", "demo", "--out", str(folder)],
                           cwd=REPO, check=True, stdout=subprocess.DEVNULL)
        print(f"machine: {machine()}", flush=True)
        driver = chrome()
        driver.get("about:blank")
        proc = None
        try:
            proc, url, t_address = start_server(folder)
            driver.get(url)
            wait_for(driver, "return document.body.dataset.ready === '1'")
            page_ready = (time.monotonic() - t_address) * 1000
            names = driver.execute_script(
                "return Array.from(document.querySelectorAll('#sliders input[type=range]')).map(s => s.id.slice(6))")

            cpu0 = cpu_seconds(proc.pid)
            n0 = driver.execute_script("return window.podkrigPredictions")
            quiet = single_moves(driver, names, args.moves)
            n1 = driver.execute_script("return window.podkrigPredictions")
            cpu_per_prediction = (cpu_seconds(proc.pid) - cpu0) / max(1, n1 - n0) * 1000
            dragged = drag(driver, names, args.moves)
            n_drawn = driver.execute_script("return window.podkrigPredictions") - n1

            stop = threading.Event()
            finished = []
            worker = threading.Thread(target=calibrations_in_background, args=(url, stop, finished), daemon=True)
            worker.start()
            time.sleep(0.3)
            try:
                busy = single_moves(driver, names, args.moves)
            finally:
                stop.set()
                worker.join(timeout=120)

            calib = calibrate_from_page(driver, args.calibrations)
        finally:
            driver.quit()
            if proc is not None:
                proc.terminate()
                proc.wait(timeout=30)

    print()
    print(f"`podkrig serve` over the demo, measured in headless Chromium "
          f"({datetime.date.today().isoformat()}, {platform.python_version()})")
    print()
    print("| measurement | n | median | p90 | max |")
    print("|---|---|---|---|---|")
    print(row("slider → plot, single moves", quiet))
    print(row(f"slider → plot, drag at 60 Hz ({n_drawn} predictions drawn)", dragged))
    print(row(f"slider → plot, single moves while calibrations run ({len(finished)} finished)", busy))
    print(row("calibration from the page (click → results)", calib))
    print(f"| page ready after the server prints its address | 1 | {page_ready:.0f} ms | | |")
    print()
    print(f"server CPU time per prediction (user + system): {cpu_per_prediction:.1f} ms")


if __name__ == "__main__":
    main()
