# uio-jax: models
"""Visual-inertial structure from motion (Vi-SfM) with a partly missing IMU.

Martinelli, INRIA RR-8608 (004) section 11.2.2 and MED 2015 (001) section V-B summarize the
Vi-SfM with partial input knowledge (details in their refs. [28, 29]): a monocular camera
and an IMU (3 accelerometers, 3 gyroscopes) whose readings are the inputs; removing
inertial sensors turns inputs into unknown inputs, analyzed with the EORC. This zoo entry
is the standard Vi-SfM model in the form below (camera frame = IMU frame, extrinsically
calibrated), with position, velocity, attitude and ``n_f`` point features in the camera
frame::

    r'   = v                                   (position, global frame)
    v'   = R(q) A - g e_z                       (velocity, global frame; A: accelerometer)
    q'   = 1/2 q * [0, Omega]                   (attitude quaternion, local -> global;
                                                 Omega: gyroscope)
    P_i' = -Omega x P_i - R(q)^T v              (feature i in the camera frame, i = 1..n_f)

    y    = [P_ix / P_iz, P_iy / P_iz]_{i=1..n_f}, |q|^2        (camera bearings, constraint)

``R(q)`` is written homogeneous (quadratic) in q, as in ``vehicle_wind.py`` (eq. 6 of 002);
``|q|`` is constant along the dynamics and measured by the constraint output. Drift
``f0 = [v; -g e_z; 0; -R^T v ..]``; known fields ``A_x, A_y, A_z`` (columns of R in the
velocity rows) and ``Omega_x, Omega_y, Omega_z`` (quaternion rows and ``-e x P_i`` in the
feature rows). State dimension ``3 + 3 + 4 + 3 n_f``: 16 for two features, 19 for three.

Expected (standard Vi-SfM result recalled in 004 section 11.2.2): the observable modes are
the features and the velocity in the local frame, roll and pitch; the global position (3
directions) and the yaw about gravity (1) are not: ``dim = n - 4``. Observable state
components in these coordinates: every ``P_i`` and the vertical speed ``v_z``. With a
gyroscope (or accelerometer) missing, 004/001 report that the observable modes do not
change (at a high enough order k); the EORC is sufficient only, so lower orders may show
fewer.
"""

import importlib.util
import os

import jax.numpy as jnp

import uio_jax as uj

_spec = importlib.util.spec_from_file_location(
    "_uio_zoo_quaternion", os.path.join(os.path.dirname(os.path.abspath(__file__)), "_quaternion.py"))
_quaternion = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_quaternion)

GRAVITY = 9.81


_rotation_columns = _quaternion.rotation_columns


def _states(n_f):
    names = ["rx", "ry", "rz", "vx", "vy", "vz", "qt", "qx", "qy", "qz"]
    for i in range(1, n_f + 1):
        names += [f"P{i}x", f"P{i}y", f"P{i}z"]
    return tuple(names)


def _domain(n_f):
    d = {"vx": (-1.0, 1.0), "vy": (-1.0, 1.0), "vz": (-1.0, 1.0), "qt": (0.5, 1.5),
         "qx": (-0.5, 0.5), "qy": (-0.5, 0.5), "qz": (-0.5, 0.5)}
    for i in range(1, n_f + 1):
        d.update({f"P{i}x": (-1.0, 1.0), f"P{i}y": (-1.0, 1.0), f"P{i}z": (2.0, 4.0)})
    return d


def _features(x, n_f):
    return x[10:].reshape((n_f, 3))


def _model(n_f):
    n = 10 + 3 * n_f
    zeros3 = jnp.zeros(3)

    def drift(x):
        v, q = x[3:6], x[6:10]
        c1, c2, c3 = _rotation_columns(q)
        v_local = jnp.stack([c1 @ v, c2 @ v, c3 @ v])  # R^T v
        feats = jnp.tile(-v_local, n_f)
        return jnp.concatenate([v, jnp.array([0.0, 0.0, -GRAVITY]), jnp.zeros(4), feats])

    def acc(i):
        def f(x):
            col = _rotation_columns(x[6:10])[i]
            return jnp.concatenate([zeros3, col, jnp.zeros(4 + 3 * n_f)])

        return f

    def gyro(i):
        def f(x):
            qt, qx, qy, qz = x[6], x[7], x[8], x[9]
            q_dot = [jnp.stack([-qx, qt, qz, -qy]), jnp.stack([-qy, -qz, qt, qx]),
                     jnp.stack([-qz, qy, -qx, qt])][i]
            P = _features(x, n_f)
            e = jnp.eye(3)[i]
            p_dot = -jnp.cross(jnp.broadcast_to(e, P.shape), P)  # -Omega x P_i
            return jnp.concatenate([jnp.zeros(6), 0.5 * q_dot, p_dot.reshape(-1)])

        return f

    fields = {"A_x": acc(0), "A_y": acc(1), "A_z": acc(2),
              "Omega_x": gyro(0), "Omega_y": gyro(1), "Omega_z": gyro(2)}
    outputs = {}
    for i in range(n_f):
        outputs[f"u{i + 1}"] = lambda x, i=i: x[10 + 3 * i] / x[12 + 3 * i]
        outputs[f"v{i + 1}"] = lambda x, i=i: x[11 + 3 * i] / x[12 + 3 * i]
    outputs["q_norm"] = lambda x: jnp.sum(x[6:10] ** 2)
    assert n == len(_states(n_f))
    return drift, fields, outputs


def _system(n_f, unknown, name):
    drift, fields, outputs = _model(n_f)
    known = {k: f for k, f in fields.items() if k not in unknown}
    unk = {k: f for k, f in fields.items() if k in unknown}
    return uj.System(_states(n_f), outputs, known=known, unknown=unk, drift=drift,
                     domain=_domain(n_f), name=f"visual_inertial:{name}")


def full_imu(n_f=2):
    """Standard Vi-SfM: 3 accelerometers and 3 gyroscopes known (ORC), ``n_f`` features."""
    return _system(n_f, (), "full_imu")


def gyro_z_unknown(n_f=2):
    """The z gyroscope missing (its reading is an unknown input): EORC, 16 states."""
    return _system(n_f, ("Omega_z",), "gyro_z_unknown")


def acc_z_unknown(n_f=2):
    """The z accelerometer missing: EORC, 16 states."""
    return _system(n_f, ("A_z",), "acc_z_unknown")


def gyro_z_unknown_3f():
    """The z gyroscope missing, three features: 19 states."""
    return _system(3, ("Omega_z",), "gyro_z_unknown_3f")


def yaw_symmetry(x):
    """Rotation about the gravity axis: r, v rotate, q turns about global z, P_i fixed."""
    qt, qx, qy, qz = x[6], x[7], x[8], x[9]
    n_f = (x.shape[0] - 10) // 3
    return jnp.concatenate([jnp.stack([-x[1], x[0], 0.0 * x[0], -x[4], x[3], 0.0 * x[0]]),
                            0.5 * jnp.stack([-qz, -qy, qx, qt]), jnp.zeros(3 * n_f)])


#: Expected results (004 section 11.2.2 / 001 section V-B summary of the standard Vi-SfM:
#: features and local velocity, roll, pitch observable; position and yaw not).
PUBLISHED = {
    "full_imu": {"source": "004 section 11.2.2 (standard Vi-SfM, refs [13, 26] there)",
                 "method": "orc", "dim": 12,
                 "observable": ["vz", "P1x", "P1y", "P1z", "P2x", "P2y", "P2z"],
                 "symmetries": ["yaw_symmetry"]},
}
