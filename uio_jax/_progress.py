"""Progress on stderr (no dependency): one bar mechanism (:class:`Progress`, Monte Carlo's
trial-steps; :class:`CountProgress`, a batch's models), and the steps of an analysis as
they are decided."""

import contextlib
import contextvars
import sys
import time

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


class StepPrinter:
    """One line per decided step on ``stream``: ``uio-jax: k=3  dim 6 (+2 generators)  41.2 s``
    (``k`` for EORC orders, ``m`` for the steps of the other analyses; seconds since the
    printer was made). ``enabled=None`` prints only when the stream is a terminal."""

    def __init__(self, *, enabled=None, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = is_terminal(self.stream)
        self.enabled = bool(enabled)
        self.t0 = time.perf_counter()

    def __call__(self, step):
        if not self.enabled:
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
        line = self._line(elapsed, what)
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
    """Progress of ``total`` items, the models of a batch:
    ``batch [###---] 3/12  ETA 40 s  running NAME``.

    ``enabled=None`` shows it only on a terminal (once ``delay`` s have passed); the line is
    redrawn when an item starts and when one ends, and cleared by :meth:`close`. Off a
    terminal (with ``enabled=True``) it writes one line per finished item.
    """

    terminal_only = True
    keep_last_line = False
    bar_width = 20

    def __init__(self, total, *, enabled=None, delay=2.0, stream=None, label="batch"):
        super().__init__(total, enabled=enabled, delay=delay, stream=stream, label=label)
        self.total = int(total)
        self.enabled = self.enabled and total > 0

    def start(self, what):
        """An item named ``what`` starts (drawn only on a terminal, once the bar is due)."""
        self._show(f"running {what}", event=False)

    def finish(self, what=None):
        """An item (named ``what``) is done."""
        self.done += 1
        self._show(f"done {what}" if what else "", event=True)

    def _line(self, elapsed, what) -> str:
        eta = f"  ETA {elapsed / self.done * (self.total - self.done):4.0f} s" if self.done else ""
        line = f"{self.label} [{self._bar(self.done / self.total)}] {self.done}/{self.total}{eta}  {what}"
        return line[:110]
