"""Issue 13 findings 1 and 5-8: the pipeline never deletes a store it did not create, outputs stay
in their folder, input limits, and OS/format errors as one-line messages."""

import errno
import json
import logging
import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.cli._common import error_message
from podkrig.exceptions import StoreInUseError
from podkrig.limits import check_name, check_output_folder, check_region_samples
from podkrig.offline.sampling import sobol
from podkrig.offline.settings import Design
from podkrig.offline.store import SnapshotStore
from podkrig.io import measurement_log
from podkrig.io.measurement_log import read_measurement_csv
from podkrig.parameters import ParameterSpace
from podkrig.study.stages import _run_store

runner = CliRunner()
SENSORS, LEVELS = ("D1", "D2"), (25.0, 50.0)


class _NoProgress:
    def advance(self, completed, total):
        pass


@pytest.fixture(scope="module")
def space(coarse_diagonal):
    return ParameterSpace.from_scenario(coarse_diagonal, {"kN_bj": (10, 1000, "log")})


def _run(workers=1):
    return SimpleNamespace(study=SimpleNamespace(workers=workers, scheduler=None), progress=_NoProgress())


# ----------------------------------------------------------------------------- finding 1
def test_pipeline_never_deletes_a_store_another_run_is_writing(tmp_path, coarse_diagonal, space):
    """Finding 1: the file-lock error was taken for 'unusable store' and the store unlinked."""
    path = tmp_path / "train.h5"
    SnapshotStore.create(path, coarse_diagonal, space, sobol(8, 1, seed=0), sampling="sobol", seed=0).close()
    holder = subprocess.Popen(  # the first run, filling the store (HDF5 holds its lock)
        [sys.executable, "-c", (f"import h5py, time; f = h5py.File({str(path)!r}, 'r+'); "
                                "print('open', flush=True); time.sleep(120)")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        before = path.read_bytes()  # as the holder left it (opening sets a superblock flag)
        design = Design(n=8, seed=0, method="sobol")
        with pytest.raises(StoreInUseError, match="in use"):
            _run_store(_run(), path, coarse_diagonal, space, design)
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["train.h5"]


def test_pipeline_keeps_an_unusable_store_aside_and_says_so(tmp_path, coarse_diagonal, space, caplog):
    path = tmp_path / "train.h5"
    path.write_bytes(b"not a store, but someone's file")
    design = Design(n=4, seed=0, method="sobol")
    with caplog.at_level(logging.WARNING):
        summary, notes = _run_store(_run(), path, coarse_diagonal, space, design)
    kept = [p for p in tmp_path.iterdir() if p.name.startswith("train.unusable-")]
    assert len(kept) == 1 and kept[0].suffix == ".h5"
    assert kept[0].read_bytes() == b"not a store, but someone's file"
    assert summary.done == 4 and f"kept it as {kept[0]}" in caplog.text
    assert kept[0].name in notes[0]


# ----------------------------------------------------------------------------- finding 5
@pytest.mark.parametrize("n", [16, 0, -5, 1023])
def test_invert_region_samples_checked_like_the_study(tmp_path, n):
    """Finding 5: `podkrig invert --region-samples 16` ran and called a parameter identified."""
    result = runner.invoke(app, ["invert", str(tmp_path / "s.h5"), "--data", str(tmp_path / "d.csv"),
                                 "--noise-rel", "0.01", "--region-samples", str(n)])
    assert result.exit_code == 2
    assert "--region-samples must be at least 1024" in result.output
    check_region_samples(1024)
    with pytest.raises(ValueError, match="at most"):
        check_region_samples(2**40)


# ----------------------------------------------------------------------------- finding 6
@pytest.mark.parametrize("name", ["../../x", "/tmp/abs", "a/b", "..", ".hidden", "a\\b", "x" * 101, "é"])
def test_a_study_name_is_a_name(name):
    """Finding 6: `name = "../../x"` wrote the whole output outside the output folder."""
    with pytest.raises(ValueError, match="study name must be 1-100 characters"):
        check_name(name, "the study name")


def test_run_refuses_a_path_as_study_name_and_a_file_as_out(tmp_path, monkeypatch):
    from tests.test_study_file import VALID, _write

    study = _write(tmp_path, VALID.replace('name = "check"', 'name = "../../escaped"'))
    monkeypatch.chdir(tmp_path)
    result = runner.invoke(app, ["run", str(study)])
    assert result.exit_code == 2 and "must be 1-100 characters" in result.output
    assert not (tmp_path.parent / "escaped").exists() and not (tmp_path / "out").exists()
    (tmp_path / "file").write_text("x")
    result = runner.invoke(app, ["run", str(study), "--out", str(tmp_path / "file")])
    assert result.exit_code == 2 and "is a file; give a folder" in result.output
    with pytest.raises(ValueError, match="is a file, not a folder"):
        check_output_folder(tmp_path / "file" / "sub")


# ----------------------------------------------------------------------------- findings 7 and 8: CSV
def _csv(tmp_path, content, mode="w"):
    path = tmp_path / "m.csv"
    if mode == "w":
        path.write_text(content, encoding="utf-8")
    else:
        path.write_bytes(content)
    return path


@pytest.mark.parametrize("cell, message", [
    ("2_5", "'2_5' is not a number"), ("١٢", "is not a number"), ("1e300", "out of range"),
    ("inf", "not a finite number"), ("0x10", "is not a number"), ("1,5", "cells, expected"),
])
def test_readings_that_float_accepts_are_refused(tmp_path, cell, message):
    """Finding 7: `2_5`, non-ASCII digits and 1e300 were parsed as readings."""
    path = _csv(tmp_path, f"load,D1\n25,{cell}\n")
    with pytest.raises(ValueError, match=message):
        read_measurement_csv(path, SENSORS, LEVELS)


def test_bad_files_give_messages_with_the_file(tmp_path, monkeypatch):
    """Finding 8: non-UTF-8 files, huge cells and huge files raised without the file or row."""
    path = _csv(tmp_path, b"load,D1\n25,\x81\xfe\n", mode="b")  # 0x81 is not Windows-1252 either
    with pytest.raises(ValueError, match=r"m\.csv: not UTF-8.*byte 11 \(line 2\)"):
        read_measurement_csv(path, SENSORS, LEVELS)
    # lab software writes Windows-1252 (issue 14): read as such, and a bad cell is still named
    path = _csv(tmp_path, b"load,D1\n25,\xff\xfe\n", mode="b")
    with pytest.raises(ValueError, match=r"m\.csv, .*row 2, column 2 \(D1\): 'ÿþ'"):
        read_measurement_csv(path, SENSORS, LEVELS)
    monkeypatch.setattr(measurement_log, "MAX_FILE_BYTES", 2**20)  # the real bound (256 MiB) is slow to test
    path = _csv(tmp_path, "load,D1\n25," + "1" * 200_000 + "\n")
    with pytest.raises(ValueError, match=r"m\.csv, row 2: malformed CSV"):
        read_measurement_csv(path, SENSORS, LEVELS)
    path = _csv(tmp_path, b"load,D1\n" + b"25,1\n" * (measurement_log.MAX_FILE_BYTES // 5 + 1), mode="b")
    with pytest.raises(ValueError, match="larger than 1 MiB"):
        read_measurement_csv(path, SENSORS, LEVELS)
    if Path("/dev/zero").exists():
        with pytest.raises(ValueError, match="larger than 1 MiB"):
            read_measurement_csv("/dev/zero", SENSORS, LEVELS)
    with pytest.raises(ValueError, match="cannot read measurement file"):
        read_measurement_csv(tmp_path, SENSORS, LEVELS)


# ----------------------------------------------------------------------------- finding 8: OS errors
def test_os_errors_are_one_line_messages_with_the_path():
    e = OSError(errno.EROFS, "Read-only file system", "/data/out")
    assert error_message(e).startswith("/data/out: read-only file system") and "--out" in error_message(e)
    assert "\n" not in error_message(e)
    assert "disk full" in error_message(OSError(errno.ENOSPC, "No space left on device", "/x"))
    assert error_message(RecursionError("maximum recursion depth exceeded")).startswith("input nested")
    assert error_message(KeyError("x")) is None  # a bug stays a traceback


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores folder permissions")
def test_read_only_folder_gives_a_message(tmp_path):
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    spec = tmp_path / "coarse.json"
    spec.write_text(json.dumps({"scenario": "diagonal_compression", "nx": 2, "ny": 1}))
    try:
        result = runner.invoke(app, ["snapshots", "run", "--spec", str(spec), "--param", "kN_bj=10:1000:log",
                                     "--n", "4", "--seed", "0", "--store", str(folder / "s.h5"), "--workers", "1"])
    finally:
        folder.chmod(0o700)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "permission denied" in result.output or "is the folder writable" in result.output


def test_top_level_handler_turns_an_escaped_os_error_into_a_message(tmp_path):
    """An OSError outside a command's own handling (here: writing the export CSV into a missing folder)."""
    done = subprocess.run([sys.executable, "-c", "from podkrig.cli import app; app(prog_name='podkrig')",
                           "snapshots", "info", str(tmp_path)], capture_output=True, text=True, check=False)
    assert done.returncode == 2 and "Traceback" not in done.stderr and "error:" in done.stderr


def test_workers_and_chunk_size_are_checked_before_a_store_exists(tmp_path, coarse_diagonal, space):
    """Finding 7: `--workers 0` / `--chunk-size 0` left an empty store behind."""
    from podkrig.offline.runner import run_snapshots

    for kwargs in ({"workers": 0}, {"workers": 1, "chunk_size": 0}, {"workers": 10**6}):
        with pytest.raises(ValueError):
            run_snapshots(tmp_path / "s.h5", coarse_diagonal, space, n=4, seed=0, **kwargs)
        assert not (tmp_path / "s.h5").exists()


def test_huge_n_is_refused_with_an_estimate(tmp_path):
    spec = tmp_path / "coarse.json"
    spec.write_text(json.dumps({"scenario": "diagonal_compression", "nx": 2, "ny": 1}))
    args = ["snapshots", "run", "--spec", str(spec), "--param", "kN_bj=10:1000:log", "--seed", "0",
            "--store", str(tmp_path / "s.h5"), "--workers", "1"]
    result = runner.invoke(app, [*args, "--n", str(10**9)])
    assert result.exit_code == 2 and "above the limit" in result.output and "GiB" in result.output
    result = runner.invoke(app, [*args, "--n", str(2**20)], input="n\n")
    assert result.exit_code != 0 and "FE runs" in result.output
    assert not (tmp_path / "s.h5").exists()


@pytest.mark.parametrize("option, message", [
    ({"thickness": 1e-300}, "thickness must be > 0 mm"), ({"load_levels": [float("nan")]}, "load_levels must be"),
    ({"sensors": {}}, "at least one sensor"), ({"nx": 10**9}, "nx must be an integer in"),
    ({"nx": 64, "ny": 64}, "elements"), ({"load_levels": [1e300]}, "load_levels must be"),
    ({"sensors": {"$D_1$": {"type": "displacement"}}}, "sensor name '\\$D_1\\$'"),
])
def test_scenario_options_out_of_range_are_refused(option, message):
    """Finding 7: thickness 1e-300, load_levels = [nan], sensors = {} and nx = 10**9 were accepted."""
    from fe.exceptions import FEError
    from fe.scenarios import build_scenario

    with pytest.raises(FEError, match=message):
        build_scenario({"scenario": "diagonal_compression", **option})


@pytest.mark.parametrize("line, message", [
    ("noise_rel = inf", "inf is not a finite number"), ("noise_rel = nan", "nan is not a finite number"),
    ("noise_rel = 1" + "0" * 400, "401 digits.*not a finite number"),

])
def test_study_numbers_must_be_finite(tmp_path, line, message):
    """Finding 7: `noise_abs = inf` and integers too large for a float were accepted or crashed."""
    from podkrig.study import StudyError, load_study
    from tests.test_study_file import VALID, _write

    with pytest.raises(StudyError, match=message):
        load_study(_write(tmp_path, VALID.replace("noise_rel = 0.01", line)))
