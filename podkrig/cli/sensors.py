"""``podkrig sensors``: choose where to put the gauges so that the identification is sharpest."""

import json
import tomllib
from pathlib import Path

import typer

from podkrig.cli._common import SensitivitySource, configure_logging, user_errors
from podkrig.cli.simulate import load_spec, parse_assignment


def _read_candidates(path):
    """``{name: definition}`` from a TOML/JSON file with a ``[sensors]`` table (or the table itself)."""
    try:
        text = Path(path).read_text()
    except OSError as e:
        raise ValueError(f"--candidates {path}: cannot read: {e.strerror}") from None
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
        length: str = typer.Option("50:400", "--length", help="Gauge length range MIN:MAX mm."),
        orientation: list[float] = typer.Option([0.0, 45.0, 90.0, 135.0], "--orientation", help="Gauge direction, degrees from x (repeatable)."),
        dic_x: str = typer.Option(None, "--dic-x", help="DIC point grid along x, START:STOP:STEP mm."),
        dic_y: str = typer.Option(None, "--dic-y", help="DIC point grid along y, START:STOP:STEP mm."),
        candidates_file: Path = typer.Option(None, "--candidates", help="User candidate list: TOML/JSON [sensors] table (optional cost per sensor)."),
        noise_lvdt: float = typer.Option(0.002, "--noise-lvdt", help="σ of a gauge reading, mm."),
        noise_dic: float = typer.Option(0.005, "--noise-dic", help="σ of a DIC displacement component, mm."),
        noise_rel: float = typer.Option(None, "--noise-rel", help="Relative noise δ instead (σ = δ |reading|)."),
        cost_lvdt: float = typer.Option(1.0, "--cost-lvdt", help="Cost of one gauge."),
        cost_dic: float = typer.Option(1.0, "--cost-dic", help="Cost of one DIC point."),
        criterion: str = typer.Option("d", "--criterion", help="d, a, e or pod."),
        forbid: list[str] = typer.Option([], "--forbid", help="Forbidden zone X0:Y0:X1:Y1 mm (repeatable)."),
        min_spacing: float = typer.Option(0.0, "--min-spacing", help="Smallest distance between chosen sensor centres, mm."),
        must_include: list[str] = typer.Option([], "--must-include", help="Sensor name always chosen (repeatable)."),
        no_current: bool = typer.Option(False, "--no-current", help="Do not add/score the scenario's current sensors."),
        n_points: int = typer.Option(64, "--n-points", help="Sobol' points of the box the criteria average over."),
        n_random: int = typer.Option(20, "--random", help="Random layouts to compare against."),
        monte_carlo: int = typer.Option(0, "--monte-carlo", help="Noise realisations of the inversion check per layout (0: skip)."),
        truths: int = typer.Option(1, "--truths", help="Truth points of the Monte-Carlo check."),
        sensitivities: SensitivitySource = typer.Option(
            SensitivitySource.auto, "--sensitivities",
            help="exact: the affine FE model (one factorisation per point); fe: differences of FE runs (loads that "
                 "depend on the parameters, e.g. the flat jack's Km; nonlinear scenarios); auto: exact where possible."),
        seed: int = typer.Option(0, "--seed"),
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
        from rich.console import Console
        from rich.markup import escape
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )
        from rich.table import Table

        from fe.scenarios import SCENARIOS, build_scenario
        from podkrig.parameters import ParameterSpace, parse_params
        from podkrig.reports.sensors import comparison_markdown, comparison_rows, plot_layout
        from podkrig.sensors.candidates import (
            Zone,
            dic_points,
            gauge_grid,
            parse_range,
            user_candidates,
        )
        from podkrig.sensors.criteria import SensorNoise
        from podkrig.sensors.placement import place_sensors, spec_toml

        with user_errors():
            if scenario not in SCENARIOS:
                raise ValueError(f"unknown scenario {scenario!r}; available: {sorted(SCENARIOS)}")
            sc = build_scenario(load_spec(scenario, spec))
            space = ParameterSpace.from_scenario(sc, parse_params(param))
            fixed = dict(parse_assignment(t, "--fix") for t in fix)
            zones = [Zone.parse(t) for t in forbid]
            parts = []
            if (grid_x is None) != (grid_y is None):
                raise ValueError("give both --grid-x and --grid-y (gauge end-point grid)")
            if grid_x is not None:
                lo, _, hi = length.partition(":")
                try:
                    lengths = (float(lo), float(hi))
                except ValueError:
                    raise ValueError(f"--length {length!r}: expected MIN:MAX in mm, e.g. 50:400") from None
                parts.append(gauge_grid(sc.mesh, parse_range(grid_x, "--grid-x"), parse_range(grid_y, "--grid-y"),
                                        lengths=lengths, orientations=orientation, forbidden=zones, cost=cost_lvdt))
            if (dic_x is None) != (dic_y is None):
                raise ValueError("give both --dic-x and --dic-y (DIC point grid)")
            if dic_x is not None:
                parts.append(dic_points(sc.mesh, parse_range(dic_x, "--dic-x"), parse_range(dic_y, "--dic-y"),
                                        forbidden=zones, cost=cost_dic))
            if candidates_file is not None:
                parts.append(user_candidates(sc.mesh, _read_candidates(candidates_file), forbidden=zones, cost=cost_lvdt))
            if not parts:
                raise ValueError("no candidates: give --grid-x/--grid-y, --dic-x/--dic-y and/or --candidates FILE")
            cands = parts[0]
            for extra in parts[1:]:
                cands = cands + extra
            noise = SensorNoise(lvdt=noise_lvdt, dic=noise_dic, relative=noise_rel)
            progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                                console=Console(stderr=True))
            tasks = {}

            def report(stage, done, total):
                if not progress.live.is_started:
                    progress.start()
                if stage not in tasks:
                    tasks[stage] = progress.add_task(stage, total=total)
                progress.update(tasks[stage], completed=done, total=total)

            try:
                result = place_sensors(
                    sc, space, cands, k=k, budget=budget, noise=noise, criterion=criterion, fixed=fixed,
                    n_points=n_points, seed=seed, must_include=tuple(must_include), min_spacing=min_spacing,
                    include_current=not no_current, n_random=n_random, n_monte_carlo=monte_carlo,
                    n_truths=truths, forbidden=zones, model=str(sensitivities), progress=report,
                )
            finally:
                progress.stop()
            out.mkdir(parents=True, exist_ok=True)
            (out / "layout.toml").write_text(spec_toml(result.spec()))
            (out / "scenario_table.toml").write_text(spec_toml(result.spec(), table="scenario"))
            (out / "placement.json").write_text(json.dumps(result.to_dict(), indent=2))
            (out / "comparison.md").write_text(comparison_markdown(result))
            plot_layout(result, out / "layout.png")

        console = Console()
        lay = result.layout
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
        has_mc = monte_carlo > 0
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
