"""Hidden-truth coverage of a strength study: N pseudo-experiments on one set of surrogates.

For a study (the triplet series of ``examples/triplet_series.toml``, or the J4D wall) this script

1. runs the study once (``podkrig run``: probe, training and held-out snapshots, surrogates, and a
   validation model whose peak load is the *capacity*) — the surrogates are trained once;
2. draws N hidden truths inside the parameter box, away from its faces: a scrambled Sobol' set
   mapped to the middle 80 % of each range (in each parameter's sampling scale). The truths make
   the data and judge the result; the calibration never sees them;
3. for each truth, runs every test's FE scenario there and adds the study's noise (σ² = σ_abs² +
   (δ d)², δ = 1 %, σ_abs = 0.05 kN on forces, 2 µm on gauges, drawn around the noise-free
   reading d), then calibrates on the study's surrogates exactly as the study's calibration stage
   does (:func:`podkrig.online.calibrate.calibrate`: GA + polish, 95 % region of equivalence, FE
   check, RVC of the capacity model — its surrogate over the region's members; the FE runs at
   members that count its failures are left out, they do not move the band);
4. counts how often the truth lies inside the 95 % region (ω(truth) ≤ ω(m*) + ½ χ²_p(0.95), with
   the surrogate's variance in C_T frozen at m* as the region has it) and how often the 5–95 %
   band of the capacity RVC (the validation model's peak load over the region's members) contains
   the FE peak load of the validation model at the truth.

The table also gives, per pseudo-experiment, ω(truth) − ω(m*) against the region's height
½ χ²_p(0.95) and the surrogate's error at the truth in units of the noise σ (RMS over the
readings): the two numbers that explain a miss (a data realisation in the tail, or a surrogate
less accurate than its C_T says).

Usage, from the repository root::

    nice -n 5 python scripts/hidden_truth.py --study triplet --n 40 --out out/hidden_truth_triplet
    nice -n 5 python scripts/hidden_truth.py --study j4d --n 40 --out out/hidden_truth_j4d

The study's own stages are cached in ``OUT/study`` (a rerun does no FE work but the
pseudo-experiments'); ``OUT/hidden_truth.json`` holds every row and the summary. Results are
recorded in BENCHMARKS.md ("Hidden-truth coverage of the strength studies").
"""

import argparse
import dataclasses
import json
import re
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from fe.scenarios import build_scenario
from podkrig._qmc import scrambled_sobol
from podkrig.io.surrogate_file import load_surrogate
from podkrig.offline.failures import without_peak
from podkrig.online.calibrate import calibrate
from podkrig.online.joint import JointProblem
from podkrig.online.problem import InverseProblem, SurrogateModel, fix_from_scenario
from podkrig.online.propagation import RVCModel
from podkrig.study import load_study, run_study
from podkrig.study.stages import read_study_measurement

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: share of each range left out at either end when the truths are drawn
MARGIN = 0.1
#: the capacity: the peak load of a scenario with ``peak_readings`` (kN)
CAPACITY = "F_peak"


@dataclass(frozen=True)
class Case:
    """A study under test: its file and the measurement files it reads. The study declares its
    capacity: a ``[[validation]]`` whose scenario has ``peak_readings`` (the first such)."""

    study: Path
    data: tuple
    truth_seed: int = 32
    noise_seed: int = 3200


CASES = {
    # capacity: the fourth triplet at 1.4 MPa (the study's [[validation]] "p1_4MPa")
    "triplet": Case(EXAMPLES / "triplet_series.toml",
                    tuple(f"triplet_series_{p}MPa.csv" for p in ("0.2", "0.6", "1.0"))),
    # capacity: the wall at 1.21 MPa (the study's [[validation]] "J6D")
    "j4d": Case(EXAMPLES / "j4d_wall.toml", ("j4d_wall_measured.csv",)),
}


def prepare(case, folder, train=None):
    """The study of ``case`` with its capacity validation model, written to ``folder`` (with copies
    of its measurement files, which it reads for its own calibration): the loaded Study.
    ``train``: another number of training snapshots per test than the study's."""
    if not case.study.is_file():
        raise SystemExit(f"{case.study.relative_to(ROOT)} is not in this checkout: nothing to test")
    folder.mkdir(parents=True, exist_ok=True)
    for name in case.data:
        shutil.copyfile(case.study.parent / name, folder / name)
    text = case.study.read_text()
    if train is not None:
        text, n = re.subn(r"(train\s*=\s*\{\s*n\s*=\s*)\d+", rf"\g<1>{train}", text)
        if n != 1:
            raise SystemExit(f"{case.study.name}: no single 'train = {{ n = ... }}' to change")
    path = folder / case.study.name
    path.write_text(text)
    study = load_study(path)
    capacity = capacity_model(study)
    if capacity is None:
        raise SystemExit(f"{case.study.name} declares no capacity model (a [[validation]] with peak_readings)")
    # the pseudo-experiments need the surrogates and the capacity model, not the study's other
    # validation models, its sensitivity or its diagnosis
    return dataclasses.replace(study, validation=(capacity,),
                               sensitivity=dataclasses.replace(study.sensitivity, enabled=False),
                               diagnosis=dataclasses.replace(study.diagnosis, enabled=False))


def capacity_model(study):
    """The study's capacity model: its first validation model with ``peak_readings`` (None if none)."""
    return next((v for v in study.validation if v.spec.options.get("peak_readings")), None)


def truths(space, n, seed, margin=MARGIN):
    """``n`` hidden truths, ``(n, n_free)`` physical: scrambled Sobol' points in the middle
    ``1 − 2 margin`` of each range (in the parameter's sampling scale)."""
    U = margin + (1 - 2 * margin) * scrambled_sobol(n, len(space.names), seed)
    return space.from_unit(U)


def pseudo_data(data, noise, clean, rng):
    """A noisy copy of ``data`` (a Measurement of the test) around the noise-free readings
    ``clean`` (its observed vector): σ from the study's noise model evaluated at ``clean``."""
    sigma = noise.std(data.with_data(clean))
    return data.with_data(clean + sigma * rng.standard_normal(clean.shape), source="hidden-truth pseudo-data")


class Experiments:
    """The study's surrogates, loaded once, and what each pseudo-experiment needs."""

    def __init__(self, study, out):
        self.study, self.out = study, Path(out)
        self.tests = study.calibration_tests
        self.scenarios = {t.name: build_scenario(t.spec) for t in self.tests}
        self.models, self.base, self.noise, self.fixed = {}, {}, {}, {}
        for t in self.tests:
            model = SurrogateModel(load_surrogate(self.out / t.file("surrogate.h5")))
            data, noise = read_study_measurement(t, model.sensor_names, model.load_levels, model.load_unit,
                                                 model.load_response, self.scenarios[t.name].sensor_units)
            self.models[t.name], self.base[t.name], self.noise[t.name] = model, data, noise
            self.fixed[t.name] = fix_from_scenario(model)
        val = capacity_model(study)
        self.validation_name = val.name
        self.validation_model = SurrogateModel(load_surrogate(self.out / f"validation_{val.name}_surrogate.h5"))
        self.validation_scenario = build_scenario(val.spec)
        self.settings = study.calibration_settings()

    def problem(self, measurements):
        """The calibration problem on the surrogates with these data (test name → Measurement)."""
        problems = {}
        for t in self.tests:
            free, fixed = self.fixed[t.name]
            m = t.measurement
            problems[t.name] = InverseProblem(self.models[t.name], measurements[t.name], self.noise[t.name],
                                              free=free, fixed=fixed, rigid_body=m.rigid_body,
                                              rigid_groups=m.rigid_groups)
        if not self.study.tests:
            return problems[self.tests[0].name]
        return JointProblem(problems)

    def capacity_of(self, values):
        """The FE capacity (the validation model's peak load ``F_peak``) at ``values``, or None when
        the run gives none: it stopped early, or its load has no maximum within the control range
        (:func:`~podkrig.offline.failures.without_peak`; ``F_peak`` is then a lower bound)."""
        response = self.validation_scenario.run(values)
        last = dict(zip(response.sensor_names, response.readings[-1]))
        if getattr(response, "status", "converged") != "converged" or without_peak(last["d_peak"],
                                                                                  response.load_levels):
            return None
        return float(last[CAPACITY])

    def run(self, x_true, seed, data_from="fe"):
        """One pseudo-experiment at the free values ``x_true``: its row of the table (dict).
        ``data_from`` "surrogate" makes the pseudo-data from the surrogates instead of the FE
        model: a control in which the surrogate is exact, so that only the region's statistics
        (Wilks' χ² bound on a nonlinear model) are tested."""
        names = self.study.space.names
        truth = dict(zip(names, map(float, x_true)))
        rng = np.random.default_rng(seed)
        measurements, surrogate_error = {}, []
        for t in self.tests:
            data, model = self.base[t.name], self.models[t.name]
            response = self.scenarios[t.name].run({n: truth[n] for n in t.space.names})
            if getattr(response, "status", "converged") != "converged":  # no whole curve to measure
                return {"seed": seed, "truth": truth, "skipped": f"the FE run of test {t.name} at the truth "
                                                                 f"stopped early ({response.status})"}
            flat = lambda Y: data.observation(model.sensor_names, model.load_levels, model.load_response,  # noqa: E731
                                              model.load_unit).apply(np.atleast_2d(Y).reshape(1, -1))[0]
            fe = flat(response.readings)
            full = np.array([[truth[n] if n in truth else self.fixed[t.name][1][n] for n in model.space.names]])
            predicted = flat(model.predict(full)[0])
            surrogate_error.append((predicted - fe) / self.noise[t.name].std(data.with_data(fe)))
            clean = predicted if data_from == "surrogate" else fe
            measurements[t.name] = pseudo_data(data, self.noise[t.name], clean, rng)
        problem = self.problem(measurements)
        result = calibrate(problem, self.settings, scenarios=lambda name: self.scenarios[name],
                           validation={self.validation_name: RVCModel(self.validation_model, (CAPACITY,))},
                           check_measurement=False, range_check=False, calibration_rvc=False)
        region, inv = result.region, result.inversion
        frozen = problem.freeze_model_error(inv.x)
        omega_truth = float(frozen.omega(np.atleast_2d(x_true))[0])
        omega_best = float(frozen.omega(np.atleast_2d(inv.x))[0])
        band = result.rvc[self.validation_name]
        lo, hi = band.quantiles[:, 0]  # the 5 % and 95 % quantiles over the region's members
        cap_true = self.capacity_of(truth)
        return {"seed": seed, "truth": truth, "estimate": dict(zip(names, map(float, inv.x))),
                "chi2_dof": float(inv.chi2_dof), "omega_excess": omega_truth - omega_best,
                "height": float(region.threshold - omega_best), "inside": bool(omega_truth <= region.threshold),
                "intervals": {n: list(region.intervals[n]) for n in names},
                "surrogate_error_sigma": float(np.sqrt(np.mean(np.concatenate(surrogate_error) ** 2))),
                "capacity_band": [float(lo), float(hi)], "capacity_truth": cap_true,
                "capacity_inside": None if cap_true is None else bool(lo <= cap_true <= hi),
                "seconds": result.seconds}


def coverage(rows):
    """Counts ``(inside, capacity_inside, n, n_capacity)``: the truth inside the region, its
    capacity inside the band, of ``n`` experiments (those whose FE runs at the truth reached the
    end of the curve), ``n_capacity`` of them with an FE capacity at the truth (a run without a
    load maximum has none)."""
    rows = [r for r in rows if "skipped" not in r]
    capacities = [r["capacity_inside"] for r in rows if r["capacity_inside"] is not None]
    return sum(r["inside"] for r in rows), sum(capacities), len(rows), len(capacities)


def binomial_floor(n, p=0.95, alpha=0.05):
    """The smallest count k with P(X < k) ≤ ``alpha`` for X ~ Binomial(n, p): fewer than k inside
    is evidence, at level alpha, that the coverage is below p (36 for n = 40)."""
    return int(stats.binom.ppf(alpha, n, p))


def table(rows, names, unit_of):
    """The per-experiment table as text lines."""
    head = (["#", *(f"{n} truth/est" for n in names), "ω−ω*", "in", "sur.err/σ", "capacity 5-95 %", "FE truth", "in"])
    lines = [" | ".join(head)]
    for k, r in enumerate(rows):
        if "skipped" in r:
            lines.append(f"{k} | skipped: {r['skipped']}")
            continue
        cells = [str(k), *(f"{r['truth'][n]:.4g}/{r['estimate'][n]:.4g}" for n in names),
                 f"{r['omega_excess']:.2f}/{r['height']:.2f}", "y" if r["inside"] else "n",
                 f"{r['surrogate_error_sigma']:.2f}",
                 f"[{r['capacity_band'][0]:.4g}, {r['capacity_band'][1]:.4g}] {unit_of}",
                 "no peak" if r["capacity_truth"] is None else f"{r['capacity_truth']:.4g}",
                 {True: "y", False: "n", None: "-"}[r["capacity_inside"]]]
        lines.append(" | ".join(cells))
    return lines


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--study", choices=sorted(CASES), default="triplet")
    parser.add_argument("--n", type=int, default=40, help="Pseudo-experiments (default 40).")
    parser.add_argument("--out", type=Path, default=None, help="Output folder (default out/hidden_truth_STUDY).")
    parser.add_argument("--train", type=int, default=None,
                        help="Training snapshots per test instead of the study's (a surrogate-accuracy experiment).")
    parser.add_argument("--reuse", type=Path, default=None,
                        help="A finished `podkrig run` folder of the same study: copied to OUT/study first, so its "
                             "snapshots and surrogates are reused (its stages are cached by their inputs).")
    parser.add_argument("--data-from", choices=("fe", "surrogate"), default="fe",
                        help="Make the pseudo-data from the FE model (default) or from the surrogates (a control).")
    args = parser.parse_args(argv)
    case = CASES[args.study]
    out = args.out or ROOT / "out" / f"hidden_truth_{args.study}"
    if args.reuse is not None:
        shutil.copytree(args.reuse, out / "study", dirs_exist_ok=True)
    study = prepare(case, out / "study", args.train)
    cpu0 = time.process_time()
    run_study(study, out / "study")
    cpu_study = time.process_time() - cpu0
    exp = Experiments(study, out / "study")
    X = truths(study.space, args.n, case.truth_seed)
    rows = []
    cpu1 = time.process_time()
    for k, x in enumerate(X):
        rows.append(exp.run(x, case.noise_seed + k, args.data_from))
        r = rows[-1]
        (out / "hidden_truth.json").write_text(json.dumps({"rows": rows}, indent=1))  # kept as they come
        if "skipped" in r:
            print(f"{k:3d}: skipped: {r['skipped']}", flush=True)
            continue
        print(f"{k:3d}: inside {'y' if r['inside'] else 'n'} (ω−ω* {r['omega_excess']:.2f} of {r['height']:.2f}), "
              f"capacity {({True: 'y', False: 'n', None: '-'})[r['capacity_inside']]}", flush=True)
    cpu_exp = time.process_time() - cpu1
    inside, cap_inside, n, n_cap = coverage(rows)
    unit = exp.validation_scenario.sensor_units[CAPACITY]
    print("\n".join(table(rows, study.space.names, unit)))
    floor = binomial_floor(n)
    summary = {"study": args.study, "n": n, "train": args.train, "data_from": args.data_from, "inside": inside,
               "capacity_inside": cap_inside, "n_capacity": n_cap, "target": floor,
               "capacity_target": binomial_floor(n_cap),
               "cpu_seconds_study": cpu_study, "cpu_seconds_experiments": cpu_exp,
               "skipped": len(rows) - n,
               "median_surrogate_error_sigma": float(np.median([r["surrogate_error_sigma"] for r in rows
                                                                if "skipped" not in r]))}
    print(f"\ntruth inside the 95 % region: {inside} of {n} (target ≥ {floor}); capacity inside its 5-95 % band: "
          f"{cap_inside} of the {n_cap} truths with a load maximum (target ≥ {summary['capacity_target']})")
    print(f"CPU: study {cpu_study:.0f} s, {n} pseudo-experiments {cpu_exp:.0f} s")
    (out / "hidden_truth.json").write_text(json.dumps({"summary": summary, "rows": rows}, indent=1))
    return summary


if __name__ == "__main__":
    main()
