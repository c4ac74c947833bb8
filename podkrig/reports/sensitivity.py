"""Figure and words of a global sensitivity analysis (reads a
:class:`~podkrig.online.sensitivity.SensitivityResult`).

A Sobol' index is a share of variance, ≥ 0 by definition, but its sampling estimate of a
parameter with no effect scatters around 0 and can come out slightly negative (e.g. −0.0009).
Wherever an index is printed, :func:`negative_index` says which of two cases a negative
estimate is: estimator noise (0 lies inside its bootstrap interval: read it as 0) or an estimate
negative beyond its interval, which is flagged (too few base samples for this output).
"""

import math

import numpy as np

from podkrig.reports.figures import pyplot, save

#: the words of a negative index estimate, by :func:`negative_index`'s kind
NEGATIVE_INDEX = {
    "noise": "negative estimate: sampling noise around 0 (0 lies inside its bootstrap interval); read it as 0",
    "suspect": "negative beyond its bootstrap interval: the estimate is not reliable; raise the base samples n",
}


def negative_index(value, low, high):
    """The kind of a negative Sobol' index estimate.

    Parameters
    ----------
    value : float or None
        The estimate (-); None or NaN for an output without variance.
    low, high : float or None
        Its bootstrap interval (-).

    Returns
    -------
    {None, "noise", "suspect"}
        None for an estimate ≥ 0 (or missing); ``"noise"`` when the interval contains 0 (the
        negative value is within the estimator's noise); ``"suspect"`` otherwise (:data:`NEGATIVE_INDEX`).
    """
    if value is None or not math.isfinite(value) or value >= 0:
        return None
    inside = low is not None and high is not None and low <= 0.0 <= high
    return "noise" if inside else "suspect"


def index_notes(*estimates):
    """The note of a table row showing the index estimates ``(value, low, high)``: the words of
    :data:`NEGATIVE_INDEX` for each kind found (a suspect one first), joined; "" when none is negative."""
    kinds = {negative_index(*e) for e in estimates} - {None}
    return "; ".join(NEGATIVE_INDEX[k] for k in ("suspect", "noise") if k in kinds)


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
