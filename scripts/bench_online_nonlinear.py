"""Benchmark: the online stage on nonlinear surrogates — inversion (GA + polish), the region of
equivalence from 10⁶ surrogate evaluations and the Sobol' indices — on the triplet series' three
surrogates (one joint calibration) and on a J4D surrogate, with peers in the same run.

Surrogates from snapshots this script makes (or finds already made in ``--out``):

- *triplet series*: ``examples/triplet_series.toml`` run by :func:`podkrig.study.run_study` into
  ``OUT/triplet_series`` (438 FE runs, about 30 s of CPU; three surrogates of 128 runs each, four
  free parameters; a second call reuses every stage);
- *J4D*: ``shear_compression_nl`` with the top fixed (the scenario's defaults), ``ft_bj``, ``c_bj``,
  ``tanphi_bj``, ``GfII_bj`` at Set A ± 20 %, a study of ``--j4d-train`` Sobol' runs (seed 0; 2–5 s
  of CPU each: run under ``nice``) written to ``OUT/j4d`` with pseudo-data from one FE run at
  :data:`J4D_TRUTH` with the triplet series' noise (1 % + 0.05 kN on F, 1 % + 2 µm on the gauges,
  seed 0); or, with ``--j4d-study DIR``, the J4D wall's study (``examples/j4d_wall.toml`` or the
  file ``--j4d-study-file`` names) on the surrogate in ``DIR`` — fitted here with the study's
  settings when ``DIR`` holds only its training store ``train.h5``.

Timed per case, in CPU seconds of this process (``time.process_time``: every thread of it, so the
figure does not depend on the machine's load or on how many cores the numba kernels used):

- the inversion of the calibration stage (:func:`podkrig.online.invert.invert` with the study's
  settings: GA 100 × 100 and polishes from six starts), median of ``--repeat`` runs; peer:
  ``scipy.optimize.differential_evolution`` on the same misfit in the same unit cube, population
  100, at most 100 generations, its own L-BFGS-B polish, vectorised;
- the region of equivalence by the likelihood ratio (:func:`~podkrig.online.region.likelihood_ratio_region`,
  the calibration stage's method) with ``--region-samples`` points (2^20 by default); a joint
  point costs one evaluation of each test's surrogate, so the surrogate evaluations are
  ``points × tests``; no peer (no other code builds this region);
- the Sobol' indices of the study's sensitivity stage (misfit and every reading of each test,
  ``n`` base samples from the study, 200 bootstrap replicates); peer:
  ``scipy.stats.sobol_indices`` on the same functions and points, point estimates only (its own
  bootstrap costs about a minute per replicate; SALib is not installed).

Usage: PYTHONPATH=. nice -n 5 python scripts/bench_online_nonlinear.py [--out DIR] [--cases triplet j4d]
       [--repeat 3] [--region-samples 1048576] [--j4d-train 64] [--j4d-study DIR [--j4d-study-file F]]
"""

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import numpy as np

J4D_SPEC = {"scenario": "shear_compression_nl", "top": "fixed_vertical"}
J4D_FREE = ("ft_bj", "c_bj", "tanphi_bj", "GfII_bj")
J4D_SPREAD = 0.2  # bounds: the scenario's default ± 20 %
#: hidden values of the J4D pseudo-data, relative to the scenario's defaults
J4D_TRUTH = {"ft_bj": 1.05, "c_bj": 0.95, "tanphi_bj": 1.05, "GfII_bj": 0.97}
NOISE_ABS_F, NOISE_ABS_GAUGE, NOISE_REL = 0.05, 0.002, 0.01  # kN, mm, -


def cpu(fun, *args, **kwargs):
    """``(result, CPU seconds of this process)``."""
    c0 = time.process_time()
    out = fun(*args, **kwargs)
    return out, time.process_time() - c0


def j4d_study(folder, n_train):
    """Write the J4D study (its file and pseudo-data) into ``folder``; returns the study file."""
    from fe.scenarios import build_scenario
    from podkrig.io.measurement_log import response_csv

    folder.mkdir(parents=True, exist_ok=True)
    sc = build_scenario(J4D_SPEC)
    data = folder / "j4d_measured.csv"
    if not data.exists():
        truth = {n: sc.parameters[n].default * J4D_TRUTH[n] for n in J4D_FREE}
        header, *body = response_csv(sc, sc.run(truth)).splitlines()
        names = [cell.split(" [")[0] for cell in header.split(",")[1:]]
        clean = np.array([[float(c) for c in row.split(",")[1:]] for row in body])
        sigma = np.hypot([NOISE_ABS_F if n == "F" else NOISE_ABS_GAUGE for n in names], NOISE_REL * clean)
        noisy = clean + sigma * np.random.default_rng(0).standard_normal(clean.shape)
        rows = [",".join([row.split(",")[0], *(f"{v:.8g}" for v in values)]) for row, values in zip(body, noisy)]
        data.write_text("\n".join([header, *rows]) + "\n")
    else:
        names = [cell.split(" [")[0] for cell in data.read_text().splitlines()[0].split(",")[1:]]
    bounds = "\n".join(f"{n} = {{ lower = {sc.parameters[n].default * (1 - J4D_SPREAD)!r}, "
                       f"upper = {sc.parameters[n].default * (1 + J4D_SPREAD)!r} }}" for n in J4D_FREE)
    noise = ", ".join(f"{n} = {NOISE_ABS_F if n == 'F' else NOISE_ABS_GAUGE}" for n in names)
    spec = ", ".join(f"{k} = {json.dumps(v)}" for k, v in J4D_SPEC.items())
    path = folder / "j4d.toml"
    path.write_text(f"""name = "j4d_bench"
scenario = {{ {spec} }}

[parameters]
{bounds}

[sampling]
train = {{ n = {n_train}, seed = 0 }}
held_out = {{ n = 4, seed = 1, method = "random" }}
workers = 1

[measurement]
file = "{data.name}"
noise_abs = {{ {noise} }}
noise_rel = {NOISE_REL}

[inversion]
seed = 0
confidence = 0.95

[sensitivity]
enabled = true
n = 1024
""")
    return path


def prepare(case, args):
    """``(label, problem, study)`` of a case, its surrogates built (or reused) by the study pipeline."""
    from podkrig.study import Progress, load_study, run_study
    from podkrig.study.stages import StudyRun

    out = Path(args.out)
    if case == "triplet":
        study_file, folder, label = Path("examples/triplet_series.toml"), out / "triplet_series", "triplet series"
    elif args.j4d_study:
        folder = Path(args.j4d_study)
        study_file = Path(args.j4d_study_file or "examples/j4d_wall.toml")
        label = "J4D study"
    else:
        folder, label = out / "j4d", f"J4D ({args.j4d_train} runs)"
        study_file = j4d_study(folder, args.j4d_train)
        folder = folder / "study"
    study = load_study(study_file)
    if case == "j4d" and args.j4d_study and not (folder / "surrogate.h5").exists():
        from podkrig.study.stages import _fit  # a folder with the study's training store only

        t0 = time.process_time()
        _fit(folder / "train.h5", study.surrogate, folder / "surrogate.h5")
        print(f"  {label}: surrogate fitted on {folder / 'train.h5'} ({time.process_time() - t0:.1f} s CPU)", flush=True)
    if not (case == "j4d" and args.j4d_study):
        t0 = time.process_time()
        run_study(study, folder)
        print(f"  {label}: study in {folder} ({time.process_time() - t0:.1f} s CPU here)", flush=True)
    return label, StudyRun(study, folder, Progress()).calibration_problem(), study


def n_surrogates(problem):
    return len(getattr(problem, "problems", {None: problem}))


def bench_inversion(problem, study, repeat):
    from scipy.optimize import differential_evolution

    from podkrig.online.invert import invert

    options = study.calibration_settings().inversion.options()
    times, result = [], None
    for _ in range(repeat):
        result, t = cpu(invert, problem, **options)
        times.append(t)
    p = problem.n_free
    calls = [0]

    def omega(U):  # scipy's vectorised layout: (p, S) -> (S,), and (p,) -> scalar in its polish
        U = np.asarray(U, dtype=float)
        calls[0] += 1 if U.ndim == 1 else U.shape[1]
        if U.ndim == 1:
            return float(problem.omega_unit(U[None])[0])
        return problem.omega_unit(np.ascontiguousarray(U.T))

    popsize = -(-options["population_size"] // p)
    de, t_de = cpu(differential_evolution, omega, [(0.0, 1.0)] * p, popsize=popsize, maxiter=options["generations"],
                   polish=True, seed=0, vectorized=True, updating="deferred")
    x_de = problem.free_space.from_unit(de.x[None])[0]
    return {"ours": statistics.median(times), "ours_all": times, "result": result, "peer": t_de,
            "peer_omega": float(problem.omega(x_de[None])[0]), "peer_x": x_de, "peer_nfev": calls[0]}


def bench_region(problem, study, x, n_samples):
    from podkrig.online.region import likelihood_ratio_region

    s = study.calibration_settings()
    region, t = cpu(likelihood_ratio_region, problem, x, confidence=s.confidence, n_samples=n_samples,
                    rng=s.inversion.seed)
    return {"ours": t, "region": region, "points": region.n_evaluated,
            "evaluations": region.n_evaluated * n_surrogates(problem)}


def bench_sensitivity(problem, study):
    from scipy import stats

    from podkrig.online.calibrate import problems_by_test
    from podkrig.online.sensitivity import misfit_sensitivity, reading_sensitivity

    options = study.sensitivity.options()
    c0 = time.process_time()
    misfit = misfit_sensitivity(problem, **options)
    readings = {name: reading_sensitivity(p.model, **options) for name, p in problems_by_test(problem).items()}
    ours = time.process_time() - c0
    n, d = options["n"], problem.n_free
    rng = np.random.default_rng(options["rng"])
    dists = [stats.uniform()] * d
    c0 = time.process_time()
    stats.sobol_indices(func=lambda u: problem.omega_unit(np.ascontiguousarray(u.T))[None], n=n, dists=dists,
                        random_state=rng)
    for name, p in problems_by_test(problem).items():
        index = np.array([p.model.space.names.index(f) for f in p.free])
        template = p._template_unit

        def readings_of(u, p=p, index=index, template=template):
            full = np.tile(template, (u.shape[1], 1))
            full[:, index] = u.T
            return p.model.predict_unit(full).T

        stats.sobol_indices(func=readings_of, n=n, dists=[stats.uniform()] * len(index), random_state=rng)
    peer = time.process_time() - c0
    n_eval = misfit.n_evaluations + sum(r.n_evaluations for r in readings.values())
    return {"ours": ours, "peer": peer, "misfit": misfit, "evaluations": n_eval}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="bench_out/online_nonlinear", help="folder of the studies (reused)")
    ap.add_argument("--cases", nargs="+", default=["triplet", "j4d"], choices=["triplet", "j4d"])
    ap.add_argument("--repeat", type=int, default=3, help="inversions timed per case (the median is shown)")
    ap.add_argument("--region-samples", type=int, default=2**20, help="points of the region (a power of two)")
    ap.add_argument("--j4d-train", type=int, default=64, help="training runs of the J4D surrogate")
    ap.add_argument("--j4d-study", help="a J4D study folder (its surrogate.h5, or train.h5 to fit one) to use instead")
    ap.add_argument("--j4d-study-file", help="the study file of --j4d-study (default examples/j4d_wall.toml)")
    args = ap.parse_args(argv)
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}; "
          f"load {os.getloadavg()[0]:.1f}", flush=True)
    rows = []
    for case in args.cases:
        label, problem, study = prepare(case, args)
        problem.omega_unit(np.full((4, problem.n_free), 0.5))  # compiled kernels loaded before timing
        inv = bench_inversion(problem, study, args.repeat)
        res = inv["result"]
        print(f"  {label}: {n_surrogates(problem)} surrogate(s), free {list(res.free)}", flush=True)
        print(f"    inversion: x = {np.array2string(res.x, precision=6)}, ω = {res.misfit:.6g}, "
              f"{res.n_evaluations} evaluations; CPU s {[round(t, 3) for t in inv['ours_all']]}", flush=True)
        print(f"    scipy DE: x = {np.array2string(inv['peer_x'], precision=6)}, ω = {inv['peer_omega']:.6g}, "
              f"{inv['peer_nfev']} evaluations", flush=True)
        reg = bench_region(problem, study, res.x, args.region_samples)
        r = reg["region"]
        print(f"    region: {len(r.samples)} members of {reg['points']} points; "
              + ", ".join(f"{n} [{lo:.5g}, {hi:.5g}]" for n, (lo, hi) in r.intervals.items()), flush=True)
        sens = bench_sensitivity(problem, study)
        print(f"    misfit total indices: {dict(zip(sens['misfit'].parameters, sens['misfit'].total[0].round(4)))}",
              flush=True)
        per_million = reg["ours"] / reg["evaluations"] * 1e6
        rows += [
            (label, "inversion, GA 100 × 100 + polishes (target ≤ 1 s)",
             f"{inv['ours']:.2f} ({res.n_evaluations} evaluations)",
             f"scipy DE (population 100, ≤ 100 generations, polish): {inv['peer']:.2f} s, {inv['peer_nfev']} "
             f"evaluations, ω {inv['peer_omega']:.6g} (ours {res.misfit:.6g})"),
            (label, f"region, {reg['points']} points = {reg['evaluations'] / 1e6:.2f} M surrogate evaluations "
                    "(target: 10⁶ surrogate evaluations ≤ 10 s)",
             f"{reg['ours']:.2f} ({per_million:.2f} per 10⁶ surrogate evaluations)", "—"),
            (label, f"Sobol' indices of the misfit and every reading, {sens['evaluations']} model evaluations, "
                    "200 bootstrap replicates (target ≤ 5 s)", f"{sens['ours']:.2f}",
             f"scipy.stats.sobol_indices, same n, no intervals: {sens['peer']:.2f} s"),
        ]
    print(f"\nload after: {os.getloadavg()[0]:.1f}\n")
    print("| case | metric | CPU s | peer, same run |")
    print("|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
