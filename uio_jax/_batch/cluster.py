"""A batch on a Dask cluster: ``uj.batch_analyze(..., client=...)``, ``uio-jax batch --scheduler``.

The :class:`DaskExecutor` is the cluster's :class:`~uio_jax._batch.executor.Executor`; the
driver (order, time limits, rows of stopped models, progress) is the one of the local
pool. What the cluster adds:

* **one model per worker thread**: the executor never submits more models than the
  cluster has worker threads free, so the longest-first order is the caller's (start workers
  with ``--nthreads 1``: a model over its time limit takes its worker process down);
* **time limits**: a model's clock starts when its task starts on a worker (Dask's event
  log). Over the limit, its future is cancelled and its worker process killed; the worker's
  nanny starts a fresh worker, which takes the next model;
* **a worker that dies**: Dask sends its model to another worker, up to the scheduler's
  ``allowed-failures``, then the model is an error row ("worker process died"). A cluster
  left without any worker for :data:`~uio_jax._filter.cluster.NO_WORKER_S` seconds fails the
  models not done;
* **Ctrl-C**: the models still running are cancelled and their workers killed, the rows
  done are kept;
* **one CPU per worker process** (:func:`~uio_jax._filter.cluster.claim_one_cpu`;
  ``UIO_JAX_PIN_WORKERS=0`` on a host turns it off);
* **caches**: each task enables the caller's compilation cache directory on its worker
  (else the worker's own default, ``$UIO_JAX_CACHE_DIR``, else none).

Model files travel as absolute paths: the workers must see them, and the cache, at the same
path (a shared file system).
"""

import os
import queue
import time
import uuid

from .._filter.cluster import NO_WORKER_S, claim_one_cpu, drain_queue, stop_tasks, worker_threads
from .._filter.compile_cache import cache_dir_in_use, default_cache_dir, disable_compile_cache, enable_compile_cache
from .._io.loading import one_line
from .executor import Executor, drive

#: Seconds between two looks at the cluster while nothing happens.
POLL_S = 0.5


def run_on_cluster(entries, todo, client, timeout, analyze_kwargs, tracker):
    """Run ``entries[i]`` for ``i in todo`` (in that order) on the workers of ``client`` (a
    ``distributed.Client``): the driver of :func:`uio_jax._batch.executor.drive` with a
    :class:`DaskExecutor`."""
    drive(DaskExecutor(client, cache_dir_in_use()), entries, todo, timeout, analyze_kwargs, tracker)


class DaskExecutor(Executor):
    """Models as Dask tasks, one per free worker thread (see the module doc).

    Args:
        client: a connected ``distributed.Client``.
        cache_dir: the compilation cache directory the workers use (None: no cache).
    """

    retries_lost = True  # the scheduler re-runs a lost task itself (allowed-failures)

    def __init__(self, client, cache_dir=None):
        self.client = client
        self.cache_dir = cache_dir
        self.topic = f"uio_jax-batch-{uuid.uuid4().hex}"
        self.inbox = queue.Queue()
        self.futures = {}  # i -> Future of the models submitted and not done
        self.where = {}  # i -> address of the worker running it (from its "started" event)
        self.labels = {}
        self._threads, self._asked = 0, -1.0
        self._lonely_since = None
        client.subscribe_topic(self.topic, lambda event: self.inbox.put(tuple(event[1])))

    def _worker_threads(self) -> int:
        now = time.monotonic()
        if now - self._asked >= POLL_S:
            try:
                self._threads = worker_threads(self.client)
            except Exception:  # the scheduler does not answer: as if it had no worker
                self._threads = 0
            self._asked = now
        return self._threads

    def free(self) -> int:
        """Worker threads of the cluster not running one of this batch's models."""
        return max(self._worker_threads() - len(self.futures), 0)

    def submit(self, i, task):
        """Send model ``i`` as a task (its spec made absolute for the workers)."""
        label, spec, kind, kwargs, deferred, options = task
        task = (label, absolute_spec(spec, kind), kind, kwargs, deferred, options)
        fut = self.client.submit(cluster_task, i, task, self.topic, self.cache_dir,
                                 key=f"uio_jax-model-{self.topic[-12:]}-{i}", pure=False)
        self.labels[i] = label
        self.futures[i] = fut
        fut.add_done_callback(lambda f, i=i: self.inbox.put(("done", i, f)))

    def events(self, wait_s):
        """The tasks' events (started, steps) and their results, as driver events."""
        wait_s = POLL_S if wait_s is None else min(wait_s, POLL_S)
        out = []
        for msg in drain_queue(self.inbox, wait_s):
            kind, i = msg[0], msg[1]
            if kind == "done":
                if self.futures.get(i) is msg[2]:
                    del self.futures[i]
                    self.where.pop(i, None)
                    out.append(self._result(i, msg[2]))
            elif i not in self.futures:
                continue  # a model stopped already
            elif kind == "started":
                self.where[i] = msg[2]
                out.append(("started", i))
            elif kind == "step":
                out.append(("step", i, msg[2]))
        out.extend(self._lonely())
        return out

    def _result(self, i, fut):
        """The driver event of a finished future: its row, or its loss."""
        status = fut.status
        if status == "finished":
            try:
                return ("row", i, fut.result())
            except Exception as exc:  # pragma: no cover - finished futures return
                return ("row", i, {"model": self.labels[i], "error": one_line(exc)})
        if status == "cancelled":
            return ("lost", i, "cancelled by the scheduler")
        exc = fut.exception()
        if type(exc).__name__ == "KilledWorker":
            return ("lost", i, "Dask gave up after its workers died running it")
        return ("row", i, {"model": self.labels[i], "error": f"the worker could not run it: {one_line(exc)}"})

    def _lonely(self):
        """A ``failed`` event once the cluster has had no worker (or no scheduler) for
        :data:`NO_WORKER_S` seconds."""
        if self._worker_threads() > 0 and self.client.status == "running":
            self._lonely_since = None
            return []
        now = time.monotonic()
        if self._lonely_since is None:
            self._lonely_since = now
        if now - self._lonely_since < NO_WORKER_S:
            return []
        where = getattr(self.client.scheduler, "address", "the scheduler")
        return [("failed", f"the Dask cluster at {where} had no worker for {NO_WORKER_S:g} s")]

    def kill(self, i):
        """Cancel model ``i`` and kill its worker process (its nanny starts a fresh one)."""
        fut = self.futures.pop(i, None)
        if fut is not None:
            where = self.where.pop(i, None)
            stop_tasks(self.client, [fut], where={where} if where else None)

    def close(self):
        """Stop the models still running (Ctrl-C, a failed cluster) and stop listening."""
        try:
            if self.futures:
                known = set(self.where.values())
                stop_tasks(self.client, list(self.futures.values()),
                           where=known if len(known) == len(self.futures) else None)
            self.futures.clear()
            self.client.unsubscribe_topic(self.topic)
        except Exception:  # pragma: no cover - the client is closed already
            pass


def absolute_spec(spec, kind):
    """``spec`` with its file made absolute (the workers' working directory is theirs)."""
    if spec is None or kind == "system":
        return spec
    if kind == "spec":
        path, sep, name = spec.rpartition(":")
        if sep and path:
            return f"{os.path.abspath(path)}:{name}"
    return os.path.abspath(spec)


def _use_cache(cache_dir):
    """In a worker: the caller's cache directory, else this worker's default one, else none
    (``cache_dir`` None: the caller runs without a cache, so do the workers)."""
    if cache_dir is None:
        if cache_dir_in_use() is not None:
            disable_compile_cache()
        return
    if cache_dir_in_use() == os.path.abspath(cache_dir):
        return
    for path in (cache_dir, default_cache_dir()):
        try:
            enable_compile_cache(path)
            return
        except OSError:
            continue
    disable_compile_cache()


class _Events:
    """The ``conn`` of :func:`uio_jax._batch.workers.worker_run` in a Dask task: each
    ``("step", text)`` goes to the caller through the event log."""

    def __init__(self, worker, topic, i):
        self.worker, self.topic, self.i = worker, topic, i

    def send(self, msg):
        self.worker.log_event(self.topic, [msg[0], self.i, msg[1]])


def cluster_task(i, task, topic, cache_dir):
    """A model in a Dask worker: say it started (with this worker's address), analyse it
    (every decided step sent as an event), return the row's fields (see
    :func:`uio_jax._batch.workers.worker_run`)."""
    from distributed import get_worker

    from .workers import worker_run

    worker = get_worker()
    if worker.state.nthreads == 1:
        claim_one_cpu()  # one CPU per worker process, as the local pool's workers
    _use_cache(cache_dir)
    worker.log_event(topic, ["started", i, worker.address])
    return worker_run(*task, conn=_Events(worker, topic, i))
