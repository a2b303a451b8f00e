"""One driver for a batch's models in other processes, whatever runs them: the local pool of
worker processes (:class:`uio_jax._batch.workers.ProcessPool`, ``jobs``) or the workers of a
Dask cluster (:class:`uio_jax._batch.cluster.DaskExecutor`, ``client``).

An executor runs one model per worker at a time and reports what happens as events; the
driver (:func:`drive`) owns the rest, the same for both: the order (longest recorded time
first, given by the caller), the time limit of each model counted from the moment it
starts on its worker, the rows of models stopped or lost, and progress.

Events (tuples) an executor returns from :meth:`Executor.events`:

* ``("started", i)``: model ``i`` began running on a worker now (its clock starts; a
  model run again after its worker died starts again);
* ``("step", i, text)``: its analysis decided a step (``"k=5, dim 4/7"``);
* ``("row", i, fields)``: it finished: the :class:`~uio_jax.BatchRow` fields (no report),
  or ``{"skipped": why}`` for a zoo function that gave no System;
* ``("lost", i, why)``: its worker died under it (``why``: ``"exit code -9"``);
* ``("failed", why)``: no worker can be started at all: every model not finished fails.
"""

import time
from collections import deque

from .discovery import Skipped
from .rows import BatchRow

#: A model whose worker dies under it is sent once more (to a fresh or another worker)
#: before its row reports the death, unless the executor's engine retries on its own
#: (:attr:`Executor.retries_lost`).
RETRIES = 1


class Executor:
    """What the driver needs from whatever runs the models: free worker slots, submit,
    events, kill one model (its worker is replaced), close."""

    #: The engine itself sends a model whose worker died to another worker (Dask does, up
    #: to its ``allowed-failures``); ``lost`` is then final and the driver does not retry.
    retries_lost = False

    def free(self) -> int:
        """How many more models can start now (idle worker slots)."""
        raise NotImplementedError

    def submit(self, i, task):
        """Run model ``i``: ``task = (label, spec, kind, analyze_kwargs, deferred, options)``."""
        raise NotImplementedError

    def events(self, wait_s):
        """Events (see the module doc) that arrived, waiting up to ``wait_s`` seconds for
        the first (None: until one arrives)."""
        raise NotImplementedError

    def kill(self, i):
        """Stop model ``i`` now: its worker process is killed and a fresh one takes its place."""
        raise NotImplementedError

    def close(self):
        """Stop every model still running and release the workers (also after Ctrl-C)."""
        raise NotImplementedError


class _Run:
    """A submitted model: when it started (None: not yet), the last step it reached."""

    __slots__ = ("since", "reached")

    def __init__(self):
        self.since = None
        self.reached = None

    def where(self) -> str:
        """`` at order k=5, dim 4/7`` (`` at step m=...`` outside the EORC), or '' before
        the first decided step."""
        if self.reached is None:
            return ""
        return f" at {'order' if self.reached.startswith('k=') else 'step'} {self.reached}"

    def elapsed(self) -> float:
        """Seconds since the model started (0 before it started)."""
        return 0.0 if self.since is None else time.monotonic() - self.since


def drive(executor, entries, todo, timeout, analyze_kwargs, tracker, *, retries=RETRIES):
    """Run ``entries[i]`` for ``i in todo`` (in that order) on ``executor``.

    ``tracker.start(i)`` is told when model ``i`` starts on a worker, ``tracker.finish(i,
    row)`` receives its :class:`~uio_jax.BatchRow` (or :class:`Skipped`). A model running
    longer than ``timeout`` seconds (None: no limit) is killed with its worker and its row
    says "timed out after S s at order k=..."; a model whose worker dies is sent once more
    (``retries``), then its row says "worker process died". The executor is closed on the
    way out, Ctrl-C included (it stops the models still running).
    """
    pending = deque(todo)
    runs = {}  # i -> _Run of the models submitted and not finished
    tries = {}
    try:
        while pending or runs:
            while pending and executor.free() > 0:
                i = pending.popleft()
                e = entries[i]
                executor.submit(i, (e.label, e.spec, e.kind, analyze_kwargs, e.deferred, e.options))
                runs[i] = _Run()
            for event in executor.events(_wait_s(runs, timeout)):
                kind, rest = event[0], event[1:]
                if kind == "failed":
                    for i in [*runs, *pending]:
                        tracker.finish(i, BatchRow(entries[i].label, error=rest[0]))
                    runs.clear()
                    pending.clear()
                    break
                i = rest[0]
                run = runs.get(i)
                if run is None:  # a late event of a model stopped already
                    continue
                if kind == "started":
                    run.since, run.reached = time.monotonic(), None
                    tracker.start(i)
                elif kind == "step":
                    run.reached = rest[1]
                elif kind == "row":
                    del runs[i]
                    skip = rest[1].get("skipped")
                    tracker.finish(i, Skipped(entries[i].spec, skip) if skip else BatchRow(**rest[1]))
                elif kind == "lost":
                    del runs[i]
                    tries[i] = tries.get(i, 0) + 1
                    if not executor.retries_lost and tries[i] <= retries:
                        pending.appendleft(i)  # next, on a fresh worker
                        continue
                    again = " twice" if tries[i] > 1 and not executor.retries_lost else ""
                    tracker.finish(i, BatchRow(entries[i].label, seconds=run.elapsed(),
                                               error=f"worker process died{again} ({rest[1]}){run.where()}",
                                               reached=run.reached))
            if timeout is not None:
                for i, run in list(runs.items()):
                    if run.since is not None and run.elapsed() >= timeout:
                        executor.kill(i)
                        del runs[i]
                        tracker.finish(i, BatchRow(
                            entries[i].label, seconds=run.elapsed(), reached=run.reached,
                            error=f"timed out after {timeout:g} s{run.where()} (worker stopped)"))
    finally:
        executor.close()


def _wait_s(runs, timeout):
    """Seconds until the first running model's time limit (None: no limit)."""
    if timeout is None:
        return None
    left = [timeout - r.elapsed() for r in runs.values() if r.since is not None]
    return max(0.0, min(left)) if left else None
