"""Monte Carlo trials in this process: batched, sharded, compiled once per experiment.

:func:`simulate_trials` runs trials ``first .. first + count - 1`` of an experiment (the
functions of one trial: :mod:`uio_jax._filter.trial`), the records only; :func:`trajectories`
recomputes the full float64 trajectories of a few trials. Both :func:`uio_jax.run_montecarlo`
(:mod:`uio_jax._filter.montecarlo`) and a cluster's workers (:mod:`uio_jax._filter.cluster`)
call them.

Layout of one run (the measurements behind its choices: ``docs/benchmarks/ekf.md``):

* nested scan: chunks (a Python loop, which drives the progress bar) -> records
  (statistics kept every ``record_every`` epochs) -> epochs (one output update) -> Euler
  sub-steps (truth, readings, EKF predict; :data:`uio_jax._filter.trial.UNROLL`).
* trials are split over all devices with ``shard_map`` (on a CPU, split the host into one
  device per core *before* JAX starts: ``jax.config.update("jax_num_cpu_devices", 2)``;
  the command line does it).
* per trial and record only ``2 N + 2 d + 1`` float32 numbers are kept (errors, filter
  sigmas, errors and sigmas along the named quantities, NEES); full trajectories (truth,
  dead reckoning, EKF) only for the first ``keep`` trials, recomputed in float64.
"""

import time
import weakref
from concurrent.futures import ThreadPoolExecutor

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from .._engine import threefry
from .._errors import ModelError
from .._model.experiment import Experiment
from .trial import check_filter, trial_functions

#: Trial-steps per chunk between two progress-bar updates (about 1-3 s on 2 CPU cores).
CHUNK_TRIAL_STEPS = 1.5e7

#: Compiled programs per experiment: ``(devices, per device, records per chunk, filter)``
#: -> the sharded init and chunk programs; ``("traj", filter)`` -> the trajectories program.
_CACHE: "weakref.WeakKeyDictionary[Experiment, dict]" = weakref.WeakKeyDictionary()


# ---------------------------------------------------------------------- batched, sharded
def _compiled(exp, devices, per_dev, n_rec_chunk, filter="fast"):
    """Jitted, sharded init and chunk functions (cached per experiment, shape and filter)."""
    key = (tuple(d.id for d in devices), per_dev, n_rec_chunk, filter)
    cache = _CACHE.setdefault(exp, {})
    if key in cache:
        return cache[key]
    init, epoch, stats = trial_functions(exp, traj=False, filter=filter)
    R = exp.record_every
    mesh = Mesh(np.array(devices), ("trials",))
    spec = P("trials")

    def init_local(ids, root):
        return jax.vmap(init, in_axes=(0, None))(ids, root)

    def chunk_local(carry, j0):
        # the statistics at the chunk's start too (the host keeps the first chunk's: the
        # record at t = 0), so that init, compiled beside this program, has none of them
        def per_trial(c):
            def rec(c, r):
                def ep(c, e):
                    c, _ = epoch(c, j0 + r * R + e)
                    return c, None

                c, _ = lax.scan(ep, c, jnp.arange(R))
                return c, stats(c)

            start = stats(c)
            c, recs = lax.scan(rec, c, jnp.arange(n_rec_chunk))
            return c, (start, recs)

        return jax.vmap(per_trial)(carry)

    init_j = jax.jit(jax.shard_map(init_local, mesh=mesh, in_specs=(spec, P()),
                                   out_specs=spec, check_vma=False))
    chunk_j = jax.jit(jax.shard_map(chunk_local, mesh=mesh, in_specs=(spec, P()),
                                    out_specs=(spec, (spec, spec)), check_vma=False),
                      donate_argnums=0)
    cache[key] = (init_j, chunk_j, NamedSharding(mesh, spec))
    return cache[key]


def _compile_chunk(chunk_j, shapes, j0):
    """The compiled chunk program for carries of ``shapes`` (run in a helper thread)."""
    with jax.enable_x64(True):  # the flag is per thread
        return chunk_j.lower(shapes, j0).compile()


def chunk_records(exp, n_trials):
    """Records per chunk: the largest divisor of the record count within the budget."""
    n_rec = exp.n_epochs // exp.record_every
    steps_per_rec = exp.record_every * exp.epoch_steps * n_trials
    best = max((c for c in range(1, n_rec + 1) if n_rec % c == 0 and c * steps_per_rec <= CHUNK_TRIAL_STEPS),
               default=1)
    return best, n_rec


def simulate_trials(exp: Experiment, first: int, count: int, *, seed: int, filter: str = "fast",
                    devices=None, on_start=None, on_chunk=None):
    """Records of trials ``first .. first + count - 1`` of ``exp`` in this process.

    The trials are split over ``devices`` (default: all of this process's JAX devices),
    padded to a multiple of their number. Trial ``i`` uses the key ``fold_in(key(seed), i)``:
    its records do not depend on ``first``, ``count`` or the devices (a cluster splits a run
    and merges it back bit for bit).

    Args:
        exp: the experiment (checked by the caller: options, memory, model at x0).
        first, count: the trials (``count >= 1``).
        seed: the run's seed. filter: ``"fast"`` or ``"reference"``.
        devices: JAX devices to shard over (default: all).
        on_start: None, or called once when the programs are compiled, before the first chunk.
        on_chunk: None, or called with the trial-steps of ``count`` trials done by each chunk.

    Returns:
        ``(stats, timings)``: ``(count, n_records + 1, S)`` float32 records and
        ``{"compile_s", "run_s", "process_s", "setup_process_s", "devices", "device_kind"}``.
    """
    with jax.enable_x64(True):
        t0 = time.perf_counter()  # compile_s: from here to both programs compiled
        p0 = time.process_time()
        devices = list(jax.devices() if devices is None else devices)
        nd = len(devices)
        per_dev = -(-count // nd)
        Bp = per_dev * nd
        n_rec_chunk, n_rec = chunk_records(exp, Bp)
        init_j, chunk_j, sharding = _compiled(exp, devices, per_dev, n_rec_chunk, filter)
        root = threefry.seed_key(seed)
        ids = jax.device_put(np.arange(first, first + Bp, dtype=np.uint32), sharding)  # host arrays:
        j0 = np.asarray(0, np.int32)                                     # no dispatch, no compile
        # the chunk program compiles in a thread while init compiles and runs (XLA's
        # compiler releases the GIL; the compile time saved: docs/benchmarks/ekf.md, run 7)
        replicated = NamedSharding(sharding.mesh, P())  # what JAX gives empty arrays
        shapes = jax.tree.map(
            lambda a: jax.ShapeDtypeStruct(a.shape, a.dtype, sharding=sharding if a.size else replicated),
            jax.eval_shape(init_j, ids, root))
        with ThreadPoolExecutor(1) as pool:
            pending = pool.submit(_compile_chunk, chunk_j, shapes, j0)
            carry = init_j(ids, root)
            chunk_c = pending.result()
        if any(a.sharding != s.sharding for a, s in zip(jax.tree.leaves(carry), jax.tree.leaves(shapes))):
            chunk_c = _compile_chunk(chunk_j, carry, j0)  # placed otherwise: compiled for it
        compile_s = time.perf_counter() - t0
        steps_chunk = n_rec_chunk * exp.record_every * exp.epoch_steps
        if on_start is not None:
            on_start()
        records = []
        t1 = time.perf_counter()
        p1 = time.process_time()
        for c in range(n_rec // n_rec_chunk):
            j0 = np.asarray(c * n_rec_chunk * exp.record_every, np.int32)
            carry, (start, rec) = chunk_c(carry, j0)
            if c == 0:
                records.append(np.asarray(start)[:count, None])  # t = 0
            records.append(np.asarray(rec)[:count])
            if on_chunk is not None:
                on_chunk(count * steps_chunk)
        run_s = time.perf_counter() - t1
        run_p = time.process_time() - p1
    stats = np.concatenate(records, axis=1)  # (count, n_rec + 1, S)
    return stats, {"compile_s": compile_s, "run_s": run_s, "process_s": run_p,
                   "setup_process_s": p1 - p0, "devices": nd, "device_kind": devices[0].platform}


def check_finite(exp, stats):
    """Raise when a record of ``stats`` is NaN/inf.

    Raises:
        ModelError: naming how many trials and the first time.
    """
    bad = ~np.isfinite(stats).all(axis=2)
    if bad.any():
        k = int(np.argmax(bad.any(axis=0)))
        t = k * exp.record_every * exp.epoch_steps * exp.dt
        raise ModelError(f"experiment {exp.name!r}: the filter became NaN/inf in "
                         f"{int(bad.any(axis=1).sum())} of {stats.shape[0]} trials "
                         f"(first at t={t:.4g} s); does the model return NaN there?")


# ---------------------------------------------------------------------- full trajectories
def trajectories(experiment: Experiment, trial_ids, *, seed: int = 0, filter: str = "fast") -> dict:
    """Full float64 trajectories of some trials, at every output epoch.

    The same trials as in :func:`run_montecarlo` with the same seed (trial ``i`` depends
    only on ``(seed, i)``), recomputed one epoch at a time, unsharded.

    Args:
        experiment: the experiment.
        trial_ids: iterable of trial indices.
        seed: the run's seed, an integer in ``[0, 2**64)``.
        filter: ``"fast"`` or ``"reference"``, as in :func:`run_montecarlo`.

    Returns:
        dict of numpy arrays (``k`` trials, ``E`` epochs, index 0 is t = 0):
        ``t (E+1,)``, ``x_true (k, E+1, n)``, ``x_hat (k, E+1, N)``,
        ``sigma (k, E+1, N)``, ``x_dr (k, E+1, n)`` (dead reckoning: readings only,
        ``w = 0``), ``y (k, E, n_out)`` (the outputs read), ``u_read (k, E*K, m)``,
        ``P (k, E+1, N, N)`` (only when ``k <= 4``; else absent), ``ids``.
    """
    exp = experiment
    ids = np.asarray(list(trial_ids), np.uint32)
    with jax.enable_x64(True):
        fn = _traj_fn(exp, check_filter(filter))
        out = fn(jnp.asarray(ids), threefry.seed_key(threefry.check_seed(seed)))
        out = jax.tree.map(np.asarray, out)
    (x_t0, xa0, sig0, xdr0, P0), (x_t, xa, sig, xdr, y, u_reads, Ps) = out
    k, E = x_t.shape[0], x_t.shape[1]
    res = {
        "ids": ids,
        "t": np.arange(E + 1) * exp.epoch_steps * exp.dt,
        "x_true": np.concatenate([x_t0[:, None], x_t], 1),
        "x_hat": np.concatenate([xa0[:, None], xa], 1),
        "sigma": np.concatenate([sig0[:, None], sig], 1),
        "x_dr": np.concatenate([xdr0[:, None], xdr], 1),
        "y": y,
        "u_read": u_reads.reshape(k, E * exp.epoch_steps, -1),
    }
    if k <= 4:
        res["P"] = np.concatenate([P0[:, None], Ps], 1)
    return res


def _traj_fn(exp, filter="fast"):
    cache = _CACHE.setdefault(exp, {})
    if ("traj", filter) in cache:
        return cache[("traj", filter)]
    init, epoch, _ = trial_functions(exp, traj=True, filter=filter)

    def one(i, root):
        c = init(i, root)
        c0 = (c[1], c[4], jnp.sqrt(jnp.diag(c[5])), c[6], c[5])
        _, outs = lax.scan(epoch, c, jnp.arange(exp.n_epochs))
        return c0, outs

    cache[("traj", filter)] = jax.jit(jax.vmap(one, in_axes=(0, None)))
    return cache[("traj", filter)]


__all__ = ["CHUNK_TRIAL_STEPS", "check_finite", "chunk_records", "simulate_trials", "trajectories"]
