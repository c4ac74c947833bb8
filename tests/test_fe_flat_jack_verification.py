"""The flat-jack FE against the closed forms (reference §5.10 items 1, 2, 4): homogeneous limit
(stiff joints) of a pressurised slot vs Jaeger–Cook, the finite-panel trend, and the double slot
vs the DDM. ``scripts/verify_flat_jack.py`` prints the full ladder (finer meshes, 20× panels)."""

import numpy as np
import pytest

from fe.scenarios import build_scenario
from fe.scenarios.flat_jack import homogeneous_slot_spec
from podkrig.analytical.flat_jack import Slot, elliptical_hole_field, solve_slots

E, NU, A = 4000.0, 0.2, 130.0
OFFSETS = (32.5, 97.5, 162.5)


def _jaeger_cook(offsets, x=1.0):
    """Pin-distance change (mm) of pins at (x, ±y) across a slot of half-length A, p = 1 MPa (the
    crack limit of the ellipse, i.e. Westergaard/Jaeger–Cook at x ≠ 0)."""
    y = np.asarray(offsets)
    f = elliptical_hole_field(np.full(2 * len(y), x), np.r_[-y, y], A, 0.0, p=1.0, E=E, nu=NU)
    return f.uy[len(y):] - f.uy[: len(y)]


def _fe(size, nx, ny):
    return build_scenario(homogeneous_slot_spec(size, nx, ny, 2 * A, gauge_offsets=OFFSETS)).run().readings[0]


def test_coarse_mesh_reads_a_few_percent_below_jaeger_cook():
    """The fast lane's case of the convergence test below: on the coarse mesh (2×1 Q8 per unit,
    h = a/2 near the slot) every pin reads 3.7 … 5.0 % below the closed form (measured): below, as
    a displacement FE model is too stiff; tolerance 0 … −7 %, the coarse error plus a margin."""
    error = _fe(10, 2, 1) / _jaeger_cook(OFFSETS) - 1
    assert np.all((error < 0) & (error > -0.07)), error


@pytest.mark.slow
def test_homogeneous_limit_converges_to_jaeger_cook():
    """Panel 10× the slot length. Measured (scripts/verify_flat_jack.py): −3.7 … −5.0 % at 2×1 Q8
    per unit (h = a/2 near the slot), −1.3 … −1.6 % at 4×2 (h = a/4), first-order convergence
    (the tip singularity), Richardson limit +1.1 … +2.1 % (the finite panel). Tolerances: ≤ 2 %
    at h = a/4, error ratio between the meshes in [1.6, 4]."""
    exact = _jaeger_cook(OFFSETS)
    coarse = _fe(10, 2, 1) / exact - 1
    fine = _fe(10, 4, 2) / exact - 1
    assert np.all(np.abs(fine) < 0.02), fine
    ratio = coarse / fine
    assert np.all((ratio > 1.6) & (ratio < 4.0)), ratio


@pytest.mark.slow
def test_finite_panel_trend():
    """The same slot in smaller panels reads more (free side edges and top): monotone in the
    panel size, ≈ +6 % at 4× and ≈ +2 % at 6× relative to 10× at the centre pins (measured; the
    free-edged square of reference §2.4 gives +11 % and +6 % relative to the infinite plate; the
    supported bottom edge of this panel stiffens it)."""
    r4, r6, r10 = (_fe(s, 2, 1)[0] for s in (4, 6, 10))
    assert r4 > r6 > r10
    assert 0.03 < r4 / r10 - 1 < 0.12
    assert 0.005 < r6 / r10 - 1 < 0.05


@pytest.mark.slow
def test_double_slot_apparent_modulus():
    """Two slots 390 mm apart (L = 350 mm), gauge length 195 mm centred between them: the FE
    apparent modulus p/ε matches the DDM of the same geometry (an infinite plate) at the centre
    line and 100 mm off it, where it over-estimates E by ≈ 46 %. Measured: +0.8 % / +2.6 % at
    8×4 Q8 per unit, +3.4 % off-centre at 4×2 (the panel is 10× L, the mesh error is first order);
    tolerance 5 %."""
    ddm = solve_slots([Slot((0, -195.0), 350.0, 0, 1.0), Slot((0, 195.0), 350.0, 0, 1.0)], E, NU, 80)
    for x0 in (0.0, 100.0):
        spec = homogeneous_slot_spec(10 * 350 / 260, 4, 2, slot_length=350.0, spacing=390.0, gauge_offsets=(97.5,), x0=x0)
        fe_app = 195.0 / -build_scenario(spec).run().readings[0, 0] / E
        f = ddm.field(np.array([x0 + 1, x0 + 1]), np.array([-97.5, 97.5]))
        ddm_app = 195.0 / -(f.uy[1] - f.uy[0]) / E
        assert fe_app == pytest.approx(ddm_app, rel=0.05), (x0, fe_app, ddm_app)
    assert ddm_app > 1.3  # the off-centre gauge over-estimates E (reference §2.3)
