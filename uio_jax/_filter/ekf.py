"""One-trial extended Kalman filter on the state augmented by the unknown inputs.

Filter state (``N = n + p * order``)::

    xa = [x (n); w (p); w1 (p); ...; w^(order-1) (p)]

    x'        = f0(x) + sum_i f_i(x) u_i + sum_j g_j(x) w_j
    w^(k)'    = w^(k+1)           (k < order - 1)
    w^(top)'  = 0 + white noise

discretised by Euler at ``dt``: ``xa+ = xa + dt * F(xa, u)``. Everything here acts on ONE
trial (shapes without a batch axis); the Monte Carlo driver vmaps it.

* **Predict** ``P <- J P J^T + Q(xa, u)``, ``J = d xa+ / d xa``, using its structure: the
  augmented rows are ``I + dt * shift`` by construction, and ``D = d f / d(x, w)`` (the only
  dense part) has the structural zeros that :func:`~uio_jax._filter.sparsity.jacobian_pattern`
  reads from the model's jaxpr. Only the columns of ``D`` that can be non-zero are
  computed (one JVP tangent each, the step's value from the same pass), and the products
  are element-wise sums over the non-zeros, never ``@`` (XLA's CPU dot on a batch of small
  matrices runs one matrix at a time: ``docs/benchmarks/ekf.md``, runs 4 and 5).
* **Process noise**, state- and input-dependent::

      Q = dt^2 sum_i std_i(u)^2 f_i(x) f_i(x)^T      (known-input reading noise)
        + dt^2 sum_j sigma_j^2 g_j(x) g_j(x)^T         (white part of w_j)
        + dt * diag(0, q_aug)                          (augmented random walk)

* **Update** (Joseph form, all outputs of an epoch at once, ``H = dh/dxa`` by autodiff)::

      nu = wrap(y - h(xa))      (angle outputs wrapped to [-pi, pi))
      S  = H P H^T + R,   K = P H^T S^-1
      xa <- xa + K nu,    P <- (I - K H) P (I - K H)^T + K R K^T

  Outputs not read at this epoch (``mask`` false) get a zero row in ``H``, a zero
  innovation and unit variance: their gain column is exactly zero.

:mod:`uio_jax._filter.reference_ekf` is the same filter written as the plain matrix
equations (``jacfwd``, ``@``, ``solve``); ``tests/test_ekf_reference.py`` holds the two equal.
"""

import math
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from .fast_trig import with_vectorized_trig
from .sparsity import jacobian_pattern

TWO_PI = 2.0 * math.pi


def wrap_angle(a):
    """Wrap angles (rad) to ``[-pi, pi)``; any shape."""
    return jnp.mod(a + math.pi, TWO_PI) - math.pi


class Model(NamedTuple):
    """The experiment's functions specialised for one trial (no batch axis).

    Attributes:
        n, p, order, N: sizes (system state, unknown inputs, augmentation order, filter).
        dt: Euler step (s).
        dynamics: ``(x (n,), u (m,), w (p,)) -> x' (n,)``, the system's vector field.
        process_noise: ``(xa (N,), u_read (m,)) -> Q (N, N)``.
        h: ``xa (N,) -> (n_out,)``, every measurement on the filter state.
        h_true: ``x (n,) -> (n_out,)``, the same on the system state.
        sigma: ``(n_out,)`` measurement noise std. angle_out: ``(n_out,)`` bool.
        period: ``(n_out,)`` int, each output's period in epochs.
        pattern: ``(n, n + p)`` bool, where ``d dynamics / d(x, w)`` may be non-zero (read
            from the jaxpr by :func:`~uio_jax._filter.sparsity.jacobian_pattern`).
    """

    n: int
    p: int
    order: int
    N: int
    dt: float
    dynamics: object
    process_noise: object
    h: object
    h_true: object
    sigma: np.ndarray
    angle_out: np.ndarray
    period: np.ndarray
    pattern: np.ndarray


def make_model(exp, fast_trig: bool = True) -> Model:
    """Build the one-trial :class:`Model` of an :class:`~uio_jax.Experiment`.

    ``fast_trig``: the model's functions evaluate float64 ``sin`` / ``cos`` by
    :func:`~uio_jax._filter.fast_trig.with_vectorized_trig` (XLA's CPU backend runs the
    library calls one element at a time); ``False`` keeps ``jnp.sin`` / ``jnp.cos`` (the
    reference filter). ``pattern`` is read from the plain functions either way.
    """
    sys_ = exp.system
    n, p, order = sys_.n, len(sys_.unknown), exp.order
    N = n + p * order
    dt = float(exp.dt)
    # float64 sin / cos by vectorizable arithmetic (measured: docs/benchmarks/ekf.md, run 7)
    trig = with_vectorized_trig if fast_trig else (lambda fn: fn)
    known = tuple(trig(f) for f in sys_.known.values())
    unknown = tuple(trig(g) for g in sys_.unknown.values())
    drift = trig(sys_.drift) if sys_.drift is not None else None
    w_white = np.asarray(exp.w_white_std, np.float64)
    q_aug = np.asarray(exp.q_aug, np.float64) * dt
    known_std = exp.known_std
    dynamics = _vector_field(n, drift, known, unknown)

    def process_noise(xa, u_read):
        # sum of outer products of a few columns, written elementwise (batched small
        # dots are slow on XLA CPU); padded to (N, N) with the augmented diagonal
        x = xa[:n]
        std = known_std(u_read)
        cols = [f(x) * (dt * std[i]) for i, f in enumerate(known)]
        cols += [g(x) * (dt * w_white[j]) for j, g in enumerate(unknown)]
        pad = jnp.zeros(N - n, xa.dtype)
        Q = jnp.zeros((N, N), xa.dtype)
        for c in cols:
            c = jnp.concatenate([c, pad]) if p else c
            Q = Q + c[:, None] * c[None, :]
        if p:
            Q = Q + jnp.diag(jnp.concatenate([jnp.zeros(n, xa.dtype), jnp.asarray(q_aug)]))
        return Q

    meas = exp.measurements
    fns = tuple(trig(m.fn) for m in meas)

    def h_true(x):
        return jnp.stack([fn(x) for fn in fns])

    def h(xa):
        return h_true(xa[:n])

    sigma = np.array([m.sigma for m in meas], np.float64)
    angle_out = np.array([m.angle for m in meas], bool)
    period = np.array([m.every // exp.epoch_steps for m in meas], np.int64)
    m = len(known)
    plain = _vector_field(n, sys_.drift, tuple(sys_.known.values()), tuple(sys_.unknown.values()))
    pattern = jacobian_pattern(lambda z: plain(z[:n], z[n + p:], z[n:n + p]),
                               np.zeros(n + p + m))[:, :n + p]
    return Model(n, p, order, N, dt, dynamics, process_noise, h, h_true,
                 sigma, angle_out, period, pattern)


def _vector_field(n, drift, known, unknown):
    """``(x, u, w) -> f0(x) + sum_i f_i(x) u_i + sum_j g_j(x) w_j``, shape ``(n,)``."""

    def dynamics(x, u, w):
        dx = drift(x) if drift is not None else jnp.zeros(n, x.dtype)
        for i, f in enumerate(known):
            dx = dx + f(x) * u[i]
        for j, g in enumerate(unknown):
            dx = dx + g(x) * w[j]
        return dx

    return dynamics


def predict(model: Model, xa, P, u_read):
    """EKF prediction over one Euler step.

    Args:
        model: from :func:`make_model`.
        xa: filter state, shape ``(N,)``. P: covariance ``(N, N)``.
        u_read: known-input readings of this step, shape ``(m,)``.

    Returns:
        ``(xa+, P+)`` with ``P+ = J P J^T + Q(xa, u_read)`` (see the module doc).

    ``J = [[[I_n 0] + dt D, 0], [0, I + dt S]]`` (``q = n + p``, ``D = d f / d(x, w)`` of shape
    ``(n, q)``, ``S`` the shift of the derivatives of ``w``); ``J P J^T`` is ``J (J P)^T``, each
    product by :func:`_apply_transition`, which skips the structural zeros of ``D``.
    """
    n, p = model.n, model.p

    def flow(xw):
        return model.dynamics(xw[:n], u_read, xw[n:])

    # the columns of D that the pattern says can be non-zero, one tangent each
    cols = np.flatnonzero(model.pattern.any(axis=0))
    if cols.size:
        f, Dc = jax.vmap(lambda t: jax.jvp(flow, (xa[:n + p],), (t,)),
                         out_axes=(None, 1))(np.eye(n + p)[cols])
    else:
        f, Dc = flow(xa[:n + p]), None
    D = {j: Dc[:, k] for k, j in enumerate(cols)}                    # column j of D, (n,)
    JP = _apply_transition(model, D, P)
    if p:
        f = jnp.concatenate([f, xa[n + p:], jnp.zeros(p, xa.dtype)])
    return xa + model.dt * f, _apply_transition(model, D, JP.T) \
        + model.process_noise(xa, u_read)


def _apply_transition(model: Model, D, X):
    """``J X`` for the filter's transition ``J`` (see :func:`predict`), ``X`` of shape ``(N, N)``.

    ``D`` maps a column index ``j`` to column ``j`` of ``D`` (``(n,)``), for the columns
    where ``model.pattern`` has a non-zero.

    Row ``i`` of the system state: ``X[i] + dt sum_j D[i, j] X[j]`` over the ``j`` where
    ``model.pattern[i, j]`` (``n q N`` multiply-adds at most, against ``N^3`` for a dense
    ``J``); rows of ``w^(k)``: ``X[w^(k)] + dt X[w^(k+1)]``, the top one unchanged.
    """
    n, p, dt = model.n, model.p, model.dt
    rows = []
    for i in range(n):
        terms = [D[j][i] * X[j] for j in np.flatnonzero(model.pattern[i])]
        rows.append(X[i] + dt * sum(terms[1:], terms[0]) if terms else X[i])
    top = jnp.stack(rows)
    if X.shape[0] == n:
        return top
    aug = X[n:]
    aug = aug + dt * jnp.concatenate([aug[p:], jnp.zeros((p, X.shape[1]), X.dtype)])
    return jnp.concatenate([top, aug])


def _small_matmul(A, B):
    """``A @ B`` for small matrices ``(a, c) x (c, b)``, as ``c`` broadcast rank-one terms.

    Under ``vmap`` over trials XLA fuses the terms into one element-wise loop, where its CPU
    dot runs one small matrix of the batch at a time.
    """
    return sum(A[:, j, None] * B[None, j, :] for j in range(A.shape[1]))


def _sandwich(A, P):
    """``A P A^T`` for small square matrices, by :func:`_small_matmul`."""
    return _small_matmul(_small_matmul(A, P), A.T)


def mahalanobis_squared(e, P):
    """``e^T P^-1 e`` for a small symmetric positive-definite ``P`` ``(d, d)``, ``e`` ``(d,)``.

    Symmetric Gaussian elimination written out element by element (``P = L D L^T``, then
    ``sum_i y_i^2 / D_i`` with ``L y = e``): about ``d^3 / 6`` multiply-adds that XLA fuses
    over a batch (``docs/benchmarks/ekf.md``, run 5). No pivoting: exact for SPD ``P`` (as
    stable as Cholesky); an indefinite ``P`` of a broken filter gives a finite value as long
    as no leading minor is singular.
    """
    d = e.shape[0]
    A = [[P[i, j] for j in range(d)] for i in range(d)]
    y = [e[i] for i in range(d)]
    total = 0.0
    for k in range(d):
        piv = A[k][k]
        total = total + y[k] * y[k] / piv
        for i in range(k + 1, d):
            f = A[i][k] / piv
            y[i] = y[i] - f * y[k]
            for j in range(k + 1, i + 1):
                A[i][j] = A[i][j] - f * A[j][k]
    return total


def update(model: Model, xa, P, y, mask=None):
    """EKF update (Joseph form) with the outputs ``y`` of one epoch.

    Args:
        model: from :func:`make_model`.
        xa: ``(N,)``. P: ``(N, N)``. y: ``(n_out,)`` measurements (angles in rad).
        mask: optional ``(n_out,)`` bool, outputs read at this epoch (``None``: all).

    Returns:
        ``(xa+, P+)``.
    """
    hx = model.h(xa)
    H = jax.jacrev(model.h)(xa)                               # (n_out, N)
    nu = y - hx
    if model.angle_out.any():
        nu = jnp.where(model.angle_out, wrap_angle(nu), nu)
    r = jnp.asarray(model.sigma**2)
    if mask is not None:
        nu = jnp.where(mask, nu, 0.0)
        H = jnp.where(mask[:, None], H, 0.0)
        r = jnp.where(mask, r, 1.0)
    PHt = _small_matmul(P, H.T)                                # (N, n_out)
    S = _small_matmul(H, PHt) + jnp.diag(r)
    if hx.shape[0] == 1:
        K = PHt / S[0, 0]
    else:
        K = jnp.linalg.solve(S, PHt.T).T                      # S symmetric
    xa = xa + _small_matmul(K, nu[:, None])[:, 0]
    ikh = jnp.eye(model.N, dtype=P.dtype) - _small_matmul(K, H)
    P = _sandwich(ikh, P) + _small_matmul(K * r, K.T)
    return xa, P


def output_mask(model: Model, epoch):
    """Which outputs are read at epoch index ``epoch`` (0-based; read at ``epoch + 1``)."""
    if np.all(model.period == 1):
        return None
    return jnp.mod(epoch + 1, jnp.asarray(model.period)) == 0
