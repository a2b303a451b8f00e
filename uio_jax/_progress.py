"""A small progress bar on stderr (no dependency), driven from Python between chunks."""

import sys
import time


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
