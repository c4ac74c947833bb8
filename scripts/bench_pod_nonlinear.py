"""POD of nonlinear responses, both ways: one POD over all control levels stacked against a POD +
kriging per level, each with and without scaling of the mixed outputs (kN and mm).

Snapshots: ``triplet_shear`` (EN 1052-3, sensors ``middle_ux``, ``V_top`` in mm and the force ``F``
in kN at eight control levels 0.01–2 mm) at three pre-compressions 0.2, 0.6, 1.0 MPa, each a
Sobol' design (seed 0) of ``c_bj``, ``tanphi_bj``, ``GfII_bj`` over Set A ± 20 % (``--train``
rows) and a held-out Sobol' design (seed 1, ``--held`` rows); optionally J4D
(``shear_compression_nl``, ``--j4d``) over the same three parameters plus ``ft_bj``. Every
surrogate is fitted on the finished rows of the same store and checked on the same held-out runs.
Printed per scenario and surrogate: the held-out error per unit relative to the peak of that
unit's curve, max |ŷ − y| / max |y| per run (median and max over the runs), the error of the peak
force, the largest gauge error (µm), and the fit time (CPU s of this process). SMT's KRG (stacked,
scaled per unit) is a peer when SMT is installed.

FE runs take CPU time (a triplet run about 1–3 s, J4D 2–7 s): run under ``nice``; ``--store-dir``
keeps the stores so that a second call only refits.

Usage: nice -n 5 python scripts/bench_pod_nonlinear.py [--train 32] [--held 16] [--j4d]
       [--j4d-train 64] [--store-dir DIR]
(BENCHMARKS.md: ``--j4d --held 32``.)
"""

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

from fe.scenarios import build_scenario
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.parameters import ParameterSpace
from podkrig.surrogate.podkriging import training_data
from podkrig.surrogate.settings import SurrogateSettings, fit_surrogate
from podkrig.surrogate.validation import held_out_errors

TRIPLET = ("c_bj", "tanphi_bj", "GfII_bj")
J4D = ("ft_bj", "c_bj", "tanphi_bj", "GfII_bj")
#: the surrogates compared: label -> SurrogateSettings keywords
WAYS = {
    "stacked, no scaling": {"pod": "stacked", "scaling": "none"},
    "stacked, scaled per unit": {"pod": "stacked", "scaling": "unit"},
    "stacked, scaled per sensor": {"pod": "stacked", "scaling": "sensor"},
    "per level, no scaling": {"pod": "per_level", "scaling": "none"},
    "per level, scaled per unit": {"pod": "per_level", "scaling": "unit"},
    "per level, scaled per sensor": {"pod": "per_level", "scaling": "sensor"},
}


def space_around_defaults(sc, names, spread=0.2):
    return ParameterSpace.from_scenario(sc, {n: (sc.parameters[n].default * (1 - spread),
                                                 sc.parameters[n].default * (1 + spread), "linear") for n in names})


def stores(spec, names, n_train, n_held, store_dir, label):
    """Train and held-out stores of one scenario (run or resumed); returns their paths."""
    sc = build_scenario(spec)
    space = space_around_defaults(sc, names)
    paths = []
    for kind, n, seed in (("train", n_train, 0), ("held", n_held, 1)):
        path = Path(store_dir) / f"{label}_{kind}_{n}.h5"
        t0 = time.process_time()
        s = run_snapshots(path, spec, space, n=n, seed=seed, workers=1)
        print(f"  {label} {kind}: {s.done} of {s.total} finished ({time.process_time() - t0:.0f} s CPU here)",
              flush=True)
        paths.append(path)
    return paths


def compare(train_path, held_path, label):
    rows = []
    with SnapshotStore.open(train_path) as train, SnapshotStore.open(held_path) as held:
        X_held, Y_held = training_data(held)
        for way, kw in WAYS.items():
            t0 = time.process_time()
            sur = fit_surrogate(train, SurrogateSettings(**kw))
            cpu = time.process_time() - t0
            rep = held_out_errors(sur, X_held, Y_held, with_loo=False)
            rows.append((label, way, rep, cpu, sur))
        try:
            import smt  # noqa: F401
        except ImportError:
            pass
        else:
            t0 = time.process_time()
            sur = fit_surrogate(train, SurrogateSettings(backend="smt-krg", scaling="unit"))
            rows.append((label, "SMT KRG, stacked, scaled per unit", held_out_errors(sur, X_held, Y_held, with_loo=False),
                         time.process_time() - t0, sur))
    return rows


def table(rows):
    print("\n| snapshots | surrogate | modes | force: median / max error (% of peak) | peak force: median / max "
          "error (%) | gauges: median / max error (% of peak) | gauges: max error (µm) | fit (CPU s) |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    for label, way, rep, cpu, sur in rows:
        by = rep.by_unit()
        kn, mm = by.get("kN", {}), by.get("mm", {})
        cells = ["-" if e is None else f"{100 * e['median']:.3f} / {100 * e['max']:.3f}"
                 for e in (kn.get("peak_error"), kn.get("peak_value_error"), mm.get("peak_error"))]
        cells.append("-" if not mm else f"{1000 * mm['max_abs_error']:.2f}")
        print(f"| {label} | {way} | {rep.n_modes} | " + " | ".join(cells) + f" | {cpu:.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--train", type=int, default=32, help="training runs per scenario (a power of two)")
    ap.add_argument("--held", type=int, default=16, help="held-out runs per scenario")
    ap.add_argument("--j4d", action="store_true", help="also J4D (shear_compression_nl, fixed_vertical)")
    ap.add_argument("--j4d-train", type=int, default=64)
    ap.add_argument("--store-dir", help="keep the stores here (default: a temporary directory)")
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; load {os.getloadavg()[0]:.1f}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        store_dir = Path(args.store_dir or tmp)
        store_dir.mkdir(parents=True, exist_ok=True)
        for p in (0.2, 0.6, 1.0):
            spec = {"scenario": "triplet_shear", "precompression": p}
            train, held = stores(spec, TRIPLET, args.train, args.held, store_dir, f"triplet_{p:g}MPa")
            rows += compare(train, held, f"triplet {p:g} MPa")
        if args.j4d:
            spec = {"scenario": "shear_compression_nl", "top": "fixed_vertical"}
            train, held = stores(spec, J4D, args.j4d_train, args.held, store_dir, "j4d")
            rows += compare(train, held, "J4D")
    table(rows)


if __name__ == "__main__":
    main()
