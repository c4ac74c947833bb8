"""File safety of the offline stores: one writer per file (the lock of :mod:`podkrig.locks`), atomic publication
of a new file, moving an unusable file aside instead of deleting it, leftovers of interrupted
creations, free disk space, and OS errors in words.

Used by :mod:`podkrig.offline.store` (its module docstring describes the crash-safety rules these
functions implement) and by the runner and the study pipeline.
"""

import datetime
import errno
import logging
import os
from pathlib import Path

from podkrig.exceptions import StoreError
from podkrig.limits import human_bytes
from podkrig.locks import acquire_lock, holds_lock, lock_holder, lock_path, release_lock

logger = logging.getLogger(__name__)

DISK_MARGIN = 256 * 1024  # bytes kept free beyond a batch's estimate (HDF5 metadata, other writers)


def tmp_path(path):
    return path.with_name(f".{path.name}.tmp-{os.getpid()}")


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
    """Refuse to start writing ``need`` bytes into ``folder`` unless they fit with :data:`DISK_MARGIN`
    to spare; the message gives the estimate, the margin, their sum and the free space.

    Raises
    ------
    StoreError
        Not enough free space.
    """
    free = free_bytes(folder)
    if free is not None and free < need + DISK_MARGIN:
        raise StoreError(
            f"disk full: {what} needs about {human_bytes(need)} plus a safety margin of {human_bytes(DISK_MARGIN)} "
            f"(HDF5 metadata, other writers), {human_bytes(need + DISK_MARGIN)} in all, but {folder} has "
            f"{human_bytes(free)} free; free some space and rerun"
        )


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
