"""A step slider for the HTML page of a nonlinear run: the deformed specimen with its joints'
opening and slip at each stored step, moved through with a range slider (and a play button)
together with a marker on the load–displacement curve.

Self-contained: inline SVG and a few lines of inline JavaScript, no external script or font. The
frames are a selection of at most ``max_frames`` converged steps of the controlled phase (evenly
spaced, the peak and the last step always among them), fewer when the encoded data would exceed
``max_bytes``. Per frame the page holds the deformed corner-node positions (int16, base64) and per
joint point a colour bin of the opening and a size bin of the slip (uint8, base64); the curve and
the marker positions are plain JSON.
"""

import base64
import json
from dataclasses import dataclass

import numpy as np

MAX_FRAMES = 40
MAX_BYTES = 3_000_000
#: diverging colour bins of the opening, closing (blue) … 0 (white) … opening (red)
_PALETTE = ("#2166ac", "#3a7bb8", "#5390c4", "#6ba5d0", "#8cb9da", "#aacde5", "#c6dcec", "#dde9f2", "#eef3f7",
            "#f7f7f7", "#f9f0ea", "#f7e2d4", "#f4cfb8", "#efb698", "#e89b79", "#de7d5c", "#cf5f44", "#bc4130",
            "#a52420", "#8b0c16", "#67001f")
_SLIP_BINS = 10
_CURVE_W, _CURVE_H, _PAD = 420, 280, 46


def _b64(array):
    return base64.b64encode(np.ascontiguousarray(array).tobytes()).decode("ascii")


@dataclass(frozen=True)
class StepSlider:
    """The data of a step slider.

    Attributes
    ----------
    steps : ndarray (n_frames,) int
        Indices of the frames' converged steps in the run's path.
    control : ndarray (n_frames,)
        Control displacement of each frame, mm (the marker's abscissa).
    load : ndarray (n_frames,)
        Load of each frame, in ``force_unit`` (the marker's ordinate).
    curve : ndarray (n_steps, 2)
        Control displacement (mm) and load of every converged step of the controlled phase.
    magnification : float
        Displacement magnification of the deformed mesh.
    quantum : float
        mm per int16 unit of the encoded positions.
    opening_scale : float
        Opening (mm) of the outermost colour bins.
    slip_scale : float
        Slip (mm) of the largest marker.
    nodes : ndarray (n_used,) int
        Mesh nodes whose positions are encoded (corners of the elements and joint-point nodes).
    quads : ndarray (n_quads, 4) int
        Element corners as indices into ``nodes``.
    points : ndarray (n_points,) int
        Node of each joint point as an index into ``nodes``.
    xy : ndarray (n_frames, n_used, 2) int16
        Deformed positions (x, −y) in units of ``quantum``.
    opening_bin, slip_bin : ndarray (n_frames, n_points) uint8
    force_unit : str
    """

    steps: np.ndarray
    control: np.ndarray
    load: np.ndarray
    curve: np.ndarray
    magnification: float
    quantum: float
    opening_scale: float
    slip_scale: float
    nodes: np.ndarray
    quads: np.ndarray
    points: np.ndarray
    xy: np.ndarray
    opening_bin: np.ndarray
    slip_bin: np.ndarray
    force_unit: str

    @property
    def n_frames(self):
        return len(self.steps)

    def to_dict(self):
        """The JSON the page's script reads."""
        return {
            "steps": self.steps.tolist(), "control": self.control.tolist(), "load": self.load.tolist(),
            "curve": self.curve.tolist(), "magnification": self.magnification, "quantum": self.quantum,
            "opening_scale": self.opening_scale, "slip_scale": self.slip_scale,
            "quads": _b64(self.quads.astype(np.int32)), "points": _b64(self.points.astype(np.int32)),
            "frames": [{"xy": _b64(self.xy[k]), "open": _b64(self.opening_bin[k]), "slip": _b64(self.slip_bin[k])}
                       for k in range(self.n_frames)],
            "palette": list(_PALETTE), "force_unit": self.force_unit,
        }


def select_steps(control_steps, load, max_frames):
    """At most ``max_frames`` indices of ``control_steps`` (the path indices of the controlled
    phase), evenly spaced, with the first, the peak of ``load`` (same length) and the last step
    among them (the peak replaces the nearest inner frame)."""
    n = len(control_steps)
    if n == 0 or max_frames < 1:
        return np.zeros(0, dtype=int)
    pick = np.unique(np.linspace(0, n - 1, min(max_frames, n)).round().astype(int))
    peak = int(np.argmax(load))
    if peak not in pick and len(pick) > 1:
        first = 1 if len(pick) > 2 else 0  # the nearest inner frame gives way (first and last stay)
        pick[first + np.argmin(np.abs(pick[first:-1] - peak))] = peak
        pick = np.unique(pick)
    return np.asarray(control_steps)[pick]


def build_step_slider(scenario, response, max_frames=MAX_FRAMES, max_bytes=MAX_BYTES):
    """The :class:`StepSlider` of a run kept with its states (``field=True``).

    Raises
    ------
    ValueError
        The run kept no states, or no step of its controlled phase converged.
    """
    res = response.path
    if res.displacements is None or not len(res.displacements):
        raise ValueError("the run kept no states: run with field=True (podkrig simulate --report does)")
    control_steps = np.flatnonzero(res.of_phase(res.phase[-1]))
    control_steps = control_steps[control_steps < len(res.displacements)]
    if not len(control_steps):
        raise ValueError("no converged step of the controlled phase to show")
    mesh = scenario.mesh
    quads_all = np.asarray(mesh.quads)[:, :4]
    point_nodes = np.asarray(scenario.model.point_nodes())
    nodes = np.union1d(quads_all.ravel(), point_nodes)
    index = np.full(mesh.n_nodes, -1)
    index[nodes] = np.arange(len(nodes))
    per_frame = 4 / 3 * (2 * 2 * len(nodes) + 2 * len(point_nodes)) + 200  # base64 bytes
    budget = max(1, int((max_bytes - 4 / 3 * 4 * (quads_all.size + len(point_nodes))) // per_frame))
    disp = scenario.control_sign * np.asarray(res.path, float)
    load = np.asarray(res.load, float)
    steps = select_steps(control_steps, load[control_steps], min(max_frames, budget))
    u = np.stack([np.asarray(res.displacements[s], float)[nodes] for s in steps])
    span = max(mesh.width, mesh.height)
    umax = float(np.abs(u).max())
    magnification = 0.05 * span / umax if umax > 0 else 1.0
    xy = mesh.nodes[nodes][None] + magnification * u
    xy[..., 1] *= -1.0  # SVG's y points down
    quantum = float(np.abs(xy).max()) / 32000.0 or 1.0
    opening = np.stack([np.asarray(res.states[s]["opening"], float) for s in steps])
    slip = np.abs(np.stack([np.asarray(res.states[s]["slip"], float) for s in steps]))
    opening_scale = max(float(np.percentile(np.abs(opening), 99.5)), 1e-6)
    slip_scale = max(float(slip.max()), 1e-12)
    half = len(_PALETTE) // 2
    opening_bin = (half + np.clip(np.rint(opening / opening_scale * half), -half, half)).astype(np.uint8)
    slip_bin = np.clip(np.rint(slip / slip_scale * (_SLIP_BINS - 1)), 0, _SLIP_BINS - 1).astype(np.uint8)
    return StepSlider(
        steps=steps, control=disp[steps], load=load[steps],
        curve=np.column_stack([disp[control_steps], load[control_steps]]), magnification=magnification,
        quantum=quantum, opening_scale=opening_scale, slip_scale=slip_scale, nodes=nodes,
        quads=index[quads_all], points=index[point_nodes], xy=np.rint(xy / quantum).astype(np.int16),
        opening_bin=opening_bin, slip_bin=slip_bin, force_unit=response.force_unit)


_SCRIPT = """
(function(){
const d=JSON.parse(document.getElementById('ss-data').textContent);
function bytes(s){const b=atob(s),u=new Uint8Array(b.length);for(let i=0;i<b.length;i++)u[i]=b.charCodeAt(i);return u;}
const quads=new Int32Array(bytes(d.quads).buffer),pts=new Int32Array(bytes(d.points).buffer);
const frames=d.frames.map(f=>({xy:new Int16Array(bytes(f.xy).buffer),open:bytes(f.open),slip:bytes(f.slip)}));
const q=d.quantum,ns='http://www.w3.org/2000/svg';
const mesh=document.getElementById('ss-mesh'),joints=document.getElementById('ss-joints');
const dots=[];for(let i=0;i<pts.length;i++){const c=document.createElementNS(ns,'circle');joints.appendChild(c);dots.push(c);}
const slider=document.getElementById('ss-slider'),label=document.getElementById('ss-label');
const marker=document.getElementById('ss-marker'),W=%(w)d,H=%(h)d,P=%(p)d;
const us=d.curve.map(c=>c[0]),fs=d.curve.map(c=>c[1]);
const u0=Math.min(...us),u1=Math.max(...us),f0=Math.min(0,...fs),f1=Math.max(...fs);
const X=u=>P+(W-1.5*P)*(u-u0)/((u1-u0)||1),Y=f=>H-P+(-(H-1.5*P))*(f-f0)/((f1-f0)||1);
document.getElementById('ss-curve').setAttribute('points',d.curve.map(c=>X(c[0]).toFixed(1)+','+Y(c[1]).toFixed(1)).join(' '));
const r0=%(span)f/400;
function show(k){
 const f=frames[k],xy=f.xy;let s='';
 for(let e=0;e<quads.length;e+=4){s+='M';for(let j=0;j<4;j++){const n=quads[e+j];s+=(xy[2*n]*q).toFixed(1)+' '+(xy[2*n+1]*q).toFixed(1)+(j<3?'L':'Z');}}
 mesh.setAttribute('d',s);
 for(let i=0;i<pts.length;i++){const n=pts[i],c=dots[i];c.setAttribute('cx',(xy[2*n]*q).toFixed(1));c.setAttribute('cy',(xy[2*n+1]*q).toFixed(1));
  c.setAttribute('r',(r0*(1+0.4*f.slip[i])).toFixed(2));c.setAttribute('fill',d.palette[f.open[i]]);}
 marker.setAttribute('cx',X(d.control[k]));marker.setAttribute('cy',Y(d.load[k]));
 label.textContent='frame '+(k+1)+' of '+frames.length+' (step '+d.steps[k]+'): control '+d.control[k].toPrecision(4)+' mm, load '+d.load[k].toPrecision(4)+' '+d.force_unit;
}
slider.addEventListener('input',e=>show(+e.target.value));
let timer=null;document.getElementById('ss-play').addEventListener('click',e=>{
 if(timer){clearInterval(timer);timer=null;e.target.textContent='play';return;}
 e.target.textContent='pause';timer=setInterval(()=>{slider.value=(+slider.value+1)%%frames.length;show(+slider.value);},250);});
show(+slider.value);
})();
"""


def step_slider_html(slider):
    """The HTML fragment (inline SVG, inline script) of ``slider``."""
    xy = slider.xy.reshape(-1, 2) * slider.quantum
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = float(max(hi - lo))
    pad = 0.04 * span
    box = f"{lo[0] - pad:.1f} {lo[1] - pad:.1f} {hi[0] - lo[0] + 2 * pad:.1f} {hi[1] - lo[1] + 2 * pad:.1f}"
    data = json.dumps(slider.to_dict(), separators=(",", ":")).replace("</", "<\\/")
    w, h, p = _CURVE_W, _CURVE_H, _PAD
    last = slider.n_frames - 1
    curve_svg = (
        f'<svg width="{w}" height="{h}" viewBox="0 0 {w} {h}" role="img" aria-label="load against control displacement">'
        f'<line x1="{p}" y1="{h - p}" x2="{w - p / 2}" y2="{h - p}" stroke="#444"/>'
        f'<line x1="{p}" y1="{p / 2}" x2="{p}" y2="{h - p}" stroke="#444"/>'
        f'<text x="{w / 2}" y="{h - 8}" text-anchor="middle" font-size="12">control displacement (mm), '
        f'{slider.curve[:, 0].min():.3g} … {slider.curve[:, 0].max():.3g}</text>'
        f'<text x="12" y="{h / 2}" font-size="12" transform="rotate(-90 12 {h / 2})" text-anchor="middle">'
        f'load ({slider.force_unit}), max {slider.curve[:, 1].max():.4g}</text>'
        f'<polyline id="ss-curve" fill="none" stroke="#1f77b4" stroke-width="1.5"/>'
        f'<circle id="ss-marker" r="6" fill="#d62728"/></svg>')
    mesh_svg = (
        f'<svg width="{w + 80}" height="{int((w + 80) * min(2.0, (hi[1] - lo[1] + 2 * pad) / (hi[0] - lo[0] + 2 * pad)))}" '
        f'viewBox="{box}" role="img" aria-label="deformed specimen">'
        f'<path id="ss-mesh" fill="#ececec" stroke="#b3b3b3" stroke-width="{span / 1500:.2f}"/>'
        f'<g id="ss-joints" stroke="none"></g></svg>')
    script = _SCRIPT % {"w": w, "h": h, "p": p, "span": span}
    return (
        '<div class="step-slider">'
        f'<div style="display:flex;flex-wrap:wrap;gap:1em;align-items:flex-start">{mesh_svg}{curve_svg}</div>'
        f'<div><button id="ss-play" type="button">play</button> '
        f'<input id="ss-slider" type="range" min="0" max="{last}" step="1" value="{last}" style="width:60%">'
        f' <span id="ss-label"></span></div>'
        f'<p class="meta">Deformed ×{slider.magnification:.3g}; joint points coloured by opening (blue closing, '
        f'red opening, ±{slider.opening_scale:.3g} mm at the ends of the scale), their size grows with the slip '
        f'(largest: {slider.slip_scale:.3g} mm).</p>'
        f'<script type="application/json" id="ss-data">{data}</script><script>{script}</script></div>')
