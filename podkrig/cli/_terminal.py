"""What the command line prints while and after it works: consoles and progress.

- :func:`console`: the rich console of a command's output. On a terminal rich fits tables to the
  window; anywhere else (a pipe, a file, a batch job's log, a test runner) rich would assume 80
  columns and cut table cells (``+0.25…``) and wrap lines, so the console is as wide as the
  widest line: tables print whole.
- :class:`Progress`: the one progress display of the command line. On a terminal a rich bar on
  stderr; anywhere else, where a bar cannot be redrawn, a plain line on stderr at least every
  :data:`LINE_INTERVAL_S` seconds — the task, its count done, its elapsed time — whether or not
  the work reported progress in between (a heartbeat thread), so a log shows the job is alive.
  Every command runs inside one (``user_errors`` in :mod:`podkrig.cli._common`: ``podkrig: 40 s
  elapsed``); the commands that report progress (``run``, ``demo``, ``snapshots
  run``, ``sensors``, ``diagnose``) open their own inside it, which then speaks for them.
"""

import sys
import threading
import time

#: the longest a command that is not on a terminal stays silent while it works, s: a progress line
#: is written once this much time has passed since the last line (checked every
#: :data:`HEARTBEAT_S`), so lines are at most ``LINE_INTERVAL_S + HEARTBEAT_S`` = 21 s apart
LINE_INTERVAL_S = 20.0
#: how often the heartbeat thread looks at the clock, s
HEARTBEAT_S = 1.0
#: the width of a console that is not a terminal, characters: no table of podkrig comes near it
WIDE = 10_000

#: the plain-line displays whose blocks are running, innermost last: a command's own display (e.g.
#: the stages of ``podkrig run``) inside the heartbeat every command gets from ``user_errors``;
#: only the innermost writes heartbeat lines, and a line of any of them counts for all
_ACTIVE = []


def console(stderr=False, highlight=True):
    """The rich console of a command: rich's own on a terminal, :data:`WIDE` columns elsewhere so
    that tables print whole and lines are not wrapped (the stream is looked up when printing, as
    rich does: a test runner's capture gets the output). ``highlight``: rich's number and
    keyword colouring."""
    from rich.console import Console  # local: rich costs import time that `--help` need not pay

    plain = Console(stderr=stderr, highlight=highlight)
    return plain if plain.is_terminal else Console(stderr=stderr, highlight=highlight, width=WIDE)


def _seconds(s):
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class Progress:
    """Progress of a long command on stderr; a context manager (see the module docstring).

    Parameters
    ----------
    task : str
        What runs until the first :meth:`update` names a task (e.g. ``"sensors"``).
    rate : str or None
        Unit of a rate to show, e.g. ``"snapshots/s"`` (done per second of the task).
    terminal : bool or None
        Draw a rich bar (True) or plain lines (False); None: a bar when stderr is a terminal.
    stream : file or None
        Where plain lines go (default: ``sys.stderr`` at the time of writing).
    clock : callable
        Seconds, monotonic (tests pass a fake one).
    interval : float or None
        Seconds between lines; None: :data:`LINE_INTERVAL_S`.
    """

    def __init__(self, task, *, rate=None, terminal=None, stream=None, clock=time.monotonic, interval=None):
        self._console = console(stderr=True)
        self.terminal = self._console.is_terminal if terminal is None else terminal
        self._stream, self._clock, self._rate = stream, clock, rate
        self.interval = LINE_INTERVAL_S if interval is None else interval
        self._lock = threading.Lock()
        self._idle = self._task = task
        self._done, self._total = 0, None
        self._started = self._last = clock()
        self._bar = self._bar_task = None
        self._stop = threading.Event()
        self._thread = None

    # --- the command's side -------------------------------------------------------------------
    def __enter__(self):
        if not self.terminal:
            _ACTIVE.append(self)
            self._thread = threading.Thread(target=self._beat, name="podkrig-progress", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, *exc):
        self.stop()
        return False

    def __call__(self, task, done, total=None):
        """The callback form of :meth:`update` (``progress(stage, done, total)``)."""
        self.update(task, done, total)

    def update(self, task, done, total=None):
        """``done`` of ``total`` (None: unknown) units of ``task`` are finished."""
        with self._lock:
            if task != self._task:
                self._task, self._started = task, self._clock()
                if self._bar is not None:
                    self._bar.stop()
                    self._bar = None
            self._done, self._total = done, total
        if self.terminal:
            self._draw()
        else:
            self.tick()

    def print(self, text):
        """A line that stays (e.g. a finished stage): above the bar, or as a plain line."""
        if self.terminal:
            self._console.print(text, markup=False, highlight=False)
            return
        with self._lock:
            self._write(text)

    def finish(self, text=None):
        """The running task is over: its bar disappears, ``text`` (e.g. what it did) is printed,
        and until the next :meth:`update` the progress lines name the command's own task."""
        with self._lock:
            if self._bar is not None:
                self._bar.stop()
                self._bar = None
            self._task, self._done, self._total, self._started = self._idle, 0, None, self._clock()
        if text is not None:
            self.print(text)

    def stop(self):
        """End the display (idempotent): the bar disappears, the heartbeat ends."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        if self in _ACTIVE:
            _ACTIVE.remove(self)
        if self._bar is not None:
            self._bar.stop()
            self._bar = None

    # --- plain lines --------------------------------------------------------------------------
    def line(self):
        """The progress line of the running task: ``TASK: DONE/TOTAL (P %), RATE, ELAPSED``."""
        elapsed = self._clock() - self._started
        count = "" if self._total is None else f"{self._done}/{self._total}"
        if self._total:
            count += f" ({100 * self._done / self._total:.0f} %)"
        rate = f"{self._done / elapsed:.1f} {self._rate}" if self._rate and self._done and elapsed > 0 else ""
        return f"{self._task}: " + ", ".join(p for p in (count, rate, f"{_seconds(elapsed)} elapsed") if p)

    def tick(self):
        """Write the progress line when :attr:`interval` has passed since the last line (the
        heartbeat calls this every :data:`HEARTBEAT_S`, :meth:`update` at every report)."""
        if self in _ACTIVE and _ACTIVE[-1] is not self:  # an inner display speaks for the command
            return
        with self._lock:
            if self._clock() - self._last >= self.interval:
                self._write(self.line())

    def _write(self, text):
        stream = self._stream or sys.stderr
        stream.write(text + "\n")
        stream.flush()
        for display in [self, *_ACTIVE]:
            display._last = display._clock()

    def _beat(self):
        while not self._stop.wait(HEARTBEAT_S):
            self.tick()

    # --- the bar ------------------------------------------------------------------------------
    def _draw(self):
        from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn, TimeRemainingColumn
        from rich.progress import Progress as Bar

        if self._bar is None:
            columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn()]
            if self._rate:
                columns.append(TextColumn("{task.fields[rate]}"))
            columns += [TimeElapsedColumn(), TextColumn("ETA"), TimeRemainingColumn()]
            self._bar = Bar(*columns, console=self._console, transient=True)
            self._bar_task = self._bar.add_task(self._task, total=self._total, rate="")
            self._bar.start()
        elapsed = self._clock() - self._started
        rate = f"{self._done / elapsed:.1f} {self._rate}" if self._rate and elapsed > 0 else ""
        self._bar.update(self._bar_task, completed=self._done, total=self._total, rate=rate)

