"""Bounded reads of the small files a user hands over (scenario specs; in podkrig study files,
measurement logs, manifests): a stated cap in bytes, a device or a FIFO refused before it fills the
memory or blocks. The one implementation: :mod:`podkrig.limits` re-exports it with podkrig's caps.
"""

import errno
import os
import stat
from pathlib import Path

__all__ = ["human_bytes", "read_bounded"]


def human_bytes(nbytes):
    """``1536`` → ``"1.5 KiB"``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(nbytes) < 1024 or unit == "PiB":
            return f"{nbytes:.0f} {unit}" if unit == "B" else f"{nbytes:.1f} {unit}"
        nbytes /= 1024


def read_bounded(path, cap, what, remedy=None, error=ValueError):
    """The bytes of the file at ``path``, refusing more than ``cap`` of them.

    A regular file larger than the cap is refused from its size; otherwise at most ``cap + 1``
    bytes are read, so a device (``/dev/zero``) or a file that grows is refused after reading just
    past the cap, not at "out of memory". A FIFO, socket or folder is refused before reading (it is
    opened without waiting for a writer).

    Parameters
    ----------
    path : str or Path
    cap : int
        Largest size accepted, bytes (e.g. :data:`podkrig.limits.MAX_STUDY_FILE_BYTES`).
    what : str
        The file's role in the message (``"study file"``).
    remedy : str, optional
        What to do, appended to a refusal.
    error : type, default ValueError
        The exception class of a refusal (:class:`~fe.exceptions.SpecError` for a scenario spec).

    Raises
    ------
    error
        Naming the file, its size (or "more than CAP bytes") and the cap.
    OSError
        The file cannot be opened or read, or is a folder.
    """
    path = Path(path)
    tail = f"; {remedy}" if remedy else ""
    cap_text = f"{cap // 2**20} MiB" if cap % 2**20 == 0 else human_bytes(cap)
    too_large = f"{path}: larger than {cap_text} ({cap} bytes), the cap for a {what}: "
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO without a writer would block a plain open
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):  # as open() would say
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        if not (stat.S_ISREG(st.st_mode) or stat.S_ISCHR(st.st_mode)):
            kind = "a FIFO" if stat.S_ISFIFO(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "special"
            raise error(f"{path}: not a regular file ({kind}); a {what} is read from a file of at most "
                             f"{cap_text} ({cap} bytes)")
        if stat.S_ISREG(st.st_mode) and st.st_size > cap:
            raise error(f"{too_large}it is {human_bytes(st.st_size)}{tail}")
        os.set_blocking(fd, True)
        chunks, n = [], 0
        while n <= cap:
            block = os.read(fd, min(cap + 1 - n, 1 << 20))
            if not block:
                break
            chunks.append(block)
            n += len(block)
    finally:
        os.close(fd)
    if n > cap:
        raise error(f"{too_large}more than {cap} bytes read{tail}")
    return b"".join(chunks)
