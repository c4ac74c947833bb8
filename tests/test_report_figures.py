"""The panel description every report figure carries (podkrig.reports.figures): it must see the
defects the structural report test looks for, or that test could never fail."""

import numpy as np

from podkrig.reports.fields import auto_magnification, plot_deformed_field
from podkrig.reports.figures import colourbar, pyplot, read_panels, save


def _saved(fig, tmp_path, name="f.png"):
    return read_panels(save(fig, tmp_path / name))


def test_a_colour_scale_without_its_colour_bar_is_seen(tmp_path):
    plt = pyplot()
    fig, (a, b) = plt.subplots(1, 2)
    a.scatter([1, 2, 3], [1, 2, 3], c=[0.1, 0.5, 0.9])
    b.scatter([1, 2, 3], [1, 2, 3], c=[0.1, 0.5, 0.9])
    fig.colorbar(b.collections[0], ax=b)
    left, right = _saved(fig, tmp_path)
    assert left["colour_mapped"] and not left["colourbar"]
    assert right["colour_mapped"] and right["colourbar"]


def test_a_shared_colour_bar_counts_for_every_panel_it_serves(tmp_path):
    plt = pyplot()
    fig, axes = plt.subplots(1, 2)
    for ax in axes:
        points = ax.scatter([1, 2], [1, 2], c=[1, 2])
    colourbar(fig, points, list(axes), label="generation")
    assert all(p["colourbar"] for p in _saved(fig, tmp_path))


def test_an_empty_chart_is_seen(tmp_path):
    """Zero-length bars and a reference line only (the old 'candidate causes' chart)."""
    plt = pyplot()
    fig, (empty, full) = plt.subplots(1, 2)
    empty.barh(["a", "b"], [0.0, 0.0])
    empty.axvline(2.0, ls="--")
    full.barh(["a", "b"], [0.0, 1.5])
    e, f = _saved(fig, tmp_path)
    assert e["empty"] and not f["empty"]
    assert len(_saved(plt.subplots()[0], tmp_path, "blank.png")) == 1  # a blank axes is a panel, empty
    assert _saved(plt.subplots()[0], tmp_path, "blank2.png")[0]["empty"]


def test_deformed_field_figure_has_scale_bars_and_a_colour_bar(tmp_path, coarse_diagonal, monkeypatch):
    response = coarse_diagonal.run(field=True)
    m = auto_magnification(coarse_diagonal.mesh, response.field[-1])
    umax = np.linalg.norm(response.field[-1], axis=1).max()
    assert np.isclose(m * umax, 0.05 * max(coarse_diagonal.mesh.width, coarse_diagonal.mesh.height))
    plt = pyplot()
    texts = []
    original = plt.Axes.text

    def record(ax, x, y, s, *args, **kwargs):
        texts.append(s)
        return original(ax, x, y, s, *args, **kwargs)

    monkeypatch.setattr(plt.Axes, "text", record)
    path = plot_deformed_field(coarse_diagonal, response.field, tmp_path / "d.png")
    deformed, field = read_panels(path)
    assert not deformed["empty"] and not field["empty"]
    assert field["colour_mapped"] and field["colourbar"]
    assert f"× {m:.3g}" in deformed["title"] and "100 kN" in deformed["title"]
    assert any(t.endswith(" mm") and not t.startswith("displacement") for t in texts)  # length bar
    assert any(t.startswith("displacement") and f"× {m:.3g}" in t for t in texts)  # displacement bar
