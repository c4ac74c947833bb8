"""Figures and the HTML page of one simulated test (``podkrig simulate SCENARIO --report DIR``).

Drawn for any scenario, with the flat-jack specifics when the scenario has them: the specimen with
its joints, supports, slots and jacks (the loaded length shaded), FRP zones, gauges and DIC points;
the readings per step with the loading phases shaded; the deformed shape at a chosen step.
"""

import itertools
import json
from pathlib import Path

import numpy as np

from fe.mesh.mesh import INTERFACE_KINDS
from podkrig.reports.fields import plot_deformed_field, plot_load_readings
from podkrig.reports.figures import pyplot, save
from podkrig.reports.html import Page, fmt

_SLOT_COLOURS = ("#d62728", "#1f77b4", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")


def _joints(ax, mesh, colour="#bbb", lw=0.4):
    segs = []
    for kind in ("bed", "head"):
        conn = mesh.interfaces[mesh.interface_kind == INTERFACE_KINDS.index(kind)]
        segs.append(np.stack([mesh.nodes[conn[:, 0]], mesh.nodes[conn[:, 1]]], axis=1))
    from matplotlib.collections import LineCollection  # matplotlib is imported lazily via pyplot()

    ax.add_collection(LineCollection(np.concatenate(segs), colors=colour, linewidths=lw, zorder=1))
    (x0, y0), (x1, y1) = mesh.nodes.min(axis=0), mesh.nodes.max(axis=0)
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], color="#444", lw=1.0, zorder=1)


def _sensors(ax, scenario, fontsize=6):
    for s in scenario.sensors:
        if s.kind in ("gauge", "slip"):
            (x1, y1), (x2, y2) = s.p1, s.p2
            ax.plot([x1, x2], [y1, y2], "-", color="#333", lw=1.0, zorder=4)
            ax.plot([x1, x2], [y1, y2], "o", color="#333", ms=2.5, zorder=4)
            ax.annotate(s.name, (0.5 * (x1 + x2), 0.5 * (y1 + y2)), fontsize=fontsize, color="#000",
                        xytext=(2, 2), textcoords="offset points", zorder=5)
        elif s.kind == "point":
            ax.plot(*s.point, "s", color="#333", ms=3, zorder=4)
        else:  # DIC grid
            p = s.points
            ax.plot(p[:, 0], p[:, 1], ".", color="#17becf", ms=1.0, zorder=3, label=f"{s.name} ({len(p)} points)")


def _slots(ax, scenario):
    for k, s in enumerate(getattr(scenario, "slots", ())):
        c = _SLOT_COLOURS[k % len(_SLOT_COLOURS)]
        (x1, y1), (x2, y2) = s.endpoints()
        ax.plot([x1, x2], [y1, y2], "-", color=c, lw=3.5, solid_capstyle="butt", zorder=3, label=f"slot / jack {s.name}")
        lo, hi = s.jack_interval
        w = 6.0  # drawn jack thickness, mm
        if s.axis == 0:
            ax.fill_between([lo, hi], s.at - w, s.at + w, color=c, alpha=0.25, zorder=2)
        else:
            ax.fill_betweenx([lo, hi], s.at - w, s.at + w, color=c, alpha=0.25, zorder=2)
    zones = scenario.frp_zones() if hasattr(scenario, "frp_zones") else []
    for i, (x0, x1, y0, y1) in enumerate(zones):
        ax.fill([x0, x1, x1, x0], [y0, y0, y1, y1], facecolor="none", edgecolor="#8c564b", hatch="////", lw=0.8,
                zorder=2, label="FRP zone" if i == 0 else None)


def _window(scenario, margin=260.0):
    """The region of interest (mm): the slots and sensors with a margin; the whole specimen otherwise."""
    pts = [p for s in scenario.sensors for p in (s.points if hasattr(s, "points") else [])]
    for s in getattr(scenario, "slots", ()):
        pts += list(s.endpoints())
    if not pts:
        return 0, scenario.mesh.width, 0, scenario.mesh.height
    pts = np.asarray(pts, float)
    lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
    return max(lo[0], 0), min(hi[0], scenario.mesh.width), max(lo[1], 0), min(hi[1], scenario.mesh.height)


def plot_setup(scenario, path):
    """The specimen (left) and the test region (right): joints, supports, slots and jacks (loaded
    length shaded), FRP zones, gauges with their names and DIC points."""
    plt = pyplot()
    mesh = scenario.mesh
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.5), gridspec_kw={"width_ratios": [1, 1.3]})
    for ax, zoom in zip(axes, (False, True)):
        _joints(ax, mesh)
        _slots(ax, scenario)
        _sensors(ax, scenario, fontsize=7 if zoom else 4)
        sup = mesh.nodes[np.asarray(getattr(scenario, "supported_nodes", []), dtype=int)]
        ax.plot(sup[:, 0], sup[:, 1], "^", color="#555", ms=5, zorder=2)
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        if zoom:
            x0, x1, y0, y1 = _window(scenario)
            ax.set_xlim(x0, x1)
            ax.set_ylim(y0, y1)
            ax.set_title("test region")
            if ax.get_legend_handles_labels()[0]:  # slots and jacks, when the test has them
                ax.legend(fontsize=7, loc="upper right")
        else:
            (x0, y0), (x1, y1) = mesh.nodes.min(axis=0), mesh.nodes.max(axis=0)
            ax.set_xlim(x0 - 20, x1 + 20)
            ax.set_ylim(y0 - 20, y1 + 20)
            ax.set_title(f"{scenario.name}: {x1 - x0:g} × {y1 - y0:g} mm")
    fig.tight_layout()
    save(fig, path, dpi=130)
    return Path(path)


def shade_phases(ax, scenario, labels=True):
    """Shade the steps of each loading phase alternately on an axis of step numbers (x) and, with
    ``labels``, name the phase above the axes."""
    steps = getattr(scenario, "steps", None)
    if not steps:
        return
    phases = [s.phase for s in steps]
    bounds = [0] + [i for i in range(1, len(phases)) if phases[i] != phases[i - 1]] + [len(phases)]
    for k, (i, j) in enumerate(itertools.pairwise(bounds)):
        ax.axvspan(i + 0.5, j + 0.5, color=("#f2f2f2", "#dedede")[k % 2], zorder=0)
        if labels:
            ax.text(0.5 * (i + j) + 0.5, 1.0, f"phase {phases[i]}", transform=ax.get_xaxis_transform(),
                    ha="center", va="bottom", fontsize=8)


def jack_pressures(steps, load_levels):
    """The jack pressure that drives each load level of a flat-jack test, and its phase.

    The load levels of a flat-jack test are step numbers (``load_unit = "step"``); a figure of
    readings reads better against the pressure the phase raises. A phase is driven by the jacks
    whose pressure changes from step to step inside it (a one-step phase: from the step before;
    none for the cut, phase ``0b``, where every jack is at 0).

    Parameters
    ----------
    steps : sequence of fe.scenarios.flat_jack.Step
        The scenario's steps (``scenario.steps``): index, phase and gauge pressure of every jack, MPa.
    load_levels : array_like of shape (n_loads,)
        Step numbers of the levels to map (e.g. the measured ones).

    Returns
    -------
    pressure : ndarray of shape (n_loads,)
        Gauge pressure of the first driving jack of each level's phase, MPa (the largest pressure of
        the step where no jack drives the phase).
    phases : ndarray of shape (n_loads,) of str
        Each level's phase.
    labels : dict of str to str
        Per phase (in the order of the steps): ``"phase 1: p_H"``, ``"phase 2: p_V1 = p_V2"``
        (jacks raised together), ``"phase 0b: no jack raised"`` (the cut).
    """
    by_index = {s.index: k for k, s in enumerate(steps)}
    missing = [v for v in load_levels if int(round(v)) not in by_index]
    if missing:
        raise ValueError(f"load levels {missing} are not steps of this test (steps 1 to {len(steps)})")
    drivers = {}
    for k, s in enumerate(steps):
        before = steps[k - 1].pressures if k else dict.fromkeys(s.pressures, 0.0)
        same_phase = k > 0 and steps[k - 1].phase == s.phase
        alone = not same_phase and (k + 1 == len(steps) or steps[k + 1].phase != s.phase)
        jacks = drivers.setdefault(s.phase, [])
        if same_phase or alone:
            jacks += sorted(j for j in s.pressures if s.pressures[j] != before.get(j) and j not in jacks)
    labels = {}
    for phase, jacks in drivers.items():
        together = all(len({steps[k].pressures[j] for j in jacks}) == 1 for k in range(len(steps))
                       if steps[k].phase == phase)
        if not jacks:
            labels[phase] = f"phase {phase}: no jack raised"
        elif together:
            labels[phase] = f"phase {phase}: " + " = ".join(f"p_{j}" for j in jacks)
        else:
            labels[phase] = f"phase {phase}: p_{jacks[0]} (also varying: {', '.join(jacks[1:])})"
    picked = [steps[by_index[int(round(v))]] for v in load_levels]
    pressure = np.array([s.pressures[drivers[s.phase][0]] if drivers[s.phase] else max(s.pressures.values(), default=0.0)
                         for s in picked], dtype=float)
    return pressure, np.array([s.phase for s in picked]), labels


def plot_readings(scenario, response, path):
    """Readings (µm) per step, phases shaded; grids (DIC) as the median and maximum |u| per step."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(10, 5))
    shade_phases(ax, scenario)
    steps = response.load_levels
    gauge_names = [n for s in scenario.sensors if s.kind != "dic" for n in s.channel_names]
    for name in gauge_names:
        ax.plot(steps, 1000 * response.reading(name), "-o", ms=2.5, lw=1, label=name)
    for s in scenario.sensors:
        if s.kind == "dic":
            idx = [response.sensor_names.index(n) for n in s.channel_names]
            u = 1000 * response.readings[:, idx].reshape(len(steps), -1, 2)
            mag = np.linalg.norm(u, axis=2)
            ax.plot(steps, np.median(mag, axis=1), "--", color="k", lw=1.5, label=f"{s.name} median |u|")
            ax.plot(steps, mag.max(axis=1), ":", color="k", lw=1.5, label=f"{s.name} max |u|")
    ax.axhline(0, color="#666", lw=0.6)
    ax.set_xlabel(f"{response.load_unit}")
    ax.set_ylabel("reading since the pre-cut state (µm)" if getattr(scenario, "steps", None) else "reading (µm)")
    ax.legend(fontsize=7, ncol=2 if len(gauge_names) > 9 else 1, loc="center left", bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    save(fig, path, dpi=120)
    return Path(path)


def plot_deformed(scenario, response, path, step=-1, scale=None):
    """The deformed test region at one step (displacements since the pre-cut state, magnified),
    elements coloured by |u| (µm). Needs ``response.field``."""
    if response.field is None:
        raise ValueError("plot_deformed needs the displacement field: run the scenario with field=True")
    plt = pyplot()
    from matplotlib.collections import PolyCollection  # matplotlib is imported lazily via pyplot()

    mesh = scenario.mesh
    u = response.field[step]
    x0, x1, y0, y1 = _window(scenario)
    corner = mesh.quads[:, :4]
    centre = mesh.nodes[corner].mean(axis=1)
    keep = (centre[:, 0] > x0) & (centre[:, 0] < x1) & (centre[:, 1] > y0) & (centre[:, 1] < y1)
    umax = np.abs(u[corner[keep]]).max()
    if scale is None:
        scale = 0.04 * max(x1 - x0, y1 - y0) / umax if umax > 0 else 1.0
    poly = mesh.nodes[corner[keep]] + scale * u[corner[keep]]
    mag = 1000 * np.linalg.norm(u[corner[keep]], axis=2).mean(axis=1)
    fig, ax = plt.subplots(figsize=(8, 6))
    pc = PolyCollection(poly, array=mag, cmap="viridis", edgecolors="#333", linewidths=0.15)
    ax.add_collection(pc)
    fig.colorbar(pc, ax=ax, label="|u| (µm)")
    for s in getattr(scenario, "slots", ()):
        (a1, b1), (a2, b2) = s.endpoints()
        ax.plot([a1, a2], [b1, b2], "--", color="red", lw=0.8)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    label = response.load_levels[step]
    st = getattr(scenario, "steps", None)
    what = f"step {label:g} (phase {st[step].phase}, p = {st[step].pressures} MPa)" if st else f"{label:g} {response.load_unit}"
    ax.set_title(f"deformed shape × {scale:.0f}: {what}", fontsize=9)
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    fig.tight_layout()
    save(fig, path, dpi=130)
    return Path(path)


def write_simulation_report(scenario, response, values, out_dir, *, seconds=None):
    """Write the figures and ``out_dir/index.html`` for one simulated test; returns the page path.

    ``response`` must carry the field (``run(..., field=True)``); ``values`` are the parameter values.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    steps = getattr(scenario, "steps", None)
    drawn = "joints, supports, slots and jacks (loaded length shaded), sensors" if getattr(scenario, "slots", ()) \
        else "joints, supports and sensors"
    figures = [(f"The specimen: {drawn}; right the test region enlarged.", plot_setup(scenario, out / "setup.png"))]
    if steps:
        figures.append(("Readings per step.", plot_readings(scenario, response, out / "readings.png")))
        phases = [s.phase for s in steps]
        for i in sorted({len(phases) - 1 - phases[::-1].index(p) for p in dict.fromkeys(phases)}):
            name = f"deformed_step{int(response.load_levels[i])}.png"
            figures.append((f"Deformed shape at the last step of phase {phases[i]}.",
                            plot_deformed(scenario, response, out / name, step=i)))
    else:  # a linear test at load levels: readings with load up, the whole specimen deformed
        figures.append(("Readings (mm) across, load up, one line per sensor.",
                        plot_load_readings(response, out / "readings.png")))
        figures.append((("At the highest load: left the deformed mesh (magnified, with a length and a "
                         "displacement scale bar), right the displacement magnitude |u| (mm)."),
                        plot_deformed_field(scenario, response.field, out / "deformed.png")))
    page = Page(f"podkrig simulate {scenario.name}")
    page.paragraph(f"{scenario.n_dofs} dofs" + (f", {seconds:.3f} s" if seconds is not None else "") + "; readings in mm"
                   + (", since the pre-cut state (gauges zeroed before the cut)." if steps else "."))
    page.table(["parameter", "value", "unit"], [[k, fmt(v), scenario.parameters[k].unit] for k, v in values.items()])
    if steps:
        names = [s.name for s in scenario.slots]
        page.table(["step", "phase"] + [f"p_{n} (MPa)" for n in names],
                   [[s.index, s.phase] + [fmt(s.pressures[n]) for n in names] for s in steps], caption="loading steps (gauge pressures)")
    gauge_names = [n for s in scenario.sensors if s.kind != "dic" for n in s.channel_names]
    if gauge_names:
        page.table([response.load_unit] + gauge_names,
                   [[fmt(level)] + [f"{1000 * response.reading(n)[k]:+.2f}" for n in gauge_names] for k, level in enumerate(response.load_levels)],
                   caption="gauge readings (µm)")
    if steps and "3" in phases and hasattr(scenario, "phase3_check"):
        _phase3_table(page, scenario, values)
    for caption, path in figures:
        page.figure(Path(path).name, caption)
    page.details("scenario spec (JSON)", json.dumps(scenario.spec.to_dict(), indent=2))
    return page.write(out / "index.html")


def _phase3_table(page, scenario, values, c=0.25, tan_phi=0.70):
    """Phase 3, elastic: the block's top bed joint against the statics of the jack-loaded block
    (:func:`podkrig.analytical.flat_jack.sliding_pressure_difference`)."""
    try:
        chk = scenario.phase3_check(values, c=c, tan_phi=tan_phi)
    except ValueError as e:  # not the three-jack set-up
        page.paragraph(f"phase 3 check not available: {e}", "meta")
        return
    ph3 = chk.phase == "3"
    page.paragraph(
        "Phase 3 runs elastic here (sliding needs the nonlinear interfaces). The mean stresses on the "
        "block's top bed joint equal the statics by equilibrium; local Mohr–Coulomb exceedance "
        f"(c = {c:g} MPa, tanφ = {tan_phi:g}, the scenario's defaults) marks where progressive slip would start; "
        "the statics estimate of the critical gauge Δp_V is (L_H/h_V)(c + Km p_H tanφ)/Km.")
    page.table(["step", "Δp_V (MPa)", "mean τ FE (MPa)", "statics τ (MPa)", "peak τ (MPa)", "mean σ_n FE (MPa)",
                "statics σ_n (MPa)", "local slip", "statics Δp_V,crit (MPa)"],
               [[int(chk.steps[i]), fmt(chk.delta_p_V[i]), fmt(chk.mean_shear[i]), fmt(chk.statics_shear[i]),
                 fmt(chk.peak_shear[i]), fmt(chk.mean_normal[i]), fmt(chk.statics_normal[i]),
                 "yes" if chk.local_slip[i] else "no", fmt(chk.delta_p_V_crit[i])] for i in np.flatnonzero(ph3)],
               caption="phase 3 (elastic) vs statics")
