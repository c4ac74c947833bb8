"""Draw the picture of docs/architecture.md: the stages, what passes between them, and the layers.

Usage: python scripts/architecture_diagram.py [--out docs/architecture.svg]

Left: the stages of a study from the study file to the report, with the files and objects each
hands on, and the FE solver they call. Right: the import layers (a module imports only from its
own layer or below), read from the import-linter contract in pyproject.toml. Text stays text in the
SVG (small, searchable).
"""

import argparse
import tomllib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]

#: (stage, what it does, what it hands on)
STAGES = [
    ("study file", "TOML: test, parameters, designs,\nsurrogate, measurement, inversion", "load_study → Study"),
    ("offline", "designs, FE runner (serial / Dask),\ncrash-safe HDF5 snapshot store", "train.h5, held_out.h5"),
    ("surrogate", "POD + ordinary kriging,\nheld-out check", "surrogate.h5"),
    ("online", "measurement and noise, misfit, GA inversion,\nFE check, region, RVC, posterior", "parameters, region, χ²/dof"),
    ("diagnosis", "candidate causes,\nextended model fits", "verdict, causes"),
    ("report", "one page per study, figures;\nsummary.json for scripts", "report/index.html"),
]

#: the layers that make words, pictures and files for people (drawn apart from the numerics)
FRONT_DOORS = {"cli", "study", "reports"}


def layers(pyproject=ROOT / "pyproject.toml"):
    """The import layers of ``podkrig``, top to bottom, read from the import-linter contract.

    Returns
    -------
    list of str
        E.g. ``["cli", "study", ..., "exceptions | parallel | _qmc | config"]``.
    """
    config = tomllib.loads(Path(pyproject).read_text(encoding="utf-8"))
    for contract in config["tool"]["importlinter"]["contracts"]:
        if contract["type"] == "layers" and contract.get("containers") == ["podkrig"]:
            return list(contract["layers"])
    raise LookupError(f"{pyproject}: no layers contract for podkrig")


def box(ax, x, y, w, h, text, *, face, size=9, weight="normal"):
    ax.add_patch(FancyBboxPatch((x, y), w, h, boxstyle="round,pad=0.02,rounding_size=0.08",
                                facecolor=face, edgecolor="#333333", linewidth=0.8))
    ax.text(x + w / 2, y + h / 2, text, ha="center", va="center", fontsize=size, weight=weight)


def arrow(ax, x0, y0, x1, y1, text=None):
    ax.add_patch(FancyArrowPatch((x0, y0), (x1, y1), arrowstyle="-|>", mutation_scale=10,
                                 color="#333333", linewidth=0.8))
    if text:
        ax.text(x0 + 0.1, (y0 + y1) / 2, text, ha="left", va="center", fontsize=7.5, style="italic",
                color="#444444")


def draw(out):
    """Draw the picture into ``out`` (SVG, or any format matplotlib knows by the suffix).

    Parameters
    ----------
    out : str or Path

    Returns
    -------
    Path
    """
    plt.rcParams["svg.fonttype"] = "none"
    fig, ax = plt.subplots(figsize=(11, 7.2))
    ax.set_xlim(0, 11)
    ax.set_ylim(0, 7.2)
    ax.axis("off")

    # the stages, top to bottom
    ax.text(0.2, 7.0, "Stages of a study (podkrig run)", fontsize=11, weight="bold")
    h, gap, top = 0.62, 0.36, 6.55
    for i, (name, what, hands) in enumerate(STAGES):
        y = top - i * (h + gap) - h
        box(ax, 0.2, y, 1.5, h, name, face="#dbe9f6", weight="bold")
        box(ax, 1.85, y, 3.4, h, what, face="#f5f5f5", size=8)
        if i < len(STAGES) - 1:
            arrow(ax, 0.95, y, 0.95, y - gap, hands)
    ax.text(0.2, 0.55, "Each stage is cached: out/stages/STAGE.json holds its input hash, the SHA-256\n"
            "of its files and its results; a rerun with nothing changed does no FE work.",
            fontsize=7.5, va="center")

    # the FE solver, called by offline, online (FE check) and diagnosis
    box(ax, 5.55, 3.0, 1.3, 2.3, "fe/\nFE solver\n\nscenarios,\nK(m) = Σ θ_q K_q", face="#fde9d9", size=8)
    for i in (1, 3, 4):
        y = top - i * (h + gap) - h / 2
        ax.add_patch(FancyArrowPatch((5.25, y), (5.55, min(max(y, 3.1), 5.2)), arrowstyle="-|>",
                                     mutation_scale=9, color="#aa5500", linewidth=0.8))
    ax.text(6.2, 2.8, "FE runs", ha="center", fontsize=7.5, style="italic", color="#aa5500")

    # the layers
    ax.text(7.3, 7.0, "Import layers (podkrig/)", fontsize=11, weight="bold")
    stack = layers()
    lh = min(0.5, 5.9 / len(stack) - 0.06)
    for i, name in enumerate(stack):
        y = 6.55 - (i + 1) * (lh + 0.06)
        front = FRONT_DOORS & {part.strip() for part in name.split("|")}
        box(ax, 7.3, y, 3.4, lh, name, face="#fff2cc" if front else "#e2f0d9", size=8.5)
    ax.text(7.3, 0.55, "A module imports only from its own layer or below; fe/ never imports\n"
            "podkrig; the numerics never import the front doors (yellow: cli, study,\n"
            "reports), matplotlib, typer or rich.", fontsize=7.5, va="center")
    arrow_x = 10.85
    ax.add_patch(FancyArrowPatch((arrow_x, 6.4), (arrow_x, 0.95), arrowstyle="-|>", mutation_scale=10,
                                 color="#333333", linewidth=0.8))
    ax.text(arrow_x + 0.05, 3.7, "imports", rotation=-90, fontsize=7.5, va="center")

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, bbox_inches="tight", metadata={"Date": None} if out.suffix == ".svg" else None)
    plt.close(fig)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "architecture.svg"), help="output file")
    args = parser.parse_args(argv)
    print(draw(args.out))


if __name__ == "__main__":
    main()
