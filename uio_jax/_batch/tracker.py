"""The state of a running batch: which models are done, the progress display, and the
partial result handed to ``on_row`` after every finished model (and kept on Ctrl-C)."""

import time

from .discovery import Skipped
from .rows import BatchResult, BatchRow, verdict


class Tracker:
    """Rows of a batch as they finish.

    Args:
        entries: the batch's :class:`~uio_jax._batch.discovery.Entry` list (labels only are kept).
        skipped: ``(name, reason)`` known before any model runs.
        bar: a :class:`uio_jax._progress.CountProgress` keyed by entry index.
        options: the analysis options (for the result).
        on_row: None, or called with the partial :class:`BatchResult` after each finished
            model (``partial`` says how many of how many are done).
    """

    def __init__(self, entries, skipped, bar, options, on_row=None):
        self.labels = [e.label for e in entries]
        self.rows = [None] * len(entries)
        self.skipped = list(skipped)
        self.bar, self.options, self.on_row = bar, options, on_row
        self.t0 = time.perf_counter()

    def start(self, i):
        """Model ``i`` starts (in this process or in a worker)."""
        self.bar.start(self.labels[i], key=i)

    def finish(self, i, row):
        """Model ``i`` is done: its :class:`BatchRow` (or :class:`Skipped`)."""
        self.rows[i] = row
        if isinstance(row, BatchRow):
            self.bar.finish(self.labels[i], verdict(row), row.seconds, key=i)
        else:
            self.bar.finish(self.labels[i], f"skipped: {row.why}", key=i)
        if self.on_row is not None:
            self.on_row(self.result(f"running: {self.done} of {len(self.rows)} models done"
                                    if self.done < len(self.rows) else None))

    @property
    def done(self) -> int:
        """Models finished so far."""
        return sum(r is not None for r in self.rows)

    def result(self, partial=None) -> BatchResult:
        """The :class:`BatchResult` of the models finished so far, in the given order
        (deferred zoo functions that gave no System move to ``skipped``); ``partial``:
        None for a complete batch, else why it is not."""
        rows = [r for r in self.rows if isinstance(r, BatchRow)]
        late = [(r.spec, r.why) for r in self.rows if isinstance(r, Skipped)]
        return BatchResult(tuple(rows), tuple(self.skipped + late), time.perf_counter() - self.t0,
                           dict(self.options), partial)
