"""The EKF's small-matrix arithmetic against dense numpy / JAX formulas.

Oracles: the dense prediction ``J P J^T + Q`` with ``J = jacfwd`` of the whole augmented
Euler step (the structured prediction skips the structural zeros of ``J``), and
``numpy.linalg.solve`` for the NEES quadratic form.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj
from uio_jax._filter.ekf import mahalanobis_squared, make_model, predict
from uio_jax._model.experiment import Experiment, Measurement


def _toy_experiment(order):
    """Two unknown inputs, a drift, a known field: every block of the prediction used."""
    sys_ = uj.System(
        ("a", "b", "c"), {"y": lambda x: x[0] * x[1]},
        drift=lambda x: jnp.stack([x[1], jnp.sin(x[0]), 0.0 * x[2]]),
        known={"u": lambda x: jnp.stack([0.0 * x[0], x[2], 1.0 + 0.0 * x[0]])},
        unknown={"w1": lambda x: jnp.stack([jnp.cos(x[2]), 0.0 * x[0], 0.0 * x[0]]),
                 "w2": lambda x: jnp.stack([0.0 * x[0], 0.0 * x[0], x[0]])})
    meas = (Measurement("y", lambda x: x[0] * x[1], 0.1, 1),)
    N = 3 + 2 * order
    return Experiment("toy", sys_, 0.05, 10, (1.0, 2.0, 0.5),
                      lambda s, z: (s, z[:1], z[1:3]), (), 3, lambda u: 0.01 * u + 0.02,
                      meas, w0=(0.1, -0.2), w_white_std=(0.3, 0.4), order=order,
                      q_aug=(1e-3,) * (2 * order), prior_std=(1.0,) * N)


def _dense_predict(model, xa, P, u):
    n, p = model.n, model.p

    def step(z):
        dx = model.dynamics(z[:n], u, z[n:n + p])
        aug = jnp.concatenate([z[n + p:], jnp.zeros(p)]) if p else jnp.zeros(0)
        return z + model.dt * jnp.concatenate([dx, aug])

    J = jax.jacfwd(step)(xa)
    return step(xa), J @ P @ J.T + model.process_noise(xa, u)


@pytest.mark.parametrize("order", [1, 2, 3])
def test_predict_equals_the_dense_formula(order):
    model = make_model(_toy_experiment(order))
    rng = np.random.default_rng(order)
    N = model.N
    xa = jnp.asarray(rng.normal(size=N))
    L = rng.normal(size=(N, N))
    P = jnp.asarray(L @ L.T + np.eye(N))
    u = jnp.asarray([0.7])
    x1, P1 = jax.jit(lambda a, b, c: predict(model, a, b, c))(xa, P, u)
    x2, P2 = _dense_predict(model, xa, P, u)
    np.testing.assert_allclose(np.asarray(x1), np.asarray(x2), rtol=0, atol=1e-14)
    np.testing.assert_allclose(np.asarray(P1), np.asarray(P2), rtol=1e-13,
                               atol=1e-13 * float(np.abs(P2).max()))
    assert not model.pattern.all()


@pytest.mark.parametrize("d", [1, 2, 3, 5, 7])
def test_mahalanobis_squared_equals_a_dense_solve(d):
    rng = np.random.default_rng(d)
    for _ in range(10):
        L = rng.normal(size=(d, d))
        P = L @ L.T + 0.1 * np.eye(d)
        e = rng.normal(size=d)
        got = jax.jit(mahalanobis_squared)(jnp.asarray(e), jnp.asarray(P))
        np.testing.assert_allclose(float(got), e @ np.linalg.solve(P, e), rtol=1e-11)
    batch = jax.vmap(mahalanobis_squared)(jnp.ones((4, d)), jnp.asarray(np.stack([P] * 4)))
    np.testing.assert_allclose(np.asarray(batch), np.ones(d) @ np.linalg.solve(P, np.ones(d)),
                               rtol=1e-11)
