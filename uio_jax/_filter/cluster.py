"""A Dask cluster for the Monte Carlo trials (and the connection the batch shares).

**Connecting** (:func:`cluster_client`): ``client`` is a ``distributed.Client`` (used as
it is, left open) or a scheduler address (``tcp://host:8786``; a client is opened for the
run and closed after). An address is checked before anything is sent: its form, that
something listens there, that it is a Dask scheduler; each failure is one
:class:`~uio_jax.OptionError` line. Dask distributed is the optional extra
``pip install "uio_jax[cluster]"``; without it a cluster run is refused in one line.

**Monte Carlo over the workers** (:func:`run_trials_on_cluster`): the trials ``0..B-1`` are
cut into one contiguous shard per worker thread of the cluster, all of the same size (the
last one padded), so every worker compiles one program. A shard runs
:func:`uio_jax._filter.trials.simulate_trials` on the worker's own JAX devices: trial ``i``
uses the key ``fold_in(key(seed), i)`` wherever it runs, so the records are those of a
one-process run with the same seed, bit for bit. The caller puts the shards' float32 records
in trial order and computes every statistic once over all trials (nothing is an average of
averages). The worker that runs trial 0 also computes the ``keep`` full trajectories; each
worker reports its trial-steps after every chunk (Dask's event log) to one progress bar.

**Why not ``jax.distributed``**: it runs one SPMD program across hosts launched in lockstep,
for collectives between devices; trials are independent and only their records travel.

The experiment travels to the workers pickled by value (its functions and the model file
they come from, ``cloudpickle``): the workers need uio_jax and jax, not the model file.
"""

import asyncio
import contextlib
import hashlib
import math
import os
import pickle
import queue
import socket
import sys
import tempfile
import time
import uuid

import numpy as np

from .._errors import OptionError, UioJaxError
from .._progress import Progress

#: How to install the optional engine (named in the errors).
EXTRA = 'pip install "uio_jax[cluster]"'
#: Seconds to reach a scheduler given by address before giving up (one line, exit code 2).
CONNECT_TIMEOUT_S = 10.0
#: Seconds a run waits for the cluster to have a worker before giving up.
NO_WORKER_S = 60.0


def require_distributed():
    """The ``distributed`` module, or an OptionError saying how to install it."""
    try:
        import distributed
    except ImportError:
        raise OptionError(f"running on a Dask cluster needs Dask distributed: {EXTRA}") from None
    return distributed


@contextlib.contextmanager
def cluster_client(client, *, timeout_s: float = CONNECT_TIMEOUT_S):
    """A ``distributed.Client`` for the block: ``client`` itself when it is one (left
    open), or a new client of the scheduler at the address ``client`` (closed after).

    Raises:
        OptionError: no ``distributed`` installed, an address of the wrong form, nothing
            listening there, no Dask scheduler there, ``client`` of another type, or a bad
            ``$UIO_JAX_PIN_WORKERS`` here (:func:`pin_workers`; before any work).
    """
    pin_workers()
    distributed = require_distributed()
    if isinstance(client, distributed.Client):
        yield client
        return
    if not isinstance(client, str):
        raise OptionError(f"client must be a distributed.Client or a scheduler address "
                          f"(tcp://host:port), got {type(client).__name__}")
    address = check_scheduler(client, timeout_s=timeout_s)
    own = distributed.Client(address, timeout=timeout_s, set_as_default=False)
    try:
        yield own
    finally:
        own.close()


def check_scheduler(address: str, *, timeout_s: float = CONNECT_TIMEOUT_S) -> str:
    """Check that a Dask scheduler answers at ``address``; returns the address.

    Raises:
        OptionError: an address of the wrong form, nothing listening there (or a host
            that does not resolve), or something that is not a Dask scheduler.
    """
    require_distributed()
    from distributed.comm.addressing import parse_address, parse_host_port

    text = address.strip() if isinstance(address, str) else ""
    what = f"scheduler address {address!r}"
    if not text:
        raise OptionError(f"{what} is empty (expected tcp://host:port)")
    try:
        scheme, loc = parse_address(text, strict=False)
        from distributed.comm.registry import backends

        if scheme not in backends:
            raise ValueError(f"unknown scheme {scheme!r}")
        if scheme == "tcp":
            host, port = parse_host_port(loc)
            if not host or not 0 < int(port) < 65536:
                raise ValueError(f"bad host or port in {loc!r}")
    except (ValueError, TypeError) as exc:
        raise OptionError(f"{what}: {exc} (expected tcp://host:port)") from None
    if scheme == "tcp":
        try:
            socket.create_connection((host, int(port)), timeout=timeout_s).close()
        except socket.gaierror:
            raise OptionError(f"{what}: unknown host {host!r}") from None
        except OSError as exc:
            why = exc.strerror or type(exc).__name__
            raise OptionError(f"cannot reach a Dask scheduler at {text}: {why.lower()}") from None
    try:
        kind = asyncio.run(asyncio.wait_for(_identity(text, timeout_s), timeout_s))
    except (asyncio.TimeoutError, TimeoutError):
        raise OptionError(f"no Dask scheduler answers at {text} within {timeout_s:g} s") from None
    except Exception as exc:
        why = "the connection was closed: another service listens there" if "Closed" in type(exc).__name__ \
            else type(exc).__name__
        raise OptionError(f"no Dask scheduler answers at {text} ({why})") from None
    if kind != "Scheduler":
        raise OptionError(f"{text} is a Dask {kind or 'server'}, not a scheduler")
    return text


async def _identity(address, timeout_s):
    """The ``type`` a Dask server at ``address`` reports (``"Scheduler"``, ``"Worker"``)."""
    from distributed.comm import connect

    comm = await connect(address, timeout=timeout_s)
    try:
        await comm.write({"op": "identity"})
        info = await comm.read()
    finally:
        await comm.close()
    return info.get("type") if isinstance(info, dict) else None


def worker_threads(client) -> int:
    """Threads of all the cluster's workers (models or shards that can run at once)."""
    return sum(client.nthreads().values())


def wait_for_workers(client, timeout_s: float = NO_WORKER_S) -> int:
    """Worker threads of the cluster, waiting up to ``timeout_s`` for a first worker.

    Raises:
        OptionError: the cluster still has no worker.
    """
    deadline = time.monotonic() + timeout_s
    while not (n := worker_threads(client)) and time.monotonic() < deadline:
        time.sleep(0.2)
    if not n:
        raise OptionError(f"the Dask cluster at {client.scheduler.address} has no worker "
                          f"(waited {timeout_s:g} s); start some with: dask worker "
                          f"{client.scheduler.address} --nthreads 1")
    return n


def stop_tasks(client, futures, where=None):
    """Cancel ``futures`` and kill the worker processes running them (a Dask task cannot be
    stopped otherwise); each worker's nanny starts a fresh one in its place.

    Args:
        client: the ``distributed.Client``.
        futures: the futures to stop.
        where: the addresses of the workers running them, when known; else asked of the
            scheduler (the workers processing their keys).
    """
    futures = list(futures)
    if not futures:
        return
    if where is None:
        keys = {f.key for f in futures}
        try:
            where = {w for w, ks in client.processing().items() if keys & set(ks)}
        except Exception:  # the scheduler is gone: nothing runs there any more
            where = set()
    try:
        client.cancel(futures, force=True)
        if where:
            client.run(_exit_worker, workers=sorted(where), on_error="ignore")
    except Exception:  # pragma: no cover - the scheduler went away meanwhile
        pass


def _exit_worker():
    """Run in a worker process by :func:`stop_tasks`: end it at once (its nanny restarts it)."""
    os._exit(1)


#: ``UIO_JAX_PIN_WORKERS=0`` on a worker host leaves its Dask workers unbound.
PIN_ENV = "UIO_JAX_PIN_WORKERS"
_CLAIMED: list = []  # [cpu or None] once this process has tried


def pin_workers() -> bool:
    """``$UIO_JAX_PIN_WORKERS``: unset, empty or ``1``: bind the workers; ``0``: leave them
    unbound. Anything else is refused (OptionError) rather than read as one of them."""
    value = os.environ.get(PIN_ENV, "").strip()
    if value not in ("", "0", "1"):
        raise OptionError(f"{PIN_ENV} must be 0 (workers unbound) or 1 (bound, the default), got {value!r}")
    return value != "0"


def claim_one_cpu():
    """Bind this process, a worker of a Dask cluster, to one CPU that no other worker
    process of this host holds (the first free one), as :func:`uio_jax._batch.pinning.pin_to_one_cpu`
    binds the local pool's workers; called by its first task (a batch's model, a Monte Carlo shard), before JAX
    starts its thread pools.

    The CPUs are claimed with a lock file each (``$TMPDIR/uio_jax-cpus-UID/cpuK.lock``,
    held until the process ends, so a killed worker frees its CPU for the fresh one):
    with one worker process per core (``dask worker --nworkers $(nproc) --nthreads 1``)
    each gets its own. A worker finding every CPU taken, a host with one CPU, a platform
    without CPU affinity or ``UIO_JAX_PIN_WORKERS=0`` leaves the process unbound.

    Unbound, each worker's XLA sizes its thread pools to the whole host, and ``jobs`` workers
    oversubscribe the cores (``docs/benchmarks/batch.md``, ``docs/benchmarks/cluster.md``).

    Returns:
        the CPU bound to, or None.

    Raises:
        OptionError: ``$UIO_JAX_PIN_WORKERS`` neither 0 nor 1 on this host (:func:`pin_workers`).
    """
    if _CLAIMED:
        return _CLAIMED[0]
    pin = pin_workers()  # a bad value is an error, here as on every call (nothing is claimed)
    _CLAIMED.append(None)
    if not pin or not hasattr(os, "sched_setaffinity"):
        return None
    try:
        import fcntl

        cpus = sorted(os.sched_getaffinity(0))
        folder = os.path.join(tempfile.gettempdir(), f"uio_jax-cpus-{os.getuid()}")
        os.makedirs(folder, exist_ok=True)
    except (ImportError, OSError):  # pragma: no cover - no locks or no temp dir: unbound
        return None
    if len(cpus) < 2:
        return None
    for cpu in cpus:
        lock = open(os.path.join(folder, f"cpu{cpu}.lock"), "a")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
            os.sched_setaffinity(0, {cpu})
        except OSError:
            lock.close()
            continue
        _CLAIMED[:] = [cpu, lock]  # the lock stays open (held) as long as the process lives
        return cpu
    return None


# ---------------------------------------------------------------------- Monte Carlo
def dumps_experiment(exp) -> bytes:
    """The experiment pickled by value: its functions, and the model files they come from
    (modules loaded by path, which the workers could not import by name)."""
    import cloudpickle

    mods = [m for name, m in list(sys.modules.items()) if name.startswith("uio_jax_model_")]
    for m in mods:
        cloudpickle.register_pickle_by_value(m)
    try:
        return cloudpickle.dumps(exp)
    finally:
        for m in mods:
            cloudpickle.unregister_pickle_by_value(m)


_EXPERIMENTS: dict = {}  # digest -> Experiment, in a worker: one object, one set of programs


def _experiment(blob):
    digest = hashlib.sha256(blob).hexdigest()
    if digest not in _EXPERIMENTS:
        _EXPERIMENTS.clear()  # one experiment at a time
        _EXPERIMENTS[digest] = pickle.loads(blob)
    return _EXPERIMENTS[digest]


def _shard_task(blob, first, count, seed, filter, keep, topic, shard):
    """One shard, in a worker: records of trials ``first..first+count-1`` (and the
    trajectories of trials ``0..keep-1`` when ``keep``); progress as events on ``topic``.
    The trials run by :func:`uio_jax._filter.trials.simulate_trials` and
    :func:`~uio_jax._filter.trials.trajectories`, imported here, in the worker (this module
    is imported by the command line, which does not load JAX for it)."""
    from distributed import get_worker

    from .trials import simulate_trials, trajectories

    worker = get_worker()
    if worker.state.nthreads == 1:
        claim_one_cpu()  # one CPU per worker process
    exp = _experiment(blob)

    def on_chunk(steps):
        worker.log_event(topic, [shard, int(steps)])

    stats, timing = simulate_trials(exp, first, count, seed=seed, filter=filter, on_chunk=on_chunk)
    traj = trajectories(exp, range(keep), seed=seed, filter=filter) if keep else None
    timing["worker"] = worker.address
    return stats, traj, timing


def run_trials_on_cluster(exp, trials, *, seed, keep, filter, client, progress=None):
    """Trials ``0..trials-1`` of ``exp`` over the workers of ``client`` (see the module doc).

    Args:
        exp: the :class:`~uio_jax.Experiment`.
        trials: B. seed, keep, filter: as :func:`uio_jax.run_montecarlo`.
        client: a ``distributed.Client`` or a scheduler address.
        progress: as :func:`uio_jax.run_montecarlo`: one bar of the ``B * n_steps``
            trial-steps of all workers (``NAME [2 workers]``; padding trials excluded).

    Returns:
        ``(stats, trajectories, timings)``: the ``(B, T, S)`` float32 records in trial
        order, the kept trajectories (or None) and the run's timings.

    Raises:
        OptionError: no cluster (see :func:`cluster_client`), no worker.
        ModelError or another error raised by a shard: as in one process.
    """
    with cluster_client(client) as c:
        n = wait_for_workers(c)
        shards = max(1, min(n, trials))
        size = -(-trials // shards)
        starts = [s * size for s in range(shards) if s * size < trials]
        blob = dumps_experiment(exp)
        bar = Progress(trials * exp.n_steps, enabled=progress, delay=0.0 if progress else 3.0,
                       label=f"{exp.name.split(':')[-1]} [{len(starts)} worker{'s' if len(starts) > 1 else ''}]")
        topic = f"uio_jax-montecarlo-{uuid.uuid4().hex}"
        done = queue.Queue()
        c.subscribe_topic(topic, lambda event: done.put(tuple(event[1])))
        t0 = time.perf_counter()
        futures = [c.submit(_shard_task, blob, a, size, seed, filter, keep if a == 0 else 0, topic, k,
                            key=f"uio_jax-mc-{topic[-12:]}-{k}", pure=False)
                   for k, a in enumerate(starts)]
        try:
            pending = set(range(len(futures)))
            lonely = None
            while pending:
                _drain(done, bar, size, trials, starts, wait_s=0.2)
                for k in list(pending):
                    if futures[k].done():
                        pending.discard(k)
                        if futures[k].status != "finished":
                            _raise_shard_error(futures[k], starts[k], min(starts[k] + size, trials))
                lonely = _check_workers(c, lonely)
            results = [f.result() for f in futures]
            _drain(done, bar, size, trials, starts, wait_s=0.0)
        except BaseException:  # Ctrl-C, or a shard's error: the other shards are stopped
            stop_tasks(c, futures)
            raise
        finally:
            bar.close()
            c.unsubscribe_topic(topic)
        wall = time.perf_counter() - t0
    stats = np.concatenate([r[0] for r in results], axis=0)[:trials]
    timings = [r[2] for r in results]
    out = {
        "compile_s": max(t["compile_s"] for t in timings),
        "run_s": max(t["run_s"] for t in timings),
        "process_s": sum(t["process_s"] for t in timings),
        "setup_process_s": sum(t["setup_process_s"] for t in timings),
        "wall_s": wall,
        "workers": len({t["worker"] for t in timings}),
        "shards": len(starts),
        "devices": sum(t["devices"] for t in timings),
        "device_kind": timings[0]["device_kind"],
    }
    return stats, results[0][1], out


def _raise_shard_error(future, first, end):
    """The error of a shard that did not finish: its own when uio_jax raised it (a
    ModelError, as in one process), else one line naming the shard."""
    exc = future.exception() if future.status == "error" else None
    if isinstance(exc, UioJaxError):
        raise exc
    if exc is None:
        why = "cancelled"
    else:
        text = str(exc).strip()
        why = f"{type(exc).__name__}: {text.splitlines()[0][:200]}" if text else type(exc).__name__
    raise UioJaxError(f"the Monte Carlo trials {first}..{end - 1} failed on the cluster ({why})")


def _check_workers(client, since):
    """``since`` (when the cluster was first seen without a worker, or None); an error
    once it has had none for :data:`NO_WORKER_S` seconds."""
    try:
        if worker_threads(client):
            return None
    except Exception:  # the scheduler does not answer: as if it had no worker
        pass
    now = time.monotonic()
    if since is not None and now - since >= NO_WORKER_S:
        raise UioJaxError(f"the Dask cluster had no worker for {NO_WORKER_S:g} s: Monte Carlo stopped")
    return now if since is None else since


def drain_queue(events, wait_s) -> list:
    """The items of the queue ``events``, waiting up to ``wait_s`` seconds for the first
    (not at all when ``wait_s`` is 0); empty when none came."""
    got = []
    try:
        got.append(events.get(timeout=wait_s) if wait_s > 0 else events.get_nowait())
        while True:
            got.append(events.get_nowait())
    except queue.Empty:
        return got


def _drain(events, bar, size, trials, starts, wait_s):
    """Add the trial-steps the workers reported to ``bar`` (padding trials left out)."""
    for shard, steps in drain_queue(events, wait_s):
        real = min(size, trials - starts[shard]) if shard < len(starts) else size
        bar.update(math.floor(steps * real / size))
