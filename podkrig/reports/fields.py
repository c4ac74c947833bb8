"""The deformed specimen and its displacement field, as engineers read them in a test report.

:func:`plot_deformed_field` draws two panels of one FE response at one load level:

- left, the deformed mesh: the undeformed outline (grey) and the element edges displaced by
  ``magnification`` × u, with a length scale bar (mm of the specimen) and a displacement scale
  bar (the drawn length of a stated displacement, mm, at this magnification);
- right, the displacement magnitude |u| (mm) on the deformed elements, with its colour bar.

Matplotlib is imported lazily through :func:`podkrig.reports.figures.pyplot`.
"""

import math

import numpy as np

from podkrig.reports.figures import pyplot, save


def _nice(value):
    """The largest 1, 2 or 5 × 10ⁿ not above ``value`` (> 0): a round length for a scale bar."""
    exponent = math.floor(math.log10(value))
    for m in (5, 2, 1):
        if m * 10**exponent <= value:
            return m * 10.0**exponent
    return 10.0**exponent


def auto_magnification(mesh, u, share=0.05):
    """Magnification that draws the largest nodal displacement as ``share`` of the specimen's
    larger side (-); 1 for a zero field."""
    umax = float(np.max(np.linalg.norm(u, axis=-1)))
    return share * max(mesh.width, mesh.height) / umax if umax > 0 else 1.0


def _scale_bars(ax, mesh, magnification, umax):
    """Under the specimen, two bars from its left edge, each labelled to its right: a length bar
    (mm of specimen) and a displacement bar (mm of displacement, drawn at this magnification)."""
    span = max(mesh.width, mesh.height)
    rows = [(-0.06 * span, _nice(0.25 * mesh.width), "k", None)]
    if umax > 0:
        disp = _nice(umax)
        rows.append((-0.12 * span, disp * magnification, "tab:red", disp))
    for y, drawn, colour, disp in rows:
        ax.plot([0, drawn], [y, y], color=colour, lw=2.5, solid_capstyle="butt")
        label = f"{drawn:g} mm" if disp is None else f"displacement {disp:.3g} mm (× {magnification:.3g})"
        ax.text(drawn + 0.02 * span, y, label, ha="left", va="center", fontsize=8, color=colour)
    ax.set_ylim(rows[-1][0] - 0.05 * span, mesh.height + 0.05 * span)


def plot_deformed_field(scenario, field, path, *, level=-1, magnification=None, title=None):
    """The deformed mesh (magnified, with scale bars) and the displacement magnitude (colour bar).

    Parameters
    ----------
    scenario : fe.Scenario
        Linear or flat-jack scenario whose ``mesh`` the field lives on.
    field : ndarray of shape (n_levels, n_nodes, 2)
        Nodal displacements per load level, mm (``Response.field``).
    path : str or Path
        PNG file to write.
    level : int
        Index of the load level to draw (default: the last, the highest load).
    magnification : float, optional
        Drawing scale of the displacements (-); default :func:`auto_magnification` (largest
        displacement drawn as 5 % of the specimen).
    title : str, optional
        What the field is (e.g. "FE model at the best fit").

    Returns
    -------
    path
    """
    plt = pyplot()
    from matplotlib.collections import PolyCollection  # matplotlib is imported by pyplot() above

    mesh = scenario.mesh
    u = np.asarray(field[level], float)
    if magnification is None:
        magnification = auto_magnification(mesh, u)
    corners = mesh.quads[:, :4]
    deformed = mesh.nodes[corners] + magnification * u[corners]
    magnitude = np.linalg.norm(u, axis=1)
    umax = float(magnitude.max())
    value = scenario.load_levels[level]
    load = f"step {value:g}" if scenario.load_unit == "step" else f"{value:g} {scenario.load_unit}"
    aspect = mesh.height / mesh.width
    fig, axes = plt.subplots(1, 2, figsize=(11.5, 5.2 * max(aspect, 0.5) + 1.0), layout="constrained")
    left, right = axes
    outline = [0, mesh.width, mesh.width, 0, 0], [0, 0, mesh.height, mesh.height, 0]
    left.plot(*outline, color="0.6", lw=1.0, ls="--", label="undeformed outline")
    left.add_collection(PolyCollection(deformed, facecolors="none", edgecolors="0.25", linewidths=0.25))
    left.plot([], [], color="0.25", lw=0.8, label=f"deformed, × {magnification:.3g}")
    _scale_bars(left, mesh, magnification, umax)
    left.set_xlim(-0.05 * mesh.width, 1.05 * mesh.width)
    left.set_title(f"deformed mesh × {magnification:.3g} at {load}", fontsize=10)
    left.legend(fontsize=7, loc="upper right")
    elements = PolyCollection(deformed, array=magnitude[corners].mean(axis=1), cmap="viridis", edgecolors="none")
    right.add_collection(elements)
    right.set_xlim(-0.05 * mesh.width, 1.05 * mesh.width)
    right.set_ylim(-0.05 * mesh.height, 1.05 * mesh.height)
    right.set_title(f"displacement magnitude |u| at {load} (max {umax:.3g} mm)", fontsize=10)
    fig.colorbar(elements, ax=right, label="|u| (mm)", shrink=0.85)
    for ax in axes:
        ax.set_aspect("equal")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
    if title:
        fig.suptitle(title, fontsize=11)
    save(fig, path, dpi=110)
    return path


def plot_load_readings(response, path):
    """Every gauge's reading (mm) across, load up — the convention of test reports — one line per
    sensor, for a linear test at its load levels."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    load = np.asarray(response.load_levels, float)
    for j, name in enumerate(response.sensor_names):
        ax.plot(response.readings[:, j], load, "-o", ms=3, lw=1.2, label=name)
    ax.axvline(0, color="#666", lw=0.6)
    ax.set_xlabel("reading (mm)")
    ax.set_ylabel(f"load ({response.load_unit})")
    ax.legend(fontsize=7, ncol=2 if len(response.sensor_names) > 9 else 1, loc="center left",
              bbox_to_anchor=(1.0, 0.5))
    fig.tight_layout()
    save(fig, path, dpi=120)
    return path
