"""``podkrig sensors``: choose where to put the gauges so that the identification is sharpest."""

import json
import tomllib
from pathlib import Path

import typer

from podkrig.cli._common import (
    PlacementCriterion, SensitivitySource, configure_logging, settings_from_options, user_errors,
)
from podkrig.cli.simulate import load_spec, parse_assignment
from podkrig.config import field_info
from podkrig.limits import MAX_STUDY_FILE_BYTES, read_bounded
from podkrig.sensors.criteria import SensorNoise
from podkrig.sensors.settings import CandidateSettings, ComparisonSettings, PlacementSettings, SearchSettings

#: the defaults of the settings, shown as the options' defaults
_CANDIDATE = {k: f["default"] for k, f in field_info(CandidateSettings).items()}
_SEARCH = {k: f["default"] for k, f in field_info(SearchSettings).items()}
_COMPARISON = {k: f["default"] for k, f in field_info(ComparisonSettings).items()}
_PLACEMENT = {k: f["default"] for k, f in field_info(PlacementSettings).items()}
_NOISE = SensorNoise()


def _read_candidates(path):
    """``{name: definition}`` from a TOML/JSON file with a ``[sensors]`` table (or the table itself)."""
    try:
        text = read_bounded(path, MAX_STUDY_FILE_BYTES, "candidate-sensor file").decode("utf-8")
    except OSError as e:
        raise ValueError(f"--candidates {path}: cannot read: {e.strerror}") from None
    except ValueError as e:
        raise ValueError(f"--candidates {e}") from None
    try:
        d = json.loads(text) if str(path).endswith(".json") else tomllib.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as e:
        raise ValueError(f"--candidates {path}: not valid TOML/JSON: {e}") from None
    d = d.get("sensors", d)
    if not isinstance(d, dict) or not all(isinstance(v, dict) for v in d.values()):
        raise ValueError(f"--candidates {path}: expected a [sensors] table of name = {{ kind = ..., ... }}")
    return d


def register(app):
    @app.command()
    def sensors(
        scenario: str = typer.Option(..., "--scenario", help="Scenario name, e.g. diagonal_compression."),
        spec: Path = typer.Option(None, "--spec", help="Scenario spec file (TOML or JSON); its sensors are the current layout."),
        param: list[str] = typer.Option([], "--param", help="Free parameter NAME=LOW:HIGH[:log] (repeatable)."),
        fix: list[str] = typer.Option([], "--fix", help="Fixed parameter NAME=VALUE (repeatable)."),
        k: int = typer.Option(None, "--k", help="Number of sensors to choose."),
        budget: float = typer.Option(None, "--budget", help="Total cost budget instead of --k."),
        grid_x: str = typer.Option(None, "--grid-x", help="Gauge end-point grid along x, START:STOP:STEP mm."),
        grid_y: str = typer.Option(None, "--grid-y", help="Gauge end-point grid along y, START:STOP:STEP mm."),
        length: str = typer.Option(":".join(f"{v:g}" for v in _CANDIDATE["lengths"]), "--length",
                                   help="Gauge length range MIN:MAX mm."),
        orientation: list[float] = typer.Option(list(_CANDIDATE["orientations"]), "--orientation",
                                                help="Gauge direction, degrees from x (repeatable)."),
        dic_x: str = typer.Option(None, "--dic-x", help="DIC point grid along x, START:STOP:STEP mm."),
        dic_y: str = typer.Option(None, "--dic-y", help="DIC point grid along y, START:STOP:STEP mm."),
        candidates_file: Path = typer.Option(None, "--candidates", help="User candidate list: TOML/JSON [sensors] table (optional cost per sensor)."),
        noise_lvdt: float = typer.Option(_NOISE.lvdt, "--noise-lvdt", help="σ of a gauge reading, mm."),
        noise_dic: float = typer.Option(_NOISE.dic, "--noise-dic", help="σ of a DIC displacement component, mm."),
        noise_rel: float = typer.Option(None, "--noise-rel", help="Relative noise δ instead (σ = δ |reading|)."),
        cost_lvdt: float = typer.Option(_CANDIDATE["cost_lvdt"], "--cost-lvdt", help="Cost of one gauge."),
        cost_dic: float = typer.Option(_CANDIDATE["cost_dic"], "--cost-dic", help="Cost of one DIC point."),
        criterion: PlacementCriterion = typer.Option(PlacementCriterion(_SEARCH["criterion"]), "--criterion",
                                                     help="Criterion of the layout (pod: POD modes of the readings)."),
        forbid: list[str] = typer.Option([], "--forbid", help="Forbidden zone X0:Y0:X1:Y1 mm (repeatable)."),
        min_spacing: float = typer.Option(_SEARCH["min_spacing"], "--min-spacing", help="Smallest distance between chosen sensor centres, mm."),
        must_include: list[str] = typer.Option([], "--must-include", help="Sensor name always chosen (repeatable)."),
        no_current: bool = typer.Option(not _SEARCH["include_current"], "--no-current", help="Do not add/score the scenario's current sensors."),
        n_points: int = typer.Option(_SEARCH["n_points"], "--n-points", help="Sobol' points of the box the criteria average over."),
        n_random: int = typer.Option(_COMPARISON["n_random"], "--random", help="Random layouts to compare against."),
        monte_carlo: int = typer.Option(_COMPARISON["n_monte_carlo"], "--monte-carlo", help="Noise realisations of the inversion check per layout (0: skip)."),
        truths: int = typer.Option(_COMPARISON["n_truths"], "--truths", help="Truth points of the Monte-Carlo check."),
        sensitivities: SensitivitySource = typer.Option(
            SensitivitySource.auto, "--sensitivities",
            help="exact: the affine FE model (one factorisation per point); fe: differences of FE runs (loads that "
                 "depend on the parameters, e.g. the flat jack's Km; nonlinear scenarios); auto: exact where possible."),
        seed: int = typer.Option(_PLACEMENT["seed"], "--seed"),
        out: Path = typer.Option(Path("out/sensors"), "--out", help="Output folder."),
        verbose: bool = typer.Option(False, "--verbose", "-v"),
    ):
        """Choose k sensors (or a budget) among candidates to minimise the identification uncertainty.

        Writes OUT/layout.toml (a scenario spec with the chosen sensors: podkrig simulate --spec,
        snapshots run --spec, or a study's scenario = "layout.toml"), OUT/scenario_table.toml (the
        same as a study's [scenario] table), OUT/placement.json, OUT/layout.png and OUT/comparison.md.
        """
        configure_logging(verbose)
        # imported here, not at module top: the FE, surrogate and online stacks take ~6.5 s to import
        # (measured under load, 2026-11-24) and every other podkrig command would pay for them
        from rich.markup import escape
        from rich.table import Table

        from fe.scenarios import SCENARIOS, build_scenario
        from podkrig.cli._terminal import Progress
        from podkrig.cli._terminal import console as command_console
        from podkrig.parameters import ParameterSpace, parse_params
        from podkrig.reports.sensors import comparison_markdown, comparison_rows, plot_layout
        from podkrig.sensors.candidates import Zone
        from podkrig.sensors.placement import place_sensors, spec_toml

        with user_errors():
            if scenario not in SCENARIOS:
                raise ValueError(f"unknown scenario {scenario!r}; available: {sorted(SCENARIOS)}")
            sc = build_scenario(load_spec(scenario, spec))
            space = ParameterSpace.from_scenario(sc, parse_params(param))
            fixed = dict(parse_assignment(t, "--fix") for t in fix)
            zones = [Zone.parse(t) for t in forbid]
            lo, _, hi = length.partition(":")
            try:
                lengths = (float(lo), float(hi))
            except ValueError:
                raise ValueError(f"--length {length!r}: expected MIN:MAX in mm, e.g. 50:400") from None
            where = settings_from_options(CandidateSettings, {
                "grid_x": ("--grid-x", grid_x), "grid_y": ("--grid-y", grid_y), "lengths": ("--length", lengths),
                "orientations": ("--orientation", tuple(orientation)), "dic_x": ("--dic-x", dic_x),
                "dic_y": ("--dic-y", dic_y), "cost_lvdt": ("--cost-lvdt", cost_lvdt), "cost_dic": ("--cost-dic", cost_dic)})
            search = settings_from_options(SearchSettings, {
                "k": ("--k", k), "budget": ("--budget", budget), "criterion": ("--criterion", criterion.value),
                "n_points": ("--n-points", n_points), "must_include": ("--must-include", tuple(must_include)),
                "min_spacing": ("--min-spacing", min_spacing), "include_current": ("--no-current", not no_current)})
            comparison = settings_from_options(ComparisonSettings, {
                "n_random": ("--random", n_random), "n_monte_carlo": ("--monte-carlo", monte_carlo),
                "n_truths": ("--truths", truths)})
            settings = settings_from_options(PlacementSettings, {
                "search": ("", search), "comparison": ("", comparison), "seed": ("--seed", seed)})
            noise = settings_from_options(SensorNoise, {"lvdt": ("--noise-lvdt", noise_lvdt), "dic": ("--noise-dic", noise_dic),
                                                        "relative": ("--noise-rel", noise_rel)})
            user = None if candidates_file is None else _read_candidates(candidates_file)
            cands = where.candidates(sc.mesh, user, forbidden=zones)
            with Progress("sensors") as progress:
                result = place_sensors(sc, space, cands, settings, noise=noise, fixed=fixed, forbidden=zones,
                                       model=str(sensitivities), progress=progress)
            out.mkdir(parents=True, exist_ok=True)
            (out / "layout.toml").write_text(spec_toml(result.spec()))
            (out / "scenario_table.toml").write_text(spec_toml(result.spec(), table="scenario"))
            (out / "placement.json").write_text(json.dumps(result.to_dict(), indent=2))
            (out / "comparison.md").write_text(comparison_markdown(result))
            plot_layout(result, out / "layout.png")

        console = command_console()
        lay = result.layout
        criterion = search.criterion
        console.print(f"{len(cands)} candidates ({len(result.candidates)} with the current sensors); "
                      f"criterion {criterion.upper()} averaged over {result.n_points} Sobol' points; "
                      f"sensitivities {result.sensitivity_seconds:.1f} s, search {lay.seconds:.2f} s "
                      f"({lay.n_evaluations} layouts; best from {lay.method})")
        table = Table(title="chosen sensors (contribution: loss increase without it)")
        for col in ("sensor", "definition (mm)", "contribution"):
            table.add_column(col)
        for i, c in zip(lay.indices, result.contributions):
            s = result.candidates.sensors[i]
            table.add_row(escape(s.name), escape(json.dumps(s.to_dict())), f"{c:.4g}")
        console.print(table)
        comp = Table(title="layouts compared: 95 % interval width, fraction of the box (log10 for log parameters)")
        comp.add_column("layout")
        comp.add_column(f"Ψ_{criterion.upper()}", justify="right")
        for n in space.names:
            comp.add_column(f"lin. {n}", justify="right")
        has_mc = comparison.n_monte_carlo > 0
        if has_mc:
            for n in space.names:
                comp.add_column(f"MC {n}", justify="right")
        for label, crit, lin, mc in comparison_rows(result):
            row = [label, f"{crit[criterion]:.4g}"] + [f"{w:.3f}" for w in lin]
            if has_mc:
                row += [f"{w:.3f}" for w in mc] if mc is not None else ["–"] * len(space.names)
            comp.add_row(*row)
        console.print(comp)
        console.print(f"wrote {out}/layout.toml (spec for --spec), scenario_table.toml (study [scenario]), "
                      "placement.json, comparison.md, layout.png", markup=False)

    return sensors
