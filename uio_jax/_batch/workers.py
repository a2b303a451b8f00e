"""The worker processes of a parallel batch: a pool of spawned processes, one model at a
time each, a fresh worker in place of one killed on timeout or dead.

Each worker is spawned (its own JAX), uses the persistent cache directory of the caller,
and is bound to one CPU when there are several (:func:`~uio_jax._batch.pinning.pin_to_one_cpu`).
It ignores SIGINT (Ctrl-C reaches the whole process group): the parent stops it.

Messages from a worker to the parent: ``"ready"``; ``("step", text)`` for every step its
analysis decides (``"k=5, dim 4/7"``, from :func:`uio_jax._progress.step_listener`), so a
model stopped on timeout says how far it got; then the row's fields (a dict).
"""

import multiprocessing
import signal
import time
from multiprocessing.connection import wait

from .._engine.compile_cache import cache_dir_in_use, enable_compile_cache
from .._progress import step_listener
from .discovery import Entry, Skipped
from .one_model import run_entry
from .pinning import pin_to_one_cpu
from .rows import BatchRow


def run_in_workers(entries, todo, jobs, timeout, analyze_kwargs, tracker):
    """Run ``entries[i]`` for ``i in todo`` (in that order) in ``jobs`` spawned worker
    processes; ``tracker.finish(i, row)`` receives each model's :class:`BatchRow` (or
    :class:`Skipped`), ``tracker.start(i)`` is told when it is sent.

    Each worker takes one model at a time through a pipe (its clock starts when the model is
    sent, after the worker has imported JAX and said it is ready). A model that runs longer
    than ``timeout`` seconds (None: no limit) has its worker killed and gets a row saying
    so; a worker that dies (memory, signal) gives its model a row with the exit code. A
    fresh worker replaces a killed or dead one, so the other models go on; such a row
    names the last step the model's analysis had decided (``row.reached``). Every worker
    is stopped on the way out, Ctrl-C included.
    """
    pool = _Pool(entries, todo, jobs, timeout, analyze_kwargs, tracker)
    try:
        while pool.step():
            pass
    finally:
        pool.close()


class _Pool:
    """The worker slots of one parallel run, the models still to send, and their rows."""

    def __init__(self, entries, todo, jobs, timeout, analyze_kwargs, tracker):
        self.ctx = multiprocessing.get_context("spawn")
        self.cache_dir = cache_dir_in_use()
        self.entries, self.timeout, self.kwargs, self.tracker = entries, timeout, analyze_kwargs, tracker
        self.pending = list(todo)[::-1]  # popped from the end: in order
        self.slots = [None] * min(jobs, len(self.pending))

    def step(self) -> bool:
        """Start workers, send models, handle what the next event brings; False when done."""
        self._feed()
        live = [w for w in self.slots if w is not None and (w.task is not None or not w.ready)]
        if not live:
            return False
        ready = wait([w.conn for w in live], self._wait_s(live))
        for k, w in enumerate(self.slots):
            if w not in live:
                continue
            if w.conn in ready:
                self._receive(k, w)
            elif w.task is not None and self.timeout is not None and w.elapsed() >= self.timeout:
                self._time_out(k, w)
        return True

    def _feed(self):
        """A worker in every empty slot; the next model to every ready idle worker."""
        for k, w in enumerate(self.slots):
            if w is None and self.pending:
                self.slots[k] = w = _Worker(self.ctx, self.cache_dir, k if len(self.slots) > 1 else None)
            if w is not None and w.task is None and w.ready and self.pending:
                i = self.pending.pop()
                e = self.entries[i]
                w.send(i, (e.label, e.spec, e.kind, self.kwargs, e.deferred))
                self.tracker.start(i)

    def _wait_s(self, live):
        """Seconds until the first running model's time limit (None: no limit)."""
        deadlines = [w.since + self.timeout - time.monotonic() for w in live
                     if self.timeout is not None and w.task is not None]
        return max(0.0, min(deadlines)) if deadlines else None

    def _finish(self, i, row):
        self.tracker.finish(i, row)

    def _receive(self, k, w):
        """A message from the worker in slot ``k``: ready, a step, a row, or its death."""
        msg = w.receive()
        if msg is _Worker.DIED:
            self._died(k, w)
        elif msg == "ready":
            w.ready = True
        elif isinstance(msg, tuple) and msg[0] == "step":
            w.reached = msg[1]
        else:
            skip = msg.get("skipped")
            self._finish(w.task, Skipped(self.entries[w.task].spec, skip) if skip else BatchRow(**msg))
            w.task = None

    def _died(self, k, w):
        code = w.stop()
        self.slots[k] = None
        if w.task is not None:
            self._finish(w.task, BatchRow(self.entries[w.task].label, seconds=w.elapsed(),
                                          error=f"worker process died (exit code {code}){w.where()}",
                                          reached=w.reached))
            return
        while self.pending:  # died while starting: the others would too
            i = self.pending.pop()
            self._finish(i, BatchRow(self.entries[i].label,
                                     error=f"batch worker process failed to start (exit code {code})"))

    def _time_out(self, k, w):
        w.stop()
        self.slots[k] = None
        self._finish(w.task, BatchRow(self.entries[w.task].label, seconds=w.elapsed(),
                                      error=f"timed out after {self.timeout:g} s{w.where()} (worker stopped)",
                                      reached=w.reached))

    def close(self):
        """Stop every worker still there."""
        for w in self.slots:
            if w is not None:
                w.close()


class _Worker:
    """One spawned analysis process and the parent's end of its pipe."""

    DIED = object()

    def __init__(self, ctx, cache_dir, slot=None):
        self.conn, there = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(there, cache_dir, slot), daemon=True)
        self.proc.start()
        there.close()
        self.ready = False
        self.task = None  # index of the entry being analysed
        self.reached = None  # the last step its analysis decided ("k=5, dim 4/7")
        self.since = time.monotonic()

    def send(self, i, task):
        """Hand the worker entry ``i`` (its ``task`` tuple); its clock starts now."""
        self.conn.send(task)
        self.task, self.since, self.reached = i, time.monotonic(), None

    def where(self) -> str:
        """`` at order k=5, dim 4/7`` (`` at step m=...`` outside the EORC), or '' before
        the first decided step."""
        if self.reached is None:
            return ""
        return f" at {'order' if self.reached.startswith('k=') else 'step'} {self.reached}"

    def elapsed(self) -> float:
        """Seconds since the current model was sent (or since the worker was started)."""
        return time.monotonic() - self.since

    def receive(self):
        """The worker's next message, or :attr:`DIED` when its pipe is closed."""
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            return self.DIED

    def stop(self):
        """Kill the process; returns its exit code."""
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join()
        self.conn.close()
        return self.proc.exitcode

    def close(self):
        """Ask the process to finish (it is idle), else kill it."""
        try:
            if self.task is None and self.ready:
                self.conn.send(None)
                self.proc.join(timeout=5)
        except (OSError, ValueError):
            pass
        self.stop()


def _worker_main(conn, cache_dir, slot=None):
    """A worker process: set up the caches, say ready, then analyse models until told to stop."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's: it stops this process
    pin_to_one_cpu(slot)
    if cache_dir:
        enable_compile_cache(cache_dir)
    conn.send("ready")
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send(_worker_run(*task, conn=conn))


def step_text(step, n=None) -> str:
    """A decided Step in a few words: ``k=5, dim 4/7`` (``k``: an EORC order, ``m``: a step
    of the other analyses; ``/n`` when the dimension ``n`` is known)."""
    name = "k" if "augmented_rank" in step.extra else "m"
    return f"{name}={step.m}, dim {step.dim}" + (f"/{n}" if n is not None else "")


def _worker_run(label, spec, kind, analyze_kwargs, deferred=False, conn=None) -> dict:
    """Analyse one model in a worker; returns the row's fields (no Report), or
    ``{"skipped": reason}`` for a deferred zoo function that gave no System. Every step
    the analysis decides is sent on ``conn`` as ``("step", step_text)``."""
    n = []

    def send_step(step):
        if conn is not None:
            conn.send(("step", step_text(step, n[0] if n else None)))

    def loaded(system):
        n.append(len(system.states) + len(system.param_names))

    with step_listener(send_step):
        row = run_entry(Entry(label, spec, kind, deferred=deferred), analyze_kwargs, keep_report=False,
                        on_system=loaded)
    if isinstance(row, Skipped):
        return {"skipped": row.why}
    return {k: getattr(row, k) for k in BatchRow.__dataclass_fields__ if k != "report"}
