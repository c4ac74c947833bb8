"""Brick-wall mesh generator, named sets, load patches and sensors."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from fe.exceptions import MeshError, SensorError
from fe.mesh import BrickWallLayout, brick_wall
from fe.sensors import DICGrid, Gauge, PointDisplacement, sensor_operator


@pytest.mark.parametrize("element", ["Q8", "Q4"])
def test_default_panel_counts(element):
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2, element=element))
    assert (mesh.width, mesh.height) == (1170.0, 1170.0)
    # 18 courses: 9 of 4 full + 1 half, 9 of 1 half + 4 full → 72 full, 18 half units
    assert len(mesh.block_unit) == 72 * 2 + 18
    assert len(np.unique(mesh.block_unit)) == 90
    n_edges_per_joint = 1170 / 65  # 4 elements per unit, 65 mm each
    assert np.count_nonzero(mesh.interfaces_of_kind("bed")) == 17 * n_edges_per_joint
    assert np.count_nonzero(mesh.interfaces_of_kind("head")) == 18 * 4 * 2  # 4 head joints per course, ny = 2
    assert np.count_nonzero(mesh.interfaces_of_kind("brick")) == 72 * 2
    assert mesh.check() == []


@pytest.mark.parametrize("element", ["Q8", "Q4"])
def test_base_joints_join_the_wall_to_two_beams_and_keep_the_walls_numbering(element):
    """With ``base_joints`` the wall sits on a beam and under another, one course high and one
    element across, joined by bed joints at y = 0 and y = H; the wall's nodes, quads and node
    numbers are those of the plain wall, the beams' node sets hold every beam node, and the
    outer-face sets move to the beams' faces."""
    layout = dict(n_courses=3, units_per_course=2, nx=2, ny=1, element=element)
    plain = brick_wall(BrickWallLayout(**layout))
    mesh = brick_wall(BrickWallLayout(**layout, base_joints=True))
    assert mesh.check() == []
    assert_allclose(mesh.nodes[: plain.n_nodes], plain.nodes, rtol=0, atol=0)
    assert np.array_equal(mesh.quads[: len(plain.quads)], plain.quads)
    assert (mesh.width, mesh.height) == (plain.width, plain.height + 2 * 65.0)
    bed = mesh.interfaces_of_kind("bed")
    y = mesh.nodes[mesh.interfaces[:, 0], 1]
    per_joint = 2 * 2  # two units of two elements each
    assert np.count_nonzero(bed & (y == 0.0)) == np.count_nonzero(bed & (y == 195.0)) == per_joint
    assert np.count_nonzero(bed) == np.count_nonzero(plain.interfaces_of_kind("bed")) + 2 * per_joint
    assert len(mesh.interfaces) == len(plain.interfaces) + 2 * per_joint
    bottom, top = mesh.node_sets["bottom_beam"], mesh.node_sets["top_beam"]
    assert_allclose(mesh.nodes[bottom, 1].min(), -65.0) and np.all(mesh.nodes[bottom, 1] <= 0.0)
    assert np.all(mesh.nodes[top, 1] >= 195.0) and mesh.nodes[top, 1].max() == 260.0
    assert len(bottom) + len(top) == mesh.n_nodes - plain.n_nodes
    assert set(mesh.node_sets["bottom"]) <= set(bottom) and set(mesh.node_sets["top"]) <= set(top)
    beam_blocks = np.unique(mesh.quad_block[len(plain.quads):])
    assert len(beam_blocks) == 2 and len(np.unique(mesh.block_unit)) == len(np.unique(plain.block_unit)) + 2
    # face A below face B: the normal points from the bottom beam into the wall, from the wall into the top beam
    a, b = mesh.interface_blocks[bed & ((y == 0.0) | (y == 195.0))].T
    centre = 0.5 * (mesh.block_bounds[:, 1] + mesh.block_bounds[:, 3])
    assert np.all(centre[b] > centre[a])


def test_running_bond_course_layout():
    layout = BrickWallLayout()
    assert_allclose(layout.course_units(0), [[0, 260], [260, 520], [520, 780], [780, 1040], [1040, 1170]])
    assert_allclose(layout.course_units(1), [[0, 130], [130, 390], [390, 650], [650, 910], [910, 1170]])
    stack = BrickWallLayout(bond="stack")
    assert_allclose(stack.course_units(1), stack.course_units(0))


def test_every_unit_has_its_own_nodes():
    mesh = brick_wall(BrickWallLayout(n_courses=3, units_per_course=2, nx=2, ny=1))
    owner = -np.ones(mesh.n_nodes, int)
    for q, b in zip(mesh.quads, mesh.quad_block):
        assert np.all((owner[q] == -1) | (owner[q] == b))
        owner[q] = b


def test_interface_normals_point_from_face_a_to_face_b():
    mesh = brick_wall(BrickWallLayout(n_courses=2, units_per_course=2, nx=2, ny=1))
    centre = 0.5 * (mesh.block_bounds[:, :2] + mesh.block_bounds[:, 2:])
    a, b = mesh.interface_blocks.T
    x = mesh.nodes[mesh.interfaces]
    s = x[:, 1] - x[:, 0]
    n = np.column_stack([-s[:, 1], s[:, 0]])
    assert np.all(np.einsum("ij,ij->i", n, centre[b] - centre[a]) > 0)


def test_brick_interfaces_can_be_switched_off():
    mesh = brick_wall(BrickWallLayout(n_courses=2, units_per_course=2, nx=2, ny=1, brick_interfaces=False))
    assert not mesh.interfaces_of_kind("brick").any()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"nx": 3}, "nx must be an even integer"),
        ({"units_per_course": 4.3}, "multiple of 0.5"),
        ({"bond": "flemish"}, "bond must be 'running' or 'stack'"),
        ({"unit_height": 0.0}, "unit_height must be > 0"),
    ],
)
def test_bad_layouts_are_refused(kwargs, match):
    with pytest.raises(MeshError, match=match):
        BrickWallLayout(**kwargs)


def test_named_sets_on_faces():
    mesh = brick_wall(BrickWallLayout(n_courses=2, units_per_course=1.5, nx=2, ny=1))
    assert np.all(mesh.nodes[mesh.node_sets["top"], 1] == mesh.height)
    assert_allclose(mesh.nodes[mesh.node_sets["bottom_left"]], [[0.0, 0.0]])
    for face, (coord, value) in {"bottom": (1, 0), "top": (1, mesh.height), "left": (0, 0), "right": (0, mesh.width)}.items():
        assert np.all(mesh.nodes[mesh.edge_sets[face], coord] == value)
    assert_allclose(np.abs(np.diff(mesh.nodes[mesh.edge_sets["top"][:, :2], 0], axis=1)).sum(), mesh.width, rtol=1e-14)


def _linear_field(mesh, grad):
    """Nodal displacements of the homogeneous field u = grad @ x, ``(n_dofs,)``."""
    return (mesh.nodes @ np.asarray(grad).T).ravel()


@pytest.mark.parametrize("element", ["Q8", "Q4"])
def test_gauge_reads_elongation_positive_when_apart(element):
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2, element=element))
    gauges = [Gauge("H", (10.0, 30.0), (110.0, 30.0)), Gauge("D", (302.157, 302.157), (867.843, 867.843))]
    H, names = sensor_operator(mesh, gauges)
    assert names == ("H", "D")
    eps = 1e-4  # uniform stretch along x: ε_xx = 1e-4
    readings = H @ _linear_field(mesh, [[eps, 0.0], [0.0, 0.0]])
    # along a 45° line the normal strain of pure ε_xx is ε/2
    assert_allclose(readings, [eps * 100.0, eps / 2 * gauges[1].length], rtol=1e-12)
    # a rigid rotation gives no gauge reading
    assert_allclose(H @ _linear_field(mesh, [[0.0, -1e-3], [1e-3, 0.0]]), 0.0, rtol=0, atol=1e-15)


def test_point_and_dic_sensors():
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2))
    dic = DICGrid("DIC", 100.0, 100.0, 1000.0, 1000.0, 3, 4)
    H, names = sensor_operator(mesh, [PointDisplacement("P", (123.0, 456.0), "y"), dic])
    assert len(names) == 1 + 2 * 12 and names[1] == "DIC[0,0].ux"
    grad = [[1e-4, 2e-4], [3e-4, -1e-4]]
    r = H @ _linear_field(mesh, grad)
    assert_allclose(r[0], 3e-4 * 123 - 1e-4 * 456, rtol=1e-12)
    pts = dic.points
    assert_allclose(r[1:].reshape(-1, 2), pts @ np.array(grad).T, rtol=1e-12)


def test_dic_subset_averages_the_field_over_its_square():
    """A subset reads the mean over its square (midpoint rule on m × m cells): a linear field
    (reproduced exactly by the elements, joints included) reads its centre value for any subset;
    a unit jump across a bed joint 2.5 mm above the centre, with a 15 mm subset and 4 × 4 samples,
    reads 1/4 (one row of samples, at +5.625 mm, lies above; the exact area share is 1/3 — the
    midpoint rule's resolution is 1/m)."""
    mesh = brick_wall(BrickWallLayout(n_courses=4, units_per_course=2, nx=4, ny=2))
    plain = DICGrid("P", 200.0, 62.5, 300.0, 127.5, 3, 2)
    sub = DICGrid("S", 200.0, 62.5, 300.0, 127.5, 3, 2, subset=15.0)
    assert sub.to_dict()["subset"] == 15.0 and "subset" not in plain.to_dict()
    assert len(sub.points) == 6 and len(sub.sample_points) == 6 * 16
    H_plain, names = sensor_operator(mesh, [plain])
    H_sub, names_sub = sensor_operator(mesh, [sub])
    assert names_sub == tuple(n.replace("P", "S", 1) for n in names)
    x, y = mesh.nodes.T
    u = np.column_stack([1e-3 * x - 2e-3 * y + 0.1, 5e-4 * x + 3e-3 * y - 0.2]).ravel()
    assert_allclose(H_sub @ u, H_plain @ u, rtol=1e-12, atol=1e-14)
    above = np.zeros(mesh.n_nodes)
    for q in mesh.quads:  # the units above the bed joint y = 65 mm
        if mesh.nodes[q, 1].min() >= 65.0 - 1e-9:
            above[q] = 1.0
    jump = np.column_stack([np.zeros(mesh.n_nodes), above]).ravel()
    low_row = (H_sub @ jump)[1::2].reshape(3, 2)[:, 0]  # uy at y = 62.5, 2.5 mm below the joint
    assert_allclose(low_row, 0.25, rtol=0, atol=1e-12)
    assert_allclose((H_plain @ jump)[1::2].reshape(3, 2)[:, 0], 0.0, atol=1e-12)
    with pytest.raises(SensorError, match="subset .*>= 0 mm"):
        DICGrid("bad", 0, 0, 1, 1, 1, 1, subset=-1.0)


@pytest.mark.parametrize(
    "point, what",
    [((600.0, 585.0), "bed joint"), ((520.0, 552.5), "head joint"), ((650.0, 552.5), "unit mid-plane")],
)
def test_gauge_point_on_an_interface_is_refused_naming_the_gauge(point, what):
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2))
    with pytest.raises(SensorError, match="sensor 'G7'.*lies on an interface"):
        sensor_operator(mesh, [Gauge("G7", point, (700.0, 700.0))])


def test_sensor_outside_the_specimen_is_refused():
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2))
    with pytest.raises(SensorError, match="'far'.*outside the specimen"):
        sensor_operator(mesh, [PointDisplacement("far", (2000.0, 10.0), "x")])


def test_duplicate_sensor_names_are_refused():
    mesh = brick_wall(BrickWallLayout(nx=4, ny=2))
    g = Gauge("A", (10.0, 30.0), (110.0, 30.0))
    with pytest.raises(SensorError, match="unique"):
        sensor_operator(mesh, [g, g])


def test_continuum_mesh_merges_coincident_nodes():
    mesh = brick_wall(BrickWallLayout(n_courses=2, units_per_course=1, nx=2, ny=1, element="Q4"))
    cont = mesh.without_interfaces()
    # stack of 2 units × 2 elements, Q4: a 3 × 3 node grid
    assert cont.n_nodes == 9 and len(cont.interfaces) == 0
    assert np.unique(cont.quads).size == 9


def test_plain_wall_nodes_are_linspace_grids_bit_for_bit():
    """Every block of a plain wall has its nodes on ``linspace`` grids over the block, exactly: the
    options that add node lines (slots, refinement) must not move a default mesh's nodes by a
    rounding, or every stored snapshot and reference reading would change."""
    mesh = brick_wall(BrickWallLayout(nx=6, ny=2, element="Q8"))
    for b in range(mesh.quad_block.max() + 1):
        nodes = mesh.nodes[np.unique(mesh.quads[mesh.quad_block == b])]
        for axis in (0, 1):
            values = np.unique(nodes[:, axis])
            expected = np.linspace(values[0], values[-1], len(values))
            assert np.array_equal(values, expected), (b, axis)
