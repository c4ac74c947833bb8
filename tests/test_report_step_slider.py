"""Structure of the step slider of a nonlinear run's HTML page (podkrig.reports.step_slider)."""

import base64
import json
import re
import shutil
import subprocess

import numpy as np
import pytest

from fe.scenarios import build_scenario
from podkrig.reports.nonlinear import write_nonlinear_report
from podkrig.reports.step_slider import (
    MAX_FRAMES,
    build_step_slider,
    select_steps,
    step_slider_html,
)


@pytest.fixture(scope="module")
def triplet_run():
    """A coarse triplet pushed past its peak, states kept (≈ 60 converged steps: more than the
    frame cap, so the selection is exercised)."""
    sc = build_scenario({"scenario": "triplet_shear", "nx": 2, "ny": 1, "precompression": 0.2,
                         "load_levels": [0.05, 0.3, 1.0], "increment": 0.005, "max_increment": 0.02})
    return sc, sc.run(field=True)


def _data(html):
    return json.loads(re.search(r'<script type="application/json" id="ss-data">(.*?)</script>', html, re.DOTALL).group(1))


def _decode(text, dtype):
    return np.frombuffer(base64.b64decode(text), dtype=dtype)


def test_page_holds_a_self_contained_slider_over_at_most_40_frames(triplet_run, tmp_path):
    sc, r = triplet_run
    assert r.status == "converged"
    page = write_nonlinear_report(sc, r, sc.resolve(None), tmp_path).read_text(encoding="utf-8")
    d = _data(page)
    n = len(d["frames"])
    control = np.flatnonzero(r.path.of_phase(r.path.phase[-1]))
    assert len(control) > MAX_FRAMES and n == MAX_FRAMES
    # the slider runs over exactly the frames, starting on the last one
    slider = re.search(r'<input id="ss-slider" type="range" min="0" max="(\d+)" step="1" value="(\d+)"', page)
    assert int(slider.group(1)) == n - 1 and int(slider.group(2)) == n - 1
    # frames are stored steps of the controlled phase, in order, with the peak and the last step
    steps = np.array(d["steps"])
    assert np.all(np.diff(steps) > 0) and set(steps) <= set(control)
    assert steps[-1] == control[-1]
    assert steps[np.argmax(d["load"])] == control[np.argmax(np.asarray(r.path.load)[control])]
    # the marker data are the stored steps' control displacement and load
    assert np.allclose(d["control"], sc.control_sign * np.asarray(r.path.path)[steps], rtol=1e-12)
    assert np.allclose(d["load"], np.asarray(r.path.load)[steps], rtol=1e-12)
    assert len(d["curve"]) == len(control)
    # self-contained: no external resource, and small
    assert not re.search(r'(src|href)="https?:', page)
    assert len(page.encode()) < 3_000_000


def test_frames_decode_to_the_deformed_mesh_and_the_joint_state(triplet_run):
    """Positions within half a quantum of node + magnification × u (y flipped for SVG); opening
    bins follow the sign of the opening; slip bins grow with the slip."""
    sc, r = triplet_run
    s = build_step_slider(sc, r, max_frames=7)
    d = json.loads(json.dumps(s.to_dict()))
    assert len(d["frames"]) == 7 == s.n_frames
    quads = _decode(d["quads"], np.int32).reshape(-1, 4)
    points = _decode(d["points"], np.int32)
    assert np.array_equal(s.nodes[quads], np.asarray(sc.mesh.quads)[:, :4])
    assert np.array_equal(s.nodes[points], sc.model.point_nodes())
    for k, frame in enumerate(d["frames"]):
        xy = _decode(frame["xy"], np.int16).reshape(-1, 2) * d["quantum"]
        u = np.asarray(r.path.displacements[s.steps[k]], float)[s.nodes]
        exact = sc.mesh.nodes[s.nodes] + d["magnification"] * u
        exact[:, 1] *= -1
        assert np.abs(xy - exact).max() <= 0.5 * d["quantum"] * (1 + 1e-9)
        opening = np.asarray(r.path.states[s.steps[k]]["opening"], float)
        bins = _decode(frame["open"], np.uint8).astype(int) - len(d["palette"]) // 2
        big = np.abs(opening) > 0.6 * d["opening_scale"] / (len(d["palette"]) // 2)
        assert np.array_equal(np.sign(bins[big]), np.sign(opening[big]))
        slip = np.abs(np.asarray(r.path.states[s.steps[k]]["slip"], float))
        sb = _decode(frame["slip"], np.uint8)
        order = np.argsort(slip)
        assert np.all(np.diff(sb[order].astype(int)) >= 0)
    html = step_slider_html(s)
    assert 'max="6"' in html


def test_frame_selection_keeps_the_peak_and_the_last_step():
    load = np.array([0, 1, 5, 2, 1, 1, 1, 1, 1, 1.0])
    steps = select_steps(np.arange(10, 20), load, 3)
    assert list(steps) == [10, 12, 19]
    assert list(select_steps(np.arange(4), np.ones(4), 40)) == [0, 1, 2, 3]


def test_a_run_without_states_has_no_slider(triplet_run):
    sc, _ = triplet_run
    r = sc.run({}, field=False)
    with pytest.raises(ValueError, match="field=True"):
        build_step_slider(sc, r)


_HARNESS = r"""
// a minimal DOM: run the page's slider script, move the slider, print what it drew
const fs = require('fs');
const html = fs.readFileSync(process.argv[2], 'utf8');
const data = html.match(/<script type="application\/json" id="ss-data">([\s\S]*?)<\/script>/)[1];
const script = html.match(/<script>([\s\S]*?)<\/script><\/div>/)[1];
const els = {};
function el(id) { return els[id] || (els[id] = {attrs: {}, children: [], listeners: {}, textContent: '', value: '',
  setAttribute(k, v) { this.attrs[k] = String(v); }, appendChild(c) { this.children.push(c); },
  addEventListener(t, f) { this.listeners[t] = f; }}); }
el('ss-data').textContent = data;
el('ss-slider').value = html.match(/id="ss-slider"[^>]*value="(\d+)"/)[1];
let k = 0;
global.document = {getElementById: el, createElementNS: () => el('dot' + k++)};
eval(script);
const out = [];
for (const v of ['0', process.argv[3]]) {
  els['ss-slider'].listeners.input({target: {value: v}});
  const dots = els['ss-joints'].children;
  out.push({label: els['ss-label'].textContent, quads: (els['ss-mesh'].attrs.d.match(/M/g) || []).length,
            dots: dots.length, cx: dots.map(c => +c.attrs.cx), cy: dots.map(c => +c.attrs.cy),
            marker: [+els['ss-marker'].attrs.cx, +els['ss-marker'].attrs.cy]});
}
console.log(JSON.stringify(out));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node.js to run the page's script")
def test_page_script_draws_every_frame(triplet_run, tmp_path):
    """The inline script, run under Node with a stub DOM: the first and last frames draw one outline
    per element and one dot per joint point at the decoded positions, and the marker moves from
    the first frame's point of the curve up to the last."""
    sc, r = triplet_run
    page = write_nonlinear_report(sc, r, sc.resolve(None), tmp_path)
    harness = tmp_path / "harness.js"
    harness.write_text(_HARNESS)
    d = _data(page.read_text(encoding="utf-8"))
    last = len(d["frames"]) - 1
    out = json.loads(subprocess.run(["node", str(harness), str(page), str(last)], capture_output=True, text=True,
                                    check=True, timeout=60).stdout)
    points = _decode(d["points"], np.int32)
    for frame, drawn in zip((0, last), out):
        assert drawn["label"].startswith(f"frame {frame + 1} of {last + 1} (step {d['steps'][frame]})")
        assert drawn["quads"] == len(sc.mesh.quads) and drawn["dots"] == len(points)
        xy = _decode(d["frames"][frame]["xy"], np.int16).reshape(-1, 2) * d["quantum"]
        assert np.allclose(drawn["cx"], xy[points, 0], atol=0.051) and np.allclose(drawn["cy"], xy[points, 1], atol=0.051)
    assert out[0]["marker"][0] < out[1]["marker"][0], "the marker moves right along the curve"
