"""Figures and tables of a sensor placement (reads a :class:`~podkrig.sensors.placement.PlacementResult`)."""

import numpy as np

from podkrig.reports.figures import pyplot, save


def plot_layout(result, path, *, show_candidates=True):
    """The specimen (units outlined) with the candidates (faint), forbidden zones (hatched),
    the current layout (dashed) and the chosen layout coloured by each sensor's contribution
    (loss increase when removed)."""
    plt = pyplot()
    from matplotlib import cm, colors

    spec = result.specimen
    W, H = spec["width"], spec["height"]
    fig, ax = plt.subplots(figsize=(7.5, 7.5 * H / W + 0.6))
    for x0, y0, x1, y1 in spec["blocks"]:
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, lw=0.4, ec="0.7"))
    for z in result.zones:
        ax.add_patch(plt.Rectangle((z.x0, z.y0), z.x1 - z.x0, z.y1 - z.y0, fill=False, hatch="///", ec="tab:red", lw=0.8))
    cands = result.candidates
    if show_candidates:
        for s in cands.sensors:
            pts = s.points
            if len(pts) == 2:
                ax.plot(pts[:, 0], pts[:, 1], "-", color="0.85", lw=0.5, zorder=1)
            else:
                ax.plot(pts[:, 0], pts[:, 1], ".", color="0.8", ms=2, zorder=1)
    for i in np.flatnonzero(cands.is_current):
        pts = cands.sensors[i].points
        ax.plot(pts[:, 0], pts[:, 1], "--", color="k", lw=1.2, zorder=2)
        ax.annotate(cands.names[i], pts.mean(axis=0), fontsize=7, color="k", xytext=(3, -9), textcoords="offset points")
    contrib = np.maximum(np.asarray(result.contributions, float), 0.0)
    norm = colors.Normalize(0.0, contrib.max() if contrib.max() > 0 else 1.0)
    cmap = cm.get_cmap("viridis") if hasattr(cm, "get_cmap") else plt.colormaps["viridis"]
    for c, i in zip(contrib, result.layout.indices):
        pts = cands.sensors[i].points
        col = cmap(norm(c))
        if len(pts) == 2:
            ax.plot(pts[:, 0], pts[:, 1], "-o", color=col, lw=3, ms=4, zorder=3)
        else:
            ax.plot(pts[:, 0], pts[:, 1], "s", color=col, ms=7, zorder=3)
        where = pts[0] + 0.3 * (pts[-1] - pts[0])  # off the centre, where crossing gauges overlap
        ax.annotate(cands.names[i], where, fontsize=8, color="tab:red", xytext=(3, 3), textcoords="offset points")
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.8, label=f"contribution: loss increase without the sensor ({result.criterion.upper()})")
    ax.set_xlim(-0.02 * W, 1.02 * W)
    ax.set_ylim(-0.02 * H, 1.02 * H)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{result.base_spec.scenario}: chosen {len(result.layout.indices)} sensors (solid, coloured), "
                 "current (dashed)", fontsize=9)
    fig.tight_layout()
    save(fig, path, dpi=120)
    return path


def comparison_rows(result):
    """Rows of the comparison table: chosen, current, random median (and each random layout's
    numbers are summarised by their median). Each row: label, Ψ_D, Ψ_A, Ψ_E, Ψ_POD, linearised
    widths (unit coordinates), Monte-Carlo widths (unit coordinates, or None)."""
    rows = []
    randoms = [s for s in result.scores if s.label.startswith("random")]
    for s in result.scores:
        if s.label.startswith("random"):
            continue
        mc = None if s.monte_carlo is None else s.monte_carlo.width_unit
        rows.append((s.label, s.criteria, s.linearised_width, mc))
    if randoms:
        crit = {k: float(np.median([s.criteria[k] for s in randoms])) for k in randoms[0].criteria}
        lin = np.median([s.linearised_width for s in randoms], axis=0)
        mcs = [s.monte_carlo.width_unit for s in randoms if s.monte_carlo is not None]
        rows.append((f"random (median of {len(randoms)})", crit, lin, np.median(mcs, axis=0) if mcs else None))
    return rows


def comparison_markdown(result):
    """The comparison table as Markdown (widths: 95 % interval, fraction of the box; log10 for
    log-scaled parameters)."""
    names = result.space.names
    head = ["layout", "Ψ_D", "Ψ_A", "Ψ_E", "Ψ_POD"] + [f"lin. 95 % width {n}" for n in names] + ["mean lin."]
    has_mc = any(s.monte_carlo is not None for s in result.scores)
    if has_mc:
        head += [f"MC 95 % width {n}" for n in names] + ["mean MC"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for label, crit, lin, mc in comparison_rows(result):
        cells = [label] + [f"{crit[k]:.4g}" for k in ("d", "a", "e", "pod")] + [f"{w:.3f}" for w in lin] + [f"{lin.mean():.3f}"]
        if has_mc:
            cells += ([f"{w:.3f}" for w in mc] + [f"{mc.mean():.3f}"]) if mc is not None else ["–"] * (len(names) + 1)
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
