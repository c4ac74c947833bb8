"""Regenerate the J4D wall's pseudo-measured curve, ``examples/j4d_wall_measured.csv``.

The TU Eindhoven shear wall J4D (``shear_compression_nl``: 990 × 1000 × 100 mm, 18 courses on and
under steel beams each joined by a bed joint, default Q8 6 × 2 mesh and composite interface law)
under 0.30 MPa pre-compression with the top beam kept level and at its height (``top =
"fixed_vertical"``, the scenario's default), pushed horizontally to 1.75 mm — the end of the range
in which its curve is mesh-objective. It is run at the hidden values :data:`TRUTH` (every other
parameter at the scenario's default, the study's ``[fixed]`` values included) with the control
levels of :data:`LEVELS` (mm of top displacement). The file is exactly what ``podkrig simulate
shear_compression_nl --option load_levels=[...] --set ft_bj=0.22 ... --format csv`` prints, with
noise added to every reading: σ² = σ_abs² + (0.01 d)², σ_abs = 0.05 kN on the force ``F`` (a load
cell) and 2 µm on the displacements ``top_ux``, ``D1``, ``D2``, ``V_left``, ``V_right`` (LVDTs) —
the noise model the study declares — drawn with ``numpy.random.default_rng(SEED)`` in the file's
order (rows = control levels, columns = sensors). Readings are written to 8 significant digits.

Run from the repository root::

    python examples/make_j4d_wall.py                 # rewrites the shipped file
    python examples/make_j4d_wall.py --out DIR --seed 7
"""

import argparse
from pathlib import Path

import numpy as np

#: the hidden values: tensile strength ft_bj (MPa), cohesion c_bj (MPa), initial friction
#: coefficient tanphi_bj (-), fracture energies GfI_bj and GfII_bj (N/mm) and the shear stiffness
#: kV_bj (N/mm³) of the joints
TRUTH = {"ft_bj": 0.22, "c_bj": 0.35, "tanphi_bj": 0.70, "GfI_bj": 0.015, "GfII_bj": 0.125, "kV_bj": 40.0}
#: the scenario: J4D's pre-compression (MPa), the top condition and the control levels (mm)
SPEC = {"scenario": "shear_compression_nl", "precompression": 0.30, "top": "fixed_vertical"}
#: control levels (mm of top displacement): the elastic branch (0.05–0.2 mm), cracking and the
#: stepped diagonal crack (0.3–1.75 mm); the curve still rises at 1.75 mm with the top fixed
LEVELS = [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.75, 0.9, 1.0, 1.25, 1.5, 1.75]
NOISE_ABS = {"F": 0.05, "top_ux": 0.002, "D1": 0.002, "D2": 0.002, "V_left": 0.002, "V_right": 0.002}  # kN, mm
NOISE_REL = 0.01
SEED = 2044
HERE = Path(__file__).parent
DATA = HERE / "j4d_wall_measured.csv"


def simulate_csv(truth=None):
    """The noise-free curve: what ``podkrig simulate --format csv`` prints."""
    from fe.scenarios import build_scenario
    from podkrig.io.measurement_log import response_csv

    sc = build_scenario({**SPEC, "load_levels": LEVELS})
    return response_csv(sc, sc.run(truth or TRUTH))


def make(path=DATA, seed=SEED, truth=None):
    """Write the noisy curve to ``path``; returns the path."""
    header, *body = simulate_csv(truth).splitlines()
    names = [cell.split(" [")[0] for cell in header.split(",")[1:]]
    levels = [row.split(",")[0] for row in body]
    clean = np.array([[float(c) for c in row.split(",")[1:]] for row in body])  # (n_levels, n_sensors)
    sigma = np.hypot([NOISE_ABS[n] for n in names], NOISE_REL * clean)
    noisy = clean + sigma * np.random.default_rng(seed).standard_normal(clean.shape)
    lines = [header, *(",".join([level, *(f"{v:.8g}" for v in row)]) for level, row in zip(levels, noisy))]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=DATA, help="File to write (default: the shipped one).")
    parser.add_argument("--seed", type=int, default=SEED, help=f"Seed of the noise (default {SEED}).")
    args = parser.parse_args()
    print(f"wrote {make(args.out, args.seed)}")


if __name__ == "__main__":
    main()
