"""Exclusive locks between podkrig processes: one writer per snapshot store, one run per output folder.

A lock is an advisory ``fcntl.flock`` on a small lock file that holds the holder's PID and host.
The operating system drops a ``flock`` when its process dies (and a lock never survives a reboot),
so a lock file left by a killed job is *stale*: its text names a process that no longer holds it,
and the next job takes it over — the lock, not the file's existence, decides. Two jobs that race
for a new lock file are ordered by the kernel, and a job that waited for a holder which removed the
file re-checks that it locked the file now on disk.

Two kinds:

* :func:`acquire_lock` / :func:`release_lock`: the writer's lock of a file (a snapshot store),
  ``.NAME.lock`` beside it; re-entrant within a process (counted), so a process that holds a
  store's lock may open it again.
* :func:`folder_lock`: a context manager for a whole output folder (``podkrig run``, the demo, a
  background job of a front end), ``FOLDER/.podkrig.lock``; *not* re-entrant: a second job into the
  same folder is refused even from the same process (another thread), since ``flock`` locks belong
  to an open file, not to a process.

This module is at the bottom of the layers (it imports only :mod:`podkrig.exceptions`), so every
stage and every front end can take the same locks.
"""

import contextlib
import errno
import fcntl
import logging
import os
import socket
from pathlib import Path

from podkrig.exceptions import InUseError, StoreError, StoreInUseError

logger = logging.getLogger(__name__)

#: The lock file of an output folder, inside it.
FOLDER_LOCK_NAME = ".podkrig.lock"
#: Bytes of a lock file read to name its holder ("PID 1234 on host"): a lock file is never read whole.
_HOLDER_BYTES = 200

_HELD = {}  # resolved lock path -> [fd, count]: a process takes a store's lock once, then counts


def lock_path(path):
    """The lock file of the store at ``path``: ``.NAME.lock`` beside it, holding the writer's PID."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


def lock_holder(lock):
    """Who holds ``lock``, as its file says (``"PID 1234 on host"``; at most one short line)."""
    try:
        with open(lock, "rb") as fh:
            text = fh.read(_HOLDER_BYTES).decode("utf-8", errors="replace")
    except OSError:
        return "an unknown process"
    line = text.strip().splitlines()[0] if text.strip() else ""
    return "".join(c if c.isprintable() else "?" for c in line)[:80] or "an unknown process"


def holds_lock(path):
    """Whether this process holds the writer's lock of the store at ``path``."""
    return str(lock_path(path).resolve()) in _HELD


def _take(lock, refused):
    """Open and ``flock`` the file ``lock`` (created if missing), write our PID into it, return its fd.

    ``refused(holder)`` builds the exception raised when another open file holds the lock.
    """
    while True:
        try:
            lock.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as e:
            raise StoreError(f"cannot create the lock file {lock}: {e.strerror}; is the folder writable?") from e
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as e:
            os.close(fd)
            if e.errno in (errno.EAGAIN, errno.EACCES, errno.EWOULDBLOCK):
                raise refused(lock_holder(lock)) from None
            raise StoreError(f"cannot lock {lock}: {e.strerror}") from e
        try:  # the holder we waited for may have removed the file: lock the one on disk
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    stale = os.pread(fd, _HOLDER_BYTES, 0).decode("utf-8", errors="replace").strip()
    if stale:  # a holder that died (or ran before a reboot) without releasing
        logger.info("took over the stale lock %s (it named %s, which no longer holds it)", lock, stale[:80])
    os.ftruncate(fd, 0)
    os.write(fd, f"PID {os.getpid()} on {socket.gethostname()}\n".encode())
    return fd


def acquire_lock(path):
    """Take the exclusive writer lock of the store at ``path`` (re-entrant within a process).

    The lock is an advisory ``fcntl.flock`` on ``.NAME.lock``, held until :func:`release_lock`;
    the operating system drops it when the process dies, so a killed job never leaves a stale lock.

    Raises
    ------
    StoreInUseError
        Another process holds it (the message gives its PID and host).
    StoreError
        The lock file cannot be created (read-only folder, ...).
    """
    lock = lock_path(path)
    key = str(lock.resolve())
    if key in _HELD:
        _HELD[key][1] += 1
        return
    fd = _take(lock, lambda holder: StoreInUseError(
        f"{path} is in use by {holder} (lock {lock.name}); wait for that job to finish or stop it — "
        "nothing was changed"))
    _HELD[key] = [fd, 1]


def release_lock(path):
    """Release one :func:`acquire_lock` of this process; the last one removes the lock file."""
    lock = lock_path(path)
    key = str(lock.resolve())
    held = _HELD.get(key)
    if held is None:
        return
    held[1] -= 1
    if held[1] == 0:
        del _HELD[key]
        lock.unlink(missing_ok=True)  # while still locked: a waiter re-checks the path (see _take)
        os.close(held[0])


@contextlib.contextmanager
def folder_lock(folder, what="output folder"):
    """Hold the exclusive lock of an output ``folder`` (created if missing) for a ``with`` block.

    The lock file ``FOLDER/.podkrig.lock`` names the holder; it is removed on leaving the block,
    normally or by an exception. A folder this call created is removed again if it is still empty
    then (a run refused before it wrote anything leaves no trace). Not re-entrant: a second lock of
    the same folder, from any process or thread, is refused.

    Parameters
    ----------
    folder : str or Path
    what : str
        The folder's role in the refusal (``"output folder"``, ``"--out"``).

    Raises
    ------
    InUseError
        Another job holds the folder; the message names its PID and host, and the folder. Nothing in
        the folder was changed.
    StoreError
        The folder or its lock file cannot be created.
    """
    folder = Path(folder)
    created = not folder.exists()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StoreError(f"cannot create the {what} {folder}: {e.strerror}") from e
    lock = folder / FOLDER_LOCK_NAME
    try:
        fd = _take(lock, lambda holder: InUseError(
            f"{what} {folder} is in use by {holder} (lock {lock}); wait for that job to finish, stop it, or "
            "choose another folder — nothing was changed"))
    except BaseException:
        if created:
            _remove_if_empty(folder)
        raise
    try:
        yield folder
    finally:
        lock.unlink(missing_ok=True)  # while still locked (see _take)
        os.close(fd)
        if created:
            _remove_if_empty(folder)


def _remove_if_empty(folder):
    with contextlib.suppress(OSError):
        folder.rmdir()  # refuses a folder that is not empty


__all__ = ["FOLDER_LOCK_NAME", "acquire_lock", "folder_lock", "holds_lock", "lock_holder", "lock_path", "release_lock"]
