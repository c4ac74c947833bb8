"""Time importing a long laboratory log (issue 14 target: a 100 000-row log in ≤ 2 s).

The log is a continuous record of the bundled diagonal compression test: a time column, the load
(kN, rising unevenly from 0.5 to 100 kN with noise), the six gauges in µm and a channel-number
column; semicolon-separated with a decimal comma (the hardest CSV path: delimiter and decimal
detection, unit conversion, extra columns). It is read with every reading kept and with repeats
averaged into 0.5 kN steps, and the model's observation operator at the measured loads is built
(what an inversion then needs). The peer in the same run is ``numpy.loadtxt`` on the same numbers
written plainly (comma-separated, decimal point, no units): the floor of reading that much text.

Run from the repository root::

    python scripts/bench_measurement_import.py            # 100 000 rows, best of 3
    python scripts/bench_measurement_import.py --rows 20000 --repeat 5
"""

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np
import openpyxl

from fe.scenarios import build_scenario
from podkrig.io.measurement_log import ImportSettings, read_measurement

SENSORS = ("D1", "D2", "U1", "BJ_V", "BJ_D", "HJ_H")
LEVELS = (25.0, 50.0, 75.0, 100.0)


def make_log(folder, n_rows, seed=0):
    """Write the benchmark logs: ``(lab.csv, plain.csv, lab.xlsx or None)``."""
    rng = np.random.default_rng(seed)
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    per_kn = sc.run().readings[-1] / LEVELS[-1]  # mm per kN (the model is linear)
    loads = np.sort(rng.uniform(0.5, 100.0, n_rows)) + 0.01 * rng.standard_normal(n_rows)
    readings = loads[:, None] * per_kn[None, :] * 1000.0 + rng.standard_normal((n_rows, len(SENSORS)))  # µm
    t = np.arange(n_rows) * 0.1
    lab = folder / "lab.csv"
    with lab.open("w") as fh:
        fh.write("Diagonal compression, wall 3\ntime [s];load [kN];" + ";".join(f"{s} [µm]" for s in SENSORS)
                 + ";channel\n")
        for i in range(n_rows):
            fh.write((f"{t[i]:.1f};{loads[i]:.3f};" + ";".join(f"{v:.2f}" for v in readings[i]) + ";7\n")
                     .replace(".", ","))
    plain = folder / "plain.csv"
    np.savetxt(plain, np.column_stack([loads, readings / 1000.0]), delimiter=",", fmt="%.6g",
               header="load," + ",".join(SENSORS), comments="")
    return lab, plain


def best_of(fn, repeat):
    """Best wall time (s), the CPU time of that run (s; less sensitive to a loaded machine) and the result."""
    times, out = [], None
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        times.append((time.perf_counter() - t0, time.process_time() - c0))
    wall, cpu = min(times)
    return wall, cpu, out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=100_000, help="rows of the log (default: %(default)s)")
    parser.add_argument("--repeat", type=int, default=3, help="timed repetitions, best kept (default: %(default)s)")
    parser.add_argument("--xlsx-rows", type=int, default=20_000,
                        help="rows of the Excel variant (openpyxl is slower; default: %(default)s)")
    args = parser.parse_args()
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        lab, plain = make_log(folder, args.rows)
        # warm: pint's registry is built once per process (its import is timed separately below)
        first = best_of(lambda: read_measurement(lab, SENSORS, LEVELS, "kN", "affine",
                                                 ImportSettings(repeats="keep")), 1)
        keep_s = best_of(lambda: read_measurement(lab, SENSORS, LEVELS, "kN", "affine",
                                                        ImportSettings(repeats="keep")), args.repeat)
        avg_s = best_of(lambda: read_measurement(lab, SENSORS, LEVELS, "kN", "affine",
                                                      ImportSettings(repeats="average", load_tolerance=0.5)),
                             args.repeat)
        keep, avg = keep_s[2], avg_s[2]
        op_s = best_of(lambda: keep.observation(SENSORS, LEVELS, "affine", "kN"), args.repeat)
        peer_s = best_of(lambda: np.loadtxt(plain, delimiter=",", skiprows=1), args.repeat)
        # Excel: a smaller sheet (openpyxl parses XML cell by cell)
        book = openpyxl.Workbook(write_only=True)
        ws = book.create_sheet("log")
        ws.append(["time [s]", "load [kN]", *(f"{s} [µm]" for s in SENSORS)])
        data = np.loadtxt(plain, delimiter=",", skiprows=1)[:args.xlsx_rows]
        for i, row in enumerate(data):
            ws.append([0.1 * i, float(row[0]), *(float(1000 * v) for v in row[1:])])
        xlsx = folder / "lab.xlsx"
        book.save(xlsx)
        xlsx_s = best_of(lambda: read_measurement(xlsx, SENSORS, LEVELS, "kN", "affine",
                                                     ImportSettings(repeats="keep")), 1)
        size = lab.stat().st_size
    load1 = os.getloadavg()
    print(f"# measurement import benchmark — {platform.node()}, {platform.processor() or platform.machine()}, "
          f"{os.cpu_count()} cores, Python {platform.python_version()}")
    print(f"# load average before / after: {load0[0]:.2f} / {load1[0]:.2f} (1 min)")
    print(f"# log: {args.rows} rows, {size / 2**20:.1f} MiB, ';' + decimal comma, µm headers, 2 extra columns\n")
    print("| what | rows | wall (s) | CPU (s) | rows/s (wall) |")
    print("|---|---:|---:|---:|---:|")
    rows = [
        ("first import in the process (incl. pint registry)", args.rows, first),
        ("import, repeats = keep", args.rows, keep_s),
        (f"import, repeats = average, 0.5 kN steps → {len(avg.load_levels)} steps", args.rows, avg_s),
        ("observation operator at the measured loads (keep)", args.rows, op_s),
        ("peer: numpy.loadtxt of the same numbers, plain CSV", args.rows, peer_s),
        ("import of an .xlsx sheet (openpyxl)", min(args.xlsx_rows, args.rows), xlsx_s),
    ]
    for what, n, (wall, cpu, _) in rows:
        print(f"| {what} | {n} | {wall:.3f} | {cpu:.3f} | {n / wall:,.0f} |")
    if args.rows == 100_000:
        worst = max(keep_s[0], avg_s[0])
        print(f"\ntarget (100 000 rows ≤ 2 s wall): {'met' if worst <= 2.0 else 'NOT met'} ({worst:.2f} s at load "
              f"{load1[0]:.1f} on {os.cpu_count()} cores)")


if __name__ == "__main__":
    main()
