"""Helpers shared by CLI commands: error reporting and logging set-up."""

import contextlib
import csv
import errno
import logging

import typer

from fe.exceptions import FEError

from podkrig.exceptions import PodkrigError

_OS_HINTS = {
    errno.EACCES: "permission denied: choose a folder you can write to, or fix its permissions",
    errno.EPERM: "operation not permitted: choose another folder, or fix its permissions",
    errno.EROFS: "read-only file system: choose a writable folder (e.g. --out or --store elsewhere)",
    errno.ENOSPC: "disk full: free some space and rerun the same command (finished work is kept)",
    errno.EDQUOT: "disk quota exceeded: free some space and rerun the same command (finished work is kept)",
    errno.ENOENT: "no such file or folder: check the path",
    errno.EISDIR: "is a folder: give a file",
    errno.ENOTDIR: "a part of the path is a file, not a folder: check the path",
    errno.EEXIST: "already exists and is in the way: choose another path",
    errno.ENAMETOOLONG: "file name too long: choose a shorter path",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n) or use fewer workers",
}


def os_error_message(e):
    """One line for an OSError: the path, what went wrong and what to do."""
    where = " -> ".join(str(p) for p in (e.filename, e.filename2) if p is not None)
    what = _OS_HINTS.get(e.errno) or f"{e.strerror or type(e).__name__}: {e}"
    return f"{where}: {what}" if where else what


def error_message(e):
    """The one-line message for an exception the CLI reports instead of a traceback, or None."""
    if isinstance(e, (FEError, PodkrigError, ValueError, FileNotFoundError)) and not isinstance(e, UnicodeError):
        return str(e)
    if isinstance(e, OSError):
        return os_error_message(e)
    if isinstance(e, UnicodeDecodeError):
        return (f"a file is not UTF-8 text (byte {e.start}: {e.object[e.start:e.start + 4]!r}); save it as "
                "UTF-8")
    if isinstance(e, csv.Error):
        return f"malformed CSV ({e}); check the file's quoting and cell sizes"
    if isinstance(e, RecursionError):
        return "input nested too deeply; simplify it"
    if isinstance(e, OverflowError):
        return f"a number is too large ({e}); use values of ordinary size"
    if isinstance(e, MemoryError):
        return "not enough memory for this input or setting; reduce its size"
    return None


@contextlib.contextmanager
def user_errors():
    """Turn domain, OS and format errors into ``error: <message>`` on stderr and exit code 2."""
    try:
        yield
    except (FEError, PodkrigError, ValueError, OSError, csv.Error, RecursionError, OverflowError,
            MemoryError) as e:
        typer.echo(f"error: {error_message(e)}", err=True)
        raise typer.Exit(code=2) from None


def configure_logging(verbose):
    logging.basicConfig(level=logging.DEBUG if verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
