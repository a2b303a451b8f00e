"""The worker processes of a parallel batch on one machine: a pool of spawned processes, one
model at a time each, a fresh worker in place of one killed on timeout or dead; an
:class:`~uio_jax._batch.executor.Executor`. Each worker is spawned (its own JAX), uses the
caller's persistent cache directory, is bound to one CPU when there are several, and ignores
SIGINT (the parent stops it).

Messages from a worker to the parent: ``"ready"``; ``("step", text)`` for every step its
analysis decides (``"k=5, dim 4/7"``, from :func:`uio_jax._progress.step_listener`), so a
model stopped on timeout says how far it got; then the row's fields (a dict).
"""

import contextlib
import multiprocessing
import os
import signal
import sys
from multiprocessing.connection import wait

from .._filter.compile_cache import cache_dir_in_use, enable_compile_cache
from .._progress import step_listener
from .discovery import Entry, Skipped
from .executor import Executor, drive
from .one_model import run_entry
from .pinning import pin_to_one_cpu
from .rows import BatchRow


def run_in_workers(entries, todo, jobs, timeout, analyze_kwargs, tracker):
    """Run ``entries[i]`` for ``i in todo`` (in that order) in ``jobs`` spawned worker
    processes, by the driver :func:`uio_jax._batch.executor.drive` (its docstring: rows,
    time limits, lost workers, Ctrl-C). Each worker takes one model at a time through a pipe;
    its clock starts when the model is sent, after the worker has imported JAX and said ready.
    """
    drive(ProcessPool(min(jobs, len(todo))), entries, todo, timeout, analyze_kwargs, tracker)


class ProcessPool(Executor):
    """The :class:`~uio_jax._batch.executor.Executor` of one machine: ``jobs`` spawned
    worker processes (started on demand), one model at a time each, each bound to one CPU
    when there are several; a killed or dead worker is replaced by a fresh one."""

    def __init__(self, jobs, cache_dir=None):
        self.ctx = multiprocessing.get_context("spawn")
        self.cache_dir = cache_dir if cache_dir is not None else cache_dir_in_use()
        self.slots = [None] * max(int(jobs), 1)
        self.held = {}  # slot -> (i, task) submitted before its worker was ready
        self.queued = []  # events produced outside events() (a model sent on "ready")

    def free(self) -> int:
        """Slots without a model (their worker is started when a model comes)."""
        return sum(w is None or (w.task is None and k not in self.held) for k, w in enumerate(self.slots))

    def submit(self, i, task):
        """Hand model ``i`` to the first free slot (a worker is started there if needed);
        it is sent as soon as the worker is ready."""
        k = next(k for k, w in enumerate(self.slots) if w is None or (w.task is None and k not in self.held))
        if self.slots[k] is None:
            self.slots[k] = _Worker(self.ctx, self.cache_dir, k if len(self.slots) > 1 else None)
        self.held[k] = (i, task)
        self._send_held(k)

    def _send_held(self, k):
        w = self.slots[k]
        if k in self.held and w is not None and w.ready and w.task is None:
            i, task = self.held.pop(k)
            w.send(i, task)
            self.queued.append(("started", i))

    def events(self, wait_s):
        """Messages of the workers (ready, steps, rows) and their deaths, as events."""
        out, self.queued = self.queued, []
        live = [w for w in self.slots if w is not None]
        if out or not live:
            wait_s = 0.0
        ready = wait([w.conn for w in live], wait_s)
        for k, w in enumerate(self.slots):
            if w is None or w.conn not in ready:
                continue
            msg = w.receive()
            if msg is _Worker.DIED:
                out.extend(self._died(k, w))
            elif msg == "ready":
                w.ready = True
                self._send_held(k)
            elif isinstance(msg, tuple) and msg[0] == "step":
                out.append(("step", w.task, msg[1]))
            else:
                out.append(("row", w.task, msg))
                w.task = None
        out.extend(self.queued)
        self.queued = []
        return out

    def _died(self, k, w):
        code = w.stop()
        self.slots[k] = None
        if w.task is not None:
            return [("lost", w.task, f"exit code {code}")]
        if not w.ready:  # died while starting: the others would too
            self.held.pop(k, None)
            return [("failed", f"batch worker process failed to start (exit code {code})")]
        return []

    def kill(self, i):
        """Kill the worker running model ``i``; its slot gets a fresh worker for the next model."""
        for k, w in enumerate(self.slots):
            if w is not None and w.task == i:
                w.stop()
                self.slots[k] = None

    def close(self):
        """Stop every worker still there."""
        for w in self.slots:
            if w is not None:
                w.close()
        self.slots = [None] * len(self.slots)
        self.held.clear()


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

    def send(self, i, task):
        """Hand the worker entry ``i`` (its ``task`` tuple)."""
        self.conn.send(task)
        self.task = i

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
    # what models print is not the parent's table (its stdout)
    with contextlib.redirect_stdout(sys.stderr):
        _serve(conn)


def _serve(conn):
    """Say ready, then analyse the models the parent sends until told to stop."""
    conn.send("ready")
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        try:
            conn.send(worker_run(*task, conn=conn))
        except OSError:  # the parent is gone (killed, SIGTERM): no one to report to, no traceback
            return


def step_text(step, n=None) -> str:
    """A decided Step in a few words: ``k=5, dim 4/7`` (``k``: an EORC order, ``m``: a step
    of the other analyses; ``/n`` when the dimension ``n`` is known)."""
    name = "k" if "augmented_rank" in step.extra else "m"
    return f"{name}={step.m}, dim {step.dim}" + (f"/{n}" if n is not None else "")


def worker_run(label, spec, kind, analyze_kwargs, deferred=False, options=None, conn=None) -> dict:
    """Analyse one model in a worker; returns the row's fields (no Report), or
    ``{"skipped": reason}`` for a deferred zoo function that gave no System. Every step
    the analysis decides is sent on ``conn`` as ``("step", step_text)``."""
    n = []

    def send_step(step):
        if conn is not None:
            try:
                conn.send(("step", step_text(step, n[0] if n else None)))
            except OSError:  # the parent is gone: stop the analysis it can no longer receive
                os._exit(0)

    def loaded(system):
        n.append(len(system.states) + len(system.param_names))

    with step_listener(send_step):
        row = run_entry(Entry(label, spec, kind, deferred=deferred, options=options), analyze_kwargs,
                        keep_report=False, on_system=loaded)
    if isinstance(row, Skipped):
        return {"skipped": row.why}
    return {k: getattr(row, k) for k in BatchRow.__dataclass_fields__ if k != "report"}
