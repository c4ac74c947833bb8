"""Figure of a global sensitivity analysis (reads a :class:`~podkrig.online.sensitivity.SensitivityResult`)."""

import numpy as np

from podkrig.reports.figures import pyplot, save


def plot_sensitivity(result, path, misfit=None):
    """Left: per parameter, the largest total and first-order index over the readings (and the
    misfit's, when given), with the bootstrap interval of the reading that sets the maximum and
    the fixing threshold. Right: the total index of every reading (rows) and parameter (columns),
    with its colour bar. Saved to ``path`` (PNG)."""
    from matplotlib import colors

    from podkrig.online.sensitivity import NEGLIGIBLE_TOTAL_INDEX

    plt = pyplot()
    names = result.parameters
    d = len(names)
    T = np.where(result.variance[:, None] > 0, result.total, np.nan)
    k = np.nanargmax(np.nan_to_num(T, nan=-1.0), axis=0)  # the reading setting each maximum
    cols = np.arange(d)
    fig, (ax, hm) = plt.subplots(1, 2, figsize=(11, 0.9 + max(3.0, 0.22 * len(result.outputs))),
                                 gridspec_kw={"width_ratios": [1, 1.2]})
    width = 0.38 if misfit is None else 0.26
    err = np.vstack([result.total[k, cols] - result.total_low[k, cols], result.total_high[k, cols] - result.total[k, cols]])
    ax.bar(cols - width / 2, result.total[k, cols], width, yerr=np.maximum(err, 0), capsize=3, label="total (largest over readings)")
    ax.bar(cols + width / 2, result.first[k, cols], width, label="first order (same reading)")
    if misfit is not None:
        ax.bar(cols + 1.5 * width, misfit.total[0], width, color="tab:red", label="total, misfit ω")
    ax.axhline(NEGLIGIBLE_TOTAL_INDEX, color="0.3", ls=":", lw=1, label=f"fixing threshold {NEGLIGIBLE_TOTAL_INDEX:g}")
    ax.set_xticks(cols, names)
    ax.set_ylabel("Sobol' index (-)")
    ax.set_ylim(0, 1.05)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=2)
    ax.set_title(f"{result.n_base} base samples, {int(100 * result.confidence)} % bootstrap intervals", fontsize=9)
    im = hm.imshow(T, aspect="auto", cmap="viridis", norm=colors.Normalize(0.0, 1.0), interpolation="nearest")
    hm.set_xticks(cols, names)
    hm.set_yticks(np.arange(len(result.outputs)), result.outputs, fontsize=6)
    hm.set_title("total index per reading (SENSOR@LOAD)", fontsize=9)
    fig.colorbar(im, ax=hm, label="total Sobol' index (-)")
    fig.tight_layout()
    save(fig, path, dpi=120)
