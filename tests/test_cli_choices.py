"""Options with a fixed set of values: the CLI offers exactly the study file's words, and the
parser refuses anything else with exit code 2, naming the option and the allowed values."""

import re

import pytest
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.cli._common import (
    KrigingCriterion,
    PlacementCriterion,
    RegionMethod,
    RigidBody,
    SamplingMethod,
    SensitivitySource,
    SurrogateBackend,
    Variogram,
)
from podkrig.config import choices
from podkrig.offline.settings import Design, SamplingSettings
from podkrig.online.rigid_body import RIGID_BODY_CHOICES
from podkrig.sensors.placement import SENSITIVITY_SOURCES
from podkrig.sensors.settings import SearchSettings
from podkrig.study.settings import REGION_METHODS, StudyFile
from podkrig.surrogate.settings import SurrogateSettings

runner = CliRunner()


@pytest.mark.parametrize(
    "enum, settings, field",
    [(SamplingMethod, Design, "method"), (Variogram, SurrogateSettings, "variogram"),
     (KrigingCriterion, SurrogateSettings, "criterion"), (SurrogateBackend, SurrogateSettings, "backend"),
     (PlacementCriterion, SearchSettings, "criterion")],
)
def test_cli_choices_are_the_settings_choices(enum, settings, field):
    assert tuple(c.value for c in enum) == choices(settings, field)


def test_the_study_file_validates_into_the_stages_settings():
    # the [sampling] and [surrogate] tables are the stages' own settings classes, so the study
    # file, the CLI and the library offer the same words
    hints = StudyFile.__pydantic_fields__
    assert hints["sampling"].annotation is SamplingSettings
    assert hints["surrogate"].annotation is SurrogateSettings


@pytest.mark.parametrize("enum, words", [(RegionMethod, REGION_METHODS), (RigidBody, RIGID_BODY_CHOICES)])
def test_cli_choices_are_the_study_file_words(enum, words):
    assert tuple(c.value for c in enum) == words


def test_sensitivity_sources_are_the_library_words():
    assert set(c.value for c in SensitivitySource) == set(SENSITIVITY_SOURCES)


@pytest.mark.parametrize(
    "args, option, allowed",
    [
        (["simulate", "diagonal_compression", "--format", "xml"], "--format", ["table", "json", "csv"]),
        (["simulate", "diagonal_compression", "--solver", "mumps"], "--solver",
         ["auto", "pardiso", "superlu"]),
        (["snapshots", "info", "x.h5", "--format", "yaml"], "--format", ["text", "json"]),
        (["surrogate", "build", "x.h5", "--out", "y.h5", "--variogram", "gauss"], "--variogram",
         ["exponential", "power"]),
        (["invert", "x.h5", "--data", "d.csv", "--noise-rel", "0.01", "--region-method", "mcmc"],
         "--region-method", ["likelihood-ratio", "noise-mc"]),
        (["invert", "x.h5", "--data", "d.csv", "--noise-rel", "0.01", "--rigid-body", "off"],
         "--rigid-body", ["auto", "remove", "keep"]),
        (["diagnose", "--scenario", "diagonal_compression", "--data", "d.csv", "--rigid-body", "yes"],
         "--rigid-body", ["auto", "remove", "keep"]),
    ],
)
def test_a_wrong_choice_is_refused_with_the_allowed_values(args, option, allowed):
    result = runner.invoke(app, args)
    assert result.exit_code == 2
    text = re.sub(r"[\s│╭╮╰╯─]+", " ", result.output)  # undo rich's box and line wrapping
    assert f"Invalid value for '{option}'" in text, text
    for word in allowed:
        assert f"'{word}'" in text, (word, text)


def test_choices_arrive_as_plain_text(tmp_path):
    # StrEnum members are str: the library sees the same text as from the study file
    assert SamplingMethod("lhs-ese") == "lhs-ese" and isinstance(SamplingMethod.sobol, str)
    assert f"{RegionMethod.noise_mc}" == "noise-mc"
