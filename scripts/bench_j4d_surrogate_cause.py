"""Why the J4D study's surrogate error stops falling with more runs: cheap refits on the study's
stores (no FE run), printed as one table.

Reads ``train.h5`` and ``held_out.h5`` of a finished ``podkrig run examples/j4d_wall.toml`` (read
only) and fits the stacked POD + kriging with settings varied one at a time: scaling (per unit,
none), the number of POD modes, the variogram exponent β (fit-shared, fit per mode, fixed), a
nugget, a log box (log of the parameters, box from the training runs). Printed per fit: modes,
force error (max |ŷ − y| / max |y| per held-out run, % of the peak; median / max), peak-load error
(|max ŷ_F − max y_F| / max y_F, median, %), fit CPU s. Then where the force error sits: the
scaled variance per sensor and the force's share of the first POD modes, and the median force
error per control level on the first 64, 128, 256 training runs (Sobol' prefixes). Last, an
ordinary kriging of the peak load itself (one output, the largest force of each run, in the unit
box) with the exponent β fixed or fitted: whether a surrogate of the peak does better than the
curve's (``--peak-only`` prints this part alone, a few s of CPU).
Each fit ≈ 3–17 s of CPU on a loaded machine.

Usage: PYTHONPATH=. nice -n 5 python scripts/bench_j4d_surrogate_cause.py --store-dir DIR [--peak-only]
"""

import argparse
import time

import numpy as np

from podkrig.offline.store import SnapshotStore
from podkrig.surrogate.kriging.ordinary import OrdinaryKriging
from podkrig.surrogate.podkriging import PODKriging, training_data
from podkrig.surrogate.settings import SurrogateSettings

#: label -> SurrogateSettings keywords (log: fit on log parameters over the training runs' box)
FITS = {
    "per unit (default)": {},
    "per unit, 20 modes": {"modes": 20},
    "per unit, β fit per mode": {"beta": "fit"},
    "per unit, β 2": {"beta": 2.0},
    "per unit, log box": {"log": True},
    "none": {"scaling": "none"},
    "none, 10 modes": {"scaling": "none", "modes": 10},
    "none, nugget 1e-6": {"scaling": "none", "nugget": 1e-6},
    "none, β fit per mode": {"scaling": "none", "beta": "fit"},
    "none, β 2": {"scaling": "none", "beta": 2.0},
    "none, β 1.5": {"scaling": "none", "beta": 1.5},
    "none, β 1.25": {"scaling": "none", "beta": 1.25},
    "none, log box": {"scaling": "none", "log": True},
}


def fit(X, Y, units, space, log=False, **kw):
    s = SurrogateSettings(**kw)
    pod, kriging = s.templates()
    t0 = time.process_time()
    sur = PODKriging(pod=pod, kriging=kriging, space=None if log else space, layout=s.pod,
                     scaling=s.scaling).fit(np.log(X) if log else X, Y, units)
    return sur, time.process_time() - t0


def force_errors(sur, Xh, Yh, iF, log=False):
    """Per held-out run: curve error (of the peak), peak-load error, and per level |error| / peak."""
    P = np.asarray(sur.predict(np.log(Xh) if log else Xh, extrapolate=log)).reshape(Yh.shape)
    F, Fp = Yh[:, :, iF], P[:, :, iF]
    peak = np.abs(F).max(axis=1)
    return (np.abs(Fp - F).max(axis=1) / peak, np.abs(Fp.max(axis=1) - F.max(axis=1)) / F.max(axis=1),
            np.abs(Fp - F) / peak[:, None])


def peak_kriging(X, Y, Xh, Yh, iF, space):
    """Held-out error of an ordinary kriging of the peak load itself, per exponent setting: a table."""
    U, Uh = space.to_unit(X), space.to_unit(Xh)
    y, yh = Y[:, :, iF].max(axis=1), Yh[:, :, iF].max(axis=1)
    print("\nkriging of the peak load itself (one output)\n\n| β | peak load: median / max error (%) | fit (CPU s) |")
    print("|---|---:|---:|")
    for beta in (1.0, 1.5, 1.9, "fit"):
        t0 = time.process_time()
        k = OrdinaryKriging(beta=beta).fit(U, y)
        cpu = time.process_time() - t0
        e = np.abs(np.ravel(k.predict(Uh)) - yh) / np.abs(yh)
        print(f"| {beta} | {100 * np.median(e):.3f} / {100 * e.max():.2f} | {cpu:.1f} |", flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--store-dir", required=True, help="output folder of podkrig run examples/j4d_wall.toml")
    ap.add_argument("--peak-only", action="store_true", help="only the kriging of the peak load itself")
    args = ap.parse_args(argv)
    with SnapshotStore.open(f"{args.store_dir}/train.h5") as tr, SnapshotStore.open(f"{args.store_dir}/held_out.h5") as he:
        X, Y = training_data(tr)
        Xh, Yh = training_data(he)
        defs, names, space = tr.sensor_definitions, tr.sensor_names, tr.space
    units = [defs.get(n, {}).get("unit", "mm") if defs.get(n, {}).get("kind") == "force" else "mm" for n in names]
    iF = units.index("kN")
    print(f"{len(X)} training runs, {len(Xh)} held-out runs, sensors {list(names)}")
    if args.peak_only:
        peak_kriging(X, Y, Xh, Yh, iF, space)
        return
    print("\n| fit | modes | β | force: median / max (% of peak) | peak load: median (%) | fit (CPU s) |")
    print("|---|---:|---:|---:|---:|---:|")
    for label, kw in FITS.items():
        sur, cpu = fit(X, Y, units, space, **kw)
        e, pk, _ = force_errors(sur, Xh, Yh, iF, kw.get("log", False))
        beta = np.ravel(sur.kriging_.hyperparameters_.beta)
        b = f"{beta.min():.2f}" if np.ptp(beta) == 0 else f"{beta.min():.2f}–{beta.max():.2f}"
        print(f"| {label} | {sur.n_modes_} | {b} | {100 * np.median(e):.3f} / {100 * e.max():.2f} | "
              f"{100 * np.median(pk):.3f} | {cpu:.1f} |", flush=True)
    Yf = Y.reshape(len(Y), -1)
    for scaling in ("unit", "none"):
        sur, _ = fit(X, Y, units, space, scaling=scaling)
        v = (Yf / sur.scale_).var(axis=0).reshape(Y.shape[1:]).sum(axis=0)
        modes = sur.pod_.modes_[:5].reshape(5, *Y.shape[1:])
        print(f"\nscaling {scaling}: share of the scaled variance per sensor "
              + ", ".join(f"{n} {100 * s:.1f} %" for n, s in zip(names, v / v.sum()))
              + "; the force's share of POD modes 1-5: " + ", ".join(f"{s:.2f}" for s in (modes[:, :, iF] ** 2).sum(axis=1)))
    print("\nmedian force error per control level (% of the peak); peak at the last level in "
          f"{int(np.sum(np.argmax(Yh[:, :, iF], axis=1) == Y.shape[1] - 1))} of {len(Yh)} held-out runs")
    for scaling in ("unit", "none"):
        for n in (64, 128, 256):
            if n > len(X):
                continue
            sur, _ = fit(X[:n], Y[:n], units, space, scaling=scaling)
            lev = np.median(force_errors(sur, Xh, Yh, iF)[2], axis=0)
            print(f"  {scaling:4s} n = {n:3d}: " + " ".join(f"{100 * v:.2f}" for v in lev), flush=True)
    peak_kriging(X, Y, Xh, Yh, iF, space)


if __name__ == "__main__":
    main()
