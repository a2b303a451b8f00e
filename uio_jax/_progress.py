"""Progress on stderr (no dependency): a bar driven from Python between chunks, and the
steps of an analysis as they are decided."""

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
    """Progress of ``total`` trial-steps, shown only once a run has lasted ``delay`` s.

    Args:
        total: trial-steps of the whole run.
        enabled: ``False`` silences it; ``None`` shows it only on a terminal-like stream
            (anything with ``write``) once ``delay`` seconds have passed.
        delay: seconds before the bar appears (short runs print nothing).
        stream: where to write (default ``sys.stderr``).
    """

    def __init__(self, total, *, enabled=None, delay=3.0, stream=None, label="montecarlo"):
        self.total = max(int(total), 1)
        self.enabled = enabled is not False
        self.delay = float(delay)
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.start = time.perf_counter()
        self.done = 0
        self.shown = False

    def update(self, steps):
        """Add ``steps`` trial-steps and redraw if the bar is visible."""
        self.done += int(steps)
        elapsed = time.perf_counter() - self.start
        if not self.enabled or (elapsed < self.delay and not self.shown):
            return
        self.shown = True
        frac = min(self.done / self.total, 1.0)
        rate = self.done / max(elapsed, 1e-9)
        eta = (self.total - self.done) / rate if rate > 0 else float("inf")
        width = 28
        fill = int(round(frac * width))
        bar = "#" * fill + "-" * (width - fill)
        self.stream.write(f"\r{self.label} [{bar}] {100 * frac:5.1f}%  "
                          f"{rate / 1e6:6.2f} M trial-steps/s  ETA {eta:5.1f} s ")
        self.stream.flush()

    def close(self):
        """End the bar's line (if it was shown)."""
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
