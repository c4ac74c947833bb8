"""Capacity of validation models with its spread (RVC, :mod:`podkrig.online.propagation`): the
quantiles and CV of a region of known distribution pushed through known models, the FE validation
runs at region members and their failed share on stub and real (triplet) scenarios, the runs of a
snapshot store without a load maximum, and the ``[[validation]]`` keys that declare all this."""

import json
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import norm

from fe.scenarios import build_scenario
from podkrig.offline.failures import no_peak_rows
from podkrig.offline.runner import run_snapshots
from podkrig.offline.store import SnapshotStore
from podkrig.online.propagation import RVCResult, rvc, run_validation
from podkrig.online.region import Region
from podkrig.parameters import Parameter, ParameterSpace
from podkrig.study import StudyError, load_study

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


class Capacity:
    """A closed-form "capacity" model: ``F_peak = 2 A (c + σ tanφ)`` (kN, A = 21 000 mm², σ = 1.4
    MPa) and ``d_peak = exp(c)`` (mm, a monotone but not linear map), the same at both levels."""

    space = ParameterSpace((Parameter("tanphi", 0.0, 2.0), Parameter("c", -5.0, 5.0)))
    sensor_names = ("F_peak", "d_peak")
    sensor_units = {"F_peak": "kN", "d_peak": "mm"}
    load_levels = np.array([0.5, 2.0])

    def predict(self, X, return_std=False):
        tanphi, c = np.atleast_2d(X).T
        one = np.column_stack([2 * 21000.0 * (c + 1.4 * tanphi) / 1000, np.exp(c)])
        Y = np.tile(one, (1, len(self.load_levels)))
        return (Y, np.zeros_like(Y)) if return_std else Y


def _region(samples, names):
    samples = np.asarray(samples, dtype=float)
    intervals = {n: (samples[:, j].min(), samples[:, j].max()) for j, n in enumerate(names)}
    return Region("likelihood-ratio", 0.95, samples, np.zeros(len(samples)), 1.0, intervals, tuple(names),
                  ("-",) * len(names), len(samples), 0.0, {})


def test_quantiles_and_cv_of_a_normal_region_through_a_linear_and_a_monotone_model():
    """Fails if the quantiles are not those of the distribution drawn (e.g. mean ± 1.645 std, or
    the quantiles of the parameters instead of the outputs), if the CV is not std/mean, or if the
    units of the outputs are lost. Members: c ~ N(0.3, 0.02²) on a stratified grid of 20 001
    points (exact normal quantiles), tanφ = 0.85 fixed by the region; then F_peak = 42 (c + 1.19)
    kN is normal with CV 42·0.02 / (42·1.49) and quantiles 42 (q_c + 1.19), and d_peak = exp(c) is
    lognormal: its quantiles are exp(q_c), not a symmetric band (the mean ± z σ of this lognormal
    misses them by 0.03 σ, 30 times the tolerance)."""
    n = 20001
    c = 0.3 + 0.02 * norm.ppf((np.arange(n) + 0.5) / n)
    members = np.column_stack([c, np.full(n, 0.85)])
    out = rvc(_region(members, ("c", "tanphi")), Capacity(), outputs=["F_peak", "d_peak@0.5"], quantiles=(0.05, 0.95))
    assert out.outputs == ("F_peak", "d_peak@0.5") and out.units == ("kN", "mm")
    z = norm.ppf([0.05, 0.95])
    q_c = 0.3 + 0.02 * z
    # the grid's 5 % point lies half a stratum (2.2e-4 σ) from the normal's quantile: atol 1e-3 σ
    assert_allclose(out.quantiles[:, 0], 42 * (q_c + 1.4 * 0.85), rtol=0, atol=1e-3 * 42 * 0.02)
    assert_allclose(out.quantiles[:, 1], np.exp(q_c), rtol=0, atol=1e-3 * 0.02 * np.exp(0.3))
    assert_allclose(out.cv[0], 42 * 0.02 / (42 * (0.3 + 1.19)), rtol=1e-3)  # the grid's std is σ to ~1e-4
    lognormal_mean, lognormal_std = np.exp(0.3 + 0.02**2 / 2), np.exp(0.3 + 0.02**2 / 2) * np.sqrt(np.expm1(0.02**2))
    assert_allclose(out.mean[1], lognormal_mean, rtol=1e-6)
    assert_allclose(out.std[1], lognormal_std, rtol=1e-3)
    # the band is asymmetric about the mean as a lognormal's is: a mean ± z σ band would be symmetric
    assert out.quantiles[1, 1] - out.mean[1] > out.mean[1] - out.quantiles[0, 1]
    # to_dict is complete and round-trips through JSON (values are for figures only)
    d = json.loads(json.dumps(out.to_dict()))
    assert d["quantile_levels"] == [0.05, 0.95] and d["units"] == ["kN", "mm"] and d["failed_share"] is None
    assert RVCResult.from_dict(d).to_dict() == d


class Triplet:
    """A stub FE scenario with the nonlinear response's outcome fields: a run at ``c`` > 0.7 stops
    early (budget exhausted at 1 mm), one at ``tanphi`` > 1.5 raises, one at ``c`` < 0.1 keeps its
    load rising to the last level (no load maximum); readings F_peak, d_peak as :class:`Capacity`."""

    load_levels = (0.5, 2.0)
    load_unit = "mm"

    def run(self, params):
        c, tanphi = params["c"], params["tanphi"]
        if tanphi > 1.5:
            raise RuntimeError("the interface return map diverged")
        Y = Capacity().predict([[tanphi, c]]).reshape(2, 2)
        stopped = c > 0.7
        no_peak = c < 0.1
        return type("Response", (), {
            "readings": Y, "status": "budget_exhausted" if stopped else "converged", "limit": "max_steps" if stopped
            else "", "reached": 1.0 if stopped else 2.0, "peak_displacement": 2.0 if no_peak else 0.12})()


def test_fe_runs_at_region_members_count_each_failure_where_it_happens():
    """Fails if a run that stopped early, raised, or has no load maximum is not counted as failed
    (or a good one is), if the members run are not the recorded ones, or if the failed share is
    not the failed runs over the runs: 40 members spread over c in [0, 1], tanφ in [0, 2]; the
    seeded subsample of 24 is run, and each run's outcome is predicted from its recorded member."""
    rng = np.random.default_rng(5)
    members = np.column_stack([rng.random(40), 2 * rng.random(40)])
    out = rvc(_region(members, ("c", "tanphi")), Capacity(), outputs=["F_peak", "d_peak"], scenario=Triplet(),
              fe_runs=24, rng=3)
    runs = out.runs
    assert runs.n_runs == 24 and runs.names == ("c", "tanphi")
    assert len({tuple(p) for p in runs.parameters}) == 24  # 24 distinct members, each a row of the region
    assert all((members == p).all(axis=1).any() for p in runs.parameters)
    c, tanphi = runs.parameters.T
    raised = tanphi > 1.5
    stopped = (c > 0.7) | raised
    no_peak = (c < 0.1) & ~raised
    assert stopped.any() and no_peak.any() and (~stopped & ~no_peak).any()  # the premise: every outcome drawn
    assert_allclose(runs.stopped, stopped, rtol=0) and assert_allclose(runs.no_peak, no_peak, rtol=0)
    assert [s for s, r in zip(runs.status, raised) if r] == ["error"] * int(raised.sum())
    assert all("max_steps" in m for m, s, r in zip(runs.messages, stopped, raised) if s and not r)
    assert out.failed_share == pytest.approx((stopped | no_peak).mean(), rel=1e-12)
    ok = ~(stopped | no_peak)
    assert_allclose(runs.fe[ok], runs.surrogate[ok], rtol=1e-12)  # the stub's FE is the model itself
    assert np.isnan(runs.fe[raised]).all()
    d = json.loads(json.dumps(out.to_dict()))
    assert d["runs"]["n_failed"] == int((stopped | no_peak).sum()) and d["runs"]["n_no_peak"] == int(no_peak.sum())
    assert RVCResult.from_dict(d).to_dict() == d


def test_rvc_refuses_bad_quantiles_and_fe_runs_without_a_scenario():
    """Fails if a quantile level outside (0, 1) or out of order is accepted, or FE runs are asked
    for without the FE scenario to run."""
    region = _region([[0.3, 0.8], [0.31, 0.82]], ("c", "tanphi"))
    with pytest.raises(ValueError, match=r"quantiles.*\(0, 1\).*\[5, 95\]"):
        rvc(region, Capacity(), quantiles=(5, 95))
    with pytest.raises(ValueError, match=r"quantiles.*ascending.*\[0.95, 0.05\]"):
        rvc(region, Capacity(), quantiles=(0.95, 0.05))
    with pytest.raises(ValueError, match=r"fe_runs = 4.*scenario="):
        rvc(region, Capacity(), fe_runs=4)


LEVELS = [0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0]
TRUTH = {"c_bj": 0.30, "tanphi_bj": 0.85, "GfII_bj": 0.10, "ft_bj": 0.10}


def test_real_triplet_runs_are_classified_by_their_outcome():
    """On the FE triplet at 1.4 MPa (0.05 s of CPU per run): fails if a finished run with a peak is
    called failed, if a run whose control stops at 0.05 mm (before the peak near 0.12 mm, so its
    load still rises) is not counted as without a load maximum, or if a run cut short by a budget
    of 3 steps is not counted as stopped early with its limit."""
    names = list(TRUTH)
    X = np.array([list(TRUTH.values())])
    cases = {"peak": ({}, False, False), "no_peak": ({"load_levels": [0.01, 0.02, 0.05]}, False, True),
             "budget": ({"max_steps": 3}, True, False)}
    for case, (options, stopped, no_peak) in cases.items():
        sc = build_scenario({"scenario": "triplet_shear", "precompression": 1.4, "peak_readings": True,
                             "load_levels": LEVELS, **options})
        runs = run_validation(sc, names, X, [len(sc.sensor_names) - 2], np.zeros((1, 1)), tuple(names), X)
        assert bool(runs.stopped[0]) is stopped and bool(runs.no_peak[0]) is no_peak, (case, runs.messages)
        assert runs.failed_share == float(stopped or no_peak), case
        if stopped:
            assert "steps" in runs.messages[0]  # the budget limit that ended it
    # the capacity of the finished run is the FE model's peak: 2 A (c + σ tanφ) = 62.6 kN within 2 %
    # (the FE peak lies a little below Coulomb's line: softening starts at the joints' ends first)
    sc = build_scenario({"scenario": "triplet_shear", "precompression": 1.4, "peak_readings": True,
                         "load_levels": LEVELS})
    runs = run_validation(sc, names, X, [len(sc.sensor_names) - 2], np.zeros((1, 1)), tuple(names), X)
    assert runs.fe[0, 0] == pytest.approx(2 * 21000 * (0.30 + 1.4 * 0.85) / 1000, rel=0.02)


def test_store_rows_without_a_load_maximum(tmp_path):
    """Fails if a finished run without a load maximum (friction below the residual friction,
    tanφ < tanφ_r = 0.75, with little cohesion: the force rises or plateaus to 2 mm) is not found,
    or one with a peak is: 8 triplet runs at 1.4 MPa with c in [0.15, 0.3] MPa and tanφ in [0.5,
    0.8], checked against the force column itself (no level after the peak's interval where the
    force fell 0.5 % below the largest)."""
    spec = {"scenario": "triplet_shear", "precompression": 1.4, "peak_readings": True, "load_levels": LEVELS,
            "parameters": {"ft_bj": 0.1}}
    space = ParameterSpace((Parameter("c_bj", 0.15, 0.3, unit="MPa"), Parameter("tanphi_bj", 0.5, 0.8)))
    path = tmp_path / "v.h5"
    run_snapshots(path, spec, space, n=8, seed=0)
    with SnapshotStore.open(path) as store:
        found = no_peak_rows(store)
        F = store.readings(only_done=True)[:, :, store.sensor_names.index("F")]
        done = np.flatnonzero(store.done_mask())
    # a maximum: the force at the last level 0.5 % or more below the curve's largest
    rising = tuple(int(i) for i in done[F[:, -1] > 0.995 * F.max(axis=1)])
    assert 0 < len(rising) < len(done)  # the premise: both kinds of run in the store
    assert found == rising


def test_a_capacity_validation_is_declared_in_the_study_file(tmp_path):
    """Fails if the triplet series' validation triplet loses its capacity outputs or FE runs, if a
    nonlinear validation model does not default to FE runs at region members, if a bad quantile
    level is accepted without naming the key and the allowed values, or if a capacity output of a
    scenario without peak readings waits for the calibration to fail (after all FE work)."""
    study = load_study(EXAMPLES / "triplet_series.toml")
    (v,) = study.validation
    assert v.spec.options["precompression"] == 1.4 and v.spec.options["peak_readings"]
    assert v.outputs == ("F_peak", "d_peak") and v.fe_runs == 16 and v.quantiles == (0.05, 0.95)
    text = (EXAMPLES / "triplet_series.toml").read_text()
    for f in ("0.2", "0.6", "1.0"):
        (tmp_path / f"triplet_series_{f}MPa.csv").write_text((EXAMPLES / f"triplet_series_{f}MPa.csv").read_text())
    path = tmp_path / "s.toml"
    path.write_text(text.replace("fe_runs = 16 ", "quantiles = [0.1, 0.5, 0.9] "))
    (v,) = load_study(path).validation
    assert v.fe_runs == 16 and v.quantiles == (0.1, 0.5, 0.9)
    path.write_text(text.replace("fe_runs = 16 ", "fe_runs = 0 "))
    assert load_study(path).validation[0].fe_runs == 0
    path.write_text(text.replace("fe_runs = 16 ", "quantiles = [0.95, 1.5] "))
    with pytest.raises(StudyError, match=r"validation\[1\]\.quantiles: .*\[0.95, 1.5\].*allowed: .*\(0, 1\)"):
        load_study(path)
    path.write_text(text.replace("fe_runs = 16 ", "fe_runs = 300 "))
    with pytest.raises(StudyError, match=r"validation\[1\]\.fe_runs: 300 is out of range.*\[0, 256\]"):
        load_study(path)
    # a capacity output of a scenario without peak readings: refused at load time, before any FE run
    path.write_text(text.replace("peak_readings = true, ", ""))
    with pytest.raises(StudyError, match=r"validation\[1\]\.outputs: .*'F_peak'.*peak_readings = true"):
        load_study(path)


def test_the_report_shows_the_band_the_failed_share_and_why_runs_failed(tmp_path):
    """Fails if the report's RVC section loses an output's unit or quantiles, the failed share with
    its counts, the reason a run failed, or the distribution figure (one panel per output, a PNG
    written). The stub runs of the test above: 24 FE runs, some stopped early or without a peak."""
    from podkrig.reports.html import Page
    from podkrig.reports.inverse import plot_rvc_distributions, render_rvc

    rng = np.random.default_rng(5)
    members = np.column_stack([rng.random(40), 2 * rng.random(40)])
    out = rvc(_region(members, ("c", "tanphi")), Capacity(), outputs=["F_peak", "d_peak"], scenario=Triplet(),
              fe_runs=24, rng=3)
    figures = plot_rvc_distributions({"calibration": out, "wall": out}, tmp_path)
    assert figures == {"wall": "rvc_wall.png"}  # validation models only
    assert (tmp_path / "rvc_wall.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = Page("t")
    render_rvc(page, {"wall": out}, figures=figures)
    html = page.markup()
    runs = out.runs
    assert "5 % quantile" in html and "95 % quantile" in html and ">kN<" in html
    cells = [f'<td class="num">{n}</td>' for n in (runs.n_runs, int(runs.stopped.sum()), int(runs.no_peak.sum()),
                                                    f"{100 * out.failed_share:.3g}")]
    assert "".join(cells) in html
    raised = int(sum(s == "error" for s in runs.status))
    budget = int(runs.stopped.sum()) - raised
    assert f"{budget} × budget_exhausted: max_steps" in html and f"{raised} × FE error RuntimeError" in html
    assert f"{int(runs.no_peak.sum())} × no load maximum" in html
    assert 'src="rvc_wall.png"' in html
