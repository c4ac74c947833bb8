"""Regenerate the flat-jack study's pseudo-measured data, ``examples/flat_jack_measured.csv``.

It runs exactly ``podkrig simulate flat_jack --spec examples/flat_jack_scenario.toml --set E_b=9500
--set kN_bj=70 --set kV_bj=30 --set r_hj=0.5 --set Km=0.82 --format csv`` (σ0 = 0.30 MPa and
ν_b = 0.15 are the defaults) and adds to every reading an absolute Gaussian error of σ = 2 µm
(0.002 mm, an LVDT of reference §5.7) drawn with ``numpy.random.default_rng(2027)`` in the file's
order (step-major: all gauges at step 1, then step 2, ...). Readings are written to 0.01 µm.

Run from the repository root::

    python examples/make_flat_jack_data.py            # rewrites the shipped file
    python examples/make_flat_jack_data.py --out x.csv --seed 7
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
    parser.add_argument("--out", type=Path, default=OUT, help="CSV file to write (default: the shipped file).")
    parser.add_argument("--seed", type=int, default=SEED, help="Seed of the noise (default: %(default)s).")
    args = parser.parse_args()
    print(f"wrote {make(args.out, args.seed)}")


if __name__ == "__main__":
    main()
