"""The settings the offline and surrogate stages own: one declaration of each default and choice,
read by the library (templates, run arguments), the study file and the CLI alike."""

import dataclasses

import pydantic
import pytest

from podkrig.cli._common import settings_from_options
from podkrig.config import field_info
from podkrig.offline.settings import Design, SamplingSettings, TrainingDesign
from podkrig.surrogate.kriging import DEFAULT_BETA, OrdinaryKriging
from podkrig.surrogate.podkriging import DEFAULT_ENERGY
from podkrig.surrogate.settings import SurrogateSettings


def test_design_gives_the_runner_its_arguments():
    design = Design(n=16, seed=3, method="lhs")
    assert design.run_arguments() == {"n": 16, "seed": 3, "sampling": "lhs"}
    assert dataclasses.asdict(design) == {"n": 16, "seed": 3, "method": "lhs"}  # the stage's cache key
    with pytest.raises(pydantic.ValidationError, match="n"):
        TrainingDesign(n=3, seed=0)  # a surrogate needs at least 4 runs
    assert SamplingSettings(train=TrainingDesign(n=8, seed=0), held_out=Design(n=4, seed=1)).workers == 1


def test_surrogate_templates_follow_the_settings():
    pod, kriging = SurrogateSettings().templates()
    assert pod.energy == DEFAULT_ENERGY and pod.n_modes is None
    defaults = OrdinaryKriging().get_params()
    assert {k: kriging.get_params()[k] for k in ("variogram", "beta", "criterion", "nugget")} == {
        k: defaults[k] for k in ("variogram", "beta", "criterion", "nugget")}
    pod, kriging = SurrogateSettings(modes=4, variogram="power", beta=1.5, criterion="loo", nugget=1e-6).templates()
    assert pod.n_modes == 4 and pod.energy is None
    assert (kriging.variogram, kriging.beta, kriging.criterion, kriging.nugget) == ("power", 1.5, "loo", 1e-6)
    assert SurrogateSettings(energy=0.999, backend="smt-krg").templates()[1].backend == "smt-krg"


def test_one_default_per_field():
    info = field_info(SurrogateSettings)
    assert info["beta"]["default"] == DEFAULT_BETA and info["backend"]["default"] == "podkrig"
    assert info["variogram"]["choices"] == ("exponential", "power")


@pytest.mark.parametrize(
    "kwargs, fragments",
    [({"energy": 0.9, "modes": 2}, ["modes", "either energy or modes"]),
     ({"beta": 2.0, "variogram": "power"}, ["beta", "out of range"]),
     ({"beta": "steep"}, ["beta", "steep"])],
)
def test_surrogate_settings_refuse_inconsistent_values(kwargs, fragments):
    with pytest.raises(pydantic.ValidationError) as e:
        SurrogateSettings(**kwargs)
    for fragment in fragments:
        assert fragment in str(e.value)


def test_cli_options_build_settings_and_a_wrong_value_names_its_option():
    options = {"modes": ("--modes", 3), "energy": ("--energy", None), "nugget": ("--nugget", None)}
    assert settings_from_options(SurrogateSettings, options) == SurrogateSettings(modes=3)
    with pytest.raises(ValueError, match=r"--nugget -1.0: .*\[0, 1\]"):
        settings_from_options(SurrogateSettings, {"nugget": ("--nugget", -1.0)})
    with pytest.raises(ValueError, match="--modes 2.*either energy or modes"):
        settings_from_options(SurrogateSettings, {"energy": ("--energy", 0.9), "modes": ("--modes", 2)})


def test_candidate_settings_build_the_grids_the_candidate_functions_build(coarse_diagonal):
    from podkrig.sensors.candidates import Zone, dic_points, gauge_grid, parse_range
    from podkrig.sensors.settings import CandidateSettings

    mesh, zone = coarse_diagonal.mesh, Zone(150.0, 150.0, 250.0, 250.0)
    where = CandidateSettings(grid_x="20:380:40", grid_y="20:380:40", lengths=(80.0, 160.0), dic_x="50:350:100",
                              dic_y="50:350:100", cost_dic=2.0)
    got = where.candidates(mesh, forbidden=[zone])
    g = parse_range("20:380:40")
    want = gauge_grid(mesh, g, g, lengths=(80.0, 160.0), forbidden=[zone]) + dic_points(
        mesh, parse_range("50:350:100"), parse_range("50:350:100"), forbidden=[zone], cost=2.0)
    assert got.names == want.names and got.cost.tolist() == want.cost.tolist()
    with pytest.raises(ValueError, match="no candidates"):
        CandidateSettings().candidates(mesh)


@pytest.mark.parametrize(
    "options, fragments",
    [({"grid_x": ("--grid-x", "20:380:40"), "grid_y": ("--grid-y", None)}, ["--grid-y", "give both grid_x and grid_y"]),
     ({"grid_x": ("--grid-x", "20:10:40"), "grid_y": ("--grid-y", "0:1:1")}, ["--grid-x '20:10:40'", "STEP > 0",
                                                                               "START:STOP:STEP"]),
     ({"cost_dic": ("--cost-dic", 0.0)}, ["--cost-dic 0.0", "a number > 0"])],
)
def test_candidate_options_are_refused_by_their_option(options, fragments):
    from podkrig.sensors.settings import CandidateSettings

    with pytest.raises(ValueError) as e:
        settings_from_options(CandidateSettings, options)
    for fragment in fragments:
        assert fragment in str(e.value), (fragment, str(e.value))


def test_placement_settings_defaults_are_the_documented_ones():
    from podkrig.sensors.criteria import UNIFORM_PRIOR_INFORMATION
    from podkrig.sensors.search import METHODS
    from podkrig.sensors.settings import PlacementSettings

    s = PlacementSettings()
    assert (s.search.criterion, s.search.n_points, s.search.methods, s.search.prior_information) == (
        "d", 64, METHODS, UNIFORM_PRIOR_INFORMATION)
    assert (s.comparison.n_random, s.comparison.n_monte_carlo, s.comparison.n_truths, s.seed) == (20, 0, 1, 0)
    with pytest.raises(pydantic.ValidationError, match="criterion"):
        PlacementSettings(search={"criterion": "b"})
