"""Regenerate the pseudo-measured data of the demo (``examples/diagonal_compression_measured.csv``)
and of the joint calibration's shear wall (``examples/shear_wall_measured.csv``, ``--scenario
shear_compression``: the same hidden values, the same noise model, seed 2027).

It runs exactly ``podkrig simulate diagonal_compression --set E_b=10500 --set kN_bj=70
--set kV_bj=28 --set r_hj=0.55 --format csv`` (the default mesh; ν_b = 0.15 is the default) and
adds ``σ_i z`` to every reading d_i, with the LVDT noise of the study file (``instrument =
"lvdt"``): σ_i² = σ_res² + (δ d_i)², σ_res = 1 µm, δ = 1 % (a purely relative 1 %, used before,
gave the ~2 µm U1 gauge σ ≈ 0.02 µm, finer than any instrument), and ``z`` standard normal from
``numpy.random.default_rng(2026)``, drawn in the file's order (load-major: all gauges at 25 kN,
then at 50 kN, ...). Readings are written with 6 significant digits (0.1 µm and finer), under
headers with units (``load [kN]``, ``D1 [mm]`` ...).

Run from the repository root::

    python examples/make_measured_data.py            # rewrites the shipped file
    python examples/make_measured_data.py --scenario shear_compression    # the shear wall's file
    python examples/make_measured_data.py --out x.csv --seed 7
"""

import argparse
import csv
import io
from pathlib import Path

import numpy as np

#: the hidden parameter values of the demo (units: MPa, N/mm³, N/mm³, -)
TRUTH = {"E_b": 10500.0, "kN_bj": 70.0, "kV_bj": 28.0, "r_hj": 0.55}
NOISE_REL = 0.01
#: the resolution floor σ_res of an LVDT, mm (podkrig.online.measurement.INSTRUMENTS["lvdt"])
NOISE_RES_MM = 0.001
SEED = 2026
OUT = Path(__file__).with_name("diagonal_compression_measured.csv")
#: the shipped file and noise seed of each scenario
SHIPPED = {"diagonal_compression": (OUT, SEED),
           "shear_compression": (Path(__file__).with_name("shear_wall_measured.csv"), 2027)}


def simulate_csv(truth, scenario="diagonal_compression"):
    """The output of ``podkrig simulate SCENARIO --set ... --format csv`` (text)."""
    from typer.testing import CliRunner

    from podkrig.cli import app

    args = ["simulate", scenario, "--format", "csv"]
    for name, value in truth.items():
        args += ["--set", f"{name}={value:g}"]
    result = CliRunner().invoke(app, args)
    if result.exit_code != 0:
        raise RuntimeError(f"podkrig {' '.join(args)} failed: {result.output}")
    return result.stdout


def make(out=OUT, seed=SEED, noise_rel=NOISE_REL, truth=None, noise_res=NOISE_RES_MM, scenario="diagonal_compression"):
    """Write the pseudo-measured CSV of ``scenario`` (default options) to ``out``; returns the path."""
    rows = list(csv.reader(io.StringIO(simulate_csv(truth or TRUTH, scenario))))
    header, body = rows[0], rows[1:]
    clean = np.array([[float(c) for c in row[1:]] for row in body])  # (n_loads, n_sensors), mm
    sigma = np.sqrt(noise_res**2 + (noise_rel * clean) ** 2)  # σ_i² = σ_res² + (δ d_i)², mm
    noisy = clean + sigma * np.random.default_rng(seed).standard_normal(clean.shape)
    with Path(out).open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)  # simulate's header: load [kN], D1 [mm] ...
        for row, values in zip(body, noisy):
            w.writerow([row[0], *(f"{v:.6g}" for v in values)])
    return Path(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", choices=sorted(SHIPPED), default="diagonal_compression",
                        help="The test to simulate (default options; default: %(default)s).")
    parser.add_argument("--out", type=Path, help="CSV file to write (default: the shipped file of the scenario).")
    parser.add_argument("--seed", type=int, help="Seed of the noise (default: the shipped file's, 2026 or 2027).")
    args = parser.parse_args()
    out, seed = SHIPPED[args.scenario]
    path = make(args.out or out, seed if args.seed is None else args.seed, scenario=args.scenario)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
