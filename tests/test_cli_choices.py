"""Options with a fixed set of values: the CLI offers exactly the study file's words, and the
parser refuses anything else with exit code 2, naming the option and the allowed values."""

import re

import pytest
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.cli._common import (
    KrigingCriterion,
    RegionMethod,
    RigidBody,
    SamplingMethod,
    SensitivitySource,
    SurrogateBackend,
    Variogram,
)
from podkrig.online.rigid_body import RIGID_BODY_CHOICES
from podkrig.sensors.placement import SENSITIVITY_SOURCES
from podkrig.study.settings import BACKENDS, CRITERIA, REGION_METHODS, SAMPLING_METHODS, VARIOGRAMS

runner = CliRunner()


@pytest.mark.parametrize(
    "choices, words",
    [(SamplingMethod, SAMPLING_METHODS), (Variogram, VARIOGRAMS), (KrigingCriterion, CRITERIA),
     (RegionMethod, REGION_METHODS), (SurrogateBackend, BACKENDS), (RigidBody, RIGID_BODY_CHOICES)],
)
def test_cli_choices_are_the_study_file_words(choices, words):
    assert tuple(c.value for c in choices) == words


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
