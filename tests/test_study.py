"""``podkrig run``: a tiny study end to end, its stage cache, and the structure of its HTML report."""

import dataclasses
import html
import html.parser
import json
import re
import shutil
import struct
import zlib

import numpy as np
import pytest
from typer.testing import CliRunner

from fe.scenarios import build_scenario
from podkrig.cli import app
from podkrig.io.measurement_log import response_csv, write_measurement_csv
from podkrig.io.surrogate_file import load_surrogate
from podkrig.offline.store import SnapshotStore
from podkrig.online.findings import CHI2_BASIS, RESIDUAL_CONVENTION
from podkrig.online.measurement import Measurement
from podkrig.online.region import Region
from podkrig.reports import study as study_report
from podkrig.reports.figures import read_panels
from podkrig.reports.html import Page
from podkrig.reports.jupyter import inverse_result_html, region_html
from podkrig.reports.study import SECTIONS
from podkrig.study import StudyResult, load_study, run_study, stages
from podkrig.study.cache import Progress, jsonable
from podkrig.study.stages import region_members, save_region
from podkrig.surrogate.podkriging import training_data
from podkrig.surrogate.settings import fit_surrogate
from podkrig.surrogate.validation import held_out_errors

runner = CliRunner()

#: a tiny study: coarse meshes, two free parameters, a few FE runs, small GA and region
TINY = """\
name = "tiny"

[scenario]
scenario = "diagonal_compression"
nx = 2
ny = 1

[parameters]
kN_bj = { lower = 30.0, upper = 300.0, scale = "log" }
kV_bj = { lower = 10.0, upper = 120.0, scale = "log" }

[fixed]
E_b = 11000.0
r_hj = 0.6

[sampling]
train = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers = 1

[surrogate]
beta = "fit-shared"

[measurement]
file = "measured.csv"
noise_rel = 0.01

[inversion]
population_size = 20
generations = 10
n_starts = 2
region_samples = 4096

[diagnosis]
enabled = true

[[validation]]
name = "shear"
scenario = { scenario = "shear_compression", nx = 2, ny = 1 }
n = 8
seed = 2
outputs = ["top_ux@40", "D1@40"]
"""

TRUTH = {"E_b": 11000.0, "r_hj": 0.6, "kN_bj": 90.0, "kV_bj": 35.0}


def _measured(path, seed):
    sc = build_scenario({"scenario": "diagonal_compression", "nx": 2, "ny": 1})
    clean = sc.run(TRUTH).readings
    noisy = clean * (1 + 0.01 * np.random.default_rng(seed).standard_normal(clean.shape))
    write_measurement_csv(path, Measurement(noisy, sc.sensor_names, sc.load_levels))


def _run(study, out):
    result = runner.invoke(app, ["run", str(study), "--out", str(out)])
    assert result.exit_code == 0, result.output
    return result.output


def _stages(out):
    return {p.stem: json.loads(p.read_text()) for p in (out / "stages").glob("*.json")}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny study run once: (study file, output folder, CLI output)."""
    d = tmp_path_factory.mktemp("study")
    (d / "study.toml").write_text(TINY)
    _measured(d / "measured.csv", seed=0)
    out = d / "out"
    return d / "study.toml", out, _run(d / "study.toml", out)


def test_run_writes_every_stage_and_a_summary(tiny):
    _, out, text = tiny
    assert "identified parameters" in text and "report:" in text and "FE runs" in text
    assert not (out / ".podkrig.lock").exists()  # the output folder's lock is released at the end
    stages = _stages(out)
    assert set(stages) == {"measurement", "probe", "offline", "held_out", "validation_model.shear", "surrogate",
                           "held_out_validation", "sensitivity", "calibration", "diagnosis"}
    assert stages["probe"]["fe_runs"] == 5  # the centre, and each of the 2 parameters at its bounds
    assert stages["offline"]["fe_runs"] == 16 and stages["held_out"]["fe_runs"] == 4
    assert stages["validation_model.shear"]["fe_runs"] == 8 and stages["calibration"]["fe_runs"] == 1
    for m in stages.values():  # every output file is recorded with its hash
        for rel, sha in m["outputs"].items():
            assert (out / rel).is_file() and len(sha) == 64
    summary = json.loads((out / "summary.json").read_text())
    calibration = summary["stages"]["calibration"]
    params = calibration["inversion"]["parameters"]
    assert set(params) == {"kN_bj", "kV_bj"}
    for name, (lo, hi) in calibration["region"]["intervals"].items():
        assert lo <= params[name] <= hi
    assert calibration["rvc"]["shear"]["outputs"] == ["top_ux@40", "D1@40"]
    with np.load(out / "region.npz") as f:  # columns named, with their units, readable without pickle
        assert len(f["samples"]) == calibration["region"]["n_members"]
        assert f["names"].tolist() == calibration["region"]["names"] == ["kN_bj", "kV_bj"]
        assert f["units"].tolist() == calibration["region"]["units"]
    with np.load(out / "probe.npz") as f:
        assert f["names"].tolist() == ["kN_bj", "kV_bj"] and f["X"].shape == (5, 2)
        assert f["readings"].shape == (5, len(f["load_levels"]), len(f["sensor_names"])) and str(f["load_unit"]) == "kN"


def test_region_files_name_their_columns_and_old_files_still_read(tmp_path):
    """``region.npz`` names its columns; a file written before it did (no ``names``) reads as it
    is; a file naming other parameters (another study's) is refused, naming both lists and the
    remedy."""
    samples, omega = np.arange(6.0).reshape(3, 2), np.array([1.0, 2.0, 3.0])
    region = Region("likelihood-ratio", 0.95, samples, omega, 4.0, {}, ("E_b", "c"), ("MPa", "MPa"), 10, 1.0, {})
    save_region(tmp_path / "region.npz", region)
    got = region_members(tmp_path / "region.npz", ["E_b", "c"])
    assert all(np.array_equal(a, b) for a, b in zip(got, (samples, omega)))  # npz round trip is exact
    np.savez(tmp_path / "old.npz", samples=samples, omega=omega)
    assert np.array_equal(region_members(tmp_path / "old.npz", ["E_b", "c"])[0], samples)
    with pytest.raises(ValueError, match=r"\['E_b', 'c'\].*\['E_b', 'ft'\].*--out"):
        region_members(tmp_path / "region.npz", ["E_b", "ft"])


def test_a_first_look_without_the_diagnosis_then_the_diagnosis_alone(tiny, tmp_path, fe_counter):
    """``podkrig run --skip-diagnosis`` leaves the model diagnosis out (no FE run, no diagnosis
    stage, no diagnosis line); the same run without it then runs the diagnosis alone, every other
    stage cached."""
    study, out, _ = tiny
    copy = tmp_path / "out"
    shutil.copytree(out, copy)
    (copy / "stages" / "diagnosis.json").unlink()  # as if the study had never run its diagnosis
    counter = fe_counter()
    result = runner.invoke(app, ["run", str(study), "--out", str(copy), "--skip-diagnosis"])
    assert result.exit_code == 0, result.output
    assert counter.calls == 0 and re.search(r"\b0 FE runs in", result.output)  # the stages' count, all kinds
    assert not (copy / "stages" / "diagnosis.json").exists() and "model diagnosis" not in result.output
    assert "diagnosis" not in json.loads((copy / "summary.json").read_text())["stages"]
    text = _run(study, copy)
    ran = {name for name, m in _stages(copy).items() if m["finished"] != _stages(out)[name]["finished"]}
    assert ran <= {"diagnosis", "measurement"} and "diagnosis" in ran  # the measurement check is 0 FE runs
    assert re.search(rf"\b{_stages(copy)['diagnosis']['fe_runs']} FE runs in", text) and "model diagnosis" in text


def test_rerun_with_nothing_changed_does_no_fe_work(tiny, fe_counter):
    study, out, _ = tiny
    before = _stages(out)
    counter = fe_counter()
    _run(study, out)
    assert counter.calls == 0
    after = _stages(out)
    assert {k: v["finished"] for k, v in after.items()} == {k: v["finished"] for k, v in before.items()}


def _scale_first_gauge(path, factor):
    """Scale the first reading column of a measurement file: data the model cannot explain."""
    lines = path.read_text().splitlines()
    lines[1:] = [",".join([c.split(",")[0]] + [f"{factor * float(v):.8g}" if j == 0 else v
                                               for j, v in enumerate(c.split(",")[1:])]) for c in lines[1:]]
    path.write_text("\n".join(lines) + "\n")


@pytest.fixture(scope="module")
def new_measurement(tiny, tmp_path_factory, count_fe_runs):
    """A copy of the tiny study and its cache, rerun with a new measurement file: another noise
    realisation whose first gauge is scaled by 1.3 (data the model cannot explain). One rerun for
    two checks: which stages rerun, and the report's warning. (folder, stages before, stages
    after, FE runs of the rerun)."""
    study, _, _ = tiny
    d = tmp_path_factory.mktemp("new_measurement") / "copy"
    shutil.copytree(study.parent, d)
    before = _stages(d / "out")
    _measured(d / "measured.csv", seed=1)
    _scale_first_gauge(d / "measured.csv", 1.3)
    with count_fe_runs() as counter:
        _run(d / "study.toml", d / "out")
    return d, before, _stages(d / "out"), counter.calls


def test_new_measurement_reruns_only_the_online_stages(new_measurement):
    _, before, after, calls = new_measurement
    rerun = {k for k in after if after[k]["finished"] != before[k]["finished"] or after[k]["input_hash"] != before[k]["input_hash"]}
    assert rerun == {"measurement", "sensitivity", "calibration", "diagnosis"}  # the check does no FE work
    # FE work only in the online stages: the check at the new optimum and the diagnosis' refits
    assert 1 <= calls <= after["calibration"]["fe_runs"] + after["diagnosis"]["fe_runs"]


# ---------------------------------------------------------------------------------------------
# the report: a structural check that fails on a broken page (no browser needed)

_VOID = {"meta", "img", "br", "hr", "link", "input"}


class _Page(html.parser.HTMLParser):
    """Collects what the structural checks need and checks that tags are balanced."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack, self.errors = [], []
        self.images, self.ids, self.hrefs, self.tables, self.text = [], [], [], [], []
        self._row = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag not in _VOID:
            self.stack.append(tag)
        if tag == "img":
            self.images.append(a.get("src"))
            if not a.get("alt"):
                self.errors.append(f"<img src={a.get('src')!r}> without alt text")
        if "id" in a:
            self.ids.append(a["id"])
        if tag == "a":
            self.hrefs.append(a.get("href"))
        if tag == "table":
            self.tables.append([])
        if tag == "tr":
            self._row = 0
        if tag in ("td", "th") and self._row is not None:
            self._row += 1

    def handle_endtag(self, tag):
        if tag in _VOID:
            return
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes <{self.stack[-1] if self.stack else 'nothing'}>")
            return
        self.stack.pop()
        if tag == "tr":
            self.tables[-1].append(self._row)
            self._row = None

    def handle_data(self, data):
        self.text.append(data)


def _check_png(path):
    """A PNG file that a decoder would accept: signature, chunks with valid CRCs, IHDR, IDAT, IEND."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path.name}: not a PNG"
    pos, kinds = 8, []
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"{path.name}: bad CRC in chunk {kind!r}"
        kinds.append(kind)
        pos += 12 + length
    assert kinds[0] == b"IHDR" and b"IDAT" in kinds and kinds[-1] == b"IEND", f"{path.name}: chunks {kinds}"
    width, height = struct.unpack(">II", data[16:24])
    assert width > 100 and height > 100, f"{path.name}: {width}x{height} px"


def test_report_structure(tiny):
    _, out, _ = tiny
    page_path = out / "report" / "index.html"
    source = page_path.read_text(encoding="utf-8")
    page = _Page()
    page.feed(source)
    page.close()
    assert not page.errors, page.errors
    assert page.stack == [], f"unclosed tags: {page.stack}"
    # every section, in order, reachable from the contents
    headings = [i for i in page.ids if i in dict(SECTIONS)]
    assert headings == [anchor for anchor, _ in SECTIONS]
    internal = [h[1:] for h in page.hrefs if h.startswith("#")]
    assert set(internal) <= set(page.ids) and len(internal) == len(SECTIONS)
    # every figure exists beside the page and is a valid PNG; each stage's figures are shown
    expected = {"energy.png", "modes.png", "predicted_vs_fe.png", "sensitivity.png", "fit.png", "residuals.png",
                "ga_history.png", "ga_parameters.png", "region.png", "rvc.png", "deformed.png",
                "rvc_shear.png"}  # the distribution of the validation model's outputs
    assert set(page.images) == expected
    for src in page.images:
        _check_png(page_path.parent / src)
    # links to other pages (the diagnosis report) lead to pages whose figures are valid too
    pages = [h for h in page.hrefs if not h.startswith("#")]
    assert pages == ["diagnosis/index.html"]
    sub = _Page()
    sub.feed((page_path.parent / pages[0]).read_text(encoding="utf-8"))
    assert sub.images and not sub.errors
    for src in sub.images:
        _check_png(page_path.parent / "diagnosis" / src)
    # tables: every row has as many cells as the header
    assert len(page.tables) >= 10
    for rows in page.tables:
        assert rows and len(set(rows)) == 1, rows
    # numbers are finite and carry units
    text = " ".join(page.text)
    assert not re.search(r"\bnan\b|\binf\b", source, re.IGNORECASE)
    for unit in ("(mm)", "(%)", "(s)", "MPa", "N/mm³", "χ²/dof"):
        assert unit in text, unit
    # the page shows exactly the warnings of summary.json, or says there are none
    warnings = json.loads((out / "summary.json").read_text(encoding="utf-8"))["warnings"]
    assert source.count("<b>Warning:</b>") == 2 * len(warnings)  # in the summary and in its section
    assert ("No warnings" in source) is (not warnings)


_FIGURE = re.compile(r'<figure><img src="([^"]+)" alt="[^"]*"><figcaption>([^<]*)</figcaption></figure>')


def _figures(page_path):
    """(file, caption, panels) of every figure of a report page; panels as recorded by
    :func:`podkrig.reports.figures.save`."""
    source = page_path.read_text(encoding="utf-8")
    out = []
    for src, caption in _FIGURE.findall(source):
        panels = read_panels(page_path.parent / src)
        assert panels is not None, f"{src}: saved without its panel description (not through reports.figures.save)"
        out.append((src, html.unescape(caption), panels))
    return source, out


def test_report_figures_and_words_agree(tiny):
    """The structural checks of issue 14: every figure of the study page and the diagnosis page has
    no empty panel, a colour bar for every colour scale, log axes for the log-sampled parameters and
    a caption that names only panels that exist; one residual sign convention across the pages and
    summary.json; every χ²/dof says what it includes; no range printed with equal ends."""
    _, out, cli_text = tiny
    report = out / "report"
    log_params = ("kN_bj", "kV_bj")  # scale = "log" in TINY
    sources = []
    for page_path in (report / "index.html", report / "diagnosis" / "index.html"):
        source, figures = _figures(page_path)
        sources.append(source)
        assert figures
        for src, caption, panels in figures:
            assert panels, src
            for panel in panels:
                assert not panel["empty"], f"{src}: empty panel {panel}"
                if panel["colour_mapped"]:
                    assert panel["colourbar"], f"{src}: colour scale without a colour bar in {panel['title']!r}"
                for axis in ("x", "y"):
                    if panel[f"{axis}label"].split(" ")[0] in log_params and src in ("region.png", "ga_parameters.png"):
                        assert panel[f"{axis}scale"] == "log", f"{src}: {panel[f'{axis}label']} on a linear axis"
            if re.search(r"\b(left|right)(-hand)?\b(?! out)", caption.lower()):  # "left out" names no panel
                assert len(panels) >= 2, f"{src}: caption {caption!r} names panels the figure does not have"
        assert "model − measured" not in html.unescape(source)
        assert RESIDUAL_CONVENTION in html.unescape(source)
        equal_ends = re.findall(r"(\d[\d.]*)–(\d[\d.]*) ?mm", html.unescape(source))
        assert all(a != b for a, b in equal_ends), equal_ends
    study_page = html.unescape(sources[0])
    for basis in (CHI2_BASIS["surrogate"], CHI2_BASIS["fe_check"], CHI2_BASIS["diagnosis"]):
        assert basis in study_page, basis
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))["stages"]
    assert summary["calibration"]["inversion"]["residual_convention"] == RESIDUAL_CONVENTION
    assert summary["diagnosis"]["residual_convention"] == RESIDUAL_CONVENTION
    assert summary["calibration"]["inversion"]["chi2_basis"] == CHI2_BASIS["surrogate"]
    assert summary["diagnosis"]["adequacy"]["basis"].startswith(CHI2_BASIS["diagnosis"])
    assert "estimated per reading from two meshes" in summary["diagnosis"]["adequacy"]["basis"]
    # the CLI prints the three χ²/dof with their bases too
    flat = " ".join(cli_text.split())
    assert "χ² includes" in flat and "FE refit" in flat
    # a candidate that is not significant: its fitted value carries the caveat, and an empty
    # evidence chart is replaced by words
    d = summary["diagnosis"]
    diag_page = html.unescape(sources[1])
    for c in d["candidates"]:
        if c["applicable"] and c["p_corrected"] >= d["alpha"]:
            assert f"{c['parameter']['name']} = " in diag_page
            assert "not significant" in diag_page
    if "candidates.png" not in diag_page:
        assert "Nothing significant" in diag_page


def test_report_warning_in_plain_words(new_measurement):
    """Data the model cannot explain (a scaled gauge) raises a χ²/dof warning with what to do."""
    d, _, _, _ = new_measurement
    source = (d / "out" / "report" / "index.html").read_text()
    assert "within the stated noise" in source
    assert "What to do:" in source


def test_study_estimates_the_model_form_error_when_asked(tiny, tmp_path, fe_counter):
    """``[measurement] model_form_error = "estimated"``: two FE runs more in the calibration (the
    coarse and the twice-refined mesh at a first optimum), its estimate in C_D of the inversion and
    the region (a wider region than with noise alone: more variance per reading), nothing offline
    rerun; a fixed ε is taken as given, without FE runs."""
    study, out0, _ = tiny
    d = tmp_path / "copy"
    shutil.copytree(study.parent, d)
    (d / "study.toml").write_text(TINY.replace("noise_rel = 0.01", 'noise_rel = 0.01\nmodel_form_error = "estimated"'))
    counter = fe_counter()
    _run(d / "study.toml", d / "out")
    stages = _stages(d / "out")
    assert stages["calibration"]["fe_runs"] == 2 + 1  # the two meshes, and the FE check
    assert counter.calls <= stages["calibration"]["fe_runs"] + stages["diagnosis"]["fe_runs"]
    calibration = stages["calibration"]["result"]
    estimate = calibration["model_form_errors"]["calibration"]
    assert estimate["method"] == "two meshes" and estimate["mesh"] == "Q8 2×1 and 4×2 per unit"
    inv = calibration["inversion"]
    assert inv["measurement"]["model_form_error"]["mesh"] == estimate["mesh"]
    assert len(estimate["std_mm"]) == inv["measurement"]["n_obs"] and min(estimate["std_mm"]) >= 0
    assert "FE model-form error" in inv["chi2_basis"]
    plain = _stages(out0)
    width = {k: np.log(hi / lo) for k, (lo, hi) in calibration["region"]["intervals"].items()}
    width0 = {k: np.log(hi / lo) for k, (lo, hi) in plain["calibration"]["result"]["region"]["intervals"].items()}
    assert all(width[k] > width0[k] for k in width)
    (d / "study.toml").write_text(TINY.replace("noise_rel = 0.01", "noise_rel = 0.01\nmodel_form_error = 0.02"))
    _run(d / "study.toml", d / "out")
    inv = _stages(d / "out")["calibration"]["result"]["inversion"]
    assert "ε = 2 %" in inv["chi2_basis"] and inv["measurement"]["model_form_error"]["tolerance"] == 0.02


def test_study_with_a_library_backend(tmp_path):
    """``[surrogate] backend`` puts a library's regressor behind the same pipeline: surrogate,
    held-out check and inversion run, the summary and the report name the backend."""
    study = TINY.replace('[surrogate]\nbeta = "fit-shared"', '[surrogate]\nbackend = "sklearn-gpr"')
    study = study[: study.index("[diagnosis]")]  # the diagnosis builds its own surrogate
    (tmp_path / "study.toml").write_text(study)
    _measured(tmp_path / "measured.csv", seed=0)
    _run(tmp_path / "study.toml", tmp_path / "out")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    sur = summary["stages"]["surrogate"]
    assert sur["backend"] == "sklearn-gpr" and "beta" not in sur and "scikit-learn" in sur["description"]
    assert summary["stages"]["calibration"]["inversion"]["chi2_dof"] < 5
    assert "sklearn-gpr" in (tmp_path / "out" / "report" / "index.html").read_text()


def test_results_show_in_jupyter(tiny):
    """The study result (its ``_repr_html_``), the inversion and the region (the Jupyter tables of
    :mod:`podkrig.reports.jupyter`) render as HTML: well-formed, with the numbers, what each χ²
    includes, and the figures inline."""
    study, out, _ = tiny
    result = run_study(load_study(study), out)  # every stage cached: seconds
    # summary.json is the result's to_dict (written as write_json writes it)
    assert json.loads((out / "summary.json").read_text()) == json.loads(json.dumps(result.to_dict(), default=jsonable))
    inv, region = result.calibration.inversion, result.calibration.region
    for obj, words, text in (
            (result, ["kN_bj", CHI2_BASIS["surrogate"], "data:image/png;base64,", RESIDUAL_CONVENTION],
             result._repr_html_()),
            (inv, ["kN_bj", "N/mm³", f"{inv.chi2_dof:.3g}", "χ² includes"], inverse_result_html(inv)),
            (region, ["kN_bj", "identified", f"{100 * region.confidence:.0f} %"], region_html(region))):
        page = _Page()
        page.feed(text)
        page.close()
        assert not page.errors and page.stack == [], (type(obj).__name__, page.errors, page.stack)
        for rows in page.tables:
            assert rows and len(set(rows)) == 1, (type(obj).__name__, rows)
        for w in words:
            assert w in html.unescape(text), (type(obj).__name__, w)


#: a nonlinear test (a triplet's force–slip curve at six control levels), its stores and surrogate only
TRIPLET = """\
name = "triplet_layouts"

[scenario]
scenario = "triplet_shear"
load_levels = [0.02, 0.05, 0.1, 0.2, 0.5, 1.0]

[parameters]
c_bj      = { lower = 0.15, upper = 0.6 }
tanphi_bj = { lower = 0.6, upper = 1.1 }

[fixed]
ft_bj = 0.1

[sampling]
train    = { n = 16, seed = 0 }
held_out = { n = 4, seed = 1, method = "random" }
workers  = 1

[measurement]
file = "measured.csv"
noise_rel = 0.01
"""


def _held_out_stages(study, out):
    """The stages up to the held-out check of a one-test study; returns the run."""
    run = stages.StudyRun(study, out, Progress())
    run.figures.mkdir(parents=True, exist_ok=True)
    (test,) = study.calibration_tests
    stages.offline(run, test, "offline", "Training snapshots (FE)", "train.h5", test.train)
    stages.offline(run, test, "held_out", "Held-out snapshots (FE)", "held_out.h5", test.held_out)
    stages.surrogate(run, test)
    stages.held_out_validation(run, test)
    return run


def test_a_nonlinear_tests_held_out_check_compares_both_pod_layouts(tmp_path):
    """The held-out check of a nonlinear test with several control levels also scores the other
    POD layout on the same training snapshots: the study's own layout (the default, stacked) with
    exactly the errors of its surrogate, the per-level one with those of a per-level surrogate
    fitted directly; both in the report's held-out section (naming the study's) and in
    ``summary.json``; the study's surrogate stays stacked, and a rerun reuses the stage. Defects: no
    comparison, one that refits the study's own layout to other numbers, the comparison's
    surrogate saved in place of the study's."""
    sc = build_scenario({"scenario": "triplet_shear", "load_levels": [0.02, 0.05, 0.1, 0.2, 0.5, 1.0]})
    (tmp_path / "measured.csv").write_text(response_csv(sc, sc.run()))
    (tmp_path / "study.toml").write_text(TRIPLET)
    study = load_study(tmp_path / "study.toml")
    (test,) = study.calibration_tests
    run = _held_out_stages(study, tmp_path / "out")
    r = run.manifest(test.stage("held_out_validation"))["result"]
    assert r["layout"] == study.surrogate.pod == "stacked" and set(r["layouts"]) == {"stacked", "per_level"}
    assert r["layouts"]["stacked"]["by_unit"] == r["by_unit"] and set(r["by_unit"]) == {"mm", "kN"}
    with SnapshotStore.open(tmp_path / "out" / test.file("train.h5")) as store:
        per_level = fit_surrogate(store, dataclasses.replace(study.surrogate, pod="per_level"))
    with SnapshotStore.open(tmp_path / "out" / test.file("held_out.h5")) as store:
        direct = held_out_errors(per_level, *training_data(store), with_loo=False).by_unit()
    assert r["layouts"]["per_level"] == json.loads(json.dumps({"n_modes": per_level.n_modes_, "by_unit": direct},
                                                              default=jsonable))
    assert load_surrogate(tmp_path / "out" / test.file("surrogate.h5")).layout == "stacked"
    page = Page("held-out")
    study_report._held_out(page, r)
    text = html.unescape(page.markup())
    assert all(f in text for f in ("stacked (this surrogate)", "per level", "[surrogate] pod = \"stacked\"", "in kN: "))
    summary = StudyResult(study, run.out, tuple(run.records), [], run.figures / "index.html", 0.0).to_dict()
    assert summary["stages"][test.stage("held_out_validation")]["layouts"] == r["layouts"]
    again = _held_out_stages(study, tmp_path / "out")
    assert all(record.cached for record in again.records)
