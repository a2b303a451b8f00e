# uio-jax: models
"""The standard Vi-SfM: a monocular camera and a full IMU with biases, uncalibrated.

004 section 11.2 recalls the most general result on the *standard* visual-inertial structure
from motion (a camera and an IMU of three accelerometers and three gyroscopes, all read):
"all the independent observable modes are: the positions in the local frame of all the
observed features, the three components of the speed in the local frame, the biases affecting
the inertial measurements, the roll and the pitch angle, the magnitude of the gravity and the
transformation between the camera and IMU frames"; the yaw is not observable (the invariance
under rotations about gravity). This file writes that system twice.

**Local form** (:func:`full_imu_local`; the IMU frame is the local frame)::

    x = [F_1 .. F_nf (3 each), V (3), G (3), B_a (3), B_w (3), c (3), P (3)]     n = 18 + 3 n_f

    F_j' = -w x F_j - V                 w = Omega - B_w  (Omega: gyroscope readings, known)
    V'   = -w x V + G + A - B_a                           (A: accelerometer readings, known)
    G'   = -w x G
    B_a' = B_w' = c' = P' = 0
    y    = [C_jx / C_jz, C_jy / C_jz]_j,  C_j = S(c)^T (F_j - P)

``F_j``: feature j, ``V``: speed, ``G``: gravity (its direction gives roll and pitch, its norm
``g``), all in the IMU frame; ``B_a``, ``B_w``: accelerometer and gyroscope biases; ``P``: the
camera centre in the IMU frame; ``c``: the camera -> IMU rotation as a Gibbs (Cayley) vector,
``R(c) = S(c) / (1 + |c|^2)`` with ``S(c) = (1 - |c|^2) I + 2 c c^T + 2 [c]_x`` (three
parameters, rational; the bearings are ratios, so ``S`` serves for ``R``). The yaw is not a
state of this form; the paper's modes are functions of it: ``F_j``, ``V``, ``B_a``, ``B_w``,
roll ``atan2(-G_y, -G_z)``, pitch ``atan2(G_x, sqrt(G_y^2 + G_z^2))``, ``g = |G|``, ``c`` and
``P``: ``3 n_f + 18 = n`` functions. Expected: every state observable (dim n).

**Global form** (:func:`full_imu_global`; z up, origin at feature 1, the yaw a state)::

    x = [r (3), v (3), q (4), g, B_a (3), B_w (3), c (3), P (3), F_2 .. F_nf]   n = 20 + 3 n_f

    r' = v,   v' = R(q) (A - B_a) - g e_z,   q' = 1/2 q * [0, Omega - B_w],   the rest constant
    y  = [C_jx / C_jz, C_jy / C_jz]_j,  |q|^2,   C_j = S(c)^T (R(q)^T (F_j - r) - P)

Expected: dim ``n - 1``, the yaw (``yaw_symmetry``, declared and verified) the one unobservable
direction; the yaw-invariant states ``r_z, v_z, g``, the biases, ``c``, ``P`` and the heights
``F_jz`` observable. The paper's modes (``R(q)^T (F_j - r)``, ``R(q)^T v``, the biases, roll
and pitch of ``q``, ``g``, ``c``, ``P``) with the measured ``|q|^2`` are ``3 n_f + 19 = n - 1``
independent functions.

Both with the whole IMU known: the ORC (exact). One feature (the default) suffices: the local
form's ORC reaches ``n`` with dims 2, 10, 17, 21 (0.1 s), the global one ``n - 1`` with dims 3,
11, 18, 22, 22 (0.4 s); more features add their own coordinates and nothing else (two: 24 of 24
and 25 of 26, three: 27 of 27 and 28 of 29).
"""

import importlib.util
import os

import jax.numpy as jnp

import uio_jax as uj

_spec = importlib.util.spec_from_file_location(
    "_uio_zoo_quaternion", os.path.join(os.path.dirname(os.path.abspath(__file__)), "_quaternion.py"))
_quaternion = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_quaternion)

GRAVITY_BOX = (9.0, 10.5)
N_FEATURES = 1


def gibbs_rotation(c):
    """``S(c) = (1 - |c|^2) I + 2 c c^T + 2 [c]_x`` (3, 3): ``(1 + |c|^2)`` times the rotation
    of Gibbs vector ``c`` (3,)."""
    cx = jnp.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]) * c[2] + \
        jnp.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]]) * c[1] + \
        jnp.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]) * c[0]
    return (1.0 - c @ c) * jnp.eye(3) + 2.0 * jnp.outer(c, c) + 2.0 * cx


rotation_columns = _quaternion.rotation_columns
right_pure = _quaternion.right_pure


def _bearings(camera, n_f):
    """Outputs ``u_j, v_j`` of the camera-frame features ``camera(x)`` (n_f, 3)."""
    out = {}
    for j in range(n_f):
        out[f"u{j + 1}"] = lambda x, j=j: camera(x)[j, 0] / camera(x)[j, 2]
        out[f"v{j + 1}"] = lambda x, j=j: camera(x)[j, 1] / camera(x)[j, 2]
    return out


def _check(n_f):
    if isinstance(n_f, bool) or int(n_f) != n_f or n_f < 1:
        raise uj.ModelError(f"n_f must be a positive integer (number of features), got {n_f!r}")
    return int(n_f)


# ------------------------------------------------------------------ local form
def local_states(n_f=N_FEATURES) -> tuple:
    """State names of :func:`full_imu_local`."""
    names = [f"F{j}{a}" for j in range(1, n_f + 1) for a in "xyz"]
    for block in ("V", "G", "Ba", "Bw", "c", "P"):
        names += [f"{block}{a}" for a in "xyz"]
    return tuple(names)


def _local_domain(n_f):
    d = {f"F{j}{a}": b for j in range(1, n_f + 1) for a, b in zip("xyz", [(-1.0, 1.0), (-1.0, 1.0), (2.0, 4.0)])}
    d.update({"Gx": (-3.0, 3.0), "Gy": (-3.0, 3.0), "Gz": (-10.0, -8.0)})
    d.update({f"{blk}{a}": (-0.3, 0.3) for blk in ("Ba", "Bw", "c", "P") for a in "xyz"})
    return d


def full_imu_local(n_f=N_FEATURES):
    """The standard Vi-SfM in the IMU frame (module docstring): ``n_f`` features, gravity of
    unknown magnitude, accelerometer and gyroscope biases, the camera-IMU rotation (Gibbs
    vector) and translation; the six IMU readings known. ``18 + 3 n_f`` states."""
    n_f = _check(n_f)
    m = 3 * n_f  # V starts here

    def moving(x):  # the vectors a rotation of the IMU frame turns: F_j, V, G
        return x[: m + 6].reshape((-1, 3))

    def drift(x):
        Ba, Bw = x[m + 6:m + 9], x[m + 9:m + 12]
        turned = jnp.cross(jnp.broadcast_to(Bw, (n_f + 2, 3)), moving(x)).reshape(-1)  # -(-B_w) x .
        push = jnp.concatenate([jnp.tile(-x[m:m + 3], n_f), x[m + 3:m + 6] - Ba, jnp.zeros(3)])
        return jnp.concatenate([turned + push, jnp.zeros(12)])

    def acc(i):
        return lambda x: jnp.zeros(m + 18).at[m + i].set(1.0)

    def gyro(i):
        def f(x):
            e = jnp.broadcast_to(jnp.eye(3)[i], (n_f + 2, 3))
            return jnp.concatenate([-jnp.cross(e, moving(x)).reshape(-1), jnp.zeros(12)])
        return f

    def camera(x):
        S = gibbs_rotation(x[m + 12:m + 15])
        return (x[:m].reshape((n_f, 3)) - x[m + 15:m + 18]) @ S  # rows: S^T (F_j - P)

    known = {f"A_{a}": acc(i) for i, a in enumerate("xyz")}
    known.update({f"Omega_{a}": gyro(i) for i, a in enumerate("xyz")})
    return uj.System(local_states(n_f), _bearings(camera, n_f), known=known, drift=drift,
                     domain=_local_domain(n_f), name="visual_inertial_standard:full_imu_local")


# ------------------------------------------------------------------ global form
def global_states(n_f=N_FEATURES) -> tuple:
    """State names of :func:`full_imu_global`."""
    names = ["rx", "ry", "rz", "vx", "vy", "vz", "qt", "qx", "qy", "qz", "g"]
    for block in ("Ba", "Bw", "c", "P"):
        names += [f"{block}{a}" for a in "xyz"]
    return tuple(names + [f"F{j}{a}" for j in range(2, n_f + 1) for a in "xyz"])


def _global_domain(n_f):
    d = {"rx": (-0.5, 0.5), "ry": (-0.5, 0.5), "rz": (-4.0, -2.0),
         "vx": (-1.0, 1.0), "vy": (-1.0, 1.0), "vz": (-1.0, 1.0),
         "qt": (0.8, 1.2), "qx": (-0.15, 0.15), "qy": (-0.15, 0.15), "qz": (-0.15, 0.15),
         "g": GRAVITY_BOX}
    d.update({f"{blk}{a}": (-0.3, 0.3) for blk in ("Ba", "Bw", "c", "P") for a in "xyz"})
    d.update({f"F{j}{a}": b for j in range(2, n_f + 1) for a, b in zip("xyz", [(-1.0, 1.0)] * 2 + [(-0.5, 0.5)])})
    return d


def global_camera(x):
    """``C_j = S(c)^T (R(q)^T (F_j - r) - P)`` for every feature of :func:`full_imu_global`,
    ``(n_f, 3)`` (feature 1 at the origin)."""
    cols = jnp.stack(rotation_columns(x[6:10]))  # rows: R^T
    feats = jnp.concatenate([jnp.zeros((1, 3)), x[23:].reshape((-1, 3))])
    local = (feats - x[0:3]) @ cols.T - x[20:23]
    return local @ gibbs_rotation(x[17:20])


def full_imu_global(n_f=N_FEATURES):
    """The standard Vi-SfM in a global frame (module docstring): the yaw is a state,
    declared as the symmetry ``yaw_symmetry``. ``20 + 3 n_f`` states."""
    n_f = _check(n_f)
    n = 20 + 3 * n_f

    def drift(x):
        q, g, Ba, Bw = x[6:10], x[10], x[11:14], x[14:17]
        cols = rotation_columns(q)
        dv = -(Ba[0] * cols[0] + Ba[1] * cols[1] + Ba[2] * cols[2]) - jnp.stack([0.0 * g, 0.0 * g, g])
        dq = -0.5 * (Bw[0] * right_pure(q, 0) + Bw[1] * right_pure(q, 1) + Bw[2] * right_pure(q, 2))
        return jnp.concatenate([x[3:6], dv, dq, jnp.zeros(n - 10)])

    def acc(i):
        return lambda x: jnp.concatenate([jnp.zeros(3), rotation_columns(x[6:10])[i], jnp.zeros(n - 6)])

    def gyro(i):
        return lambda x: jnp.concatenate([jnp.zeros(6), 0.5 * right_pure(x[6:10], i), jnp.zeros(n - 10)])

    known = {f"A_{a}": acc(i) for i, a in enumerate("xyz")}
    known.update({f"Omega_{a}": gyro(i) for i, a in enumerate("xyz")})
    outputs = _bearings(global_camera, n_f)
    outputs["q_norm"] = lambda x: jnp.sum(x[6:10] ** 2)
    return uj.System(global_states(n_f), outputs, known=known, drift=drift,
                     domain=_global_domain(n_f), symmetries={"yaw_symmetry": yaw_symmetry},
                     name="visual_inertial_standard:full_imu_global")


def yaw_symmetry(x):
    """Rotation about gravity through feature 1 (per radian) of :func:`full_imu_global`'s
    state: ``r``, ``v``, ``F_j`` turn about z, ``q -> e_z q``; the rest fixed."""
    def about_z(w):
        return jnp.stack([-w[1], w[0], 0.0 * w[0]])

    qt, qx, qy, qz = x[6], x[7], x[8], x[9]
    feats = [about_z(f) for f in x[23:].reshape((-1, 3))]
    return jnp.concatenate([about_z(x[0:3]), about_z(x[3:6]), 0.5 * jnp.stack([-qz, -qy, qx, qt]),
                            jnp.zeros(13), *feats])


#: 004 section 11.2: the standard Vi-SfM's observable modes (refs [13, 26] there), in the
#: coordinates of this file, one feature: every state of the local form; in the global form
#: every state the yaw does not move.
PUBLISHED = {
    "full_imu_local": {"source": "004 section 11.2 (standard Vi-SfM, refs [13, 26] there)",
                       "method": "orc", "dim": 21, "observable": list(local_states(1))},
    "full_imu_global": {"source": "004 section 11.2 (standard Vi-SfM, refs [13, 26] there)",
                        "method": "orc", "dim": 22,
                        "observable": ["rz", "vz", "g", "Bax", "Bay", "Baz", "Bwx", "Bwy", "Bwz",
                                       "cx", "cy", "cz", "Px", "Py", "Pz"],
                        "symmetries": ["yaw_symmetry"]},
}
