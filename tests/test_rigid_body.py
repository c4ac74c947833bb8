"""Rigid-body removal from displacement readings (issue 18, deliverable 2): the projector, the
χ² with its lost degrees of freedom, and an inversion and a diagnosis fit that a rigid rotation of
the data no longer biases."""

import numpy as np
from scipy import stats
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from fe import build_scenario
from fe.scenarios.diagonal_compression import DEFAULT_SENSORS
from fe.sensors import DICGrid, Gauge, PointDisplacement, SlipGauge, absolute_displacements
from podkrig.diagnosis.candidates import FEContext
from podkrig.diagnosis.engine import _Fitter
from podkrig.online.measurement import Measurement, NoiseModel
from podkrig.online.misfit import Misfit
from podkrig.online.problem import FEModel, InverseProblem
from podkrig.online.rigid_body import POINT_GROUP, RigidBodyModes, may_remove, project_out, rigid_body_modes
from podkrig.parameters import ParameterSpace

SENSORS = (Gauge("D1", (0.0, 0.0), (100.0, 100.0)), SlipGauge("S1", (10.0, 10.0), (10.0, 50.0)),
           DICGrid("G", 10.0, 20.0, 300.0, 400.0, 3, 4),
           PointDisplacement("P1", (5.0, 5.0), "x"), PointDisplacement("P2", (500.0, 5.0), "y"),
           PointDisplacement("P3", (250.0, 600.0), "x"), PointDisplacement("P4", (250.0, 600.0), "y"))
NAMES = tuple(n for s in SENSORS for n in s.channel_names)
DISPLACEMENTS = absolute_displacements(SENSORS)
GAUGES = np.array([n in ("D1", "S1") for n in NAMES])


def _measurement(n_loads=3, missing=True, seed=0):
    values = np.random.default_rng(seed).normal(size=(n_loads, len(NAMES)))
    if missing:
        values[1, 5] = np.nan  # a DIC reading missing at one level: that block has one entry less
    return Measurement(values, NAMES, np.arange(1.0, n_loads + 1))


def _rigid(meas, t, omega, centre=(0.0, 0.0)):
    """Readings of the rigid motion ``t`` ``(n_loads, 2)`` mm, ``omega`` ``(n_loads,)`` rad about
    ``centre`` at every absolute displacement channel (zero at gauges), ``(n_loads, n_sensors)``."""
    out = np.zeros(meas.values.shape)
    for j, name in enumerate(meas.sensor_names):
        if name in DISPLACEMENTS:
            x, y, c, _ = DISPLACEMENTS[name]
            out[:, j] = t[:, 0] - omega * (y - centre[1]) if c == 0 else t[:, 1] + omega * (x - centre[0])
    return out


def test_absolute_displacements_name_points_and_components_and_leave_gauges_out():
    assert "D1" not in DISPLACEMENTS and "S1" not in DISPLACEMENTS
    assert DISPLACEMENTS["P2"] == (500.0, 5.0, 1, None)
    assert DISPLACEMENTS["G[2,3].ux"] == (300.0, 400.0, 0, "G") and DISPLACEMENTS["G[0,1].uy"][2:] == (1, "G")
    assert len(DISPLACEMENTS) == 2 * 12 + 4


@pytest.mark.parametrize("option, groups", [("auto", None), ("remove", None), ("auto", {"pair": ["P3", "P4"]})])
def test_a_pure_rigid_motion_is_removed_exactly_at_every_load_level(option, groups):
    """Any (t_x, t_y, ω), different at each level, about any centre: P r = 0 to 1e-12 of |r|,
    and the fit returns the motion (translation at the block's centroid, ω itself)."""
    meas = _measurement()
    modes = rigid_body_modes(meas, DISPLACEMENTS, option, groups)
    rng = np.random.default_rng(1)
    for _ in range(5):
        t, omega = rng.normal(scale=0.1, size=(3, 2)), rng.normal(scale=1e-3, size=3)
        rigid = meas.with_data(_rigid(meas, t, omega, centre=rng.normal(scale=500, size=2))[meas.mask]).data
        grid_rows = np.array([n.startswith("G[") for n in meas.sensor_names])
        grid = np.broadcast_to(grid_rows, meas.values.shape)[meas.mask]
        removed = modes.remove(rigid)
        assert np.max(np.abs(removed[grid])) <= 1e-12 * np.max(np.abs(rigid))
        fitted = modes.fit(rigid)
        for b, (g, level) in enumerate(modes.labels):
            if g == "G":
                assert_allclose(fitted[b, 2], omega[level], rtol=1e-10)
    assert modes.groups == {"auto": ("G",), "remove": ("G", POINT_GROUP)}.get(option if groups is None else "",
                                                                             ("G", "pair"))


def test_projector_is_symmetric_idempotent_of_rank_n_minus_3_per_block_and_leaves_gauges_alone():
    meas = _measurement()
    modes = rigid_body_modes(meas, DISPLACEMENTS, "remove")
    P = modes.projector()
    assert_allclose(P, P.T, atol=1e-15)
    assert_allclose(P @ P, P, atol=1e-14)
    # grid: 3 per level; the four point sensors (x, y, x, y at three points): 3 per level too
    assert modes.n_removed == 3 * 2 * 3 and np.linalg.matrix_rank(P) == meas.n_obs - modes.n_removed
    gauges = np.broadcast_to(GAUGES, meas.values.shape)[meas.mask]
    assert_allclose(P[gauges], np.eye(meas.n_obs)[gauges], atol=0)  # gauges: identity rows and columns
    v = meas.data
    assert_allclose(modes.remove(v), P @ v, atol=1e-14)
    assert_allclose(modes.remove(v)[gauges], v[gauges], atol=0)
    J = np.random.default_rng(2).normal(size=(meas.n_obs, 4))  # a Jacobian goes in transposed
    assert_allclose(modes.remove(J.T).T, P @ J, atol=1e-13)


def test_blocks_that_cannot_see_all_motions_remove_fewer_dof():
    """Two x components at different heights see t_x and ω, not t_y: rank 2; one point: rank 2
    (translations only); a lone x reading: rank 1."""
    meas = Measurement(np.ones((1, 4)), ("P1", "P3", "P2", "P4"), [1.0])
    assert rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["P1", "P3"]}).rank.tolist() == [2]
    assert rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["P3", "P4"]}).rank.tolist() == [2]
    assert rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["P1"]}).rank.tolist() == [1]


def test_chi2_is_the_pseudo_inverse_of_the_projected_covariance():
    """χ² of the projected whitening = (P r)ᵀ (P C Pᵀ)⁺ (P r), for a diagonal and a full C."""
    meas = _measurement()
    modes = rigid_body_modes(meas, DISPLACEMENTS, "remove")
    rng = np.random.default_rng(3)
    r = rng.normal(size=meas.n_obs)
    sd = rng.uniform(0.5, 2.0, size=meas.n_obs)
    P = modes.projector()
    A = rng.normal(size=(meas.n_obs,) * 2) * 0.2
    for C in (np.diag(sd**2), A @ A.T + np.eye(meas.n_obs)):
        reference = (P @ r) @ np.linalg.pinv(modes.covariance(C), rcond=1e-10, hermitian=True) @ (P @ r)
        L = np.linalg.cholesky(C)
        w = project_out(modes.whitened_basis(L), np.linalg.solve(L, r))
        assert_allclose(w @ w, reference, rtol=1e-9)
        assert np.linalg.matrix_rank(modes.covariance(C), tol=1e-10) == meas.n_obs - modes.n_removed
    w = modes.whiten_diagonal((r / sd)[None], sd)[0]
    assert_allclose(w @ w, (P @ r) @ np.linalg.pinv(modes.covariance(np.diag(sd**2)), rcond=1e-10) @ (P @ r), rtol=1e-9)
    gauges = np.broadcast_to(GAUGES, meas.values.shape)[meas.mask]
    assert_allclose(w[gauges], (r / sd)[gauges], rtol=1e-14)  # gauges keep their whitened residual


@pytest.mark.parametrize("covariance", [False, True])
def test_chi2_of_noise_has_n_minus_removed_minus_p_degrees_of_freedom(covariance):
    """Mean χ² over 200 noise realisations after a linear least-squares fit of p = 2 parameters:
    n − k − p (k = 3 per grid or point group and load level). Tolerance 4 standard errors of the
    mean, √(2 (n − k − p) / 200) each; the error of forgetting k (= 18 here) is 5 of them."""
    meas = _measurement(missing=False)
    modes = rigid_body_modes(meas, DISPLACEMENTS, "remove")
    n, k, p = meas.n_obs, modes.n_removed, 2
    rng = np.random.default_rng(4)
    sd = np.where(np.broadcast_to(GAUGES, meas.values.shape).ravel(), 1e-3, 2.5e-3)
    near = 0.4 * sd[:-1] * sd[1:]  # neighbouring readings correlated (ρ = 0.4)
    noise = (NoiseModel(covariance=np.diag(sd**2) + np.diag(near, 1) + np.diag(near, -1)) if covariance
             else NoiseModel(sigma=dict(zip(NAMES, np.where(GAUGES, 1e-3, 2.5e-3)))))
    C = noise.covariance_matrix(meas)
    A = rng.normal(scale=0.01, size=(n, p))  # a linear model g(m) = A m, mm
    misfit = Misfit(lambda X: (X @ A.T, None), meas, noise, np.arange(n), model_error=False, rigid_body=modes)
    chi2 = []
    L = np.linalg.cholesky(C)
    for _ in range(200):
        data = meas.with_data(L @ rng.standard_normal(n)  # noise plus a rigid motion (removed)
                              + _rigid(meas, rng.normal(size=(3, 2)), rng.normal(size=3) * 1e-4).ravel())
        fit = Misfit(misfit.model, data, noise, np.arange(n), model_error=False, rigid_body=modes)
        w0 = fit.whiten(-data.data)[0]
        J = fit.whiten(A.T)  # whitening is linear for a fixed C: rows = whitened columns of A
        m = np.linalg.lstsq(J.T, -w0, rcond=None)[0]
        w = w0 + J.T @ m
        chi2.append(w @ w)
        assert_allclose(fit.chi2(m[None])[0], w @ w, rtol=1e-8)
    dof = n - k - p
    assert abs(np.mean(chi2) - dof) < 4 * np.sqrt(2 * dof / 200), (np.mean(chi2), dof, n)


def test_group_and_option_errors_name_the_key_and_the_allowed_values():
    meas = _measurement()
    with pytest.raises(ValueError, match=r"rigid_body .*\['auto', 'remove', 'keep'\]; got 'off'"):
        rigid_body_modes(meas, DISPLACEMENTS, "off")
    points = sorted(k for k, v in DISPLACEMENTS.items() if v[3] is None)
    assert points and len(points) < len(DISPLACEMENTS)  # point sensors and DIC channels both present
    with pytest.raises(ValueError, match=r"rigid_groups: 'D1' in group 'a'") as raised:
        rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["D1", "P1"]})
    assert "not a point displacement sensor" in str(raised.value) and str(points) in str(raised.value)  # allowed ones
    with pytest.raises(ValueError, match=r"'G\[0,0\].ux' in group 'a'.*DIC grid channel"):
        rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["G[0,0].ux"]})
    with pytest.raises(ValueError, match="'P1' .*groups 'a' and 'b'"):
        rigid_body_modes(meas, DISPLACEMENTS, "auto", {"a": ["P1"], "b": ["P1", "P2"]})
    assert rigid_body_modes(meas, DISPLACEMENTS, "keep") is None
    default, auto = rigid_body_modes(meas, DISPLACEMENTS), rigid_body_modes(meas, DISPLACEMENTS, "auto")
    assert default.labels == auto.labels and np.array_equal(default.modes, auto.modes)  # "auto" is the default
    gauges_only = Measurement(np.ones((2, 2)), ("D1", "S1"), [1.0, 2.0])
    assert rigid_body_modes(gauges_only, DISPLACEMENTS, "remove") is None


def test_subset_keeps_whole_blocks():
    meas = _measurement(missing=False)
    modes = rigid_body_modes(meas, DISPLACEMENTS, "auto")
    rows = np.arange(meas.n_obs).reshape(3, -1)[[0, 2]].ravel()
    sub = modes.subset(rows)
    assert isinstance(sub, RigidBodyModes) and sub.labels == (("G", 0), ("G", 2)) and sub.n_removed == 6
    assert_allclose(sub.projector(), modes.projector()[np.ix_(rows, rows)], atol=1e-14)


# ---------------------------------------------------------------------------- inversion and diagnosis

OMEGA = 1.8e-5  # rad: the rigid rotation between two FE codes of the diagonal test (issue 18)


@pytest.fixture(scope="module")
def dic_wall():
    """The diagonal test on a coarse mesh with the six gauges and a 5 × 6 DIC grid; kN_bj, kV_bj
    free; data at a hidden truth with DIC noise 2.5 µm and gauge noise 1 µm."""
    sensors = {g.name: g.to_dict() for g in DEFAULT_SENSORS}
    sensors["DIC"] = {"kind": "dic", "x0": 65.0, "y0": 32.5, "x1": 1105.0, "y1": 1072.5, "nx": 5, "ny": 6}
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1, "sensors": sensors})
    space = ParameterSpace.from_scenario(sc, {"kN_bj": (10.0, 1000.0, "log"), "kV_bj": (4.0, 400.0, "log")})
    clean = sc.run({"kN_bj": 60.0, "kV_bj": 25.0}).readings
    names = sc.sensor_names
    is_dic = np.array([n.startswith("DIC[") for n in names])
    sigma = dict(zip(names, np.where(is_dic, 2.5e-3, 1e-3)))
    noise = NoiseModel(sigma=sigma)
    rng = np.random.default_rng(5)
    e = rng.standard_normal(clean.shape) * np.array([sigma[n] for n in names])
    disp = absolute_displacements(sc.sensors)
    rotation = np.zeros(clean.shape)  # ω about the bottom-left corner, growing with the load
    for j, n in enumerate(names):
        if n in disp:
            x, y, c, _ = disp[n]
            rotation[:, j] = (-OMEGA * y if c == 0 else OMEGA * x) * sc.load_levels / sc.load_levels[-1]
    plain = Measurement(clean + e, names, sc.load_levels, "plain")
    rotated = Measurement(clean + e + rotation, names, sc.load_levels, "rotated")
    return sc, space, noise, plain, rotated


def _polish(sc, space, meas, noise, rigid_body):
    problem = InverseProblem(FEModel(sc, space), meas, noise, rigid_body=rigid_body)
    x, _ = problem.polish(space.from_unit(np.full((1, 2), 0.5))[0], max_nfev=60)
    return problem, x, float(problem.chi2(x[None])[0])


def test_inversion_on_dic_data_is_blind_to_a_rigid_rotation_with_removal(dic_wall):
    sc, space, noise, plain, rotated = dic_wall
    p_plain, x_plain, chi2_plain = _polish(sc, space, plain, noise, "auto")
    p_rot, x_rot, chi2_rot = _polish(sc, space, rotated, noise, "auto")
    assert p_rot.n_removed == 3 * len(sc.load_levels)
    # the two misfits agree to rounding; the optimiser stops at its own tolerance (xtol 1e-8 in the
    # unit cube), so the optima agree to about that
    assert_allclose(x_rot, x_plain, rtol=1e-6)
    assert_allclose(chi2_rot, chi2_plain, rtol=1e-6)
    assert_allclose(p_rot.chi2(x_plain[None]), p_plain.chi2(x_plain[None]), rtol=1e-9)
    dof = p_rot.n_obs - p_rot.n_removed - 2
    assert chi2_rot / dof < 1.5  # the model explains the data within the noise
    assert_allclose(x_plain, [60.0, 25.0], rtol=0.1)
    # kept, the same rotation (up to 18 µm, 7 σ of a DIC point) wrecks the fit: inadequate, biased
    p_keep, x_keep, chi2_keep = _polish(sc, space, rotated, noise, "keep")
    assert p_keep.n_removed == 0
    # (χ²/dof 4.4 with the rigid supports of issue 18: p < 1e-100 for 262 dof; the bound leaves room)
    assert stats.chi2.sf(chi2_keep, p_keep.n_obs - 2) < 1e-20 and chi2_keep / (p_keep.n_obs - 2) > 3.0
    assert np.max(np.abs(x_keep / x_plain - 1.0)) > 0.05, x_keep


def test_diagnosis_fit_is_blind_to_a_rigid_rotation_with_removal(dic_wall):
    """The diagnosis's FE fitter (``_Fitter``, where diagnose() hooks the removal): same base fit
    and χ² on rotated and plain data with the modes; a χ²/dof far off without them."""
    sc, space, noise, plain, rotated = dic_wall
    values = sc.resolve()
    fits = {}
    for name, meas, option in (("plain", plain, "auto"), ("rotated", rotated, "auto"), ("kept", rotated, "keep")):
        ctx = FEContext(sc, space.names, values, offset_scale=np.max(np.abs(meas.values)))
        modes = rigid_body_modes(meas, absolute_displacements(sc.sensors), option)
        fitter = _Fitter(ctx, space, meas, noise, np.arange(meas.n_obs), None, modes)
        fits[name] = fitter.fit(np.full(2, 0.5))
    assert_allclose(fits["rotated"].chi2, fits["plain"].chi2, rtol=1e-6)
    assert_allclose([fits["rotated"].free[n] for n in space.names], [fits["plain"].free[n] for n in space.names],
                    rtol=1e-6)
    assert fits["rotated"].n_removed == 12 and fits["rotated"].dof == plain.n_obs - 12 - 2
    # kept: χ²/dof 4.4 over 262 dof (p < 1e-100) with the rigid supports of issue 18
    assert fits["rotated"].chi2_dof < 1.5 and fits["kept"].chi2_dof > 3.0
    assert stats.chi2.sf(fits["kept"].chi2, fits["kept"].dof) < 1e-20


# ----------------------------------------------------------------- fourth mutation run (issue 12)


def test_may_remove_decides_from_the_channel_names_alone():
    """Without sensor definitions: "keep" never removes; "remove" always may (point sensors form a
    group); "auto" (the default) only with a DIC channel name ``grid[i,j].ux``/``.uy`` or with user
    groups — gauges and point sensors alone are left as they are. An unknown option is refused
    with the allowed ones. Guards an inversion that silently drops or keeps 3 dof per block."""
    points, dic = ["D1", "P1", "P2"], ["D1", "G[0,1].uy"]
    assert may_remove(points) is False and may_remove(dic) is True
    assert may_remove(points, "auto", {"pair": ["P1", "P2"]}) is True
    assert may_remove(points, "remove") is True
    assert may_remove(dic, "keep") is False and may_remove(dic, "keep", {"pair": ["P1", "P2"]}) is False
    assert may_remove(["G[0,1]"], "auto") is False and may_remove(["G.ux"], "auto") is False  # not a DIC channel
    with pytest.raises(ValueError, match=r"rigid_body .*\['auto', 'remove', 'keep'\]; got 'Keep'"):
        may_remove(points, "Keep")


def test_fit_returns_the_motion_of_the_centroid_and_nan_for_what_a_block_cannot_see():
    """A rigid motion (t_x, t_y, ω) about the origin, read by the 3 × 4 DIC grid and by two x
    components at (5, 5) and (250, 600) mm (group "pair", ℓ = √(122.5² + 297.5²) mm, their RMS
    distance from the centroid (127.5, 302.5)): the grid's fit is the
    translation of its centroid (t_x − ω y_c, t_y + ω x_c) and ω in rad; the pair sees t_x at its
    centroid and ω but not t_y (NaN). 1e-10 relative: rounding of a least-squares fit."""
    meas = Measurement(np.zeros((1, len(NAMES))), NAMES, [1.0])
    modes = rigid_body_modes(meas, DISPLACEMENTS, "auto", {"pair": ["P1", "P3"]})
    t, omega = np.array([[0.3, -0.2]]), np.array([2e-4])
    v = _rigid(meas, t, omega).ravel()
    fitted = modes.fit(v)
    assert modes.labels == (("G", 0), ("pair", 0)) and modes.rank.tolist() == [3, 2]
    xc, yc = np.mean([10.0, 155.0, 300.0]), np.mean([20.0, 146.0 + 2 / 3, 273.0 + 1 / 3, 400.0])
    assert_allclose(fitted[0], [0.3 - 2e-4 * yc, -0.2 + 2e-4 * xc, 2e-4], rtol=1e-10)
    assert_allclose(fitted[1, [0, 2]], [0.3 - 2e-4 * 302.5, 2e-4], rtol=1e-10)
    assert np.isnan(fitted[1, 1])
    assert_allclose(modes.lengths[1], np.hypot(122.5, 297.5), rtol=1e-12)
    # a lone x reading (P1 at (5, 5) mm) sees only its own translation: t_x = the reading, the rest NaN
    lone = rigid_body_modes(meas, DISPLACEMENTS, "auto", {"lone": ["P1"]})
    fitted = lone.fit(v)
    assert lone.labels[-1] == ("lone", 0) and lone.rank[-1] == 1
    assert_allclose(fitted[-1, 0], 0.3 - 2e-4 * 5.0, rtol=1e-12)
    assert np.isnan(fitted[-1, 1:]).all()


def test_whitening_of_a_batch_is_row_by_row():
    """Several residual rows with their own σ (the model's predictive std differs per point) are
    whitened each as if alone, blocks of rank 3 and of rank 1 alike (1e-12: rounding)."""
    meas = _measurement(n_loads=2)
    modes = rigid_body_modes(meas, DISPLACEMENTS, "auto", {"lone": ["P2"]})
    assert sorted(set(modes.rank.tolist())) == [1, 3] and modes.n_blocks == 4
    rng = np.random.default_rng(6)
    u, sd = rng.normal(size=(3, meas.n_obs)), rng.uniform(0.5, 2.0, size=(3, meas.n_obs))
    batch = modes.whiten_diagonal(u, sd)
    for k in range(3):
        assert_allclose(batch[k], modes.whiten_diagonal(u[k], sd[k])[0], rtol=1e-12, atol=1e-14)
        P = modes.projector()
        r = u[k] * sd[k]
        chi2 = (P @ r) @ np.linalg.pinv(modes.covariance(np.diag(sd[k] ** 2)), rcond=1e-10) @ (P @ r)
        assert_allclose(batch[k] @ batch[k], chi2, rtol=1e-9)


def test_to_dict_records_groups_blocks_and_removed_dof():
    """What an inversion's summary records: the groups in order, blocks (group × level) and dof."""
    meas = _measurement()
    assert rigid_body_modes(meas, DISPLACEMENTS, "remove").to_dict() == {
        "groups": ["G", POINT_GROUP], "n_blocks": 6, "n_removed": 18}


def test_subset_of_one_level_and_subset_of_a_subset():
    """The load levels a fit keeps, taken at once or in two steps, give the same modes: blocks
    renumbered in order, gauges and ungrouped sensors outside every block (−1), the removed dof
    and the fitted motion (ω needs each block's ℓ) of the kept blocks unchanged (1e-12:
    rounding). One level alone is one block."""
    meas = _measurement(missing=False)
    modes = rigid_body_modes(meas, DISPLACEMENTS, "auto")
    level = np.arange(meas.n_obs).reshape(3, -1)
    direct = modes.subset(level[2])
    two_steps = modes.subset(level[[0, 2]].ravel()).subset(np.arange(level.shape[1], 2 * level.shape[1]))
    for sub in (direct, two_steps):
        assert sub.labels == (("G", 2),) and sub.n_blocks == 1 and sub.n_removed == 3
        assert_array_equal(sub.block, modes.block[level[2]] - 2 * (modes.block[level[2]] >= 0))
        assert_allclose(sub.lengths, modes.lengths[2:], rtol=0)
        v = _rigid(meas, np.array([[0.1, 0.2]] * 3), np.array([1e-4, 2e-4, 3e-4])).ravel()
        assert_allclose(sub.fit(v[level[2]]), modes.fit(v)[2:], rtol=1e-12)
        assert_allclose(sub.projector(), modes.projector()[np.ix_(level[2], level[2])], atol=1e-14)


def test_a_subset_without_displacement_readings_removes_nothing():
    """Rows holding only gauge readings (e.g. the levels a fit keeps read no DIC point): no block,
    P = I, nothing removed, an empty whitened basis (n, 0) and whitened residuals left as they
    are; the χ² of such a subset keeps every degree of freedom. Defect fixed (fourth mutation
    run): ``remove`` raised IndexError and ``whiten_diagonal`` ValueError on such modes."""
    meas = _measurement(missing=False)
    modes = rigid_body_modes(meas, DISPLACEMENTS, "auto")
    gauges = np.flatnonzero(np.broadcast_to(GAUGES, meas.values.shape).ravel())
    sub = modes.subset(gauges)
    assert sub.n_blocks == 0 and sub.n_removed == 0 and sub.dense_basis().shape == (len(gauges), 0)
    assert_array_equal(sub.projector(), np.eye(len(gauges)))
    L = np.diag(np.arange(1.0, len(gauges) + 1))
    Q = sub.whitened_basis(L)
    w = np.arange(len(gauges), dtype=float)
    assert Q.shape == (len(gauges), 0)
    assert_array_equal(project_out(Q, w), w)
    assert_array_equal(sub.remove(w), w)
    assert_array_equal(sub.whiten_diagonal(w, np.ones(len(gauges))), w[None])
