"""Vectorised Monte Carlo EKF: ``lax.scan`` over time, ``vmap`` over trials, sharded.

Layout of one run (the measurements behind its choices: ``docs/benchmarks/ekf.md``):

* trial ``i`` uses the key ``fold_in(key(seed), i)`` (split once into an initial and a run
  key); epoch ``j`` draws ONE block of normals ``normal(fold_in(run_key, j), ...)`` for all
  its Euler sub-steps and its outputs (float32 normals, see :func:`_trial_functions`). So every
  trial's numbers depend only on ``(seed, i)``: not on the batch size, the chunking or
  the sharding. The numbers are JAX's default threefry ones, bit for bit, drawn by
  :mod:`uio_jax._engine.threefry` (unrolled hash: faster to compile and to run on a CPU).
* nested scan: chunks (a Python loop, which drives the progress bar) -> records
  (statistics kept every ``record_every`` epochs) -> epochs (one output update) -> Euler
  sub-steps (truth, readings, EKF predict; ``UNROLL`` below).
* trials are split over all devices with ``shard_map`` (on a CPU, split the host into one
  device per core *before* JAX starts: ``jax.config.update("jax_num_cpu_devices", 2)``;
  the command line does it).
* per trial and record only ``2 N + 2 d + 1`` float32 numbers are kept (errors, filter
  sigmas, errors and sigmas along the named quantities, NEES); full trajectories (truth,
  dead reckoning, EKF) only for the first ``keep`` trials, recomputed in float64.
* the filter: the fast kernels of :mod:`uio_jax._filter.ekf` (``filter="fast"``, the
  default) or the plain equations of :mod:`uio_jax._filter.reference_ekf`
  (``filter="reference"``, their oracle). The simulation (truth, readings, outputs) is the
  same code either way, so the two runs see the very same data.
"""

import numbers
import os
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
from .._errors import ModelError, OptionError
from .._model.experiment import Experiment
from .._progress import Progress
from . import reference_ekf
from .ekf import mahalanobis_squared, make_model, output_mask, predict, update, wrap_angle
from .result import MonteCarloResult
from .shapes import check_shapes

#: Trial-steps per chunk between two progress-bar updates (about 1-3 s on 2 CPU cores).
CHUNK_TRIAL_STEPS = 1.5e7
#: Inner-scan unroll of the Euler sub-steps: 1, as larger unrolls ran slower at large batches
#: (docs/benchmarks/ekf.md, "Reading").
UNROLL = 1
#: The values of ``run_montecarlo(filter=...)``.
FILTERS = ("fast", "reference")

_CACHE: "weakref.WeakKeyDictionary[Experiment, dict]" = weakref.WeakKeyDictionary()


# ---------------------------------------------------------------------- one trial
def _filter_kernels(exp: Experiment, model, filter: str):
    """``(model, predict, update, mahalanobis_squared)`` of the filter named ``filter``.

    ``"fast"``: ``model`` itself and the kernels of :mod:`uio_jax._filter.ekf` (looked up
    at each call, so that ``scripts/bench_ekf.py`` can swap them out); ``"reference"``: the
    plain equations of :mod:`uio_jax._filter.reference_ekf` with their own model.
    """
    if filter == "fast":
        return model, predict, update, mahalanobis_squared
    return (reference_ekf.make_model(exp), reference_ekf.predict, reference_ekf.update,
            reference_ekf.mahalanobis_squared)


def _check_filter(filter):
    if not (isinstance(filter, str) and filter in FILTERS):
        raise OptionError(f"filter must be one of {', '.join(map(repr, FILTERS))}, got {filter!r}")
    return filter


def _trial_functions(exp: Experiment, traj: bool, filter: str = "fast"):
    """``init(trial_id, root) -> carry``, ``epoch(carry, j)``, ``stats(carry)``.

    ``carry = (run_key, x, istate, w_last, xa, P[, x_dr])`` for one trial; ``filter``: see
    :func:`_filter_kernels` (the simulation uses the fast model either way).
    """
    model = make_model(exp)
    fmodel, f_predict, f_update, f_nees = _filter_kernels(exp, model, filter)
    n, p, N = model.n, model.p, model.N
    K = exp.epoch_steps
    ni = exp.n_input_normals
    m = len(exp.system.known)
    n_out = len(exp.measurements)
    law = exp.inputs
    known_std = exp.known_std
    dt = model.dt
    x0 = np.asarray(exp.x0, np.float64)
    istate0 = np.asarray(exp.istate0, np.float64)
    w0 = np.asarray(exp.w0, np.float64)
    prior = np.asarray(exp.prior_std, np.float64)
    ang = exp.angle_mask()
    sig_out = model.sigma
    names = exp.state_names()
    nees_idx = np.array([names.index(s) for s in exp.nees_states])
    quantities = exp.quantities
    w_reference = exp.w_reference

    def truth_aug(x, w_last):
        return jnp.concatenate([x, w_last, jnp.zeros(p * (exp.order - 1))])

    def init(trial_id, root):
        k_init, k_run = threefry.split(threefry.fold_in(root, trial_id))
        z = threefry.normal(k_init, N).astype(jnp.float64)
        x = jnp.asarray(x0)
        w_last = jnp.asarray(w0)
        xa = truth_aug(x, w_last) + prior * z
        Pm = jnp.diag(jnp.asarray(prior**2))
        carry = (k_run, x, jnp.asarray(istate0), w_last, xa, Pm)
        if traj:
            carry = carry + (xa[:n],)
        return carry

    def epoch(carry, j):
        key, x, istate, w_last, xa, Pm = carry[:6]
        # float32 normals, used in float64: half the threefry bits of float64 ones and a
        # cheap inverse error function (the simulation's gain: docs/benchmarks/ekf.md, run
        # 5). The cost: they resolve 2^-24 and reach about 5.3 sigma (1e-7 beyond) where
        # float64 ones reach about 8; noise levels of a few percent do not see the difference.
        z = threefry.normal(threefry.fold_in(key, j), K * (ni + m) + n_out).astype(jnp.float64)
        zs = z[:K * (ni + m)].reshape(K, ni + m)
        zy = z[K * (ni + m):]

        def sub(c, zk):
            x, istate, w_last, xa, Pm = c[:5]
            istate, u, w = law(istate, zk[:ni])
            u = jnp.asarray(u, jnp.float64).reshape(m)
            w = jnp.asarray(w, jnp.float64).reshape(p)
            u_read = u + known_std(u) * zk[ni:]
            x = x + dt * model.dynamics(x, u, w)
            xa, Pm = f_predict(fmodel, xa, Pm, u_read)
            w_ref = w if w_reference is None else jnp.asarray(
                w_reference(istate, w), jnp.float64).reshape(p)
            out = (x, istate, w_ref, xa, Pm)
            if traj:
                x_dr = c[5]
                out = out + (x_dr + dt * model.dynamics(x_dr, u_read, jnp.zeros(p)),)
                return out, u_read
            return out, None

        c0 = (x, istate, w_last, xa, Pm) + ((carry[6],) if traj else ())
        c, u_reads = lax.scan(sub, c0, zs, unroll=min(UNROLL, K))
        x, istate, w_last, xa, Pm = c[:5]
        y = model.h_true(x) + sig_out * zy
        if model.angle_out.any():
            y = jnp.where(model.angle_out, wrap_angle(y), y)
        xa, Pm = f_update(fmodel, xa, Pm, y, output_mask(model, j))
        new = (key, x, istate, w_last, xa, Pm) + ((c[5],) if traj else ())
        if traj:
            return new, (x, xa, jnp.sqrt(jnp.diag(Pm)), c[5], y, u_reads, Pm)
        return new, None

    def stats(carry):
        _, x, _, w_last, xa, Pm = carry[:6]
        err = xa - truth_aug(x, w_last)
        if ang.any():
            err = jnp.where(ang, wrap_angle(err), err)
        sig = jnp.sqrt(jnp.diag(Pm))
        qe, qs = [], []
        for q in quantities:
            v_hat = q.fn(xa[:n])
            e = v_hat - q.fn(x)
            qe.append(wrap_angle(e) if q.angle else e)
            g = jax.grad(q.fn)(xa[:n])
            qs.append(jnp.sqrt(jnp.sum(g[:, None] * Pm[:n, :n] * g[None, :])))
        es = err[nees_idx]
        Ps = Pm[np.ix_(nees_idx, nees_idx)]
        nees = jnp.asarray(f_nees(es, Ps))
        parts = [err, sig, jnp.stack(qe) if qe else jnp.zeros(0),
                 jnp.stack(qs) if qs else jnp.zeros(0), nees[None]]
        return jnp.concatenate(parts).astype(jnp.float32)

    return init, epoch, stats


# ---------------------------------------------------------------------- batched, sharded
def _mesh(devices):
    return Mesh(np.array(devices), ("trials",))


def _compiled(exp, devices, per_dev, n_rec_chunk, filter="fast"):
    """Jitted, sharded init and chunk functions (cached per experiment, shape and filter)."""
    key = (tuple(d.id for d in devices), per_dev, n_rec_chunk, filter)
    cache = _CACHE.setdefault(exp, {})
    if key in cache:
        return cache[key]
    init, epoch, stats = _trial_functions(exp, traj=False, filter=filter)
    R = exp.record_every
    mesh = _mesh(devices)
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


def _check_int(value, what, lo):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < lo:
        raise OptionError(f"{what} must be an integer >= {lo}, got {value!r}")
    return int(value)




def _chunk_records(exp, n_trials):
    """Records per chunk: the largest divisor of the record count within the budget."""
    n_rec = exp.n_epochs // exp.record_every
    steps_per_rec = exp.record_every * exp.epoch_steps * n_trials
    best = 1
    for c in range(1, n_rec + 1):
        if n_rec % c == 0 and c * steps_per_rec <= CHUNK_TRIAL_STEPS:
            best = c
    return best, n_rec


def _check_model(exp):
    """Fail early, with one line, when the model is NaN at the experiment's start; then warn
    when ``dt`` is far from the dynamics' time scale (:meth:`Experiment.check_time_scale`,
    from the Jacobian this same program computes)."""
    cache = _CACHE.setdefault(exp, {})
    if "check" not in cache:  # one small program (the input law too): no op-by-op dispatch
        check_shapes(exp)  # a wrong shape named here, not by JAX inside the filter
        model = make_model(exp)
        n, m, p = exp.n, len(exp.system.known), len(exp.system.unknown)

        def values(x0, w0, istate0):
            _, u, w = exp.inputs(istate0, jnp.zeros(exp.n_input_normals))
            u = jnp.asarray(u, jnp.float64).reshape(m)
            w = jnp.asarray(w, jnp.float64).reshape(p)

            def flow(xw):
                return model.dynamics(xw[:n], u, xw[n:])

            xw0 = jnp.concatenate([x0, w0])
            return (model.dynamics(x0, u, w), model.h_true(x0), exp.known_std(u),
                    flow(xw0), jax.jacfwd(flow)(xw0))

        cache["check"] = jax.jit(values)
    out = cache["check"](np.asarray(exp.x0, np.float64), np.asarray(exp.w0, np.float64),
                         np.asarray(exp.istate0, np.float64))
    for what, v in zip(("the dynamics", "the measurements", "the known-input noise std"), out):
        if not np.all(np.isfinite(np.asarray(v))):
            raise ModelError(f"experiment {exp.name!r}: {what} return NaN/inf at the true "
                             f"start x0={list(exp.x0)}")
    exp.check_time_scale((np.asarray(out[3]), np.asarray(out[4])))


def run_montecarlo(experiment: Experiment, trials: int = 256, *, seed: int = 0, keep: int = 4,
                   devices=None, progress=None, filter: str = "fast", client=None) -> MonteCarloResult:
    """Run ``trials`` independent simulations of an experiment, each filtered by the EKF.

    Every trial: truth by Euler at ``experiment.dt``; known inputs read with noise every
    step; outputs read at their own periods; the EKF of :mod:`uio_jax._filter.ekf` on the state
    augmented by the unknown inputs and their derivatives, started at
    ``truth + N(0, diag(prior_std^2))``. Statistics per trial are recorded every
    ``record_every`` output epochs (and at t = 0); the result computes RMSE, filter sigma,
    NEES, ratios end/start and the verdict.

    Args:
        experiment: an :class:`~uio_jax.Experiment` (e.g. from the zoo).
        trials: number of trials B (>= 1). Trial i uses ``fold_in(key(seed), i)``, so the
            first 64 trials of a run with B = 256 equal a run with B = 64.
        seed: integer in ``[0, 2**64)``.
        keep: number of trials (the first ones) whose full trajectories (truth, dead
            reckoning, EKF and its sigma, at every epoch) are kept, for plots.
        devices: JAX devices to shard the trials over (default: all of them; not with
            ``client``).
        progress: ``True``/``False`` forces the stderr progress bar on/off; ``None``
            (default) shows it when the run lasts more than a few seconds.
        filter: ``"fast"`` (default): the EKF's fast kernels; ``"reference"``: the same
            filter as plain matrix equations (:mod:`uio_jax._filter.reference_ekf`; equal
            to round-off, several times slower), to check a result against.
        client: None (default: this process), or a Dask cluster: a ``distributed.Client``
            or a scheduler address (``"tcp://host:8786"``). The trials are split over its
            workers (:mod:`uio_jax._filter.cluster`); every trial keeps its key, so the
            records equal those of a one-process run with the same seed bit for bit, and
            the statistics are computed once over all of them. Needs the extra
            ``uio_jax[cluster]``.

    Returns:
        :class:`MonteCarloResult` (host numpy arrays; ``errors`` has shape
        ``(trials, n_records + 1, N)`` in float32).

    Raises:
        OptionError: trials <= 0, seed outside ``[0, 2**64)``, negative keep, an unknown
            filter, a run whose records would not fit in memory
            (:meth:`~uio_jax.Experiment.check_memory`), ``devices`` with ``client``, a
            cluster that cannot be reached or has no worker, all before any work.
        ModelError: the model is NaN at the start, or the filter became NaN/inf.

    Warns:
        TimeScaleWarning: ``dt`` or the horizon far from the time scale of the dynamics
            at the start (:meth:`~uio_jax.Experiment.check_time_scale`), before compiling.
    """
    if not isinstance(experiment, Experiment):
        raise OptionError(f"run_montecarlo needs a uio_jax Experiment, got "
                          f"{type(experiment).__name__}")
    B = _check_int(trials, "trials", 1)
    seed = threefry.check_seed(seed)
    keep = min(_check_int(keep, "keep", 0), B)
    filter = _check_filter(filter)
    if client is not None and devices is not None:
        raise OptionError("run_montecarlo takes devices or client, not both (a cluster's "
                          "workers use their own devices)")
    exp = experiment
    exp.check_memory(B, keep)
    label = exp.name.split(":")[-1]
    t0 = time.perf_counter()
    with jax.enable_x64(True):
        _check_model(exp)
    check_s = time.perf_counter() - t0
    if client is not None:
        from .cluster import run_trials_on_cluster

        stats, traj, timings = run_trials_on_cluster(exp, B, seed=seed, keep=keep, filter=filter,
                                                     client=client, progress=progress,
                                                     simulate_trials=simulate_trials, trajectories=trajectories)
        _check_finite(exp, stats)
    else:
        bars = []

        def started():
            bars.append(Progress(B * exp.n_steps, enabled=progress,
                                 delay=0.0 if progress else 3.0, label=label))

        try:
            stats, timings = simulate_trials(exp, 0, B, seed=seed, filter=filter, devices=devices,
                                             on_start=started, on_chunk=lambda steps: bars[0].update(steps))
        finally:
            for bar in bars:
                bar.close()
        _check_finite(exp, stats)
        with jax.enable_x64(True):
            traj = trajectories(exp, range(keep), seed=seed, filter=filter) if keep else None
    timings["compile_s"] += check_s
    timings.update({"trial_steps": B * exp.n_steps,
                    "trial_steps_per_s": B * exp.n_steps / max(timings["run_s"], 1e-12),
                    "loadavg": os.getloadavg()})
    t = np.arange(stats.shape[1]) * exp.record_every * exp.epoch_steps * exp.dt
    return MonteCarloResult(exp, B, seed, t, stats, traj, timings, filter)


def simulate_trials(exp: Experiment, first: int, count: int, *, seed: int, filter: str = "fast",
                    devices=None, on_start=None, on_chunk=None):
    """Records of trials ``first .. first + count - 1`` of ``exp`` in this process.

    The trials are split over ``devices`` (default: all of this process's JAX devices),
    padded to a multiple of their number (the padding trials are computed and dropped).
    Trial ``i`` uses the key ``fold_in(key(seed), i)``: its records do not depend on
    ``first``, ``count`` or the devices, which is what lets a cluster split a run
    (:mod:`uio_jax._filter.cluster`) and merge it back bit for bit.

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
        n_rec_chunk, n_rec = _chunk_records(exp, Bp)
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


def _check_finite(exp, stats):
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
        fn = _traj_fn(exp, _check_filter(filter))
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
    init, epoch, _ = _trial_functions(exp, traj=True, filter=filter)

    def one(i, root):
        c = init(i, root)
        c0 = (c[1], c[4], jnp.sqrt(jnp.diag(c[5])), c[6], c[5])
        _, outs = lax.scan(epoch, c, jnp.arange(exp.n_epochs))
        return c0, outs

    cache[("traj", filter)] = jax.jit(jax.vmap(one, in_axes=(0, None)))
    return cache[("traj", filter)]
