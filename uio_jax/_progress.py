"""Progress on stderr (no dependency): one bar mechanism (:class:`Progress`, Monte Carlo's
trial-steps; :class:`CountProgress`, a batch's models), and the steps of an analysis as
they are decided."""

import contextlib
import contextvars
import sys
import threading
import time

from ._output import printable

_STEP_LISTENER = contextvars.ContextVar("uio_jax_step_listener", default=None)


@contextlib.contextmanager
def step_listener(fn):
    """Call ``fn(step)`` with every :class:`~uio_jax.Step` an analysis decides in the block
    (ORC, single_ui and series steps m, EORC orders k), as soon as it is decided."""
    token = _STEP_LISTENER.set(fn)
    try:
        yield
    finally:
        _STEP_LISTENER.reset(token)


def is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal (progress displays default to on only there)."""
    return bool(getattr(stream, "isatty", lambda: False)())


def announce_step(step):
    """Hand a freshly decided Step to the listener of :func:`step_listener`, if any."""
    fn = _STEP_LISTENER.get()
    if fn is not None:
        fn(step)
    return step


#: Seconds of a run after which its steps are printed off a terminal (:class:`StepPrinter`).
OFF_TERMINAL_AFTER = 5.0


class StepPrinter:
    """One line per decided step on ``stream``: ``uio-jax: k=3  dim 6 (+2 generators)  41.2 s``
    (``k`` for EORC orders, ``m`` for the steps of the other analyses; seconds since the
    printer was made). ``enabled=None``: every step on a terminal; on another stream (a log,
    a pipe) the steps decided once the run has lasted :data:`OFF_TERMINAL_AFTER` seconds, so
    that long work shows where it is and short runs print nothing."""

    def __init__(self, *, enabled=None, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        self.after = 0.0 if enabled or is_terminal(self.stream) else OFF_TERMINAL_AFTER
        self.enabled = enabled is None or bool(enabled)
        self.t0 = time.perf_counter()

    def __call__(self, step):
        if not self.enabled or time.perf_counter() - self.t0 < self.after:
            return
        name = "k" if "augmented_rank" in step.extra else "m"
        added = len(step.added)
        self.stream.write(f"uio-jax: {name}={step.m}  dim {step.dim} "
                          f"(+{added} generator{'' if added == 1 else 's'})  "
                          f"{time.perf_counter() - self.t0:.1f} s\n")
        self.stream.flush()


class Progress:
    """A progress bar on stderr: the mechanism of every bar of the package, and the bar of
    ``total`` trial-steps of a Monte Carlo run.

    The bar appears once the work has lasted ``delay`` seconds (short runs print nothing).
    On a terminal it is one line redrawn in place; on any other stream (a log, a pipe) it
    is one finished line per event (here: per :meth:`update`), never a carriage return.

    Args:
        total: trial-steps of the whole run.
        enabled: ``False`` silences it, ``True`` shows it; ``None`` shows it on any stream
            (subclasses may show it only on a terminal, :attr:`terminal_only`).
        delay: seconds before the bar appears.
        stream: where to write (default ``sys.stderr``).
        label: the line's first word.
    """

    #: ``enabled=None`` shows the bar only when the stream is a terminal.
    terminal_only = False
    #: On a terminal, ``close`` leaves the last line (True) or clears it (False).
    keep_last_line = True
    #: Characters of the bar itself.
    bar_width = 28

    def __init__(self, total, *, enabled=None, delay=3.0, stream=None, label="montecarlo"):
        self.total = max(int(total), 1)
        self.stream = stream if stream is not None else sys.stderr
        self.terminal = is_terminal(self.stream)
        if enabled is None:
            enabled = self.terminal or not self.terminal_only
        self.enabled = bool(enabled)
        self.delay = float(delay)
        self.label = label
        self.t0 = time.perf_counter()
        self.done = 0
        self.shown = False
        self._width = 0

    def update(self, steps):
        """Add ``steps`` trial-steps and redraw if the bar is visible."""
        self.done += int(steps)
        self._show("", event=True)

    def _show(self, what, *, event):
        """Draw the line once the bar is due; off a terminal only for an ``event``."""
        elapsed = time.perf_counter() - self.t0
        if not self.enabled or (not self.shown and elapsed < self.delay):
            return
        self.shown = True
        line = printable(self._line(elapsed, what))  # model names from files: made inert
        if self.terminal:
            self.stream.write("\r" + line.ljust(self._width))
            self._width = len(line)
        elif event:
            self.stream.write(line.rstrip() + "\n")
        else:
            return
        self.stream.flush()

    def _bar(self, frac) -> str:
        fill = int(round(frac * self.bar_width))
        return "#" * fill + "-" * (self.bar_width - fill)

    def _line(self, elapsed, what) -> str:
        """``label [###---]  45.0%  1.23 M trial-steps/s  ETA 3.0 s``."""
        frac = min(self.done / self.total, 1.0)
        rate = self.done / max(elapsed, 1e-9)
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        return (f"{self.label} [{self._bar(frac)}] {100 * frac:5.1f}%  "
                f"{rate / 1e6:6.2f} M trial-steps/s  ETA {eta:5.1f} s ")

    def close(self):
        """End the bar: on a terminal, end its line (or clear it); elsewhere nothing is left."""
        if not (self.shown and self.terminal):
            return
        self.stream.write("\n" if self.keep_last_line else "\r" + " " * self._width + "\r")
        self.stream.flush()


class CountProgress(Progress):
    """Progress of ``total`` items, the models of a batch, with an ETA.

    * On a terminal: ``batch [###---] 3/12  ETA 40 s  running NAME 12 s``, one line redrawn
      when an item starts or ends and every ``tick`` seconds in between (a background
      thread, so the ETA and the running time move while one long item runs), once the
      batch has lasted ``delay`` s; :meth:`close` clears it.
    * Anywhere else (a log, a pipe): one line per finished item, from the first one:
      ``batch 3/12  NAME  dim 4/7  2.3 s  ETA 40 s`` (never a carriage return).

    **ETA.** Each item's expected time is ``expected[key]`` (seconds recorded by an earlier
    run; items are keyed by their index ``0..total-1``), else the mean time of the items
    finished so far, else (nothing finished yet) the elapsed time of the longest running
    one. A running item is expected to need at least as long again as it has run so far
    (``remaining = max(expected - elapsed, elapsed)``), so the ETA grows while an item
    runs past its estimate instead of freezing. The work left (running items' remaining
    plus the waiting items' expected times) is shared by ``workers`` processes: ETA =
    ``max(longest running remaining, work / workers)``. No ETA is shown when nothing is
    known yet.

    Args:
        total: number of items.
        enabled: ``False`` silences it; ``True`` or ``None`` shows it (bar on a terminal,
            lines elsewhere).
        delay: seconds before the terminal bar appears (the lines of a log do not wait).
        stream: where to write (default ``sys.stderr``).
        label: the line's first word.
        expected: expected seconds of item ``k`` at index ``k`` (None: unknown), or None.
        workers: items that run at the same time (processes of a parallel batch).
        tick: seconds between two redraws of the terminal bar.
    """

    terminal_only = False
    keep_last_line = False
    bar_width = 20

    def __init__(self, total, *, enabled=None, delay=2.0, stream=None, label="batch", expected=None,
                 workers=1, tick=1.0):
        super().__init__(total, enabled=enabled, delay=delay, stream=stream, label=label)
        self.total = int(total)
        self.enabled = self.enabled and total > 0
        if not self.terminal:
            self.delay = 0.0
        self.expected = list(expected) if expected is not None else []
        self.workers = max(int(workers), 1)
        self.tick = float(tick)
        self.running = {}  # key -> (name, start time)
        self.started = set()
        self.finished_s = []
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._ticker = None

    def start(self, what, key=None):
        """Item ``key`` (default: its name ``what``) starts; redraws the terminal bar."""
        key = what if key is None else key
        with self._lock:
            self.running[key] = (what, time.perf_counter())
            self.started.add(key)
            self._show(self._running_text(), event=False)
        if self.enabled and self.terminal and self._ticker is None:
            self._ticker = threading.Thread(target=self._tick, name="uio_jax-progress", daemon=True)
            self._ticker.start()

    def finish(self, what=None, verdict="", seconds=None, key=None):
        """Item ``key`` (default: its name ``what``) is done: its outcome ``verdict`` (e.g.
        ``dim 4/7``) and time ``seconds`` (default: measured since :meth:`start`)."""
        key = what if key is None else key
        with self._lock:
            name, since = self.running.pop(key, (what, None))
            if seconds is None and since is not None:
                seconds = time.perf_counter() - since
            if seconds is not None:
                self.finished_s.append(float(seconds))
            self.started.add(key)
            self.done += 1
            if self.terminal:
                self._show(self._running_text() or (f"done {name}" if name else ""), event=True)
            else:
                parts = [p for p in (name, verdict, None if seconds is None else f"{seconds:.1f} s") if p]
                self._show("  ".join(parts), event=True)

    def eta(self, now=None):
        """Estimated seconds until every item is done (see the class doc), or None."""
        now = time.perf_counter() if now is None else now
        with self._lock:
            running = [(k, now - t) for k, (_, t) in self.running.items()]
            mean = sum(self.finished_s) / len(self.finished_s) if self.finished_s else None
            fallback = mean if mean is not None else max((t for _, t in running), default=None)

            def guess(key):
                known = self.expected[key] if isinstance(key, int) and 0 <= key < len(self.expected) else None
                return known if known is not None else fallback

            lefts = [max((guess(k) or 0.0) - t, t) for k, t in running]
            if self.expected:
                waiting = [guess(k) for k in range(self.total) if k not in self.started]
            else:
                waiting = [fallback] * max(self.total - len(self.started), 0)
            if any(w is None for w in waiting):
                return None
            if not lefts and not waiting:
                return 0.0
            return max(max(lefts, default=0.0), (sum(lefts) + sum(waiting)) / self.workers)

    def _running_text(self) -> str:
        """``running NAME 12 s`` of the longest running item ('' when none runs)."""
        if not self.running:
            return ""
        name, since = min(self.running.values(), key=lambda v: v[1])
        more = f" (+{len(self.running) - 1})" if len(self.running) > 1 else ""
        return f"running {name} {time.perf_counter() - since:.0f} s{more}"

    def _tick(self):
        while not self._stop.wait(self.tick):
            with self._lock:
                if self.running:
                    self._show(self._running_text(), event=False)

    def _line(self, elapsed, what) -> str:
        left = self.eta() if self.done < self.total else None
        eta = f"  ETA {format_seconds(left)}" if left is not None else ""
        if not self.terminal:
            return f"{self.label} {self.done}/{self.total}  {what}{eta}"
        line = f"{self.label} [{self._bar(self.done / self.total)}] {self.done}/{self.total}{eta}  {what}"
        return line[:110]

    def close(self):
        """Stop the redraws and clear the terminal bar."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join()
        with self._lock:
            super().close()


def format_seconds(s: float) -> str:
    """``42 s``, ``4.5 min`` or ``2.1 h``: a duration in seconds, for a progress line."""
    if s < 100:
        return f"{s:.0f} s"
    if s < 6000:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"
