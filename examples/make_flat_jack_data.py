"""Regenerate the flat-jack study's pseudo-measured data, ``examples/flat_jack_measured.csv``.

It runs exactly ``podkrig simulate flat_jack --spec examples/flat_jack_scenario.toml --set E_b=9500
--set kN_bj=70 --set kV_bj=30 --set r_hj=0.5 --set Km=0.82 --format csv`` (σ0 = 0.30 MPa and
ν_b = 0.15 are the defaults) and adds to every reading an absolute Gaussian error of σ = 2 µm
(0.002 mm, a typical LVDT) drawn with ``numpy.random.default_rng(2027)`` in the file's
order (step-major: all gauges at step 1, then step 2, ...). Readings are written to 0.01 µm.

Run from the repository root::

    python examples/make_flat_jack_data.py            # rewrites the shipped file
    python examples/make_flat_jack_data.py --joint    # the joint calibration's file (below)
    python examples/make_flat_jack_data.py --out x.csv --seed 7

``--joint`` writes ``examples/joint_flat_jack_measured.csv`` for ``joint_three_tests.toml``: the
same test at the demo's hidden values (E_b = 10 500 MPa, kN_bj = 70, kV_bj = 28 N/mm³,
r_hj = 0.55; Km = 0.82), so that it describes the same masonry as the diagonal and shear-wall
files, with the same 2 µm noise drawn with ``default_rng(2028)``.
"""

import argparse
import csv
import io
from pathlib import Path

import numpy as np

#: the hidden parameter values (MPa, N/mm³, N/mm³, -, -)
TRUTH = {"E_b": 9500.0, "kN_bj": 70.0, "kV_bj": 30.0, "r_hj": 0.5, "Km": 0.82}
NOISE_ABS = 0.002  # mm
SEED = 2027
HERE = Path(__file__).parent
SPEC = HERE / "flat_jack_scenario.toml"
OUT = HERE / "flat_jack_measured.csv"
#: the joint calibration's file: the demo's hidden values (make_measured_data.TRUTH) and Km
JOINT_TRUTH = {"E_b": 10500.0, "kN_bj": 70.0, "kV_bj": 28.0, "r_hj": 0.55, "Km": 0.82}
JOINT_OUT, JOINT_SEED = HERE / "joint_flat_jack_measured.csv", 2028


def simulate_csv(truth, spec=SPEC):
    """The output of ``podkrig simulate flat_jack --spec SPEC --set ... --format csv`` (text)."""
    from typer.testing import CliRunner

    from podkrig.cli import app

    args = ["simulate", "flat_jack", "--spec", str(spec), "--format", "csv"]
    for name, value in truth.items():
        args += ["--set", f"{name}={value:g}"]
    result = CliRunner().invoke(app, args)
    if result.exit_code != 0:
        raise RuntimeError(f"podkrig {' '.join(args)} failed: {result.output}")
    return result.stdout


def make(out=OUT, seed=SEED, noise_abs=NOISE_ABS, truth=None):
    """Write the pseudo-measured CSV to ``out``; returns the path."""
    rows = list(csv.reader(io.StringIO(simulate_csv(truth or TRUTH))))
    header, body = rows[0], rows[1:]
    clean = np.array([[float(c) for c in row[1:]] for row in body])  # (n_steps, n_gauges), mm
    noisy = clean + noise_abs * np.random.default_rng(seed).standard_normal(clean.shape)
    with Path(out).open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(header)
        for row, values in zip(body, noisy):
            w.writerow([row[0], *(f"{v:.5f}" for v in values)])
    return Path(out)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--joint", action="store_true",
                        help="The joint calibration's file (the demo's hidden values; joint_three_tests.toml).")
    parser.add_argument("--out", type=Path, help="CSV file to write (default: the shipped file).")
    parser.add_argument("--seed", type=int, help="Seed of the noise (default: 2027, or 2028 with --joint).")
    args = parser.parse_args()
    out, seed, truth = (JOINT_OUT, JOINT_SEED, JOINT_TRUTH) if args.joint else (OUT, SEED, TRUTH)
    print(f"wrote {make(args.out or out, seed if args.seed is None else args.seed, truth=truth)}")


if __name__ == "__main__":
    main()
