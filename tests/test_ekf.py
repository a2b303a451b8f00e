"""The JAX EKF against an independent implementation (filterpy, analytic Jacobians).

Oracle: filterpy's ``ExtendedKalmanFilter`` (numpy, Joseph-form update, ``residual`` hook
for angles) fed with the very readings and outputs our simulation drew, with the
Jacobians, process noise and measurement Jacobian written out by hand for the unicycle
of 003 section 5. Tolerance 1e-10: the two differ only by floating-point round-off
(measured earlier: at most 9e-14 in the states).
"""

import math

import numpy as np
import pytest
from conftest import zoo

from uio_jax._filter.montecarlo import trajectories
from uio_jax._io.loading import load_module

filterpy = pytest.importorskip("filterpy.kalman")

UNI = load_module(zoo("unicycle_disturbance.py"))
DT = 5e-4
N_STEPS = 4000  # 2 s: enough for 80 updates, short enough for a fast test


def _wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class _UnicycleEKF(filterpy.ExtendedKalmanFilter):
    """Euler prediction of [xv, yv, theta, (gamma), w, w1] written out by hand."""

    def __init__(self, gamma_known):
        self.gk = gamma_known
        n = 5 if gamma_known else 6
        super().__init__(dim_x=n, dim_z=1)
        self.n = n

    def _gamma(self, x):
        return UNI.GAMMA if self.gk else x[3, 0]

    def set_model(self, u, std):
        """F (Jacobian at the prior) and Q, before predict (filterpy keeps them as attrs)."""
        x = self.x
        v, om = u
        th, g = x[2, 0], self._gamma(x)
        iw = 3 if self.gk else 4
        F = np.eye(self.n)
        F[0, 2] = -DT * v * math.sin(th)
        F[1, 2] = DT * v * math.cos(th)
        F[0, iw] = DT * math.cos(g)
        F[1, iw] = DT * math.sin(g)
        F[iw, iw + 1] = DT
        w = x[iw, 0]
        if not self.gk:
            F[0, 3] = -DT * w * math.sin(g)
            F[1, 3] = DT * w * math.cos(g)
        self.F = F
        bv = np.zeros(self.n)
        bv[:3] = [math.cos(th), math.sin(th), 0.0]
        bo = np.zeros(self.n)
        bo[2] = 1.0
        bw = np.zeros(self.n)
        bw[:2] = [math.cos(g), math.sin(g)]
        Q = DT**2 * (std[0] ** 2 * np.outer(bv, bv) + std[1] ** 2 * np.outer(bo, bo)
                     + 0.005**2 * np.outer(bw, bw))
        Q[iw, iw] += 1e-8 * DT
        Q[iw + 1, iw + 1] += 1e-8 * DT
        self.Q = Q

    def predict_x(self, u=0):
        x = self.x
        v, om = u
        th, g = x[2, 0], self._gamma(x)
        iw = 3 if self.gk else 4
        w, w1 = x[iw, 0], x[iw + 1, 0]
        dx = np.zeros((self.n, 1))
        dx[0, 0] = v * math.cos(th) + w * math.cos(g)
        dx[1, 0] = v * math.sin(th) + w * math.sin(g)
        dx[2, 0] = om
        dx[iw, 0] = w1
        self.x = x + DT * dx


def _range_H(x):
    r = math.hypot(x[0, 0], x[1, 0])
    H = np.zeros((1, x.shape[0]))
    H[0, :2] = [x[0, 0] / r, x[1, 0] / r]
    return H


def _range(x):
    return np.array([[math.hypot(x[0, 0], x[1, 0])]])


def _phi_H(x):
    r2 = x[0, 0] ** 2 + x[1, 0] ** 2
    H = np.zeros((1, x.shape[0]))
    H[0, :2] = [-x[1, 0] / r2, x[0, 0] / r2]
    return H


def _phi(x):
    return np.array([[math.atan2(x[1, 0], x[0, 0])]])


def _run_filterpy(exp, tr, gamma_known, output):
    f = _UnicycleEKF(gamma_known)
    f.x = tr["x_hat"][0, 0][:, None].copy()
    f.P = np.diag(np.asarray(exp.prior_std) ** 2)
    sigma = exp.measurements[0].sigma
    f.R = np.array([[sigma**2]])
    Hj, hx = (_range_H, _range) if output == "range" else (_phi_H, _phi)
    residual = np.subtract if output == "range" else (lambda a, b: _wrap(a - b))
    u_read = tr["u_read"][0]
    K = exp.epoch_steps
    xs, Ps = [f.x[:, 0].copy()], [f.P.copy()]
    for e in range(exp.n_epochs):
        for k in range(e * K, (e + 1) * K):
            u = u_read[k]
            f.set_model(u, 0.01 * np.abs(u))
            f.predict(u)
        f.update(np.array([[tr["y"][0, e, 0]]]), Hj, hx, residual=residual)
        xs.append(f.x[:, 0].copy())
        Ps.append(f.P.copy())
    return np.array(xs), np.array(Ps)


@pytest.mark.parametrize("name, gamma_known, output", [
    ("range_gamma_known_experiment", True, "range"),
    ("phi_gamma_unknown_experiment", False, "phi"),
])
def test_ekf_equals_filterpy(name, gamma_known, output):
    exp = getattr(UNI, name)().with_(n_steps=N_STEPS)
    tr = trajectories(exp, [3], seed=7)
    xs, Ps = _run_filterpy(exp, tr, gamma_known, output)
    ours = tr["x_hat"][0]
    # angles: compare wrapped differences
    diff = ours - xs
    for i in (2,) if gamma_known else (2, 3):
        diff[:, i] = _wrap(diff[:, i])
    assert np.max(np.abs(diff)) < 1e-10
    assert np.max(np.abs(tr["P"][0] - Ps)) < 1e-10 * np.max(np.abs(Ps))
    # the filter actually did something: it moved away from dead reckoning
    assert np.max(np.abs(ours[-1, :2] - tr["x_dr"][0, -1, :2])) > 1e-4


def test_update_skips_masked_outputs():
    """A masked output leaves the state and covariance unchanged (gain column is zero),
    and one output read equals the scalar Kalman update with it alone."""
    import jax
    import jax.numpy as jnp

    import uio_jax as uj
    from uio_jax._filter.ekf import make_model, update
    from uio_jax._model.experiment import Experiment, Measurement

    sys_ = uj.System(("a", "b"), {"a": lambda x: x[0]},
                     known={"u": lambda x: jnp.array([1.0, 0.0])},
                     unknown={"w": lambda x: jnp.array([0.0, 1.0])})
    meas = (Measurement("a", lambda x: x[0], 0.1, 2),
            Measurement("ab", lambda x: x[0] * x[1], 0.2, 3))
    exp = Experiment("toy", sys_, 0.1, 12, (1.0, 2.0), lambda s, z: (s, z[:1], z[1:]), (),
                     2, lambda u: 0.0 * u, meas, w0=(0.0,), w_white_std=(0.0,), order=1,
                     q_aug=(0.0,), prior_std=(1.0, 1.0, 1.0))
    assert exp.epoch_steps == 1 and exp.n_epochs == 12
    model = make_model(exp)
    xa = jnp.array([1.0, 2.0, 0.5])
    P = jnp.array([[1.0, 0.2, 0.1], [0.2, 2.0, 0.3], [0.1, 0.3, 0.5]])
    y = jnp.array([1.3, 1.7])
    upd = jax.jit(lambda m: update(model, xa, P, y, m))
    xa1, P1 = upd(jnp.array([False, False]))
    np.testing.assert_array_equal(np.asarray(xa1), np.asarray(xa))
    np.testing.assert_allclose(np.asarray(P1), np.asarray(P), rtol=0, atol=1e-15)
    xa2, P2 = upd(jnp.array([True, False]))
    H = np.array([[1.0, 0.0, 0.0]])
    Pn = np.asarray(P)
    S = H @ Pn @ H.T + 0.01
    Kg = Pn @ H.T / S
    np.testing.assert_allclose(np.asarray(xa2), np.asarray(xa) + Kg[:, 0] * (1.3 - 1.0),
                               rtol=1e-13)
    ikh = np.eye(3) - Kg @ H
    np.testing.assert_allclose(np.asarray(P2), ikh @ Pn @ ikh.T + 0.01 * Kg @ Kg.T, rtol=1e-13)
