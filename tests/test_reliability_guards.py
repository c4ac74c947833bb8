"""Guards at the edges of a run: one run per output folder, bounded reads of every input file,
measurement paths kept inside the study folder, error messages that quote no file content, and a
disk-full message whose numbers add up."""

import os
import re
import shutil
import subprocess
import sys
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from podkrig.cli import app
from podkrig.exceptions import InUseError, StoreError
from podkrig.io import surrogate_file
from podkrig.io.measurement_log import read_measurement
from podkrig.limits import MAX_STUDY_FILE_BYTES
from podkrig.locks import FOLDER_LOCK_NAME, folder_lock
from podkrig.offline import files
from podkrig.study import cache, load_study, run_study
from podkrig.study.schema import StudyError

runner = CliRunner()
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
DEMO = EXAMPLES / "diagonal_compression.toml"


def _contents(folder):
    """Every file under ``folder`` with its bytes (what a refused run must not change)."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _holder(folder):
    """A subprocess holding the output-folder lock of ``folder`` until killed."""
    code = (f"from podkrig.locks import folder_lock\nwith folder_lock({str(folder)!r}):\n"
            "    print('ready', flush=True)\n    import time; time.sleep(120)")
    job = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True,
                           env=dict(os.environ, PYTHONPATH=os.getcwd()))
    assert job.stdout.readline().strip() == "ready"
    return job


# ----------------------------------------------------------------------------- output-folder lock
def test_second_run_into_a_held_folder_is_refused_with_the_pid_and_changes_nothing(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "summary.json").write_text('{"name": "the first run"}')
    job = _holder(out)
    try:
        before = _contents(out)
        result = runner.invoke(app, ["run", str(DEMO), "--out", str(out)])
        assert result.exit_code == 2
        assert f"PID {job.pid}" in result.output and str(out) in result.output and "in use" in result.output
        assert "Traceback" not in result.output
        assert _contents(out) == before
    finally:
        job.kill()
        job.wait()
        job.stdout.close()


def test_a_second_job_in_the_same_process_is_refused(tmp_path):
    """A front end running jobs in threads of one process: flock belongs to an open file, so the
    folder lock is not re-entrant."""
    out = tmp_path / "job"
    with folder_lock(out):
        errors = []

        def second():
            try:
                with folder_lock(out):
                    pass
            except InUseError as e:
                errors.append(str(e))

        t = threading.Thread(target=second)
        t.start()
        t.join()
        assert len(errors) == 1 and f"PID {os.getpid()}" in errors[0] and str(out) in errors[0]
        assert (out / FOLDER_LOCK_NAME).exists()
    assert not (out / FOLDER_LOCK_NAME).exists()  # released on leaving the block


def test_stale_lock_of_a_dead_process_is_taken_over(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    (out / FOLDER_LOCK_NAME).write_text(f"PID {dead.stdout.strip()} on a-machine-before-its-reboot\n")
    with folder_lock(out):
        assert (out / FOLDER_LOCK_NAME).read_text().startswith(f"PID {os.getpid()} on ")
    assert not (out / FOLDER_LOCK_NAME).exists()


def test_lock_is_released_when_the_run_raises(tmp_path):
    """run_study holds the lock from its start: an exception (here the confirmation refused) releases it,
    and a folder the refused run created is removed again (it wrote nothing)."""
    study = load_study(DEMO)
    out = tmp_path / "new"

    def refuse(text, large):
        assert (out / FOLDER_LOCK_NAME).exists()  # held while the run decides
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_study(study, out, confirm=refuse)
    assert not out.exists()
    with folder_lock(out):  # free again
        pass


def test_refused_lock_in_a_new_folder_leaves_no_folder(tmp_path):
    out = tmp_path / "a"
    with folder_lock(out):
        with pytest.raises(InUseError, match="nothing was changed"):
            with folder_lock(tmp_path / "a" / ".." / "a"):
                pass
    assert not out.exists()


# ----------------------------------------------------------------------------- disk full
def test_disk_full_message_states_the_margin_so_the_numbers_add_up(tmp_path, monkeypatch):
    monkeypatch.setattr(files, "free_bytes", lambda folder: 136 * 1024)
    with pytest.raises(StoreError, match=r"needs about 77\.0 KiB plus a safety margin of 256\.0 KiB.* 333\.0 KiB "
                                         r"in all.* 136\.0 KiB free"):
        files.check_disk_space(tmp_path, 77 * 1024, "the store")
    files.check_disk_space(tmp_path, 136 * 1024 - files.DISK_MARGIN, "the store")  # fits exactly: no error


# ----------------------------------------------------------------------------- bounded reads
@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero")
@pytest.mark.parametrize("args, what", [
    (["run", "/dev/zero"], "study file"),
    (["simulate", "diagonal_compression", "--spec", "/dev/zero"], "scenario spec"),
    (["snapshots", "run", "--spec", "/dev/zero", "--param", "kN_bj=10:1000", "--n", "4", "--seed", "0",
      "--store", "{tmp}/s.h5"], "scenario spec"),
])
def test_endless_input_is_refused_at_the_cap(tmp_path, args, what):
    result = runner.invoke(app, [a.format(tmp=tmp_path) for a in args])
    assert result.exit_code == 2 and "Traceback" not in result.output
    for fragment in ("/dev/zero", "larger than 1 MiB (1048576 bytes)", f"the cap for a {what}",
                     "more than 1048576 bytes read"):
        assert fragment in result.output
    assert not (tmp_path / "s.h5").exists()


@pytest.mark.parametrize("args", [["run", "{fifo}"], ["simulate", "diagonal_compression", "--spec", "{fifo}"]])
def test_a_fifo_is_refused_at_once_without_waiting_for_a_writer(tmp_path, args):
    fifo = tmp_path / "in.toml"
    os.mkfifo(fifo)
    result = runner.invoke(app, [a.format(fifo=fifo) for a in args])  # a blocking open would hang here
    assert result.exit_code == 2
    for fragment in (str(fifo), "not a regular file", "at most 1 MiB"):
        assert fragment in result.output


def test_study_file_over_the_cap_is_refused_by_its_size(tmp_path):
    big = tmp_path / "big.toml"
    big.write_bytes(b"# " + b"x" * MAX_STUDY_FILE_BYTES + b"\n")
    with pytest.raises(StudyError, match=r"big\.toml: larger than 1 MiB \(1048576 bytes\), the cap .*it is 1\.0 MiB"):
        load_study(big)


def test_damaged_artefacts_are_refused_naming_the_cap(tmp_path, monkeypatch, caplog):
    """The files podkrig reads back from its output folder: an array file over the cap (also once
    unpacked: a zip bomb) and a manifest over the cap (the stage reruns, the log says why)."""
    np.savez_compressed(tmp_path / "region.npz", samples=np.zeros((1000, 4)))  # 32 kB unpacked, ~100 B packed
    assert cache.read_arrays(tmp_path / "region.npz")["samples"].shape == (1000, 4)
    monkeypatch.setattr(cache, "MAX_ARRAY_FILE_BYTES", 10_000)
    with pytest.raises(ValueError, match=r"region\.npz: larger than .*10000 bytes.*the cap for an array file: its "
                                         r"arrays unpack to"):
        cache.read_arrays(tmp_path / "region.npz")
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match=r"bad\.npz: not an \.npz"):
        cache.read_arrays(tmp_path / "bad.npz")
    (tmp_path / "m.json").write_text('{"stage": "x"}')
    assert cache.read_manifest(tmp_path / "m.json") == {"stage": "x"}
    monkeypatch.setattr(cache, "MAX_JSON_BYTES", 5)
    with caplog.at_level("WARNING", logger="podkrig.study.cache"):
        assert cache.read_manifest(tmp_path / "m.json") is None
    assert "m.json: larger than 5 B (5 bytes), the cap for a stage manifest" in caplog.text



def test_a_surrogate_file_over_the_cap_is_refused_naming_it(tmp_path, monkeypatch):
    """A surrogate file (HDF5) is held to the array-file cap on disk and in what its arrays unpack
    to (as their headers declare it, before anything is read): a small file of compressed zeros is
    refused as surely as a large one."""
    path = tmp_path / "surrogate.h5"
    shutil.copy(Path(__file__).parent / "data" / "surrogate_v1.h5", path)
    assert surrogate_file.load_surrogate(path) is not None
    size = path.stat().st_size
    monkeypatch.setattr(surrogate_file, "MAX_ARRAY_FILE_BYTES", size - 1)
    with pytest.raises(StoreError, match=rf"surrogate\.h5: larger than .*\({size - 1} bytes\), the cap for a "
                                         r"surrogate file: it is"):
        surrogate_file.load_surrogate(path)
    with h5py.File(path, "r+") as f:
        f.create_dataset("padding", data=np.zeros(2**20), compression="gzip")  # 8 MiB unpacked, ~10 kB on disk
    monkeypatch.setattr(surrogate_file, "MAX_ARRAY_FILE_BYTES", 2**20)
    assert path.stat().st_size < 2**20
    with pytest.raises(StoreError, match=r"surrogate\.h5: larger than 1\.0 MiB \(1048576 bytes\), the cap for a "
                                         r"surrogate file: its arrays unpack to 8\.\d MiB"):
        surrogate_file.load_surrogate(path)

# ----------------------------------------------------------------------------- measurement paths, quoting
def _study_with_measurement(folder, file_value):
    """The demo study copied to ``folder`` with its scenario and validation spec inline and its
    measurement ``file = file_value``."""
    folder.mkdir(parents=True, exist_ok=True)
    text = DEMO.read_text(encoding="utf-8").replace('file = "diagonal_compression_measured.csv"',
                                                    f"file = {file_value!r}".replace("'", '"'))
    (folder / "diagonal_compression_measured.csv").write_bytes((EXAMPLES / "diagonal_compression_measured.csv")
                                                               .read_bytes())
    study = folder / "study.toml"
    study.write_text(text, encoding="utf-8")
    return study


def test_a_relative_measurement_path_leaving_the_study_folder_is_refused_unread(tmp_path):
    secret = tmp_path / "secret.csv"
    secret.write_text("TOP-SECRET-FIRST-LINE\n")
    study = _study_with_measurement(tmp_path / "a" / "b", "../../secret.csv")
    result = runner.invoke(app, ["run", str(study), "--out", str(tmp_path / "out")])
    assert result.exit_code == 2 and "Traceback" not in result.output
    for fragment in (str(study), "measurement.file", "'../../secret.csv'", "leads outside", str(secret),
                     "an absolute path if the file is elsewhere on purpose"):
        assert fragment in result.output
    assert "TOP-SECRET" not in result.output and not (tmp_path / "out").exists()
    with pytest.raises(StudyError, match=r"line 30: measurement\.file: '\.\./\.\./\.\./\.\./etc/passwd' leads outside"):
        load_study(_study_with_measurement(tmp_path / "c", "../../../../etc/passwd"))


def test_a_relative_scenario_spec_path_leaving_the_study_folder_is_refused(tmp_path):
    (tmp_path / "spec.toml").write_text('scenario = "diagonal_compression"\n')
    study = _study_with_measurement(tmp_path / "s", "diagonal_compression_measured.csv")
    text = study.read_text(encoding="utf-8").replace('[scenario]                       # the scenario spec (options as '
                                                     'in `podkrig simulate --spec`)\nscenario = "diagonal_compression"'
                                                     '\nnx = 6', 'scenario = "../spec.toml"\n[scenario_unused]\nnx = 6')
    text = text.replace("[scenario_unused]\nnx = 6                           # Q8 elements along a full unit\n"
                        "ny = 2                           # ... and across its height (9360 dofs)\n", "")
    study.write_text(text, encoding="utf-8")
    with pytest.raises(StudyError, match=r"line 7: scenario: '\.\./spec\.toml' leads outside .*absolute path"):
        load_study(study)
    study.write_text(text.replace("../spec.toml", str(tmp_path / "spec.toml")), encoding="utf-8")
    assert load_study(study).spec.scenario == "diagonal_compression"  # an absolute path: on purpose


def test_an_absolute_measurement_path_is_followed_on_purpose(tmp_path):
    log = tmp_path / "lab" / "log.csv"
    log.parent.mkdir()
    log.write_bytes((EXAMPLES / "diagonal_compression_measured.csv").read_bytes())
    study = load_study(_study_with_measurement(tmp_path / "study", str(log)))
    assert study.measurement.file == log.resolve()
    inside = load_study(_study_with_measurement(tmp_path / "in", "sub/../diagonal_compression_measured.csv"))
    assert inside.measurement.file == (tmp_path / "in" / "diagonal_compression_measured.csv").resolve()


def test_a_utf16_log_without_its_byte_order_mark_is_refused_without_echoing_nul_bytes(tmp_path):
    body = "load [kN],D1 [mm],D2 [mm]\n" + "".join(f"{10 * i},{0.001 * i},{0.002 * i}\n" for i in range(1, 200))
    for name, raw in (("le.csv", body.encode("utf-16-le")), ("be.csv", body.encode("utf-16-be")),
                      ("twice.csv", b"\xff\xfe" + body.encode("utf-16-le").decode("latin-1").encode("utf-16-le"))):
        path = tmp_path / name
        path.write_bytes(raw)
        with pytest.raises(ValueError, match=r"not a text file \(NUL characters from line 1") as info:
            read_measurement(path, ("D1", "D2"), (10.0, 20.0))
        message = str(info.value)
        assert "\x00" not in message and "\\x00" not in message and "save it as UTF-8" in message
        assert len(message) <= len(str(path)) + 160
    cut = tmp_path / "cut.csv"  # with its byte-order mark, cut in the middle of a character
    cut.write_bytes(b"\xff\xfe" + body.encode("utf-16-le")[:-1])
    with pytest.raises(ValueError, match=r"cut\.csv: damaged UTF-16 text at byte \d+; save it as UTF-8"):
        read_measurement(cut, ("D1", "D2"), (10.0, 20.0))


def test_file_content_in_a_message_is_one_line_of_at_most_80_characters(tmp_path):
    """A header without the load column is quoted to identify it, cut at 80 characters; a long cell,
    a binary cell and a unit likewise."""
    cases = {  # content, a fragment, the quoted content (group 1)
        "header.csv": ("force," + ",".join(f"channel_{k:03d}_" + "x" * 40 for k in range(100)) + "\n10,1\n",
                       "no load column 'load' in the header ['force', 'channel_000_", r"header (\[.*\]) \(set"),
        "cell.csv": ("load,D1\n10," + "7" * 20 + "z" * 4000 + "\n", "'77777", r"\(D1\): ('.*) is not a number"),
        "unit.csv": ("load,D1 [" + "q" * 3000 + "]\n10,1\n", "unknown unit 'qqqq", r"unknown unit ('.*) \(use"),
        "ctrl.csv": ("load,D1\n10,\x01\x02\x03\x1b[2J" + "\x07" * 500 + "\n", r"'\x01\x02\x03\x1b[2J\x07",
                     r"\(D1\): ('.*) is not a number"),
    }
    for name, (content, fragment, pattern) in cases.items():
        path = tmp_path / name
        path.write_text(content, encoding="utf-8")
        with pytest.raises(ValueError) as info:
            read_measurement(path, ("D1",), (10.0,))
        message = str(info.value)
        assert fragment in message, message
        assert "\n" not in message and all(c.isprintable() for c in message)
        quoted = re.search(pattern, message).group(1)
        assert len(quoted) <= 80, quoted
