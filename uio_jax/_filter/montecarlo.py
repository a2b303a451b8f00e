"""Monte Carlo EKF: many independent trials of an experiment, each filtered by the EKF.

:func:`run_montecarlo` checks its options and the model at the true start, runs the trials
in this process (:func:`uio_jax._filter.trials.simulate_trials`, one trial:
:mod:`uio_jax._filter.trial`) or over a Dask cluster (:mod:`uio_jax._filter.cluster`), then
recomputes the full trajectories of the first ``keep`` trials and returns a
:class:`~uio_jax.MonteCarloResult`. Every trial's numbers depend only on ``(seed, i)``: not
on the batch size, the chunking, the sharding or the cluster.
"""

import numbers
import os
import time
import weakref

import jax
import jax.numpy as jnp
import numpy as np

from .._engine import threefry
from .._errors import ModelError, OptionError
from .._model.experiment import Experiment
from .._progress import Progress
from .ekf import make_model
from .result import MonteCarloResult
from .shapes import check_shapes
from .trial import check_filter
from .trials import check_finite, simulate_trials, trajectories

#: The start check's program per experiment (:func:`_check_model`).
_CHECKS: "weakref.WeakKeyDictionary[Experiment, object]" = weakref.WeakKeyDictionary()


def _check_int(value, what, lo):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < lo:
        raise OptionError(f"{what} must be an integer >= {lo}, got {value!r}")
    return int(value)


def _check_model(exp):
    """Fail early, with one line, when the model is NaN at the experiment's start; then warn
    when ``dt`` is far from the dynamics' time scale (:meth:`Experiment.check_time_scale`,
    from the Jacobian this same program computes)."""
    if exp not in _CHECKS:  # one small program (the input law too): no op-by-op dispatch
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

        _CHECKS[exp] = jax.jit(values)
    out = _CHECKS[exp](np.asarray(exp.x0, np.float64), np.asarray(exp.w0, np.float64),
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
            workers (:mod:`uio_jax._filter.cluster`), with the records of a one-process run
            bit for bit. Needs the extra ``uio_jax[cluster]``.

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
    filter = check_filter(filter)
    if client is not None and devices is not None:
        raise OptionError("run_montecarlo takes devices or client, not both (a cluster's "
                          "workers use their own devices)")
    exp = experiment
    exp.check_memory(B, keep)
    t0 = time.perf_counter()
    with jax.enable_x64(True):
        _check_model(exp)
    check_s = time.perf_counter() - t0
    if client is not None:
        from .cluster import run_trials_on_cluster

        stats, traj, timings = run_trials_on_cluster(exp, B, seed=seed, keep=keep, filter=filter,
                                                     client=client, progress=progress)
        check_finite(exp, stats)
    else:
        stats, traj, timings = _run_here(exp, B, seed, keep, filter, devices, progress)
    timings["compile_s"] += check_s
    timings.update({"trial_steps": B * exp.n_steps,
                    "trial_steps_per_s": B * exp.n_steps / max(timings["run_s"], 1e-12),
                    "loadavg": os.getloadavg()})
    t = np.arange(stats.shape[1]) * exp.record_every * exp.epoch_steps * exp.dt
    return MonteCarloResult(exp, B, seed, t, stats, traj, timings, filter)


def _run_here(exp, B, seed, keep, filter, devices, progress):
    """``(stats, trajectories, timings)`` of trials ``0..B-1`` in this process, with a
    progress bar of their ``B * n_steps`` trial-steps."""
    bars = []

    def started():
        bars.append(Progress(B * exp.n_steps, enabled=progress,
                             delay=0.0 if progress else 3.0, label=exp.name.split(":")[-1]))

    try:
        stats, timings = simulate_trials(exp, 0, B, seed=seed, filter=filter, devices=devices,
                                         on_start=started, on_chunk=lambda steps: bars[0].update(steps))
    finally:
        for bar in bars:
            bar.close()
    check_finite(exp, stats)
    with jax.enable_x64(True):
        traj = trajectories(exp, range(keep), seed=seed, filter=filter) if keep else None
    return stats, traj, timings


__all__ = ["run_montecarlo", "simulate_trials", "trajectories"]
