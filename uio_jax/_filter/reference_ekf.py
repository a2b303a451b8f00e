"""The reference EKF: the filter of :mod:`uio_jax._filter.ekf` as plain matrix equations.

The same filter on the same augmented state ``xa (N,)``, written as the textbook equations in
the manner of dynamax's ``inference_ekf.py``: dense ``jax.jacfwd`` Jacobians, ``@`` and
``jnp.linalg.solve``, ``jnp.sin`` / ``jnp.cos``. It is slow and serves as the oracle of the
fast kernels: ``run_montecarlo(..., filter="reference")`` runs a whole experiment with it, and
``tests/test_ekf_reference.py`` holds the two equal to round-off. The functions take the same
arguments as the fast ones, with a :class:`~uio_jax._filter.ekf.Model` from :func:`make_model`.
"""

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.linalg import block_diag

from . import ekf
from .ekf import Model, wrap_angle


def make_model(exp) -> Model:
    """The one-trial :class:`~uio_jax._filter.ekf.Model` of an experiment, plain functions.

    Its fields, outputs and ``sin`` / ``cos`` are the System's own (no vectorized trig), and
    its process noise is, with ``B = [f_1(x) .. f_m(x)]`` ``(n, m)`` the known-input fields,
    ``G = [g_1(x) .. g_p(x)]`` ``(n, p)`` the unknown-input ones, ``s(u)`` the known-input
    reading std ``(m,)``, ``sigma_w`` the white-noise std of each ``w_j`` ``(p,)`` and
    ``q_aug`` the random-walk intensity of the augmented states ``(N - n,)``::

        Q = blockdiag(dt^2 (B diag(s^2) B^T + G diag(sigma_w^2) G^T),  dt diag(q_aug))
    """
    base = ekf.make_model(exp, fast_trig=False)
    n, dt = base.n, base.dt
    fields = tuple(exp.system.known.values()) + tuple(exp.system.unknown.values())
    w_white = np.asarray(exp.w_white_std, np.float64).reshape(-1)
    q_aug = np.asarray(exp.q_aug, np.float64).reshape(-1)
    known_std = exp.known_std

    def process_noise(xa, u_read):
        x = xa[:n]
        if not fields:
            return block_diag(jnp.zeros((n, n)), jnp.diag(dt * q_aug))
        cols = jnp.stack([f(x) for f in fields], axis=1)                      # (n, m + p)
        std = jnp.concatenate([jnp.reshape(known_std(u_read), (-1,)), w_white])
        return block_diag(dt**2 * cols @ jnp.diag(std**2) @ cols.T, jnp.diag(dt * q_aug))

    return base._replace(process_noise=process_noise)


def transition(model: Model, xa, u_read):
    """One Euler step of the augmented state, ``(N,) -> (N,)``.

    ``xa+ = xa + dt [f(x, u_read, w); w^(1); ..; w^(order-1); 0]`` with ``w = w^(0)``.
    """
    n, p = model.n, model.p
    dx = model.dynamics(xa[:n], u_read, xa[n:n + p])
    return xa + model.dt * jnp.concatenate([dx, xa[n + p:], jnp.zeros(p, xa.dtype)])


def predict(model: Model, xa, P, u_read):
    """Prediction: ``xa <- f(xa)``, ``P <- F P F^T + Q(xa, u_read)``, ``F = jacfwd(f)``.

    ``f`` is :func:`transition`; ``xa (N,)``, ``P (N, N)``, ``u_read (m,)``; returns
    ``(xa+, P+)`` of the same shapes. ``Q`` is evaluated at the prior ``xa``.
    """
    F = jax.jacfwd(lambda z: transition(model, z, u_read))(xa)                  # (N, N)
    return transition(model, xa, u_read), F @ P @ F.T + model.process_noise(xa, u_read)


def update(model: Model, xa, P, y, mask=None):
    """Update with the outputs ``y (n_out,)`` of one epoch, Joseph form.

    ``H = jacfwd(h)(xa)`` ``(n_out, N)``, ``nu = y - h(xa)`` (wrapped to ``[-pi, pi)``
    for the angle outputs), ``R = diag(sigma^2)``::

        S = H P H^T + R,   K = P H^T S^-1,   xa <- xa + K nu,
        P <- (I - K H) P (I - K H)^T + K R K^T

    ``mask (n_out,)`` bool (``None``: all read): an output not read gets a zero row of
    ``H``, a zero innovation and ``R = 1``, so its column of ``K`` is zero (as if absent).
    """
    H = jax.jacfwd(model.h)(xa)
    nu = y - model.h(xa)
    nu = jnp.where(model.angle_out, wrap_angle(nu), nu)
    r = jnp.asarray(model.sigma**2)
    if mask is not None:
        nu, H, r = jnp.where(mask, nu, 0.0), jnp.where(mask[:, None], H, 0.0), jnp.where(mask, r, 1.0)
    R = jnp.diag(r)
    S = H @ P @ H.T + R
    K = jnp.linalg.solve(S, H @ P).T                   # P H^T S^-1, as S and P are symmetric
    I_KH = jnp.eye(model.N, dtype=P.dtype) - K @ H
    return xa + K @ nu, I_KH @ P @ I_KH.T + K @ R @ K.T


def mahalanobis_squared(e, P):
    """``e^T P^-1 e`` for ``e (d,)`` and a symmetric positive-definite ``P (d, d)``."""
    return e @ jnp.linalg.solve(P, e)
