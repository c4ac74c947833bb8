"""Optimal sensor placement benchmark: the diagonal compression test (issue 16).

Usage::

    python scripts/bench_sensors.py                           # the full run (~15 min on 2 cores)
    python scripts/bench_sensors.py --mc 5 --random 5         # a quick look

Set-up: default diagonal-compression panel (9 360 dofs), free E_b, kN_bj (log), kV_bj (log), r_hj
over the demo study's box; candidates: gauges between the points of a 160 mm grid (105…1065 mm
both ways; points on joints dropped), 100–500 mm long, along 0°, 45°, 90°, 135° — plus the six
current gauges (D1, D2, U1, BJ_V, BJ_D, HJ_H), which may be chosen. Noise: σ = 2 µm per gauge
reading. Criterion: D-optimal averaged over 64 Sobol' points of the box.

Prints (1) the time to choose 6 of the candidates (sensitivities from one factorisation per Sobol'
point plus the search), and (2) for the chosen, the default and 20 random 6-gauge layouts the
linearised and the Monte-Carlo 95 % interval width per parameter (fraction of the box; log10 for
log-scaled parameters): the actual inversion (GA + polish, :func:`podkrig.online.invert`) of noisy
pseudo-data from a POD-kriging surrogate of all candidates (128 FE points), ``--mc`` realisations
at each of ``--truths`` interior truth points. Targets: chosen ≤ default and ≤ 0.5 × median random.
The machine load (os.getloadavg) is printed beside the table.
"""

import argparse
import os
import platform
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from fe import build_scenario
from podkrig.parameters import ParameterSpace
from podkrig.sensors.candidates import gauge_grid
from podkrig.sensors.criteria import SensorNoise
from podkrig.sensors.montecarlo import candidate_surrogate, interior_truths, monte_carlo
from podkrig.sensors.placement import place_sensors
from podkrig.sensors.sensitivity import candidate_sensitivities, prior_points

BOUNDS = {"E_b": (5000.0, 20000.0), "kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log"), "r_hj": (0.1, 1.0)}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k", type=int, default=6, help="sensors to choose")
    ap.add_argument("--grid", type=float, default=160.0, help="grid step, mm")
    ap.add_argument("--points", type=int, default=64, help="Sobol' points of the criterion")
    ap.add_argument("--random", type=int, default=20, help="random layouts")
    ap.add_argument("--mc", type=int, default=25, help="noise realisations per truth (0: skip the Monte Carlo)")
    ap.add_argument("--truths", type=int, default=2, help="interior truth points")
    ap.add_argument("--surrogate-points", type=int, default=128, help="FE points of the candidate surrogate")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    print(f"machine: {platform.node()} {os.cpu_count()} cores, load average at start "
          f"{', '.join(f'{v:.1f}' for v in os.getloadavg())} (shared with other jobs)")
    sc = build_scenario("diagonal_compression")
    space = ParameterSpace.from_scenario(sc, BOUNDS)
    grid = np.arange(105.0, 1065.0 + 1e-9, args.grid)
    cands = gauge_grid(sc.mesh, grid, grid, lengths=(100.0, 500.0))
    noise = SensorNoise(lvdt=0.002)
    t0, c0 = time.perf_counter(), time.process_time()
    result = place_sensors(sc, space, cands, k=args.k, noise=noise, criterion="d", n_points=args.points,
                           seed=args.seed, n_random=args.random)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"\nchoose {args.k} of {len(result.candidates)} candidates ({len(cands)} grid gauges + 6 current), "
          f"{space.n_params} free parameters, D-optimal over {args.points} Sobol' points:")
    print(f"  wall {wall:.1f} s (CPU {cpu:.1f} s): sensitivities {result.sensitivity_seconds:.1f} s "
          f"({args.points} factorisations + {space.n_params} back-substitutions each), search "
          f"{result.layout.seconds:.2f} s ({result.layout.n_evaluations} layouts; best from {result.layout.method}; "
          + ", ".join(f"{m} {v:.3f}" for m, v in result.layout.by_method.items()) + ")")
    print("  chosen: " + "; ".join(f"{n} {result.candidates.sensors[i].to_dict()['p1']}→"
                                   f"{result.candidates.sensors[i].to_dict()['p2']} ({c:.2f})"
                                   for n, i, c in zip(result.layout.names, result.layout.indices, result.contributions)))

    mc = {}
    if args.mc:
        t1 = time.perf_counter()
        sens = candidate_sensitivities(sc, space, result.candidates, prior_points(space, args.surrogate_points, args.seed + 1))
        sur = candidate_surrogate(sens)
        truths = interior_truths(space, args.truths, args.seed + 2)
        print(f"\nMonte Carlo: surrogate of {len(sens.channel_names)} candidates × {len(sens.load_levels)} loads "
              f"({args.surrogate_points} FE points, {sur.n_modes_} POD modes) in {time.perf_counter() - t1:.1f} s; "
              f"truths (unit coords) {np.round(space.to_unit(truths), 3).tolist()}")
        for n, s in enumerate(result.scores):
            t2 = time.perf_counter()
            mc[s.label] = monte_carlo(sur, sens, s.indices, noise, truths, n_realisations=args.mc, rng=args.seed + n,
                                      population_size=30, generations=20, n_starts=3)
            print(f"  {s.label:10s} MC widths {np.round(mc[s.label].width_unit, 3).tolist()} "
                  f"({time.perf_counter() - t2:.1f} s)", flush=True)

    names = space.names
    print(f"\n95 % interval width per parameter, fraction of the box (log10 for kN_bj, kV_bj); "
          f"σ = 2 µm; load average now {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    head = ["layout", "Ψ_D"] + [f"lin {n}" for n in names] + ["lin mean"]
    if mc:
        head += [f"MC {n}" for n in names] + ["MC mean"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    randoms = [s for s in result.scores if s.label.startswith("random")]

    def row(label, d, lin, m):
        cells = [label, f"{d:.2f}"] + [f"{w:.3f}" for w in lin] + [f"{np.mean(lin):.3f}"]
        if mc:
            cells += [f"{w:.3f}" for w in m] + [f"{np.mean(m):.3f}"]
        print("| " + " | ".join(cells) + " |")

    for label in ("chosen", "current"):
        s = result.score(label)
        row(label if label == "chosen" else "default (current)", s.criteria["d"], s.linearised_width,
            mc[label].width_unit if mc else None)
    lin_r = np.array([s.linearised_width for s in randoms])
    med_lin = np.median(lin_r.mean(axis=1))
    mc_r = np.array([mc[s.label].width_unit for s in randoms]) if mc else None
    row(f"random, median of {len(randoms)}", float(np.median([s.criteria["d"] for s in randoms])),
        np.median(lin_r, axis=0), np.median(mc_r, axis=0) if mc else None)
    ch, de = result.score("chosen"), result.score("current")
    print(f"\nlinearised mean width: chosen {ch.linearised_width.mean():.3f}, default {de.linearised_width.mean():.3f}, "
          f"median random {med_lin:.3f} → chosen/default {ch.linearised_width.mean() / de.linearised_width.mean():.2f}, "
          f"chosen/median random {ch.linearised_width.mean() / med_lin:.2f} (target ≤ 1 and ≤ 0.5)")
    if mc:
        med_mc = np.median(mc_r.mean(axis=1))
        c, d = mc["chosen"].mean_width_unit, mc["current"].mean_width_unit
        print(f"Monte-Carlo mean width: chosen {c:.3f}, default {d:.3f}, median random {med_mc:.3f} → "
              f"chosen/default {c / d:.2f}, chosen/median random {c / med_mc:.2f} (target ≤ 1 and ≤ 0.5)")
    print("flat-jack row (L6 vs chosen 6 vs L18): not run — needs the flat-jack scenario (another branch)")


if __name__ == "__main__":
    main()
