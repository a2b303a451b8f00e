"""3D vehicle with airspeed sensors, gyroscopes and a monocular camera, in wind.

Martinelli, "State Observability in Presence of Disturbances", IROS 2017 (seed 002), section III.

State ``X = [x, y, z, qt, qx, qy, qz]``: position of the vehicle in the global frame (origin at
the observed point feature, z-axis along the wind) and the quaternion q from the global to
the local frame. Dynamics (eq. 6)::

    d r_q / dt = w k + q V_q q*          (V: airspeed in the local frame, known)
    d q / dt   = 1/2 q Omega_q           (Omega: angular speed in the local frame, known)

so the known fields are ``f1..f3`` (Omega_x, Omega_y, Omega_z) and ``f4..f6`` (V_x, V_y,
V_z: the columns of the rotation matrix, written homogeneous in q as in the paper) and the
wind field is ``g = [0, 0, 1, 0, 0, 0, 0]``. Outputs (eqs. 7, 8): the camera ratios
``h_u = F_x / F_z``, ``h_v = F_y / F_z`` with ``F = q* r q`` (up to sign), and the
constraint ``h_const = q* q``.

Note: the extracted text of seed 002 prints ``f2 = 1/2 [0,0,0, -qy, qz, qt, qx]``; the
quaternion product gives ``-qz`` in the x-slot (seed 000 has it right). With the typo even
the no-wind case would come out fully observable, against the paper.
"""

import jax.numpy as jnp

import uio_jax as uj

STATES = ("x", "y", "z", "qt", "qx", "qy", "qz")
# Positions away from the feature (camera looks at it, F_z != 0); quaternion components
# anywhere in a box (the norm is an output).
DOMAIN = {"x": (0.5, 1.5), "y": (0.5, 1.5), "z": (0.5, 1.5),
          "qt": (0.5, 1.5), "qx": (-0.5, 0.5), "qy": (-0.5, 0.5), "qz": (-0.5, 0.5)}


def _zero3():
    return jnp.zeros(3)


def rotation_columns(X):
    """Columns of the rotation local -> global, homogeneous (quadratic) in q: (3, 3)."""
    qt, qx, qy, qz = X[3], X[4], X[5], X[6]
    c1 = jnp.stack([qt**2 + qx**2 - qy**2 - qz**2, 2 * (qx * qy + qt * qz), 2 * (qx * qz - qt * qy)])
    c2 = jnp.stack([2 * (qx * qy - qt * qz), qt**2 - qx**2 + qy**2 - qz**2, 2 * (qy * qz + qt * qx)])
    c3 = jnp.stack([2 * (qx * qz + qt * qy), 2 * (qy * qz - qt * qx), qt**2 - qx**2 - qy**2 + qz**2])
    return c1, c2, c3


def _omega_field(i):
    def f(X):
        qt, qx, qy, qz = X[3], X[4], X[5], X[6]
        q_dot = [
            jnp.stack([-qx, qt, qz, -qy]),  # Omega_x
            jnp.stack([-qy, -qz, qt, qx]),  # Omega_y (seed 002 prints +qz: typo)
            jnp.stack([-qz, qy, -qx, qt]),  # Omega_z
        ][i]
        return jnp.concatenate([_zero3(), 0.5 * q_dot])

    return f


def _speed_field(i):
    def f(X):
        return jnp.concatenate([rotation_columns(X)[i], jnp.zeros(4)])

    return f


def feature_in_local_frame(X):
    """``q* r q`` (the feature position in the local frame, up to sign), homogeneous in q."""
    c1, c2, c3 = rotation_columns(X)
    r = X[:3]
    return jnp.stack([c1 @ r, c2 @ r, c3 @ r])


def _h_u(X):
    F = feature_in_local_frame(X)
    return F[0] / F[2]


def _h_v(X):
    F = feature_in_local_frame(X)
    return F[1] / F[2]


def _h_const(X):
    return X[3] ** 2 + X[4] ** 2 + X[5] ** 2 + X[6] ** 2


def _wind(X):
    return jnp.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0])


KNOWN = {
    "Omega_x": _omega_field(0), "Omega_y": _omega_field(1), "Omega_z": _omega_field(2),
    "V_x": _speed_field(0), "V_y": _speed_field(1), "V_z": _speed_field(2),
}
OUTPUTS = {"h_u": _h_u, "h_v": _h_v, "h_const": _h_const}


def no_wind():
    """No disturbance: ORC with the six known inputs (002 section III-B)."""
    return uj.System(STATES, OUTPUTS, known=KNOWN, domain=DOMAIN, name="vehicle_wind:no_wind")


def with_wind():
    """Wind along z treated as one more *known* input (an ORC sanity case)."""
    known = dict(KNOWN, w=_wind)
    return uj.System(STATES, OUTPUTS, known=known, domain=DOMAIN, name="vehicle_wind:with_wind")


def wind_unknown():
    """Wind along z of unknown, time-varying magnitude (002 section III-C)."""
    return uj.System(STATES, OUTPUTS, known=KNOWN, unknown={"w": _wind}, domain=DOMAIN,
                     name="vehicle_wind:wind_unknown")


def yaw_symmetry(X):
    """The published unobservable direction with wind (002 section III-C, seventh step)."""
    x, y, _, qt, qx, qy, qz = X
    return jnp.array([-y, x, 0.0, -qz / 2, -qy / 2, qx / 2, qt / 2])


#: Published results, next to the models they belong to.
PUBLISHED = {
    "no_wind": {
        "source": "002 section III-B",
        "method": "orc",
        "dims": [3, 4, 4],
        "dim": 4,
        "observable": [],
    },
    "wind_unknown": {
        "source": "002 section III-C",
        "method": "single_ui",
        "dims": [3, 5, 6, 6],
        "dim": 6,
        "m_prime": 0,
        "m_star": 2,
        "observable": ["z"],
        "symmetries": ["yaw_symmetry"],
    },
}
