"""File safety of the offline stores: one writer per file (an advisory lock), atomic publication
of a new file, moving an unusable file aside instead of deleting it, leftovers of interrupted
creations, free disk space, and OS errors in words.

Used by :mod:`podkrig.offline.store` (its module docstring describes the crash-safety rules these
functions implement) and by the runner and the study pipeline.
"""

import datetime
import errno
import fcntl
import logging
import os
import socket
from pathlib import Path

from podkrig.exceptions import StoreError, StoreInUseError

logger = logging.getLogger(__name__)

DISK_MARGIN = 256 * 1024  # bytes kept free beyond a batch's estimate (HDF5 metadata, other writers)


def tmp_path(path):
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


def holds_lock(path):
    """Whether this process holds the writer's lock of the store at ``path``."""
    return str(lock_path(path).resolve()) in _HELD


def lock_path(path):
    """The lock file of the store at ``path``: ``.NAME.lock`` beside it, holding the writer's PID."""
    path = Path(path)
    return path.with_name(f".{path.name}.lock")


_HELD = {}  # resolved lock path -> [fd, count]: a process takes a store's lock once, then counts


def lock_holder(lock):
    try:
        return lock.read_text(encoding="utf-8", errors="replace").strip()[:200] or "an unknown process"
    except OSError:
        return "an unknown process"


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
                raise StoreInUseError(
                    f"{path} is in use by {lock_holder(lock)} (lock {lock.name}); wait for that job to "
                    "finish or stop it — nothing was changed"
                ) from None
            raise StoreError(f"cannot lock {lock}: {e.strerror}") from e
        try:  # the holder we waited for may have removed the file: lock the one on disk
            same = os.path.samestat(os.fstat(fd), os.stat(lock))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    os.ftruncate(fd, 0)
    os.write(fd, f"PID {os.getpid()} on {socket.gethostname()}\n".encode())
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
        lock.unlink(missing_ok=True)  # while still locked: a waiter re-checks the path (see acquire_lock)
        os.close(held[0])


def move_aside(path):
    """Rename an unusable store to ``NAME.unusable-YYYYmmddTHHMMSSZ[-k].SUFFIX`` beside it, under the
    store's lock; never replaces a file. Returns the new path.

    Raises
    ------
    StoreInUseError
        Another process writes the store.
    """
    path = Path(path)
    acquire_lock(path)
    try:
        stamp = datetime.datetime.now(datetime.UTC).strftime("%Y%m%dT%H%M%SZ")
        for k in range(1000):
            target = path.with_name(f"{path.stem}.unusable-{stamp}{f'-{k}' if k else ''}{path.suffix}")
            try:
                os.link(path, target)  # fails if target exists, unlike a rename
            except FileExistsError:
                continue
            except OSError as e:
                if e.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK) or target.exists():
                    raise
                os.rename(path, target)  # no hard links on this file system; target checked just now
                return target
            path.unlink()
            return target
        raise StoreError(f"cannot find a free name to keep {path} aside")
    except OSError as e:
        raise StoreError(f"cannot move {path} aside: {io_reason(e)}") from e
    finally:
        release_lock(path)


def remove_orphans(path):
    """Delete temporary files of an interrupted create/extend of ``path`` (call with the lock held)."""
    for tmp in path.parent.glob(f".{path.name}.tmp-*"):
        try:
            tmp.unlink()
            logger.warning("removed %s, left by an interrupted creation of %s", tmp, path)
        except OSError as e:
            logger.warning("cannot remove the leftover %s: %s", tmp, e.strerror)


def free_bytes(folder):
    try:
        st = os.statvfs(folder)
    except OSError:
        return None
    return st.f_bavail * st.f_frsize


def check_disk_space(folder, need, what):
    free = free_bytes(folder)
    if free is not None and free < need + DISK_MARGIN:
        raise StoreError(
            f"disk full: {what} needs about {human_bytes(need)} but {folder} has {human_bytes(free)} free; "
            "free some space and rerun"
        )


def human_bytes(nbytes):
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if abs(nbytes) < 1024 or unit == "TiB":
            return f"{nbytes:.0f} {unit}" if unit == "B" else f"{nbytes:.1f} {unit}"
        nbytes /= 1024


def io_reason(e):
    """A short reason for an OS or HDF5 I/O error, with what to do."""
    text = str(e)
    code = getattr(e, "errno", None)
    if code == errno.ENOSPC or "errno = 28" in text or "No space left" in text:
        return "disk full (no space left on device); free some space and rerun"
    if code in (errno.EACCES, errno.EPERM) or "Permission denied" in text:
        return "permission denied; choose a folder you can write to"
    if code == errno.EROFS or "Read-only file system" in text:
        return "read-only file system; choose a writable folder"
    return f"{type(e).__name__}: {text[:300]}"


def publish(tmp, path):
    """Move a finished temporary file to ``path``, never replacing an existing file."""
    try:
        os.link(tmp, path)  # atomic and fails if path exists, unlike a rename
    except FileExistsError:
        raise StoreError(f"{path} already exists; a store is never overwritten") from None
    except OSError as e:
        if e.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EMLINK):
            raise StoreError(f"cannot create {path}: {io_reason(e)}") from e
        if path.exists():  # no hard links here (some network file systems); we hold the lock
            raise StoreError(f"{path} already exists; a store is never overwritten") from None
        os.replace(tmp, path)


__all__ = ["DISK_MARGIN", "acquire_lock", "check_disk_space", "free_bytes", "holds_lock", "human_bytes", "io_reason",
           "lock_holder", "lock_path", "move_aside", "publish", "release_lock", "remove_orphans", "tmp_path"]
