"""Study jobs of ``podkrig serve``: the study's stages in a background process, as ``podkrig run``.

A job runs :func:`podkrig.study.run_study` on the session's study file into its folder in a
separate process (a new interpreter, ``python -m podkrig.serve.jobs STUDY OUT``: nothing of the
server's threads is copied into it, and it runs in its own session and process group), which
holds the folder's lock (:func:`podkrig.locks.folder_lock`) while it runs, so a second job, a
``podkrig run`` into the same folder or another server's job is refused (409). Every stage is
cached as in ``podkrig run``: a job started again after a cancel or a crash resumes — finished
stages are reused and an interrupted FE stage resumes from its store's finished rows.

The process reports one JSON line per event on its standard output: each stage started and
finished (the lines ``podkrig run`` prints), the FE runs done of the running stage, and the log's
warnings; :class:`Jobs` keeps the
last :data:`LOG_LINES` lines and the progress of each job. Cancelling terminates the process and
its own process group (the FE workers of a parallel stage with it); the operating system drops the
folder's lock with it.
"""

import collections
import dataclasses
import itertools
import json
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import podkrig
from podkrig.exceptions import InUseError
from podkrig.locks import folder_lock
from podkrig.serve.session import RequestError, check_keys
from podkrig.study.cache import Progress, now

logger = logging.getLogger(__name__)

#: lines of a job's log kept for the page
LOG_LINES = 40
#: seconds a cancelled job gets to end after SIGTERM before SIGKILL
CANCEL_GRACE = 5.0
#: the kinds of job
KINDS = ("study",)


def _emit(*message):
    """One event of the job, a JSON line on standard output."""
    sys.stdout.write(json.dumps(message, ensure_ascii=False) + "\n")
    sys.stdout.flush()


class _LineProgress(Progress):
    """A :class:`~podkrig.study.cache.Progress` that reports each event as a JSON line."""

    def stage_started(self, name, title, total=None):
        _emit("stage", name, title, total)

    def advance(self, completed, total):
        _emit("advance", completed, total)

    def stage_finished(self, record):
        fe = f", {record.fe_runs} FE runs" if record.fe_runs else ""
        line = f"· {record.title}: cached" if record.cached else f"✓ {record.title}: {record.seconds:.1f} s{fe}"
        _emit("finished", record.name, line)


class _LineLog(logging.Handler):
    """Warnings of the job's loggers, as events."""

    def __init__(self):
        super().__init__(logging.WARNING)

    def emit(self, record):
        _emit("log", f"{record.levelname.lower()}: {record.getMessage()}")


def study_job(study_path, out, skip_diagnosis=False):
    """The body of a study job's process: load the study, run it into ``out`` and report.

    Parameters
    ----------
    study_path, out : str or Path
    skip_diagnosis : bool
        Leave the model diagnosis out (as ``podkrig run --skip-diagnosis``).

    Emits ``["stage", name, title, total]``, ``["advance", done, total]``, ``["finished", name,
    line]``, ``["log", line]`` and finally ``["done", line]`` or ``["failed", message]``.
    """
    for name in ("podkrig", "fe"):
        logging.getLogger(name).addHandler(_LineLog())
    from podkrig.study import load_study, run_study

    try:
        study = load_study(study_path)
        if skip_diagnosis:
            study = dataclasses.replace(study, diagnosis=dataclasses.replace(study.diagnosis, enabled=False))
        result = run_study(study, out, progress=_LineProgress())
        _emit("done", f"{result.fe_runs} FE runs in {result.seconds:.1f} s; {len(result.warnings)} warnings; "
                      f"report: {result.report}")
    except Exception as e:  # noqa: BLE001 - every failure is reported to the page with its message
        _emit("failed", str(e) if isinstance(e, ValueError | InUseError | OSError) else f"{type(e).__name__}: {e}")


@dataclasses.dataclass(eq=False)
class Job:
    """A study job: its process and what it reported."""

    id: str
    kind: str
    started: str
    process: object
    status: str = "running"
    progress: dict = dataclasses.field(default_factory=lambda: {"stage": "starting", "done": 0, "total": None})
    log: collections.deque = dataclasses.field(default_factory=lambda: collections.deque(maxlen=LOG_LINES))
    error: str | None = None
    cancelled: bool = False
    seconds: float | None = None
    follower: threading.Thread | None = None

    def to_dict(self):
        return {"id": self.id, "kind": self.kind, "status": self.status, "started": self.started,
                "seconds": self.seconds, "progress": dict(self.progress), "log": list(self.log), "error": self.error}


class Jobs:
    """The study jobs of a session: :meth:`start`, :meth:`get`, :meth:`cancel`, :meth:`rows`."""

    def __init__(self, session):
        self.session = session
        self._jobs = {}
        self._ids = itertools.count(1)
        self._lock = threading.Lock()

    def running(self):
        return [j for j in self._jobs.values() if j.status == "running"]

    def start(self, body):
        """``POST /api/jobs``: start the study in a background process; its id.

        Raises
        ------
        RequestError
            422 an unknown kind; 409 a job of this session running, or the folder in use by
            another job (its holder named).
        """
        check_keys(body, ("kind", "skip_diagnosis"), "jobs")
        kind = body.get("kind", "study")
        if kind not in KINDS:
            raise RequestError(f"kind {kind!r}: one of {', '.join(KINDS)}", "kind")
        skip = body.get("skip_diagnosis", False)
        if not isinstance(skip, bool):
            raise RequestError(f"skip_diagnosis must be true or false; got {skip!r}", "skip_diagnosis")
        session = self.session
        with self._lock:
            if self.running():
                raise RequestError(f"job {self.running()[0].id} is running: wait for it, or cancel it", "kind", 409)
            try:
                with folder_lock(session.folder):  # refused now, not in the job, when another job holds it
                    pass
            except InUseError as e:
                raise RequestError(str(e), None, 409) from None
            command = [sys.executable, "-m", "podkrig.serve.jobs", str(session.study.path), str(session.folder)]
            root = str(Path(podkrig.__file__).resolve().parents[1])  # the same podkrig in the job
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}
            process = subprocess.Popen(command + (["--skip-diagnosis"] if skip else []), stdin=subprocess.DEVNULL,
                                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, encoding="utf-8",
                                       errors="replace", env=env, start_new_session=True)
            job = Job(f"j{next(self._ids)}", kind, now(), process)
            job.log.append(f"study {session.study.name!r} into {session.folder}"
                           + (" (without the model diagnosis)" if skip else ""))
            self._jobs[job.id] = job
        job.follower = threading.Thread(target=self._follow, args=(job, time.perf_counter()), daemon=True,
                                        name=f"podkrig-job-{job.id}")
        job.follower.start()
        return job.id

    def _follow(self, job, t0):
        """Read the job's events until its process ends; then its final state."""
        final = None
        errors = collections.deque(maxlen=5)
        threading.Thread(target=lambda: errors.extend(job.process.stderr), daemon=True).start()
        for text in job.process.stdout:
            try:
                message = json.loads(text)
            except ValueError:
                continue  # a line printed by a library: not an event
            kind = message[0]
            if kind == "stage":
                job.progress = {"stage": message[2], "done": 0, "total": message[3]}
            elif kind == "advance":
                job.progress = {**job.progress, "done": message[1], "total": message[2]}
            elif kind in ("finished", "log"):
                job.log.append(message[-1])
            else:
                final = message
        job.process.wait()
        # new surrogates or a new calibration: the problem is built again (before the job reads as
        # ended, so a page that reloads the study on the job's end sees the new one)
        self.session.reload()
        job.seconds = time.perf_counter() - t0
        if job.cancelled:
            job.status = "cancelled"
            job.log.append("cancelled: finished stages and FE runs are kept; start the job again to resume")
        elif final is not None and final[0] == "done":
            job.status = "done"
            job.log.append(final[1])
        else:
            job.status = "failed"
            job.error = final[1] if final is not None else (
                f"the job's process ended with exit code {job.process.returncode}"
                + (f": {errors[-1].strip()}" if errors else ""))
            job.log.append(f"failed: {job.error}")

    def get(self, jid):
        job = self._jobs.get(jid)
        if job is None:
            raise RequestError(f"no job {jid!r} in this session; jobs: {list(self._jobs) or 'none yet'}", "job", 404)
        return job

    def rows(self):
        """``GET /api/jobs``: every job of the session, oldest first."""
        return [j.to_dict() for j in self._jobs.values()]

    def cancel(self, jid):
        """``DELETE /api/jobs/{id}``: terminate a running job's process group (a finished job is left
        as it is); the job as it is now."""
        job = self.get(jid)
        if job.status != "running" or job.process.poll() is not None:
            return job
        job.cancelled = True
        _terminate(job.process)
        job.follower.join(CANCEL_GRACE)  # its final state read
        return job

    def close(self):
        """Cancel every running job (the server stops)."""
        for job in self.running():
            job.cancelled = True
            _terminate(job.process)


def _terminate(process):
    """SIGTERM to the job's process group (its own session), SIGKILL after :data:`CANCEL_GRACE`."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(process.pid, sig)
        except ProcessLookupError:
            return
        try:
            process.wait(CANCEL_GRACE)
            return
        except subprocess.TimeoutExpired:
            continue


def main(argv=None):
    """``python -m podkrig.serve.jobs STUDY OUT [--skip-diagnosis]``: a study job (the server starts it)."""
    args = list(sys.argv[1:] if argv is None else argv)
    skip = "--skip-diagnosis" in args
    args = [a for a in args if a != "--skip-diagnosis"]
    if len(args) != 2:
        sys.exit("usage: python -m podkrig.serve.jobs STUDY OUT [--skip-diagnosis]")
    study_job(args[0], args[1], skip)


__all__ = ["CANCEL_GRACE", "KINDS", "LOG_LINES", "Job", "Jobs", "main", "study_job"]

if __name__ == "__main__":
    main()
