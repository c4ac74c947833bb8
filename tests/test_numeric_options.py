"""Every numeric option of the command line refused in the library's words: the option's name, the
value and the allowed range, before any file is read or FE run made (exit code 2, no traceback).

The ranges live in the settings objects (``podkrig.config`` + each stage's ``settings.py``) or in
:mod:`podkrig.limits`, so the command line, the study file and the Python API refuse the same
values; these are the holes a sweep of every command's numeric options found (issue cases:
``--mcmc-steps -1`` once said "negative dimensions are not allowed", ``--seed -1`` "expected
non-negative integer", ``noise_abs = 1e-300`` ran to exit 0).
"""

import pytest
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.config import make_settings
from podkrig.online.settings import CalibrationSettings
from podkrig.sensors.criteria import SensorNoise
from podkrig.surrogate.settings import RefineSettings, SurrogateSettings

runner = CliRunner()
PARAMS = ["--param", "E_b=6000:18000", "--param", "kN_bj=30:300:log"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Paths the commands are given; none needs to exist: every value is refused before use."""
    d = tmp_path_factory.mktemp("numeric_options")
    spec = d / "spec.toml"
    spec.write_text('scenario = "diagonal_compression"\nnx = 2\nny = 1\n')
    return d, spec


def _commands(d, spec):
    sensors = ["sensors", "--scenario", "diagonal_compression", "--spec", str(spec), *PARAMS, "--k", "2",
               "--grid-x", "100:700:300", "--grid-y", "100:700:300", "--out", str(d / "sensors")]
    return {
        "refine": ["surrogate", "refine", str(d / "sur.h5"), "--store", str(d / "s.h5"), "--held-out", str(d / "h.h5")],
        "sensors": sensors,
        "build": ["surrogate", "build", str(d / "s.h5"), "--out", str(d / "sur.h5")],
        "snapshots": ["snapshots", "run", "--spec", str(spec), *PARAMS, "--n", "2", "--seed", "0", "--store",
                      str(d / "x.h5")],
    }


@pytest.mark.parametrize("command, option, value, fragments", [
    ("refine", "--seed", "-1", ["--seed -1", "integer >= 0"]),
    ("refine", "--workers", "0", ["--workers 0", "integer in [1, 1024]"]),
    ("refine", "--target-error", "inf", ["--target-error inf", "(0, 1]"]),
    ("refine", "--candidates", "0", ["--candidates 0", "integer in [1, "]),
    ("refine", "--budget", "-1", ["--budget -1", "integer in [0, "]),
    ("sensors", "--noise-lvdt", "inf", ["--noise-lvdt inf", "[1e-07, 1e+06] mm"]),
    ("sensors", "--noise-dic", "1e-300", ["--noise-dic 1e-300", "[1e-07, 1e+06] mm"]),
    ("sensors", "--noise-rel", "1e-9", ["--noise-rel 1e-09", "[1e-06, 1)"]),
    ("sensors", "--orientation", "nan", ["--orientation (nan,)", "finite angles"]),
    ("sensors", "--length", "400:50", ["--length (400.0, 50.0)", "MIN 400 > MAX 50", "0 < MIN <= MAX"]),
    ("build", "--nugget", "1e300", ["--nugget 1e+300", "[0, 1]"]),
    ("snapshots", "--workers", "-1", ["--workers", "integer >= 1", "got -1"]),
    ("snapshots", "--chunk-size", "0", ["--chunk-size", "integer >= 1", "got 0"]),
])
def test_a_refused_option_names_itself_its_value_and_the_range(files, command, option, value, fragments):
    d, spec = files
    result = runner.invoke(app, [*_commands(d, spec)[command], option, value])
    assert result.exit_code == 2, result.output
    out = " ".join(result.output.split())
    for fragment in fragments:
        assert fragment in out, (fragment, out)
    assert not any((d / f).exists() for f in ("x.h5", "sur.h5"))


@pytest.mark.parametrize("option, value, fragments", [
    ("--mcmc-steps", "-1", ["--mcmc-steps -1", "integer >= 0"]),
    ("--seed", "-1", ["--seed -1", "integer >= 0"]),
    ("--load-tolerance", "-1", ["--load-tolerance -1.0", ">= 0"]),
])
def test_invert_names_the_option_before_reading_any_file(files, option, value, fragments):
    d, _ = files
    args = ["invert", str(d / "none.h5"), "--data", str(d / "none.csv"), "--noise-rel", "0.01"]
    result = runner.invoke(app, [*args, option, value])
    assert result.exit_code == 2, result.output
    out = " ".join(result.output.split())
    assert all(fragment in out for fragment in fragments), out


def test_the_library_words_a_refused_keyword_as_the_cli_words_an_option():
    """:func:`podkrig.config.make_settings` is the one wording: the name (the caller's, e.g. the
    option), the value and the field's allowed range; a wrong type says so."""
    with pytest.raises(ValueError, match=r"mcmc_steps -1: out of range; allowed: an integer >= 0"):
        make_settings(CalibrationSettings, {"mcmc_steps": -1})
    with pytest.raises(ValueError, match=r"--candidates 0: out of range; allowed: an integer in \[1, "):
        make_settings(RefineSettings, {"n_candidates": 0}, {"n_candidates": "--candidates"})
    with pytest.raises(ValueError, match=r"budget 2\.5: must be an integer; allowed: an integer in \[0, "):
        make_settings(RefineSettings, {"budget": 2.5})
    with pytest.raises(ValueError, match=r"nugget 2\.0: out of range; allowed: a number in \[0, 1\]"):
        make_settings(SurrogateSettings, {"nugget": 2.0})
    assert make_settings(RefineSettings, {"budget": None}) == RefineSettings()  # None: the default
    with pytest.raises(ValueError, match=r"lvdt(.|\n)*1e-300"):  # the field and the value refused
        SensorNoise(lvdt=1e-300)
