"""Regenerate the pseudo-measured logs of the in-situ flat-jack shear test and of the diagonal
compression test joined with it: ``examples/flat_jack_shear_elastic.csv``,
``examples/flat_jack_shear_sliding.csv`` and ``examples/joint_diagonal_flat_jack_diagonal.csv``.

One wall, one hidden truth (:data:`TRUTH`; every other parameter at the scenarios' defaults, the
studies' ``[fixed]`` values included):

- the flat-jack test's elastic phases (``flat_jack_elastic_nl`` with ``p_H = 0.6``: the cut, p_H
  0.1 → 0.6 MPa, p_V1 = p_V2 0.1 → 0.5 MPa; the 18 gauges of layout L18 at each of the 16 steps, mm);
- its shear phase (``flat_jack_shear_nl`` at p_H = 0.6 MPa with the repeat ``further_p_H = [0.3]``:
  the 18 gauges, V1's gauge pressure ``p_V1`` and that of the repeat at p_H = 0.3 MPa,
  ``p_V1_repeat1``, MPa, at the block's slip levels 0.005–0.5 mm);
- a diagonal compression test of the same masonry (``diagonal_compression``, the mesh of
  :data:`DIAGONAL`; six LVDTs at 25–100 kN).

Each file is exactly what ``podkrig simulate SCENARIO [--option ...] --set ... --format csv`` prints at
the truth, with noise added to every reading d: σ² = σ_abs² + (0.01 d)², σ_abs = 2 µm on the
flat-jack gauges (LVDTs on a wall in situ), 0.01 MPa on the jack pressures (a 0.1 bar pressure
transducer) and 1 µm on the diagonal test's LVDTs (the ``lvdt`` instrument of
``podkrig.online.measurement``) — the noise models the studies declare — drawn with
``numpy.random.default_rng(SEED + k)`` for the k-th file of :data:`RECORDS` (k = 0, 1, 2), in the
file's order (rows = levels, columns = sensors). Readings are written to 8 significant digits.

Run from the repository root::

    python examples/make_flat_jack_shear.py                 # rewrites the three shipped files
    python examples/make_flat_jack_shear.py --out DIR --seed 7
"""

import argparse
from pathlib import Path

import numpy as np

#: the hidden values: joint stiffness (N/mm³), head/bed stiffness ratio (-), cohesion (MPa),
#: initial friction coefficient (-), jack efficiency (-); the units' E_b (MPa) is the flat-jack
#: scenarios' default, free only in the joint study with the diagonal compression test
TRUTH = {"kN_bj": 110.0, "kV_bj": 45.0, "r_hj": 0.55, "c_bj": 0.30, "tanphi_bj": 0.75, "Km": 0.82,
         "E_b": 10000.0}
#: the horizontal jack's pressure in the shear phase, MPa: Km p_H stays at most 0.57 MPa (1.9 σ0)
#: over the studies' Km range, below the 0.8–0.9 MPa where H lifts the wall beside the block off
#: the bed joint beyond its ends (docs/nonlinear.md, the flat-jack shear test's limits)
P_H = 0.6
#: the shear record's repeat 3': the horizontal jack's pressure, MPa
FURTHER_P_H = [0.3]
#: the diagonal compression test's mesh (as ``examples/joint_diagonal_shear.toml``)
DIAGONAL = {"scenario": "diagonal_compression", "nx": 6, "ny": 2}
#: file name → (scenario spec, σ_abs of each sensor by unit: mm or MPa)
RECORDS = {
    "flat_jack_shear_elastic.csv": ({"scenario": "flat_jack_elastic_nl", "p_H": P_H}, {"mm": 0.002}),
    "flat_jack_shear_sliding.csv": ({"scenario": "flat_jack_shear_nl", "p_H": P_H, "further_p_H": FURTHER_P_H},
                                    {"mm": 0.002, "MPa": 0.01}),
    "joint_diagonal_flat_jack_diagonal.csv": (DIAGONAL, {"mm": 0.001}),
}
NOISE_REL = 0.01
SEED = 2040
HERE = Path(__file__).parent


def simulate_csv(spec, truth=None):
    """The noise-free log of ``spec`` at the truth: what ``podkrig simulate --format csv`` prints."""
    from fe.scenarios import build_scenario
    from podkrig.io.measurement_log import response_csv

    sc = build_scenario(spec)
    values = {k: v for k, v in (truth or TRUTH).items() if k in sc.parameters}
    response = sc.run(values)
    if not getattr(response, "converged", True):
        raise RuntimeError(f"{spec['scenario']} stopped early at the truth: {response.message}")
    return response_csv(sc, response)


def make(folder=HERE, seed=SEED, truth=None):
    """Write the three noisy logs to ``folder``; returns their paths."""
    paths = []
    for k, (name, (spec, sigma_abs)) in enumerate(RECORDS.items()):
        header, *body = simulate_csv(spec, truth).splitlines()
        units = [cell.split(" [")[1].rstrip("]") for cell in header.split(",")[1:]]
        levels = [row.split(",")[0] for row in body]
        clean = np.array([[float(c) for c in row.split(",")[1:]] for row in body])  # (n_levels, n_sensors)
        sigma = np.hypot([sigma_abs[u] for u in units], NOISE_REL * clean)
        noisy = clean + sigma * np.random.default_rng(seed + k).standard_normal(clean.shape)
        lines = [header, *(",".join([level, *(f"{v:.8g}" for v in row)]) for level, row in zip(levels, noisy))]
        path = Path(folder) / name
        path.write_text("\n".join(lines) + "\n")
        paths.append(path)
    return paths


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE, help="Folder to write the three files to.")
    parser.add_argument("--seed", type=int, default=SEED, help="Seed of the noise of the first file (default 2040).")
    args = parser.parse_args()
    for path in make(args.out, args.seed):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
