"""One Monte Carlo trial as JAX functions: its start, one output epoch, its statistics.

:func:`trial_functions` returns ``init(trial_id, root) -> carry``, ``epoch(carry, j)`` and
``stats(carry)`` for one trial of an experiment; :mod:`uio_jax._filter.trials` batches,
shards and compiles them. Trial ``i`` uses the key ``fold_in(key(seed), i)`` (split once
into an initial and a run key); epoch ``j`` draws ONE block of normals
``normal(fold_in(run_key, j), ...)`` for all its Euler sub-steps and its outputs, so every
trial's numbers depend only on ``(seed, i)``. The numbers are JAX's default threefry ones,
bit for bit, drawn by :mod:`uio_jax._engine.threefry`.

The filter: the fast kernels of :mod:`uio_jax._filter.ekf` (``filter="fast"``, the default)
or the plain equations of :mod:`uio_jax._filter.reference_ekf` (``filter="reference"``,
their oracle). The simulation (truth, readings, outputs) is the same code either way, so
the two runs see the very same data.
"""

from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._engine import threefry
from .._errors import OptionError
from .._model.experiment import Experiment
from . import reference_ekf
from .ekf import mahalanobis_squared, make_model, output_mask, predict, update, wrap_angle

#: Inner-scan unroll of the Euler sub-steps: 1, as larger unrolls ran slower at large batches
#: (docs/benchmarks/ekf.md, "Reading").
UNROLL = 1
#: The values of ``run_montecarlo(filter=...)``.
FILTERS = ("fast", "reference")


def filter_kernels(exp: Experiment, model, filter: str):
    """``(model, predict, update, mahalanobis_squared)`` of the filter named ``filter``.

    ``"fast"``: ``model`` itself and the kernels of :mod:`uio_jax._filter.ekf` (looked up
    in this module at each call, so that ``scripts/bench_ekf.py`` can swap them out);
    ``"reference"``: the plain equations of :mod:`uio_jax._filter.reference_ekf` with their
    own model.
    """
    if filter == "fast":
        return model, predict, update, mahalanobis_squared
    return (reference_ekf.make_model(exp), reference_ekf.predict, reference_ekf.update,
            reference_ekf.mahalanobis_squared)


def check_filter(filter):
    """``filter`` if it is one of :data:`FILTERS`.

    Raises:
        OptionError: any other value.
    """
    if not (isinstance(filter, str) and filter in FILTERS):
        raise OptionError(f"filter must be one of {', '.join(map(repr, FILTERS))}, got {filter!r}")
    return filter


@dataclass(frozen=True)
class _Trial:
    """What the three functions of one trial read: the experiment, its model and filter."""

    exp: Experiment
    model: object
    fmodel: object
    f_predict: object
    f_update: object
    f_nees: object
    traj: bool

    def truth_aug(self, x, w_last):
        """The true augmented state: ``x``, the unknown inputs, zero derivatives."""
        return jnp.concatenate([x, w_last, jnp.zeros(self.model.p * (self.exp.order - 1))])


def trial_functions(exp: Experiment, traj: bool, filter: str = "fast"):
    """``init(trial_id, root) -> carry``, ``epoch(carry, j)``, ``stats(carry)``.

    ``carry = (run_key, x, istate, w_last, xa, P[, x_dr])`` for one trial (``x_dr``, the
    dead reckoning, with ``traj``: then ``epoch`` also returns the epoch's trajectory);
    ``filter``: see :func:`filter_kernels` (the simulation uses the fast model either way).
    """
    model = make_model(exp)
    t = _Trial(exp, model, *filter_kernels(exp, model, filter), traj)
    return _init_fn(t), _epoch_fn(t), _stats_fn(t)


def _init_fn(t: _Trial):
    """``init(trial_id, root)``: the trial's keys, the true start and the filter's start
    ``truth + N(0, diag(prior_std^2))``."""
    exp, N, n = t.exp, t.model.N, t.model.n
    x0 = np.asarray(exp.x0, np.float64)
    istate0 = np.asarray(exp.istate0, np.float64)
    w0 = np.asarray(exp.w0, np.float64)
    prior = np.asarray(exp.prior_std, np.float64)

    def init(trial_id, root):
        k_init, k_run = threefry.split(threefry.fold_in(root, trial_id))
        z = threefry.normal(k_init, N).astype(jnp.float64)
        x = jnp.asarray(x0)
        w_last = jnp.asarray(w0)
        xa = t.truth_aug(x, w_last) + prior * z
        Pm = jnp.diag(jnp.asarray(prior**2))
        carry = (k_run, x, jnp.asarray(istate0), w_last, xa, Pm)
        if t.traj:
            carry = carry + (xa[:n],)
        return carry

    return init


def _substep_fn(t: _Trial):
    """``sub(c, zk)``: one Euler sub-step (truth, known-input readings, EKF predict)."""
    exp, model, traj = t.exp, t.model, t.traj
    ni, m, p, dt = exp.n_input_normals, len(exp.system.known), model.p, model.dt
    law, known_std, w_reference = exp.inputs, exp.known_std, exp.w_reference

    def sub(c, zk):
        x, istate, w_last, xa, Pm = c[:5]
        istate, u, w = law(istate, zk[:ni])
        u = jnp.asarray(u, jnp.float64).reshape(m)
        w = jnp.asarray(w, jnp.float64).reshape(p)
        u_read = u + known_std(u) * zk[ni:]
        x = x + dt * model.dynamics(x, u, w)
        xa, Pm = t.f_predict(t.fmodel, xa, Pm, u_read)
        w_ref = w if w_reference is None else jnp.asarray(
            w_reference(istate, w), jnp.float64).reshape(p)
        out = (x, istate, w_ref, xa, Pm)
        if traj:
            x_dr = c[5]
            out = out + (x_dr + dt * model.dynamics(x_dr, u_read, jnp.zeros(p)),)
            return out, u_read
        return out, None

    return sub


def _epoch_fn(t: _Trial):
    """``epoch(carry, j)``: the ``K`` Euler sub-steps of output epoch ``j``, then the
    outputs read and the EKF update."""
    exp, model, traj = t.exp, t.model, t.traj
    K, ni, m, n_out = exp.epoch_steps, exp.n_input_normals, len(exp.system.known), len(exp.measurements)
    sig_out = model.sigma
    sub = _substep_fn(t)

    def epoch(carry, j):
        key, x, istate, w_last, xa, Pm = carry[:6]
        # float32 normals, used in float64: half the threefry bits and a cheap inverse error
        # function (docs/benchmarks/ekf.md, run 5); they reach about 5.3 sigma, enough here.
        z = threefry.normal(threefry.fold_in(key, j), K * (ni + m) + n_out).astype(jnp.float64)
        zs = z[:K * (ni + m)].reshape(K, ni + m)
        zy = z[K * (ni + m):]
        c0 = (x, istate, w_last, xa, Pm) + ((carry[6],) if traj else ())
        c, u_reads = lax.scan(sub, c0, zs, unroll=min(UNROLL, K))
        x, istate, w_last, xa, Pm = c[:5]
        y = model.h_true(x) + sig_out * zy
        if model.angle_out.any():
            y = jnp.where(model.angle_out, wrap_angle(y), y)
        xa, Pm = t.f_update(t.fmodel, xa, Pm, y, output_mask(model, j))
        new = (key, x, istate, w_last, xa, Pm) + ((c[5],) if traj else ())
        if traj:
            return new, (x, xa, jnp.sqrt(jnp.diag(Pm)), c[5], y, u_reads, Pm)
        return new, None

    return epoch


def _stats_fn(t: _Trial):
    """``stats(carry)``: the ``2 N + 2 d + 1`` float32 numbers kept per record (errors,
    filter sigmas, errors and sigmas along the named quantities, NEES)."""
    exp, n = t.exp, t.model.n
    ang = exp.angle_mask()
    names = exp.state_names()
    nees_idx = np.array([names.index(s) for s in exp.nees_states])
    quantities = exp.quantities

    def stats(carry):
        _, x, _, w_last, xa, Pm = carry[:6]
        err = xa - t.truth_aug(x, w_last)
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
        nees = jnp.asarray(t.f_nees(es, Ps))
        parts = [err, sig, jnp.stack(qe) if qe else jnp.zeros(0),
                 jnp.stack(qs) if qs else jnp.zeros(0), nees[None]]
        return jnp.concatenate(parts).astype(jnp.float32)

    return stats


__all__ = ["FILTERS", "UNROLL", "check_filter", "filter_kernels", "trial_functions"]
