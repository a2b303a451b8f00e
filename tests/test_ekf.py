"""The JAX EKF against an independent implementation (filterpy, analytic Jacobians).

Oracle: filterpy's ``ExtendedKalmanFilter`` (numpy, Joseph-form update, ``residual`` hook
for angles) fed with the very readings and outputs our simulation drew, with the
Jacobians, process noise and measurement Jacobian written out by hand for the unicycle
of 003 section 5. Tolerance 1e-10: the two differ only by floating-point round-off
(notes/ekf.md measured <= 9e-14 in the states).
"""

import math

import numpy as np
import pytest
from conftest import zoo

from uio_jax._loading import load_module
from uio_jax._montecarlo import trajectories

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
    """A masked output leaves the state and covariance unchanged (gain column is zero)."""
    import jax
    import jax.numpy as jnp

    from uio_jax._ekf import make_model, update

    vw = load_module(zoo("vehicle_wind.py"))
    exp = vw.with_wind_experiment()
    model = make_model(exp)
    xa = jnp.asarray(np.r_[exp.x0, 0.2, 0.0]) + 0.01
    P = jnp.eye(model.N) * 0.01
    y = model.h(xa) + 0.1
    mask_none = jnp.zeros(len(exp.measurements), bool)
    xa1, P1 = jax.jit(lambda a, b: update(model, a, b, y, mask_none))(xa, P)
    np.testing.assert_array_equal(np.asarray(xa1), np.asarray(xa))
    np.testing.assert_allclose(np.asarray(P1), np.asarray(P), rtol=0, atol=1e-17)
    # one output read = a scalar update with that output alone
    mask1 = jnp.zeros(len(exp.measurements), bool).at[0].set(True)
    xa2, P2 = update(model, xa, P, y, mask1)
    H = np.asarray(jax.grad(exp.measurements[0].fn)(xa[:7]))
    H = np.r_[H, 0.0, 0.0][None]
    S = H @ np.asarray(P) @ H.T + exp.measurements[0].sigma ** 2
    Kg = np.asarray(P) @ H.T / S
    nu = float(y[0] - model.h(xa)[0])
    np.testing.assert_allclose(np.asarray(xa2), np.asarray(xa) + Kg[:, 0] * nu, rtol=1e-12)
