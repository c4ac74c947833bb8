"""The TU Eindhoven walls with a central opening (``wall_opening_nl``): mesh, statics, linear limit,
defaults and a full run."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from conftest import load_file
from fe.constraints import constraint_transform
from fe.exceptions import MeshError, SpecError
from fe.interfaces import CompositeInterface
from fe.mesh import INTERFACE_KINDS, BrickWallLayout, brick_wall
from fe.model import LinearModel
from fe.scenarios import build_scenario
from fe.scenarios.catalogue import describe_scenario
from fe.scenarios.masonry import masonry_parts, masonry_theta
from fe.scenarios.nonlinear import interface_properties
from fe.scenarios.wall_opening import SET_B
from fe.solvers.nonlinear import CONVERGED, PathFollower

OPENING = (330.0, 660.0, 372.0, 620.0)  # the default opening, x0, x1, y0, y1 (mm)
WALL = dict(unit_length=220.0, unit_height=62.0, n_courses=16, base_joints=True, openings=(OPENING,))
SHORT = {"scenario": "wall_opening_nl", "nx": 2, "ny": 1, "load_levels": [0.1, 0.2, 0.3]}  # coarse: cheap


@pytest.mark.parametrize("nx, ny, element", [(2, 1, "Q8"), (6, 2, "Q8"), (4, 2, "Q4")])
def test_the_mesh_leaves_the_opening_empty_and_keeps_the_bond(nx, ny, element):
    """No element reaches into the opening (every node of every element on or outside its
    boundary, so no centroid inside); units and joints (expanded units) cover the wall and its
    two beams minus the opening, exactly; the units beside the opening are whole or half units,
    a half unit on one side in every course that the opening crosses; its sides are free (no
    interface crosses or borders it)."""
    layout = BrickWallLayout(nx=nx, ny=ny, element=element, **WALL)
    mesh = brick_wall(layout)
    x0, x1, y0, y1 = OPENING
    xy = mesh.nodes[mesh.quads]
    inside = (xy[..., 0] > x0) & (xy[..., 0] < x1) & (xy[..., 1] > y0) & (xy[..., 1] < y1)
    assert not inside.any()
    centroid = xy.mean(axis=1)
    assert not layout.in_opening(centroid[:, 0], centroid[:, 1]).any()
    b = mesh.block_bounds
    area = np.sum((b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1]))
    assert area == pytest.approx(990.0 * (992.0 + 2 * 62.0) - (x1 - x0) * (y1 - y0), rel=1e-12)
    # the same by element areas (shoelace over the corner nodes)
    c = xy[:, :4]
    shoelace = 0.5 * np.sum(c[:, :, 0] * np.roll(c[:, :, 1], -1, 1) - np.roll(c[:, :, 0], -1, 1) * c[:, :, 1], 1)
    assert np.sum(shoelace) == pytest.approx(area, rel=1e-12)
    unit_width = np.bincount(mesh.block_unit, weights=b[:, 2] - b[:, 0])
    for course in range(6, 10):  # the courses the opening crosses
        yc = (course + 0.5) * 62.0
        beside = [u for u in np.unique(mesh.block_unit) if
                  np.any((b[mesh.block_unit == u, 1] < yc) & (b[mesh.block_unit == u, 3] > yc)
                         & (np.isclose(b[mesh.block_unit == u, 2], x0) | np.isclose(b[mesh.block_unit == u, 0], x1)))]
        widths = sorted(unit_width[beside])
        assert_allclose(widths, [110.0, 220.0], rtol=0, atol=1e-9)
    faces = mesh.nodes[mesh.interfaces]
    mid = faces.mean(axis=1)
    assert not layout.in_opening(mid[:, 0], mid[:, 1]).any()
    on_side = (np.isclose(faces[..., 0], x0) | np.isclose(faces[..., 0], x1)).all(axis=1) & (
        (faces[..., 1] > y0 - 1e-9) & (faces[..., 1] < y1 + 1e-9)).all(axis=1)
    assert not on_side.any()
    horizontal_in_span = (np.isclose(faces[..., 1], y0) | np.isclose(faces[..., 1], y1)).all(axis=1) & (
        (faces[..., 0] > x0 - 1e-9) & (faces[..., 0] < x1 + 1e-9)).all(axis=1)
    assert not horizontal_in_span.any()


def test_openings_off_the_bond_grid_or_outside_the_wall_are_refused():
    with pytest.raises(MeshError, match="half-unit grid.*110"):
        BrickWallLayout(**dict(WALL, openings=((300.0, 660.0, 372.0, 620.0),)))
    with pytest.raises(MeshError, match="course boundaries.*62"):
        BrickWallLayout(**dict(WALL, openings=((330.0, 660.0, 370.0, 620.0),)))
    with pytest.raises(MeshError, match="overlap"):
        BrickWallLayout(**dict(WALL, openings=(OPENING, (550.0, 770.0, 496.0, 744.0))))
    with pytest.raises(SpecError, match="opening_width = 300.*multiples of half a unit"):
        build_scenario({"scenario": "wall_opening_nl", "opening_width": 300.0})
    with pytest.raises(SpecError, match="opening_sill = 0.*outside the wall"):
        build_scenario({"scenario": "wall_opening_nl", "opening_sill": 0.0})
    with pytest.raises(SpecError, match="opening_height = 100.*unit height"):
        build_scenario({"scenario": "wall_opening_nl", "opening_height": 100.0})


def test_defaults_are_set_B_and_the_opening_is_stated():
    """``podkrig scenarios wall_opening_nl`` states Set B and the opening's four options."""
    d = describe_scenario("wall_opening_nl")
    defaults = {p.name: p.default for p in d.parameters}
    for name, value in SET_B.items():
        assert defaults[name] == value, name
    assert (defaults["kN_bj"], defaults["ft_bj"], defaults["c_bj"]) == (110.0, 0.16, 0.224)
    assert {k: d.options[k] for k in ("opening_left", "opening_width", "opening_sill", "opening_height")} == {
        "opening_left": 330.0, "opening_width": 330.0, "opening_sill": 372.0, "opening_height": 248.0}
    assert d.options["base_joints"] and d.options["top"] == "fixed_vertical"
    assert d.load_levels[-1] == 3.0  # the whole range: mesh-objective for this wall (BENCHMARKS.md)
    assert build_scenario(dict(SHORT, load_levels=[3.0])).mesh_objective_limit is None
    assert "opening" in d.summary and "Set B" in d.summary
    sc = build_scenario({"scenario": "wall_opening_nl", "opening_left": 220.0, "opening_width": 550.0, "nx": 2, "ny": 1})
    assert sc.mesh.width == 990.0 and sc.options.openings == ((220.0, 770.0, 372.0, 620.0),)


def _solve(sc, values, tolerance, target):
    """Follow ``sc``'s path to the control displacement ``target`` (mm) at ``tolerance``; the follower."""
    model = sc.model
    model.set_units(sc.theta(values))
    law = CompositeInterface(interface_properties(sc.mesh, model.interface_elements, values,
                                                  model.n_points_per_element))
    follower = PathFollower(model, law, dataclasses.replace(sc.options.path_settings(), tolerance=tolerance))
    phases = sc.phases(values)
    phases[-1] = dataclasses.replace(phases[-1], target=target, levels=(target,))
    follower.run(phases)
    return follower


@pytest.mark.parametrize("top", ["constant_force", "fixed_vertical"])
def test_statics_every_section_carries_the_applied_loads_at_several_steps(top):
    """At 0.1, 0.2 and 0.3 mm (the wall cracking beside the opening, then at the beams) the shear
    force of every horizontal section — the joints against the beams, the sections through the two
    piers beside the opening, and those at its sill and lintel where the opening's faces are free —
    equals the horizontal load H (the controlled beam's reaction), and the normal force the
    vertical force on the wall (N held, or the fixed beam's vertical reaction). Converged to 1e-9 so
    that equilibrium holds to ~1e-11; sections agree to 1e-8 relative."""
    sc = build_scenario(dict(SHORT, top=top))
    values = sc.resolve()
    model = sc.model
    w = model.weights.ravel()
    y = model.point_coordinates()[:, 1]
    bed = np.repeat(sc.mesh.interface_kind[model.interface_elements], model.n_points_per_element) == 0
    for target in (0.1, 0.2, 0.3):
        follower = _solve(sc, values, 1e-9, target)
        path = follower.result
        assert path.status == CONVERGED and path.path[-1] == pytest.approx(target)
        H = path.load[-1]
        held = path.held_reactions[-1]
        N = sc.vertical_force - (held[0] if len(held) else 0.0)
        assert H > 5.0 and N > 0.0
        t = follower.state.traction
        for level in np.arange(17) * 62.0:
            section = bed & (np.abs(y - level) < 1e-6)
            through_opening = 372.0 <= level <= 620.0
            assert np.count_nonzero(section) == (27 - 9 if through_opening else 27)
            assert_allclose(np.sum(w[section] * t[section, 1]) / 1000, H, rtol=1e-8, atol=0)
            assert_allclose(-np.sum(w[section] * t[section, 0]) / 1000, N, rtol=1e-8, atol=0)


def test_the_first_cracks_open_at_the_opening():
    """Stresses concentrate at the opening's corners: under the horizontal load the first joint
    points past the elastic opening f_t/k_n lie in the course above the lintel or below the sill,
    within a unit of the opening's sides (both top conditions); the heel of the joint against the
    bottom beam follows."""
    for top in ("constant_force", "fixed_vertical"):
        sc = build_scenario(dict(SHORT, top=top))
        r = sc.run(field=True)
        assert r.status == CONVERGED
        xy = sc.model.point_coordinates()
        kinds = np.repeat(sc.mesh.interface_kind[sc.model.interface_elements], sc.model.n_points_per_element)
        joint = kinds != INTERFACE_KINDS.index("brick")
        steps = np.flatnonzero(r.path.of_phase("shear"))
        first = next(i for i in steps if np.any(joint & (r.path.states[i]["opening"] > 0.16 / 110.0)))
        x, y = xy[joint & (r.path.states[first]["opening"] > 0.16 / 110.0)].T
        assert np.all(((y >= 620.0) & (y <= 682.0)) | ((y >= 310.0) & (y <= 372.0)))
        assert np.all((x >= 330.0 - 220.0) & (x <= 660.0 + 220.0))
        assert np.any(r.path.states[steps[-1]]["opening"][joint & (xy[:, 1] == 0.0) & (xy[:, 0] == 0.0)] > 0.16 / 110)


def test_linear_limit_is_the_linear_solver_on_the_same_mesh():
    """With strengths far beyond the stresses, the wall with the opening (N constant) equals a linear
    solve of the same mesh, supports and loads (the linear model of ``shear_compression`` built on
    this mesh) loaded by the computed horizontal reactions: readings to 1e-10 relative. Its initial
    stiffness is therefore the linear one: the opening makes the wall softer than the solid wall."""
    huge = {"ft_bj": 1e3, "c_bj": 1e4, "GfI_bj": 1e9, "GfII_bj": 1e9, "fc": 1e6, "ft_bb": 1e4, "GfI_bb": 1e9}
    nl = build_scenario({"scenario": "wall_opening_nl", "top": "constant_force", "load_levels": [0.2, 0.5],
                         "increment": 0.2, "max_increment": 0.2, "nx": 2, "ny": 1})
    r = nl.run(huge)
    assert r.status == CONVERGED
    mesh, o = nl.mesh, nl.options
    bottom, top = mesh.node_sets["bottom_beam"], mesh.node_sets["top_beam"]
    T = constraint_transform(mesh.n_dofs, np.concatenate([2 * bottom, 2 * bottom + 1]),
                             ties=[2 * top, 2 * top + 1])
    patterns = np.zeros((mesh.n_dofs, 2))
    patterns[2 * top[0] + 1, 0] = -o.precompression * mesh.width * o.thickness
    patterns[2 * top[0], 1] = 1.0
    linear = LinearModel(mesh, masonry_parts(mesh, o.thickness), T, patterns, nl.sensors)
    unit = linear.readings(linear.solve(masonry_theta(nl.resolve())))  # N alone; H = 1 N alone
    readings = unit[0] + 1000.0 * r.loads[:, None] * unit[1]
    # the sensors; the last channel is the load reading F, the horizontal load itself
    assert r.sensor_names[:-1] == tuple(s.name for s in nl.sensors) and r.sensor_names[-1] == "F"
    assert_allclose(r.readings[:, :-1], readings, rtol=1e-10, atol=1e-10 * np.abs(readings).max())
    assert_allclose(r.readings[:, -1], r.loads, rtol=1e-12, atol=0)
    solid = build_scenario({"scenario": "shear_compression_nl", "top": "constant_force", "nx": 2, "ny": 1,
                            "element": "Q8", "base_joints": True, "load_levels": [0.2], "increment": 0.2,
                            "max_increment": 0.2})
    assert r.loads[0] < 0.95 * solid.run(dict(huge, kN_bj=110.0, kV_bj=50.0)).loads[0]


@pytest.mark.slow
@pytest.mark.parametrize("top", ["fixed_vertical", "constant_force"])
def test_default_run_reaches_the_end_of_the_control_range(top):
    """The default scenario (both top conditions) reaches the last level with every level read, a
    refined peak, and N held (constant force) or growing with the rocking (top fixed)."""
    sc = build_scenario({"scenario": "wall_opening_nl", "top": top})
    r = sc.run()
    assert r.status == CONVERGED and r.reached == pytest.approx(sc.options.load_levels[-1]) == 3.0
    assert r.mesh_objective
    assert np.isfinite(r.loads).all() and np.isfinite(r.readings).all()
    assert 0 < r.peak_load and r.peak_load >= np.max(r.loads) * (1 - 1e-3)
    N = r.extra["vertical_reaction"]
    if top == "constant_force":
        assert_allclose(N, 29.7, rtol=1e-9)
    else:
        assert N[-1] > 29.7
    assert r.peak_load < 0.224 * 990 * 100 / 1000 + 0.75 * np.max(N)  # below sliding on one full bed joint


def test_mesh_convergence_script_imports_without_side_effects_and_tables_a_run():
    """``scripts/bench_wall_opening.py`` (the BENCHMARKS.md mesh study) imports without running, runs
    one mesh to the end of the range and tables it against itself (the finest of a one-mesh ladder)."""
    bench = load_file(Path(__file__).resolve().parents[1] / "scripts" / "bench_wall_opening.py")
    row = bench.run("2x1", "constant_force")
    assert row["status"] == CONVERGED and row["reached"] == 3.0 and row["cpu"] > 0
    text = bench.table([row])
    assert "| 2x1 | 2114 | converged |" in text and "within 1 % of the finest: 2x1" in text
