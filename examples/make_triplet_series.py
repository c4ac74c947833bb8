"""Regenerate the triplet series' pseudo-measured curves, ``examples/triplet_series_*MPa.csv``.

Three EN 1052-3 triplets (``triplet_shear``, default Set A specimen and mesh) at pre-compressions
0.2, 0.6 and 1.0 MPa, run at the hidden values :data:`TRUTH` (every other parameter at the
scenario's default, the study's ``[fixed]`` values included) with the control levels of
:data:`LEVELS` (mm of slip). Each file is exactly what ``podkrig simulate triplet_shear --option
precompression=P --option load_levels=[...] --set c_bj=0.3 ... --format csv`` prints, with noise
added to every reading: σ² = σ_abs² + (0.01 d)², σ_abs = 0.05 kN on the force ``F`` (a load cell)
and 2 µm on the gauges ``middle_ux``, ``V_top`` (LVDTs) — the noise model the study declares —
drawn with ``numpy.random.default_rng(SEED + k)`` for the k-th pre-compression (k = 0, 1, 2), in
the file's order (rows = control levels, columns = sensors). Readings are written to 8
significant digits.

Run from the repository root::

    python examples/make_triplet_series.py                 # rewrites the three shipped files
    python examples/make_triplet_series.py --out DIR --seed 7
"""

import argparse
from pathlib import Path

import numpy as np

from fe.scenarios import build_scenario
from podkrig.io.measurement_log import response_csv

#: the hidden values: cohesion (MPa), initial friction coefficient (-), mode-II fracture energy
#: (N/mm) of the joints; the tensile strength ft_bj (MPa) the study also leaves free
TRUTH = {"c_bj": 0.30, "tanphi_bj": 0.85, "GfII_bj": 0.10, "ft_bj": 0.10}
#: pre-compressions of the series (MPa) and the file of each
PRECOMPRESSIONS = (0.2, 0.6, 1.0)
#: control levels (mm of slip): the elastic branch, the peak (0.03-0.15 mm) and the softening branch
LEVELS = [0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.75, 1.0, 1.5, 2.0]
NOISE_ABS = {"F": 0.05, "middle_ux": 0.002, "V_top": 0.002}  # kN, mm, mm
NOISE_REL = 0.01
SEED = 2032
HERE = Path(__file__).parent


def data_file(precompression, folder=HERE):
    """The file of the triplet at ``precompression`` (MPa)."""
    return Path(folder) / f"triplet_series_{precompression:.1f}MPa.csv"


def simulate_csv(precompression, truth=None):
    """The noise-free curve at ``precompression`` (MPa): what ``podkrig simulate --format csv`` prints."""
    sc = build_scenario({"scenario": "triplet_shear", "precompression": precompression, "load_levels": LEVELS})
    return response_csv(sc, sc.run(truth or TRUTH))


def make(folder=HERE, seed=SEED, truth=None):
    """Write the three noisy curves to ``folder``; returns their paths."""
    paths = []
    for k, p in enumerate(PRECOMPRESSIONS):
        header, *body = simulate_csv(p, truth).splitlines()
        names = [cell.split(" [")[0] for cell in header.split(",")[1:]]
        levels = [row.split(",")[0] for row in body]
        clean = np.array([[float(c) for c in row.split(",")[1:]] for row in body])  # (n_levels, n_sensors)
        sigma = np.hypot([NOISE_ABS[n] for n in names], NOISE_REL * clean)
        noisy = clean + sigma * np.random.default_rng(seed + k).standard_normal(clean.shape)
        lines = [header, *(",".join([level, *(f"{v:.8g}" for v in row)]) for level, row in zip(levels, noisy))]
        path = data_file(p, folder)
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
    return paths


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE, help="Folder to write the three files to.")
    parser.add_argument("--seed", type=int, default=SEED, help="Seed of the noise of the first file (default 2032).")
    args = parser.parse_args()
    for path in make(args.out, args.seed):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
