"""Brick-wall mesh generator: expanded units, running or stack bond, zero-thickness joints.

Each masonry unit is *expanded* (unit plus half a joint on each side) and meshed with its own
nodes; bed joints, head joints and, optionally, the vertical mid-plane of every full unit
(the potential brick crack, thesis §2) become zero-thickness interfaces.

Example
-------
>>> from fe.mesh import BrickWallLayout, brick_wall
>>> mesh = brick_wall(BrickWallLayout(n_courses=2, units_per_course=2, nx=2, ny=1))
>>> mesh.width, mesh.height
(520.0, 130.0)
"""

import itertools
from dataclasses import dataclass

import numpy as np

from ..exceptions import MeshError
from .mesh import INTERFACE_KINDS, Mesh

_ROUND = 6  # decimals used to match coincident coordinates (mm): 1 nm


def on_grid(value, step):
    """True when ``value`` is a whole multiple of ``step`` (to 1e-9 of a step)."""
    return abs(value / step - round(value / step)) < 1e-9


@dataclass(frozen=True)
class BrickWallLayout:
    """Geometry and discretisation of a brick wall.

    Parameters
    ----------
    unit_length, unit_height : float
        Expanded unit size (unit plus one joint thickness), mm.
    n_courses : int
        Number of courses; course 0 is at the bottom.
    units_per_course : float
        Wall width in expanded units, a multiple of 0.5.
    bond : {"running", "stack"}
        Running bond: even courses start with a full unit at x = 0, odd courses with a half
        unit. Stack bond: every course starts with a full unit.
    nx, ny : int
        Elements along the length and height of a full unit; ``nx`` must be even so that half
        units and unit mid-planes fall on element edges.
    element : {"Q8", "Q4"}
        Continuum element; interfaces are 6-node or 4-node to match.
    brick_interfaces : bool
        Put an interface on the vertical mid-plane of every full unit.
    x_lines : tuple of float
        Extra vertical node lines (mm) through the whole wall, e.g. at the ends of a slot that
        do not fall on the regular grid of ``nx`` elements per unit.
    cuts : tuple of (x, y0, y1)
        Vertical lines (mm) splitting every unit they cross in the courses between ``y0`` and
        ``y1`` (course boundaries) into two blocks joined by a ``"brick"`` interface, e.g. the
        line of a vertical slot through units; ``x`` is also a node line through the wall.
    refine : tuple
        ``()`` or a window ``(x0, x1, y0, y1)`` (mm) meshed twice as finely: extra node lines at
        half the spacing for ``x0 < x < x1`` through the whole wall (lines must run through every
        course to keep the bed-joint faces matching) and ``2 ny`` elements across the courses
        inside ``[y0, y1]``.
    base_joints : bool
        Lay the wall on a loading beam and cap it with another, each joined to the wall by a bed
        joint (interfaces of kind ``"bed"`` at y = 0 and y = ``height``), as walls are built
        between steel beams. Each beam is one block one course high (``unit_height``) spanning the
        wall, on the wall's vertical node lines, one element across, and the last two units of
        ``block_unit`` (bottom, then top). The beams' nodes are the node sets ``bottom_beam`` and
        ``top_beam``: a scenario holds or ties all of them, so the beams are rigid. The wall's own
        nodes and their numbers are those of the wall without beams (the beams' come after).
    openings : tuple of (x0, x1, y0, y1)
        Rectangular openings (mm) left without units, e.g. a window. Their sides lie on the bond's
        half-unit grid (multiples of ``unit_length / 2``) and on course boundaries (multiples of
        ``unit_height``), strictly inside the wall, so that the units beside an opening are whole or
        half units (running bond: a half unit beside the opening every other course) and no element
        lies in it. A unit cut by an opening keeps its part outside as a unit of its own; the
        opening's sides are free faces (no joint).
    """

    unit_length: float = 260.0
    unit_height: float = 65.0
    n_courses: int = 18
    units_per_course: float = 4.5
    bond: str = "running"
    nx: int = 4
    ny: int = 2
    element: str = "Q8"
    brick_interfaces: bool = True
    x_lines: tuple = ()
    cuts: tuple = ()
    refine: tuple = ()
    base_joints: bool = False
    openings: tuple = ()

    def __post_init__(self):
        for name in ("unit_length", "unit_height"):
            if not getattr(self, name) > 0:
                raise MeshError(f"{name} must be > 0 mm; got {getattr(self, name)}")
        if int(self.n_courses) != self.n_courses or self.n_courses < 1:
            raise MeshError(f"n_courses must be an integer >= 1; got {self.n_courses}")
        if self.units_per_course < 0.5 or (2 * self.units_per_course) % 1:
            raise MeshError(
                f"units_per_course must be a multiple of 0.5 and >= 0.5; got {self.units_per_course}"
            )
        if self.bond not in ("running", "stack"):
            raise MeshError(f"bond must be 'running' or 'stack'; got {self.bond!r}")
        if int(self.nx) != self.nx or self.nx < 2 or self.nx % 2:
            raise MeshError(f"nx must be an even integer >= 2 (half units); got {self.nx}")
        if int(self.ny) != self.ny or self.ny < 1:
            raise MeshError(f"ny must be an integer >= 1; got {self.ny}")
        if self.element not in ("Q4", "Q8"):
            raise MeshError(f"element must be 'Q4' or 'Q8'; got {self.element!r}")
        object.__setattr__(self, "x_lines", tuple(float(x) for x in self.x_lines))
        object.__setattr__(self, "cuts", tuple(tuple(float(v) for v in c) for c in self.cuts))
        object.__setattr__(self, "refine", tuple(float(v) for v in self.refine))
        for x in self.x_lines:
            if not 0 < x < self.width:
                raise MeshError(f"x_lines: {x} mm is outside the wall (0, {self.width:g})")
        for c in self.cuts:
            if len(c) != 3:
                raise MeshError(f"cuts: each cut is (x, y0, y1) in mm; got {c}")
            x, y0, y1 = c
            if not 0 < x < self.width:
                raise MeshError(f"cuts: x = {x} mm is outside the wall (0, {self.width:g})")
            k0, k1 = y0 / self.unit_height, y1 / self.unit_height
            if not (0 <= k0 < k1 <= self.n_courses and abs(k0 - round(k0)) < 1e-9 and abs(k1 - round(k1)) < 1e-9):
                raise MeshError(
                    f"cuts: ({x:g}, {y0:g}, {y1:g}) mm must span whole courses: y0 < y1 multiples of "
                    f"the unit height {self.unit_height:g} mm within the wall"
                )
        object.__setattr__(self, "openings", tuple(tuple(float(v) for v in o) for o in self.openings))
        for o in self.openings:
            self._check_opening(o)
        for a, b in itertools.combinations(self.openings, 2):
            if a[0] < b[1] and b[0] < a[1] and a[2] < b[3] and b[2] < a[3]:
                raise MeshError(f"openings {a} and {b} overlap; give one rectangle for their union")
        if self.refine and (len(self.refine) != 4 or not (self.refine[0] < self.refine[1] and self.refine[2] < self.refine[3])):
            raise MeshError(f"refine must be () or (x0, x1, y0, y1) with x0 < x1, y0 < y1 (mm); got {self.refine}")

    def _check_opening(self, o):
        """An opening is (x0, x1, y0, y1) mm on the half-unit grid and course boundaries, inside."""
        if len(o) != 4:
            raise MeshError(f"openings: each opening is (x0, x1, y0, y1) in mm; got {o}")
        x0, x1, y0, y1 = o
        half, H = self.unit_length / 2, self.unit_height
        if not (0 < x0 < x1 < self.width and on_grid(x0, half) and on_grid(x1, half)):
            raise MeshError(
                f"openings: x0 = {x0:g}, x1 = {x1:g} mm must satisfy 0 < x0 < x1 < {self.width:g} (the wall) and lie on "
                f"the half-unit grid (multiples of {half:g} mm) so that the units beside the opening are whole or half")
        if not (0 < y0 < y1 < self.height and on_grid(y0, H) and on_grid(y1, H)):
            raise MeshError(
                f"openings: y0 = {y0:g}, y1 = {y1:g} mm must satisfy 0 < y0 < y1 < {self.height:g} (the wall) and lie "
                f"on course boundaries (multiples of the unit height {H:g} mm)")

    def in_opening(self, x, y):
        """True where the points ``(x, y)`` (mm, arrays) lie strictly inside an opening."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        inside = np.zeros(np.broadcast(x, y).shape, bool)
        for x0, x1, y0, y1 in self.openings:
            inside |= (x > x0) & (x < x1) & (y > y0) & (y < y1)
        return inside

    def course_openings(self, course):
        """x of the sides of the openings that cross a course (mm)."""
        y0, y1 = course * self.unit_height, (course + 1) * self.unit_height
        return [x for o in self.openings if o[2] <= y0 + 1e-9 and y1 <= o[3] + 1e-9 for x in o[:2]]

    @property
    def width(self):
        return self.units_per_course * self.unit_length

    @property
    def height(self):
        return self.n_courses * self.unit_height

    def course_units(self, course):
        """Left and right x of each unit of a course, ``(n_units, 2)`` in mm."""
        L, W = self.unit_length, self.width
        x = [0.0]
        if self.bond == "running" and course % 2 == 1:
            x.append(min(L / 2, W))
        while W - x[-1] > 1e-9:
            x.append(min(x[-1] + L, W))
        x = np.array(x)
        return np.column_stack([x[:-1], x[1:]])

    def vertical_lines(self):
        """x of every vertical element edge through the wall (mm), sorted: the regular grid of
        ``nx`` elements per unit, the refinement lines, ``x_lines`` and the cut lines.

        Raises
        ------
        MeshError
            Two lines closer than a tenth of the regular spacing (a sliver element).
        """
        h = self.unit_length / self.nx
        n = round(self.width / h)
        lines = [np.arange(n + 1) * h, np.array(self.x_lines), np.array([c[0] for c in self.cuts])]
        if self.refine:
            x0, x1 = self.refine[:2]
            lines.append(np.arange(2 * n + 1)[1::2] * (h / 2))
            lines[-1] = lines[-1][(lines[-1] > x0) & (lines[-1] < x1)]
        x = np.unique(np.round(np.concatenate(lines), _ROUND))
        close = np.flatnonzero(np.diff(x) < 0.1 * h * (0.5 if self.refine else 1.0))
        if len(close):
            i = close[0]
            raise MeshError(
                f"vertical node lines at x = {x[i]:g} and {x[i + 1]:g} mm are too close (sliver "
                f"elements); move the slot end or the line onto the element grid (spacing {h:g} mm)"
            )
        return x

    def course_ny(self, course):
        """Elements across the height of a course: ``2 ny`` inside the refinement window."""
        if self.refine:
            y0, y1 = course * self.unit_height, (course + 1) * self.unit_height
            if y0 >= self.refine[2] - 1e-9 and y1 <= self.refine[3] + 1e-9:
                return 2 * self.ny
        return self.ny

    def course_cuts(self, course):
        """x of the cuts through the units of a course (mm)."""
        y0, y1 = course * self.unit_height, (course + 1) * self.unit_height
        return [c[0] for c in self.cuts if c[1] <= y0 + 1e-9 and y1 <= c[2] + 1e-9]


def _node_lines(edges, quadratic, regular=False):
    """Node coordinates along one axis of a block: the element edges, plus the mid-side nodes of
    quadratic elements. ``regular``: equally spaced edges, whose nodes are computed by one
    ``linspace`` over the block (the default walls' nodes, bit for bit as they always were)."""
    edges = np.asarray(edges, float)
    k = 2 if quadratic else 1
    if regular:
        return np.linspace(edges[0], edges[-1], k * (len(edges) - 1) + 1)
    if quadratic:
        return np.insert(edges, np.arange(1, len(edges)), 0.5 * (edges[1:] + edges[:-1]))
    return edges


def _block_grid(xs, ys, quadratic, regular=False):
    """Nodes and connectivity of one rectangular block with element edges at ``xs`` × ``ys``
    (``regular``: equally spaced, see :func:`_node_lines`).

    Returns node coordinates, quads (local numbering) and the full-grid index map.
    """
    k = 2 if quadratic else 1
    mx, my = len(xs) - 1, len(ys) - 1
    gx, gy = _node_lines(xs, quadratic, regular), _node_lines(ys, quadratic, regular)
    I, J = np.meshgrid(np.arange(len(gx)), np.arange(len(gy)), indexing="ij")
    keep = ~((I % 2 == 1) & (J % 2 == 1)) if quadratic else np.ones_like(I, bool)
    index = -np.ones(I.shape, np.intp)
    index[keep] = np.arange(np.count_nonzero(keep))
    nodes = np.column_stack([gx[I[keep]], gy[J[keep]]])
    a, b = np.meshgrid(np.arange(mx), np.arange(my), indexing="ij")
    a, b = k * a.ravel(), k * b.ravel()
    corners = [(a, b), (a + k, b), (a + k, b + k), (a, b + k)]
    if quadratic:
        corners += [(a + 1, b), (a + 2, b + 1), (a + 1, b + 2), (a, b + 1)]
    quads = np.column_stack([index[i, j] for i, j in corners])
    return nodes, quads, index


def brick_wall(layout=BrickWallLayout()):
    """Mesh a brick wall.

    Parameters
    ----------
    layout : BrickWallLayout
        Geometry and discretisation.

    Returns
    -------
    Mesh
        With node sets ``bottom``, ``top``, ``left``, ``right``, ``bottom_left``,
        ``bottom_right``, ``top_left``, ``top_right`` and edge sets ``bottom``, ``top``,
        ``left``, ``right`` on the outer faces of the mesh (with ``base_joints``: the beams'
        outer faces), plus ``bottom_beam`` and ``top_beam`` (every node of each beam) with
        ``base_joints``.
    """
    quadratic = layout.element == "Q8"
    L, H = layout.unit_length, layout.unit_height
    nodes, quads, quad_block, block_unit, bounds = [], [], [], [], []
    edges = []  # (block, side, start, end, mid, key) for every block-boundary element edge
    n_nodes = n_units = 0
    lines = layout.vertical_lines()
    regular = not (layout.x_lines or layout.cuts or layout.refine)
    face_xs = {}  # element edges (x, mm) of the bottom and top courses' blocks, for the beams
    for course in range(layout.n_courses):
        y0, y1 = course * H, (course + 1) * H
        ys = np.linspace(y0, y1, layout.course_ny(course) + 1)
        cuts = layout.course_cuts(course) + layout.course_openings(course)
        for ux0, ux1 in layout.course_units(course):
            full = abs((ux1 - ux0) - L) < 1e-9
            splits = [ux0, 0.5 * (ux0 + ux1), ux1] if full and layout.brick_interfaces else [ux0, ux1]
            splits = sorted(set(np.round(splits + [x for x in cuts if ux0 + 1e-9 < x < ux1 - 1e-9], _ROUND)))
            blocks = [(bx0, bx1) for bx0, bx1 in itertools.pairwise(splits)
                      if not layout.in_opening(0.5 * (bx0 + bx1), 0.5 * (y0 + y1))]
            if not blocks:
                continue  # a unit wholly inside an opening
            for bx0, bx1 in blocks:
                xs = lines[(lines >= bx0 - 1e-9) & (lines <= bx1 + 1e-9)]
                if regular:  # the plain wall: nodes exactly as linspace over the block gives them
                    xs = np.linspace(bx0, bx1, len(xs))
                xy, q, index = _block_grid(xs, ys, quadratic, regular)
                if course in (0, layout.n_courses - 1):
                    face_xs.setdefault(course, []).append(xs)
                block = len(bounds)
                nodes.append(xy)
                quads.append(q + n_nodes)
                quad_block.append(np.full(len(q), block))
                block_unit.append(n_units)
                bounds.append((bx0, y0, bx1, y1))
                _collect_edges(edges, block, index + n_nodes, xy, n_nodes, quadratic)
                n_nodes += len(xy)
            n_units += 1
    beams = {}
    if layout.base_joints:  # the loading beams: one block each, below and above the wall
        for name, course, y0, y1 in (("bottom_beam", 0, -H, 0.0),
                                     ("top_beam", layout.n_courses - 1, layout.height, layout.height + H)):
            # on the adjacent course's element edges, bit for bit: the joint's faces coincide
            xs = np.unique(np.concatenate(face_xs[course]))
            xy, q, index = _block_grid(xs, np.array([y0, y1]), quadratic)
            block = len(bounds)
            nodes.append(xy)
            quads.append(q + n_nodes)
            quad_block.append(np.full(len(q), block))
            block_unit.append(n_units)
            bounds.append((0.0, y0, layout.width, y1))
            _collect_edges(edges, block, index + n_nodes, xy, n_nodes, quadratic)
            beams[name] = np.arange(n_nodes, n_nodes + len(xy))
            n_nodes += len(xy)
            n_units += 1
    nodes = np.vstack(nodes)
    quads = np.vstack(quads).astype(np.intp)
    block_unit = np.array(block_unit, np.intp)
    interfaces, kinds, pairs = _match_interfaces(edges, block_unit, quadratic)
    node_sets, edge_sets = _boundary_sets(nodes, edges, layout)
    node_sets.update(beams)
    mesh = Mesh(
        nodes=nodes,
        element=layout.element,
        quads=quads,
        quad_block=np.concatenate(quad_block).astype(np.intp),
        block_unit=block_unit,
        block_bounds=np.array(bounds),
        interfaces=interfaces,
        interface_kind=kinds,
        interface_blocks=pairs,
        node_sets=node_sets,
        edge_sets=edge_sets,
    )
    problems = mesh.check()
    if problems:
        raise MeshError("brick_wall produced an invalid mesh: " + "; ".join(problems))
    return mesh


def _collect_edges(edges, block, index, xy, offset, quadratic):
    """Append the element edges on the four sides of a block (global node numbers)."""
    k = 2 if quadratic else 1
    sides = {
        "bottom": index[:, 0],
        "top": index[:, -1],
        "left": index[0, :],
        "right": index[-1, :],
    }
    for side, line in sides.items():
        for i in range(0, len(line) - 1, k):
            start, end = line[i], line[i + k]
            mid = line[i + 1] if quadratic else -1
            p, q = xy[start - offset], xy[end - offset]
            edges.append((block, side, start, end, mid, p, q))


def _match_interfaces(edges, block_unit, quadratic):
    """Pair coincident block edges into interface elements (face A, face B)."""
    by_key = {}
    for block, side, start, end, mid, p, q in edges:
        key = (side in ("bottom", "top"),) + tuple(np.round(np.concatenate([p, q]), _ROUND))
        by_key.setdefault(key, []).append((block, side, start, end, mid))
    rows, kinds, pairs = [], [], []
    for key, group in by_key.items():
        if len(group) == 1:
            continue  # an outer boundary edge
        if len(group) != 2:
            raise MeshError(f"{len(group)} block edges coincide at {key[1:]}; expected 2")
        (b1, s1, *e1), (b2, s2, *e2) = group
        horizontal = key[0]
        # face A is below (horizontal joints) or left (vertical joints); A's tangent is +x for
        # horizontal joints and -y for vertical ones, so the normal (-s_y, s_x) points A -> B.
        lower_first = s1 in ("top", "right")
        (ba, ea), (bb, eb) = ((b1, e1), (b2, e2)) if lower_first else ((b2, e2), (b1, e1))
        if not horizontal:  # block edges run upwards: reverse to run downwards
            ea = [ea[1], ea[0], ea[2]]
            eb = [eb[1], eb[0], eb[2]]
        face_a = ea if quadratic else ea[:2]
        face_b = eb if quadratic else eb[:2]
        rows.append(list(face_a) + list(face_b))
        if horizontal:
            kind = "bed"
        elif block_unit[ba] == block_unit[bb]:
            kind = "brick"
        else:
            kind = "head"
        kinds.append(INTERFACE_KINDS.index(kind))
        pairs.append((ba, bb))
    n_if = 6 if quadratic else 4
    return (
        np.array(rows, np.intp).reshape(-1, n_if),
        np.array(kinds, np.intp),
        np.array(pairs, np.intp).reshape(-1, 2),
    )


def _boundary_sets(nodes, edges, layout):
    """Named node sets and edge sets on the four outer faces of the mesh (the wall's, or with
    ``base_joints`` the beams' bottom and top faces)."""
    W, H = layout.width, layout.height
    tol = 1e-9 * max(W, H)
    y_bottom, y_top = (-layout.unit_height, H + layout.unit_height) if layout.base_joints else (0.0, H)
    x, y = nodes[:, 0], nodes[:, 1]
    node_sets = {
        "bottom": np.flatnonzero(abs(y - y_bottom) < tol),
        "top": np.flatnonzero(abs(y - y_top) < tol),
        "left": np.flatnonzero(abs(x) < tol),
        "right": np.flatnonzero(abs(x - W) < tol),
    }
    for v, yy in (("bottom", y_bottom), ("top", y_top)):
        for h, xx in (("left", 0.0), ("right", W)):
            node_sets[f"{v}_{h}"] = np.flatnonzero((abs(x - xx) < tol) & (abs(y - yy) < tol))
    edge_sets = {}
    for face, coord, value in (("bottom", 1, y_bottom), ("top", 1, y_top), ("left", 0, 0.0), ("right", 0, W)):
        rows = [
            (start, end, mid)
            for _, side, start, end, mid, p, q in edges
            if side == face and abs(p[coord] - value) < tol and abs(q[coord] - value) < tol
        ]
        arr = np.array(rows, np.intp).reshape(-1, 3)
        edge_sets[face] = arr if layout.element == "Q8" else arr[:, :2]
    return node_sets, edge_sets
