"""POD of nonlinear responses, both ways: one POD over all control levels stacked against a POD +
kriging per level, each with and without scaling of the mixed outputs (kN and mm).

Snapshots: ``triplet_shear`` (EN 1052-3, sensors ``middle_ux``, ``V_top`` in mm and the force ``F``
in kN at eight control levels 0.01–2 mm) at three pre-compressions 0.2, 0.6, 1.0 MPa, each a
Sobol' design (seed 0) of ``c_bj``, ``tanphi_bj``, ``GfII_bj`` over Set A ± 20 % (``--train``
rows) and a held-out Sobol' design (seed 1, ``--held`` rows); optionally J4D
(``shear_compression_nl``, ``--j4d``) over the same three parameters plus ``ft_bj``, and the J4D
study of ``examples/j4d_wall.toml`` (``--j4d-study``: its six free parameters, its 13 control
levels, its training and held-out designs; ``--store-dir`` pointing at the output folder of
``podkrig run examples/j4d_wall.toml`` reuses the study's ``train.h5`` and ``held_out.h5``, read
only, when they are complete). Every surrogate is fitted on the finished rows of the same store
and checked on the same held-out runs.
Printed per scenario and surrogate: the held-out error per unit relative to the peak of that
unit's curve, max |ŷ − y| / max |y| per run (median and max over the runs), the error of the peak
force, the largest gauge error (µm), and the fit time (CPU s of this process). SMT's KRG and KPLS
(stacked, scaled per unit, one model per POD mode; KPLS with its default 2 PLS components) are
peers when SMT is installed.

FE runs take CPU time (a triplet run about 1–3 s, J4D 2–7 s): run under ``nice``; ``--store-dir``
keeps the stores so that a second call only refits.

Usage: nice -n 5 python scripts/bench_pod_nonlinear.py [--train 32] [--held 16] [--j4d]
       [--j4d-train 64] [--j4d-study] [--no-triplets] [--store-dir DIR]
(BENCHMARKS.md: ``--j4d --held 32``; ``--j4d-study --no-triplets --store-dir OUT``.)
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
from podkrig.study.schema import load_study
from podkrig.surrogate.podkriging import PODKriging, training_data
from podkrig.surrogate.settings import SurrogateSettings, fit_surrogate
from podkrig.surrogate.validation import held_out_errors

TRIPLET = ("c_bj", "tanphi_bj", "GfII_bj")
J4D_STUDY = Path(__file__).resolve().parents[1] / "examples" / "j4d_wall.toml"
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
            for backend, name in (("smt-krg", "SMT KRG"), ("smt-kpls", "SMT KPLS")):
                t0 = time.process_time()
                sur = fit_surrogate(train, SurrogateSettings(backend=backend, scaling="unit"))
                cpu = time.process_time() - t0
                rows.append((label, f"{name}, stacked, scaled per unit",
                             held_out_errors(sur, X_held, Y_held, with_loo=False), cpu, sur))
    return rows


def study_stores(store_dir):
    """Train and held-out stores of the J4D study (``examples/j4d_wall.toml``): those of a finished
    ``podkrig run`` in ``store_dir`` as they are, else run (or resumed) there with the study's
    scenario, free parameters and designs, one FE process."""
    study = load_study(J4D_STUDY)
    paths = []
    for name, design in (("train", study.train), ("held_out", study.held_out)):
        path = Path(store_dir) / f"{name}.h5"
        if path.exists():
            with SnapshotStore.open(path) as store:
                counts = store.counts()
            if counts["pending"] == 0 and counts["total"] == design.n:
                print(f"  J4D study {name}: {counts['done']} of {counts['total']} finished (reused)", flush=True)
                paths.append(path)
                continue
        t0 = time.process_time()
        s = run_snapshots(path, study.spec, study.space, workers=1, **design.run_arguments())
        print(f"  J4D study {name}: {s.done} of {s.total} finished ({time.process_time() - t0:.0f} s CPU here)",
              flush=True)
        paths.append(path)
    return paths


def learning_curve(train_path, held_path, sizes):
    """The default surrogate fitted on the first ``n`` finished training rows (a Sobol' design's
    prefix is a Sobol' design) for each ``n`` in ``sizes``, checked on the same held-out runs:
    printed as n, modes, force and peak-force errors, fit CPU s."""
    settings = SurrogateSettings()
    with SnapshotStore.open(train_path) as train, SnapshotStore.open(held_path) as held:
        X, Y = training_data(train)
        X_held, Y_held = training_data(held)
        units = [train.sensor_definitions.get(n, {}).get("unit", "mm")
                 if train.sensor_definitions.get(n, {}).get("kind") == "force" else "mm" for n in train.sensor_names]
        print("\n| training runs | modes | force: median / max error (% of peak) | peak force: median / max error (%) "
              "| fit (CPU s) |")
        print("|---:|---:|---:|---:|---:|")
        for n in sorted(k for k in sizes if k <= len(X)):
            pod, regressor = settings.templates()
            t0 = time.process_time()
            sur = PODKriging(pod=pod, kriging=regressor, space=train.space, layout=settings.pod,
                             scaling=settings.scaling).fit(X[:n], Y[:n], units)
            cpu = time.process_time() - t0
            kn = held_out_errors(sur, X_held, Y_held, with_loo=False).by_unit()["kN"]
            cells = [f"{100 * e['median']:.3f} / {100 * e['max']:.3f}" for e in (kn["peak_error"], kn["peak_value_error"])]
            print(f"| {n} | {sur.n_modes_} | " + " | ".join(cells) + f" | {cpu:.2f} |", flush=True)


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
    ap.add_argument("--j4d-study", action="store_true",
                    help="also the J4D study of examples/j4d_wall.toml (6 free parameters, its designs)")
    ap.add_argument("--no-triplets", action="store_true", help="leave the three triplet series out")
    ap.add_argument("--store-dir", help="keep the stores here (default: a temporary directory)")
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; load {os.getloadavg()[0]:.1f}", flush=True)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        store_dir = Path(args.store_dir or tmp)
        store_dir.mkdir(parents=True, exist_ok=True)
        for p in () if args.no_triplets else (0.2, 0.6, 1.0):
            spec = {"scenario": "triplet_shear", "precompression": p}
            train, held = stores(spec, TRIPLET, args.train, args.held, store_dir, f"triplet_{p:g}MPa")
            rows += compare(train, held, f"triplet {p:g} MPa")
        if args.j4d:
            spec = {"scenario": "shear_compression_nl", "top": "fixed_vertical"}
            train, held = stores(spec, J4D, args.j4d_train, args.held, store_dir, "j4d")
            rows += compare(train, held, "J4D")
        if args.j4d_study:
            train, held = study_stores(store_dir)
            rows += compare(train, held, "J4D study (6 parameters)")
            learning_curve(train, held, (32, 64, 128, 256, 512, 1024))
    table(rows)


if __name__ == "__main__":
    main()
