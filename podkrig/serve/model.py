"""The FE model on demand for ``podkrig serve``: one FE run of a test's scenario, as the page draws it.

:func:`model_view` turns a scenario and its response (run with ``field=True``) into plain arrays:
the mesh (node positions and element corner polygons, mm), the displacement of every drawn node at
each shown step (mm), a suggested magnification (:func:`podkrig.reports.fields.auto_magnification`,
the largest displacement drawn as 5 % of the specimen, as in the report's deformed mesh) and, for
a nonlinear scenario, the load–displacement curve and the joints' opening and slip at each shown
step (the frames of :func:`podkrig.reports.step_slider.select_steps`: at most
:data:`~podkrig.reports.step_slider.MAX_FRAMES` converged steps of the controlled phase, the first,
the peak and the last among them). Nothing here draws: the page does (no matplotlib).

:class:`FEViews` runs these on demand in one worker thread (FE runs queue, one at a time, so the
page's slider path keeps a core) and keeps each result by id; at most :data:`MAX_PENDING_FE` runs
wait or run at once (a further request is refused with 409).
"""

import itertools
import logging
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from fe.scenarios import build_scenario
from podkrig.reports.fields import auto_magnification
from podkrig.reports.step_slider import MAX_FRAMES, select_steps
from podkrig.serve.session import RequestError, check_keys

logger = logging.getLogger(__name__)

#: FE results kept per session (the oldest finished ones are dropped first)
MAX_VIEWS = 20
#: FE runs running or waiting at once (the page asks one at a time)
MAX_PENDING_FE = 4


def _rounded(a, digits=6):
    """``a`` to ``digits`` significant digits of its largest entry (smaller JSON, same picture)."""
    a = np.asarray(a, dtype=float)
    top = float(np.max(np.abs(a))) if a.size else 0.0
    if top == 0.0 or not np.isfinite(top):
        return a
    return np.round(a, max(0, digits - 1 - int(np.floor(np.log10(top)))))


def model_view(scenario, response, *, max_frames=MAX_FRAMES):
    """The page's view of one FE run.

    Parameters
    ----------
    scenario : fe.Scenario
        The scenario that ran (its mesh; for a nonlinear one its joints' integration points).
    response : fe.Response
        Run with ``field=True`` (a linear scenario's ``field``; a nonlinear one's path with its
        displacements and states).
    max_frames : int
        Most steps shown of a nonlinear run.

    Returns
    -------
    dict
        ``nodes`` ``(n_drawn, 2)`` mm; ``outline`` ``(n_elements, 4)`` indices into ``nodes`` (the
        corners of each element, counter-clockwise); ``steps`` the control value of each shown step
        (``x_unit``); ``displacement`` ``(n_steps, n_drawn, 2)`` mm; ``scale`` the suggested
        magnification (-); ``curve`` (nonlinear: control displacement ``x`` mm and load ``y`` in
        ``y_unit`` of every converged step of the controlled phase, and ``step_index``: the position
        on the curve of each shown step) or None; ``joints``
        (nonlinear: one entry per interface element, :func:`_joints`) or None.

    Raises
    ------
    ValueError
        The response kept no displacements (not run with ``field=True``).
    """
    mesh = scenario.mesh
    corners = np.asarray(mesh.quads)[:, :4]
    path = getattr(response, "path", None)
    nonlinear = path is not None and getattr(path, "displacements", None) is not None
    point_nodes = np.asarray(scenario.model.point_nodes()) if nonlinear else np.zeros(0, dtype=int)
    drawn = np.union1d(corners.ravel(), point_nodes)
    index = np.full(mesh.n_nodes, -1)
    index[drawn] = np.arange(len(drawn))
    curve = joints = None
    if nonlinear:
        control = np.flatnonzero(path.of_phase(path.phase[-1]))
        control = control[control < len(path.displacements)]
        if not len(control):
            raise ValueError("the FE run has no converged step of its controlled phase to show")
        disp = scenario.control_sign * np.asarray(path.path, float)
        load = np.asarray(path.load, float)
        steps = select_steps(control, load[control], max_frames)
        u = np.stack([np.asarray(path.displacements[s], float)[drawn] for s in steps])
        x, x_unit = disp[steps], "mm"
        curve = {"x": disp[control].tolist(), "y": load[control].tolist(), "x_unit": "mm",
                 "y_unit": response.force_unit, "step_index": np.searchsorted(control, steps).tolist()}
        joints = _joints(scenario, mesh.nodes[point_nodes], [path.states[s] for s in steps])
    else:
        if getattr(response, "field", None) is None:
            raise ValueError("the FE run kept no displacement field: run it with field=True")
        u = np.asarray(response.field, float)[:, drawn]
        x, x_unit = np.asarray(scenario.load_levels, float), scenario.load_unit
    scale = auto_magnification(mesh, u[-1])
    return {"nodes": mesh.nodes[drawn].tolist(), "outline": index[corners].tolist(), "steps": x.tolist(),
            "x_unit": x_unit, "displacement": _rounded(u).tolist(), "scale": float(scale),
            "scale_text": f"displacements drawn × {scale:.3g}", "curve": curve, "joints": joints}


def _joints(scenario, points, states):
    """One entry per interface element of a nonlinear scenario: its ends ``a``, ``b`` (mm, the two
    of its integration points farthest apart, on face A) and its ``opening`` and ``slip`` at each
    shown step (mm, the mean over its integration points; the states' per-point values)."""
    n_elements = len(scenario.model.interface_elements)
    n_per = len(points) // n_elements  # the points are element by element (point_nodes)
    xy = points.reshape(n_elements, n_per, 2)
    gap = np.linalg.norm(xy[:, :, None] - xy[:, None, :], axis=-1).reshape(n_elements, -1)
    ends = np.unravel_index(np.argmax(gap, axis=1), (n_per, n_per))
    rows = np.arange(n_elements)
    a, b = xy[rows, ends[0]], xy[rows, ends[1]]
    opening = _rounded([np.asarray(st["opening"], float).reshape(n_elements, n_per).mean(axis=1) for st in states])
    slip = _rounded([np.asarray(st["slip"], float).reshape(n_elements, n_per).mean(axis=1) for st in states])
    return [{"a": a[e].tolist(), "b": b[e].tolist(), "opening": opening[:, e].tolist(), "slip": slip[:, e].tolist()}
            for e in range(n_elements)]


class FEViews:
    """FE runs on demand for one session: :meth:`start` queues a run, :meth:`get` its state."""

    def __init__(self, session):
        self.session = session
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="podkrig-fe")
        self._views = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._scenarios = {}  # its own scenario per test: never run at once with a calibration's FE check

    def start(self, body):
        """``POST /api/fe``: check ``values`` (the free parameters, physical; missing ones at the
        sliders' defaults) and ``test`` (None: the first test), queue the FE run; its id."""
        check_keys(body, ("values", "test"), "fe")
        session = self.session
        problem = session.problem  # 409 before the offline stage
        test = session.test(body.get("test") if body.get("test") is not None else session.tests[0].name)
        x = session.values(body.get("values"))
        parts = problem.parts(x) or {None: (problem, x)}  # one test: the problem itself
        one, x_test = parts[test.name]
        params = one.parameters_at(x_test)
        with self._lock:
            pending = [k for k, v in self._views.items() if v["status"] == "running"]
            if len(pending) >= MAX_PENDING_FE:
                raise RequestError(f"{len(pending)} FE runs are running or waiting ({', '.join(pending)}): ask again "
                                   f"when {pending[0]} is done", None, 409)
            fid = f"f{next(self._ids)}"
            self._views[fid] = {"status": "running", "error": None, "result": None, "test": test.name,
                                "parameters": params, "started": time.time()}
            self._trim()
        self._pool.submit(self._run, fid, test, params)
        return fid

    def _trim(self):
        finished = [k for k, v in self._views.items() if v["status"] != "running"]
        for key in finished[: max(0, len(self._views) - MAX_VIEWS)]:
            del self._views[key]

    def _run(self, fid, test, params):
        view = self._views[fid]
        try:
            if test.name not in self._scenarios:  # built in the one worker thread
                self._scenarios[test.name] = build_scenario(test.spec)
            scenario = self._scenarios[test.name]
            response = scenario.run(params, field=True)
            result = model_view(scenario, response)
            view.update(status="done", result=result, seconds=time.time() - view["started"])
        except Exception as e:  # noqa: BLE001 - the page shows why the run failed (FE, convergence ...)
            logger.warning("FE run %s failed: %s", fid, e)
            view.update(status="failed", error=f"{type(e).__name__}: {e}" if not isinstance(e, ValueError) else str(e))

    def get(self, fid):
        """``GET /api/fe/{id}``: ``status``, ``error``, ``result`` (:func:`model_view`), ``test``
        and the ``parameters`` it ran with."""
        view = self._views.get(fid)
        if view is None:
            raise RequestError(f"no FE run {fid!r} in this session", "fe", 404)
        return {k: view[k] for k in ("status", "error", "result", "test", "parameters")}

    def close(self):
        self._pool.shutdown(wait=False, cancel_futures=True)


__all__ = ["FEViews", "MAX_PENDING_FE", "MAX_VIEWS", "model_view"]
