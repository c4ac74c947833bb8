"""Optimal sensor placement benchmark: the diagonal compression test (issue 16).

Usage::

    python scripts/bench_sensors.py                           # the full run (~15 min on 2 cores)
    python scripts/bench_sensors.py --mc 5 --random 5         # a quick look
    python scripts/bench_sensors.py --scenario flat_jack --mc 10   # the flat-jack test (~20 min on 2 cores; --mc 0: ~2 min)

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

Flat jack (``--scenario flat_jack``): the chisari preset with phases 0b, 1, 2 (20 steps), free
E_b, kN_bj (log), kV_bj (log), r_hj, Km over the box of ``examples/flat_jack.toml`` (σ0 = 0.30 MPa
fixed, as in that study). The jack loads scale with Km, which the scenario's frozen
``load_coefficients`` (the affine path of :func:`podkrig.sensors.sensitivity.candidate_sensitivities`)
cannot represent, so the sensitivities come from central differences of the FE model itself
(``place_sensors(..., model=FEModel)`` over a spec listing every candidate as a sensor; one
factorisation per run). Candidates: gauges between the points of a 65 mm grid round the jacks
(x 682.5…1397.5, y 617.5…1137.5 mm: unit interiors, ≥ 32.5 mm from every slot and joint), 130–390 mm
long along 0°, 45°, 90°, 135° (gauges may straddle a slot, as the L6 gauges do), plus the twelve L18
gauges beyond L6 and the six L6 gauges (the current layout). Compared: chosen 6, L6, L18 and 20 random
6-gauge layouts, by Ψ_D and the linearised 95 % widths (and, with ``--mc``, the Monte Carlo on a surrogate of all candidates).
"""

import argparse
import os
import platform
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

from fe import build_scenario
from fe.scenarios.flat_jack import L18_EXTRA
from podkrig.online.problem import FEModel
from podkrig.parameters import ParameterSpace
from podkrig.sensors.candidates import current_candidates, gauge_grid, user_candidates
from podkrig.sensors.criteria import (
    UNIFORM_PRIOR_INFORMATION,
    LayoutCriterion,
    SensorNoise,
    fisher_per_candidate,
)
from podkrig.sensors.montecarlo import candidate_surrogate, interior_truths, monte_carlo
from podkrig.sensors.placement import place_sensors
from podkrig.sensors.sensitivity import candidate_sensitivities, model_sensitivities, prior_points
from podkrig.sensors.settings import ComparisonSettings, PlacementSettings, SearchSettings

BOUNDS = {"E_b": (5000.0, 20000.0), "kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log"), "r_hj": (0.1, 1.0)}
FJ_BOUNDS = {"E_b": (5000.0, 16000.0), "kN_bj": (20.0, 200.0, "log"), "kV_bj": (10.0, 100.0, "log"),
             "r_hj": (0.2, 1.0), "Km": (0.75, 0.95)}  # examples/flat_jack.toml
FJ_SPEC = {"scenario": "flat_jack", "preset": "chisari", "phases": ["0b", "1", "2"]}  # σ0 keeps its default 0.30 MPa


class _CachedModel:
    """A batched model that remembers its rows (the criterion's points are differenced twice: once
    here for the L18 score, once inside ``place_sensors``)."""

    def __init__(self, model):
        self.model, self.cache = model, {}
        self.space, self.sensor_names = model.space, model.sensor_names
        self.load_levels, self.load_unit = model.load_levels, model.load_unit

    def predict(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        missing = [x for x in X if x.tobytes() not in self.cache]
        if missing:
            for x, y in zip(missing, self.model.predict(np.array(missing))):
                self.cache[x.tobytes()] = y
        return np.stack([self.cache[x.tobytes()] for x in X])


def _settings(args):
    """D-optimal placement of ``--k`` sensors over ``--points`` Sobol' points, ``--random`` random
    layouts compared, ``--seed``."""
    return PlacementSettings(search=SearchSettings(k=args.k, criterion="d", n_points=args.points),
                             comparison=ComparisonSettings(n_random=args.random), seed=args.seed)


def flat_jack(args):
    """L6 vs the chosen 6 vs L18 vs random 6-gauge layouts on the chisari flat-jack test."""
    spec = {**FJ_SPEC, "layout": "L6"}
    sc = build_scenario(spec)
    space = ParameterSpace.from_scenario(sc, FJ_BOUNDS)
    grid = gauge_grid(sc.mesh, np.arange(682.5, 1397.5 + 1e-9, 65.0), np.arange(617.5, 1137.5 + 1e-9, 65.0),
                      lengths=(130.0, 390.0), prefix="C")
    extra = user_candidates(sc.mesh, {g.name: g.to_dict() for g in L18_EXTRA})
    cands = grid + extra
    full = cands + current_candidates(sc)  # the order place_sensors uses
    model_spec = {**FJ_SPEC, "layout": "none", "sensors": {s.name: s.to_dict() for s in full.sensors}}
    model = _CachedModel(FEModel(build_scenario(model_spec), space))
    noise = SensorNoise(lvdt=0.002)
    t0 = time.perf_counter()
    X = prior_points(space, args.points, args.seed)
    sens = model_sensitivities(model, full, X)
    t_sens = time.perf_counter() - t0
    result = place_sensors(sc, space, cands, _settings(args), noise=noise, model=model)
    wall = time.perf_counter() - t0
    assert result.candidates.names == full.names
    crit = LayoutCriterion(fisher_per_candidate(sens, noise), "d", UNIFORM_PRIOR_INFORMATION)
    l18 = full.index([g.name for g in L18_EXTRA] + [s.name for s in sc.sensors])
    print(f"\nflat jack (chisari, phases 0b-2, {len(sc.load_levels)} steps, σ0 = {sc.resolve()['sigma0']} MPa fixed): "
          f"choose {args.k} of {len(full)} candidates ({len(grid)} grid gauges + 12 L18 extras + 6 L6), "
          f"{space.n_params} free parameters, D-optimal over {args.points} Sobol' points")
    print(f"  wall {wall:.1f} s: FE sensitivities {t_sens:.1f} s ({model.model.n_runs} FE runs, central differences), "
          f"search {result.layout.seconds:.2f} s (best from {result.layout.method})")
    print("  chosen: " + "; ".join(f"{n} {full.sensors[i].to_dict()}" f" ({c:.2f})"
                                   for n, i, c in zip(result.layout.names, result.layout.indices, result.contributions)))
    layouts = {"chosen": result.score("chosen").indices, "L6 (current)": result.score("current").indices, "L18": l18}
    randoms = [s for s in result.scores if s.label.startswith("random")]
    layouts.update({s.label: s.indices for s in randoms})
    mc = {}
    if args.mc:
        t1 = time.perf_counter()
        mc_sens = model_sensitivities(model, full, prior_points(space, args.surrogate_points, args.seed + 1))
        sur = candidate_surrogate(mc_sens)
        truths = interior_truths(space, args.truths, args.seed + 2)
        print(f"\nMonte Carlo: surrogate of {len(full)} candidates × {len(sc.load_levels)} steps ({args.surrogate_points} "
              f"FE points, {sur.n_modes_} POD modes) in {time.perf_counter() - t1:.1f} s; truths (unit coords) "
              f"{np.round(space.to_unit(truths), 3).tolist()}")
        for n, (label, L) in enumerate(layouts.items()):
            t2 = time.perf_counter()
            mc[label] = monte_carlo(sur, mc_sens, L, noise, truths, n_realisations=args.mc, rng=args.seed + n,
                                    population_size=30, generations=20, n_starts=3).width_unit
            print(f"  {label:14s} MC widths {np.round(mc[label], 3).tolist()} ({time.perf_counter() - t2:.1f} s)",
                  flush=True)

    names = space.names
    print(f"\n95 % interval width per parameter, fraction of the box (log10 for kN_bj, kV_bj); "
          f"σ = 2 µm; load average now {', '.join(f'{v:.1f}' for v in os.getloadavg())}")
    head = ["layout", "gauges", "Ψ_D"] + [f"lin {n}" for n in names] + ["lin mean"]
    if mc:
        head += [f"MC {n}" for n in names] + ["MC mean"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))

    def row(label, n, d, lin, m):
        cells = [label, str(n), f"{d:.2f}"] + [f"{w:.3f}" for w in lin] + [f"{np.mean(lin):.3f}"]
        if mc:
            cells += [f"{w:.3f}" for w in m] + [f"{np.mean(m):.3f}"]
        print("| " + " | ".join(cells) + " |")

    lin = {label: crit.linearised_widths(L[None])[0] for label, L in layouts.items()}
    for label in ("chosen", "L6 (current)", "L18"):
        L = layouts[label]
        row(label, len(L), float(crit.value(L[None])[0]), lin[label], mc.get(label))
    lin_r = np.array([lin[s.label] for s in randoms])
    mc_r = np.array([mc[s.label] for s in randoms]) if mc else None
    row(f"random, median of {len(randoms)} (per column)", args.k, float(np.median([s.criteria["d"] for s in randoms])),
        np.median(lin_r, axis=0), np.median(mc_r, axis=0) if mc else None)
    med = np.median(lin_r.mean(axis=1))
    c, l6m, l18m = (lin[k].mean() for k in ("chosen", "L6 (current)", "L18"))
    print(f"\nlinearised mean width: chosen {c:.3f}, L6 {l6m:.3f}, L18 {l18m:.3f}, median random {med:.3f} → "
          f"chosen/L6 {c / l6m:.2f}, chosen/median random {c / med:.2f}")
    if mc:
        medm = np.median(mc_r.mean(axis=1))
        c, l6m, l18m = (mc[k].mean() for k in ("chosen", "L6 (current)", "L18"))
        print(f"Monte-Carlo mean width: chosen {c:.3f}, L6 {l6m:.3f}, L18 {l18m:.3f}, median random {medm:.3f} → "
              f"chosen/L6 {c / l6m:.2f}, chosen/median random {c / medm:.2f}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", choices=("diagonal", "flat_jack"), default="diagonal")
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
    if args.scenario == "flat_jack":
        return flat_jack(args)
    sc = build_scenario("diagonal_compression")
    space = ParameterSpace.from_scenario(sc, BOUNDS)
    grid = np.arange(105.0, 1065.0 + 1e-9, args.grid)
    cands = gauge_grid(sc.mesh, grid, grid, lengths=(100.0, 500.0))
    noise = SensorNoise(lvdt=0.002)
    t0, c0 = time.perf_counter(), time.process_time()
    result = place_sensors(sc, space, cands, _settings(args), noise=noise)
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


if __name__ == "__main__":
    main()
