"""The verification ladder of the flat-jack scenario (docs/benchmarks/flat-jack.md).

Prints Markdown tables for BENCHMARKS.md:

1. homogeneous limit (stiff joints) of a single pressurised slot against Jaeger–Cook, for
   panels 10× and 20× the slot length and three meshes, with the Richardson extrapolation
   (first-order convergence, the slot-tip singularity);
2. the finite-panel trend: the same slot in panels 4×, 6×, 10× and 20× the slot length;
3. the double slot: apparent modulus p/ε of a vertical gauge between two jacks, FE vs the DDM of
   the same geometry (infinite plate), at x0 = 0 and 100 mm off the centre line;
4. phase 3: the statics estimate of the critical Δp_V against the elastic onset of local slip.

Usage: nice python scripts/verify_flat_jack.py [--quick]   (prints the machine load beside the tables)
"""

import argparse
import os
import time

import numpy as np

from fe.scenarios import build_scenario
from fe.scenarios.flat_jack import homogeneous_slot_spec
from podkrig.analytical.flat_jack import (
    Slot,
    elliptical_hole_field,
    sliding_pressure_difference,
    solve_slots,
)

E, NU = 4000.0, 0.2
OFFSETS = (32.5, 97.5, 162.5, 292.5)


def jaeger_cook(a, offsets, x=1.0):
    y = np.asarray(offsets)
    f = elliptical_hole_field(np.full(2 * len(y), x), np.r_[-y, y], a, 0.0, p=1.0, E=E, nu=NU)
    return f.uy[len(y):] - f.uy[: len(y)]


def single(size, nx, ny, slot=260.0):
    t0 = time.perf_counter()
    sc = build_scenario(homogeneous_slot_spec(size, nx, ny, slot, gauge_offsets=OFFSETS))
    r = sc.run().readings[0]
    return r, sc.n_dofs, time.perf_counter() - t0


def ladder_homogeneous(sizes, meshes):
    exact = jaeger_cook(130.0, OFFSETS)
    print("\n**Single slot, stiff joints, vs Jaeger–Cook** (2a = 260 mm, E = 4000 MPa, ν = 0.2; error % of the pin-distance change)\n")
    print("| panel / slot length | Q8 per unit (×2 near the slot) | h near slot | DOFs | " + " | ".join(f"y = ±{y:g}" for y in OFFSETS) + " | s |")
    print("|---|---|---|---|" + "---|" * len(OFFSETS) + "---|")
    results = {}
    for size in sizes:
        errs = []
        for nx, ny in meshes:
            r, n, dt = single(size, nx, ny)
            e = (r / exact - 1) * 100
            errs.append(e)
            results[(size, nx)] = r
            print(f"| {size}× | {nx}×{ny} | a/{130 / (260 / nx / 2):g} | {n} | " + " | ".join(f"{v:+.2f}" for v in e) + f" | {dt:.1f} |", flush=True)
        if len(errs) >= 2:
            rich = errs[-1] + (errs[-1] - errs[-2])  # first order: e(h) = e∞ + C h
            print(f"| {size}× | Richardson (last two) | → 0 | | " + " | ".join(f"{v:+.2f}" for v in rich) + " | |")
    return results


def finite_panel(sizes, mesh):
    exact = jaeger_cook(130.0, OFFSETS)
    ref, _, _ = single(20, *mesh)
    print(f"\n**Finite-panel trend** (Q8 {mesh[0]}×{mesh[1]}; bottom edge supported, other edges free): FE/JC − 1 and FE(size)/FE(20×) − 1, %\n")
    print("| panel / slot length | " + " | ".join(f"y = ±{y:g} vs JC" for y in OFFSETS) + " | " + " | ".join(f"±{y:g} vs 20×" for y in OFFSETS) + " |")
    print("|---|" + "---|" * (2 * len(OFFSETS)))
    for size in sizes:
        r, _, _ = single(size, *mesh)
        print(f"| {size}× | " + " | ".join(f"{v:+.1f}" for v in (r / exact - 1) * 100) + " | "
              + " | ".join(f"{v:+.1f}" for v in (r / ref - 1) * 100) + " |", flush=True)


def double_slot(size, mesh, spacing=390.0, length=350.0):
    print(f"\n**Double slot** (L = {length:g} mm, s = {spacing:g} mm, gauge length 195 mm centred between the jacks; panel {size}× L, Q8 {mesh[0]}×{mesh[1]}): E_app/E = p/(ε E)\n")
    print("| x0 (mm) | FE | DDM (infinite plate, 80 elements per slot) | FE/DDM − 1 |")
    print("|---|---|---|---|")
    ddm = solve_slots([Slot((0, -spacing / 2), length, 0, 1.0), Slot((0, spacing / 2), length, 0, 1.0)], E, NU, 80)
    for x0 in (0.0, 100.0):
        spec = homogeneous_slot_spec(size * length / 260.0, *mesh, slot_length=length, spacing=spacing, gauge_offsets=(97.5,), x0=x0)
        fe_r = build_scenario(spec).run().readings[0, 0]
        f = ddm.field(np.array([x0 + 1, x0 + 1]), np.array([-97.5, 97.5]))
        d = f.uy[1] - f.uy[0]
        fe_app, ddm_app = 195.0 / (-fe_r) / E, 195.0 / (-d) / E
        print(f"| {x0:g} | {fe_app:.3f} | {ddm_app:.3f} | {100 * (fe_app / ddm_app - 1):+.1f} % |", flush=True)


def phase3():
    print("\n**Phase 3 (elastic) vs statics** (chisari preset, defaults, Km = 0.85, c = 0.25 MPa, tanφ = 0.7): critical gauge Δp_V (MPa)\n")
    print("| p_H (MPa) | statics (L_H/h_V)(c + Km p_H tanφ)/Km | elastic onset of local slip (first step) | peak / mean shear at onset |")
    print("|---|---|---|---|")
    for pH in (0.5, 1.0, 1.5):
        steps = [{"H": p, "V1": 0.05, "V2": 0.05} for p in np.linspace(pH / 5, pH, 5)]
        steps += [{"V1": 0.5, "V2": 0.5}] + [{"V1": 0.5 + d} for d in np.arange(0.05, 4.0, 0.05)]
        sc = build_scenario({"scenario": "flat_jack", "schedule": [{"name": "0b", "steps": [{}]}, {"name": "1", "steps": steps[:6]},
                                                                  {"name": "3", "steps": steps[6:]}]})
        chk = sc.phase3_check(c=0.25, tan_phi=0.7)
        ph3 = chk.phase == "3"
        i = np.argmax(chk.local_slip[ph3])
        crit = sliding_pressure_difference(0.25, 0.7, 0.85 * pH, 390.0, 195.0) / 0.85
        print(f"| {pH:g} | {crit:.2f} | {chk.delta_p_V[ph3][i]:.2f} | {chk.peak_shear[ph3][i] / chk.mean_shear[ph3][i]:.2f} |", flush=True)


def section7():
    """Reference §7 items 1, 2 and 7 measured on the §5 set-up."""
    from fe.scenarios.flat_jack import CHISARI_SLOTS, L6, L18_EXTRA
    from podkrig.analytical.flat_jack import homogenised_moduli

    base = {"scenario": "flat_jack", "phases": ["1"], "schedule": [{"name": "1", "steps": [{"H": 1.0}]}]}
    unit = {"Km": 1.0, "sigma0": 0.0}
    small = build_scenario(base).run(unit)
    # item 1: the same test centred in a panel twice as wide and high (shift by 4 units, 12 courses)
    dx, dy = 1040.0, 780.0
    slots = [{**s, "at": s["at"] + (dy if s["orientation"] == "horizontal" else dx),
              "start": s["start"] + (dx if s["orientation"] == "horizontal" else dy),
              "end": s["end"] + (dx if s["orientation"] == "horizontal" else dy)} for s in CHISARI_SLOTS]
    sensors = {g.name: {**g.to_dict(), "p1": [g.p1[0] + dx, g.p1[1] + dy], "p2": [g.p2[0] + dx, g.p2[1] + dy]}
               for g in L6 + L18_EXTRA}
    big = build_scenario({**base, "units_per_course": 16.0, "n_courses": 48, "slots": slots, "layout": "none",
                          "sensors": sensors, "refine": [650 + dx, 1430 + dx, 585 + dy, 1170 + dy]}).run(unit)
    print("\n**§7 item 1: panel size** (p_H = 1 MPa alone, Km = 1, defaults): §5 panel 2080 × 1560 vs the same test "
          "centred in 4160 × 3120 mm; and §7 item 2: the FE vs the homogeneous DDM of §5.8 (E = 4000 MPa)\n")
    ref58 = {"G1": 191.3, "G2": 191.3, "G3": -20.3, "G6": 16.8, "G7": 184.2, "G9": -30.2, "G10": -32.1, "G15": 2.1, "G18": -36.4}
    print("| gauge | §5 panel (µm) | 2× panel (µm) | §5 / 2× − 1 | §5.8 homogeneous (µm) |")
    print("|---|---|---|---|---|")
    for g in ("G1", "G7", "G3", "G6", "G9", "G10", "G15", "G18"):
        a, b = 1000 * small.reading(g)[0], 1000 * big.reading(g)[0]
        print(f"| {g} | {a:+.1f} | {b:+.1f} | {100 * (a / b - 1):+.1f} % | {ref58.get(g, float('nan')):+.1f} |")
    Ex, Ey, G = homogenised_moduli(10000.0, 0.15, 80.0, 35.0, 0.6, 65.0, 260.0)
    print(f"\nhomogenised moduli at the §5.2 defaults (§2.5): E_x ≥ {Ex:.0f}, E_y = {Ey:.0f}, G = {G:.0f} MPa "
          f"(§5.8 used E = 4000: signals × 4000/E_y = {4000 / Ey:.2f})")
    # item 7: slot closure at the cut (σ0 = 0.30) against a 3–4 mm slot
    sc = build_scenario({"scenario": "flat_jack", "phases": ["0b"]})
    u = sc.run({"sigma0": 0.3}, field=True).field[0]
    closure = 0.0
    for name, idx in sc.slot_interfaces.items():
        conn = sc.mesh.interfaces[idx]
        half = conn.shape[1] // 2
        n = sc._normal(next(s for s in sc.slots if s.name == name))
        jump = (u[conn[:, half:]] - u[conn[:, :half]]) @ n
        closure = max(closure, -jump.min())
    print(f"\n§7 item 7: largest slot closure at the cut under σ0 = 0.30 MPa: {1000 * closure:.0f} µm (a 3–10 mm slot never closes; "
          "contact is not needed in the elastic range)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="10× panels and two meshes only")
    args = ap.parse_args()
    t0 = time.perf_counter()
    print(f"machine load (1, 5, 15 min): {os.getloadavg()}; cores: {os.cpu_count()}")
    section7()
    phase3()
    if args.quick:
        ladder_homogeneous((10,), ((2, 1), (4, 2)))
        double_slot(10, (4, 2))
        finite_panel((4, 6, 10), (4, 2))
    else:
        ladder_homogeneous((10, 20), ((2, 1), (4, 2), (8, 4)))
        double_slot(10, (8, 4))
        finite_panel((4, 6, 10), (4, 2))
    print(f"\ntotal {time.perf_counter() - t0:.0f} s; machine load after: {os.getloadavg()}")


if __name__ == "__main__":
    main()
