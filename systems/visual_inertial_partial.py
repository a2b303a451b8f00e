# uio-jax: models
"""Vi-SfM with partial input knowledge: a camera and one or two accelerometers, no gyroscope.

Martinelli, INRIA RR-8608 (004) section 11.2.2 and MED 2015 (001) section V-B summarize three
cases computed in their refs. [28] (ICRA 2014) and [29] (Foundations and Trends in Robotics
2014); the state formulation of [28, 29] is not in the shared papers, so the one below is
derived here. Its dimensions are 12 (case 1) and 23 (case 2), as published; case 3 has one
bias more, 24 (the paper says 23, see "Differences" below). The inputs are specific forces
``A`` (accelerometer axes) and angular speeds ``Omega`` (gyroscopes); a missing sensor is an
unknown input.

**Case 1: camera extrinsically calibrated, one accelerometer, one point feature**
(``calibrated_one_acc``, 12 states, global frame). The camera frame is the accelerometer
frame; the global frame has its origin at the feature and its z axis up. State::

    x = [r (3), v (3), q (4), g (1), B (1)]                                   n = 12

``r``, ``v``: position and velocity of the camera (global frame), ``q``: attitude quaternion
(local -> global), ``g``: gravity magnitude, ``B``: bias of the accelerometer (x axis).
Dynamics, with ``R(q)`` homogeneous (quadratic) in q as in ``visual_inertial.py``::

    r' = v
    v' = R(q) [a_x - B, A_y, A_z] - g e_z      a_x known; A_y, A_z unknown
    q' = 1/2 q * [0, Omega]                     Omega_x, Omega_y, Omega_z unknown
    g' = 0,  B' = 0
    y  = [F_x / F_z, F_y / F_z], |q|^2          F = R(q)^T (0 - r): the feature, camera frame

Five unknown inputs; the EORC to order k works on ``12 + 5 k`` coordinates (47 at k = 7,
as in 004). The yaw is a state direction here: the rotation about gravity (global z) of
``r``, ``v`` and ``q`` (``yaw_symmetry``) leaves the outputs and the dynamics invariant, so
it is unobservable even with the full IMU. Published: every function of the original state
except the yaw is observable (EORC, k = 7): ``dim = n - 1 = 11``, the unobservable direction
``yaw_symmetry``; the yaw-invariant state components ``r_z``, ``v_z``, ``g``, ``B``.

**Cases 2 and 3: camera extrinsically uncalibrated** (``uncalibrated_one_acc``,
``uncalibrated_two_acc``; local frame = camera frame, ``n_f`` point features, default 2).
The accelerometers sit at an unknown point ``P`` of the camera frame with an unknown
orientation ``q_c`` (accelerometer -> camera), so the camera is not at the accelerometer:
the lever arm brings ``omega x (omega x P)`` into the dynamics, quadratic in the angular
speed, which is therefore a state (its derivative ``W = omega'`` is the unknown input; the
promotion STRIKE-GOLDD makes for an input that enters non-affinely). State::

    x = [V (3), G (3), omega (3), P (3), q_c (4), B_1 (, B_2), F_1 .. F_nf (3 each)]
    n = 16 + n_acc + 3 n_f      (23 for one accelerometer, 24 for two, with n_f = 2)

``V``: camera velocity in the camera frame, ``G``: gravity acceleration in the camera frame
(its norm is g; its direction gives roll and pitch), ``omega``: camera angular speed (camera
frame), ``B_i``: bias of the known accelerometer ``i``, ``F_j``: feature ``j`` in the camera
frame. With ``R_c = R(q_c)`` and the accelerometer-frame specific force ``s``::

    F_j'   = -omega x F_j - V
    V'     = -omega x V + G + R_c s - W x P - omega x (omega x P)
    G'     = -omega x G
    omega' = W                                   (W_x, W_y, W_z unknown)
    P' = 0,  q_c' = 0,  B_i' = 0
    s      = [a_1 - B_1, A_2, A_3]               (case 2: a_1 known; A_2, A_3 unknown)
           = [a_1 - B_1, a_2 - B_2, A_3]         (case 3: a_1, a_2 known; A_3 unknown)
    y      = [F_jx / F_jz, F_jy / F_jz]_j, |q_c|^2

(derivation: the accelerometer point ``p = r_c + R P`` has ``R^T p'' = R^T r_c'' + W x P +
omega x (omega x P)`` and measures ``R_c^T (R^T p'' - G)``; ``V = R^T r_c'``.) Five unknown
inputs in case 2, four in case 3. No yaw is in this state (the global frame is gone), so
with the full IMU every component is observable (the standard Vi-SfM result of 004
section 11.2.2: features and speed in the local frame, roll, pitch, g, biases and the
camera-IMU transformation).

* Case 3 (two orthogonal accelerometers): published, the full IMU's properties at k = 2.
  In these coordinates: every state observable, ``dim = n`` (what the EORC shows: below).
* Case 2 (one accelerometer): published, ``Delta^k`` contains a single vector for every
  ``k >= 2``, an internal rotation about the accelerometer axis. Here that vector is
  ``internal_rotation``: ``q_c -> q_c * (cos(t/2), sin(t/2) e_1)``, i.e. the accelerometer
  frame turns about its own (measuring) x axis; ``R_c e_1`` does not move, ``R_c e_2`` and
  ``R_c e_3`` turn into each other and are absorbed by the unknown ``A_2``, ``A_3`` (an
  exact symmetry; a test checks it). Only ``q_c`` moves; published, in these coordinates:
  ``dim = n - 1``, every state but the four ``q_c`` components observable
  (``|q_c|`` is measured, so three independent functions of ``q_c`` stay observable).
  The speed in the accelerometer frame, ``R_c^T V``, turns about that axis under the
  symmetry: the "indistinguishability of the initial speeds that differ for a rotation
  about the accelerometer axis" of 004.

**Differences from the paper.** The paper's coordinates are unknown to us; case 1 uses
global coordinates (so the yaw is a state, as in "every function except the yaw"), with a
10-state yaw-free form ``calibrated_one_acc_local`` (``[F, V, G, B]``; a test checks that
it is the exact reduction); cases 2-3 use local ones (so the full-IMU properties are
``dim = n`` and the case-2 distribution has a single vector, as published). Case 3 carries
the bias of its second accelerometer: 24 states, where the paper says 23 for both
uncalibrated cases. The number of features of cases 2-3 is not given in 004; the default 2
makes case 2 have 23 states.

**What the EORC gives here** (4096 samples, cold, one process on the shared 2-core machine;
the analyses evaluate the expression graph, decisions on 256 samples, the final span on all,
weak decisions and every kept generator settled exactly modulo p):

* case 1, local (10 states): dims per order k = 0..7: 2, 2, 3, 5, 7, 8, 9, 10 (augmented
  ranks 2, 4, 7, 12, 18, 24, 30, 36): every state observable at k = 7 and not before, the
  published order and verdict (about 6 s; 692 s when every order was compiled by XLA).
* case 1, global (12 states): the local dims + 1 (``|q|^2``) at every order: 11 = n - 1 at
  k = 7, the yaw-invariant ``r_z, v_z, g, B`` observable, the yaw in the null space; to the
  default ``k_max = n + 2`` the answer stays 11 (about 50 s, most of it the exact checks).
* case 2 (``n_f = 2``, 23 states): dims 5, 9, 13, 15, 16, 17, 18, 19, 20, 21, 22 at k = 0..10,
  then 22 until the span closes: one unobservable direction, the published verdict (only
  the four ``q_c`` components unobservable, ``internal_rotation`` in the null space, which
  a test checks at k = 1), at k = 10 where the paper has it at k = 2: the known
  accelerometer fields act on V only, so the order-<= 2 Lie derivatives number at most
  ``1 + 4 p`` (``p`` bearing outputs) and mix G, P, B with the unknown A and W.
* case 3 (``n_f = 2``, 24 states): dims 5, 9, 14, 16, 18, 20, 22, 24 at k = 0..7: every
  state observable at k = 7 (about 20 s), the full IMU's verdict, where the paper needs
  k = 2 (at k = 2: the features, V, omega and q_c observable, G, P and the biases not yet).
* The general solution (``method="general_ui"``) answers for smooth known inputs: on case
  1's local form, dim 2 (the two bearings; 0.7 s), which the EORC under the same meaning
  confirms to k = 7; under the switchable meaning every state is observable at k = 7. The
  difference is the meaning of the known accelerometer, not an error (a test shows both).
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
_right_pure = _quaternion.right_pure


def _left_z(q):
    """``[0, e_z] * q`` (pure quaternion about global z on the left), (4,)."""
    qt, qx, qy, qz = q[0], q[1], q[2], q[3]
    return jnp.stack([-qz, -qy, qx, qt])


# ------------------------------------------------------------------ case 1: calibrated, global
CALIBRATED_STATES = ("rx", "ry", "rz", "vx", "vy", "vz", "qt", "qx", "qy", "qz", "g", "B")
CALIBRATED_DOMAIN = {
    "rx": (-0.5, 0.5), "ry": (-0.5, 0.5), "rz": (-4.0, -2.0),  # the feature ahead (F_z > 0)
    "vx": (-1.0, 1.0), "vy": (-1.0, 1.0), "vz": (-1.0, 1.0),
    "qt": (0.8, 1.2), "qx": (-0.15, 0.15), "qy": (-0.15, 0.15), "qz": (-0.15, 0.15),
    "g": (9.0, 10.5), "B": (-0.5, 0.5),
}


def _calibrated_fields():
    """Drift, the three accelerometer fields and three gyroscope fields of case 1 (12 states)."""
    z4 = jnp.zeros(4)

    def drift(x):
        v, q, g, B = x[3:6], x[6:10], x[10], x[11]
        c1 = _rotation_columns(q)[0]
        dv = -B * c1 - jnp.stack([0.0 * g, 0.0 * g, g])
        return jnp.concatenate([v, dv, z4, jnp.zeros(2)])

    def acc(i):
        def f(x):
            col = _rotation_columns(x[6:10])[i]
            return jnp.concatenate([jnp.zeros(3), col, z4, jnp.zeros(2)])

        f.__doc__ = f"Accelerometer axis {i}: the column R(q) e_{i + 1} in the velocity rows."
        return f

    def gyro(i):
        def f(x):
            return jnp.concatenate([jnp.zeros(6), 0.5 * _right_pure(x[6:10], i), jnp.zeros(2)])

        f.__doc__ = f"Gyroscope axis {i}: q' = 1/2 q * [0, e_{i + 1}]."
        return f

    fields = {"a_x": acc(0), "A_y": acc(1), "A_z": acc(2),
              "Omega_x": gyro(0), "Omega_y": gyro(1), "Omega_z": gyro(2)}
    return drift, fields


def _calibrated_outputs():
    def feature(x):
        c1, c2, c3 = _rotation_columns(x[6:10])
        r = x[0:3]
        return jnp.stack([-(c1 @ r), -(c2 @ r), -(c3 @ r)])  # R^T (0 - r)

    return {"u": lambda x: feature(x)[0] / feature(x)[2],
            "v": lambda x: feature(x)[1] / feature(x)[2],
            "q_norm": lambda x: jnp.sum(x[6:10] ** 2)}


def calibrated_one_acc():
    """Case 1 of 004 section 11.2.2: calibrated camera, the x accelerometer known (``a_x``),
    ``A_y, A_z, Omega_x, Omega_y, Omega_z`` unknown, one feature at the global origin.

    State ``[r, v, q, g, B]`` (12, global frame; see the module docstring). Published: every
    function of the state but the yaw observable by the EORC at k = 7 (dim 11).
    """
    drift, fields = _calibrated_fields()
    known = {"a_x": fields["a_x"]}
    unknown = {k: f for k, f in fields.items() if k != "a_x"}
    return uj.System(CALIBRATED_STATES, _calibrated_outputs(), known=known, unknown=unknown,
                     drift=drift, domain=CALIBRATED_DOMAIN,
                     name="visual_inertial_partial:calibrated_one_acc")


def calibrated_full_imu():
    """Case 1's model with the whole IMU known (3 accelerometers, 3 gyroscopes): ORC, 12 states.

    The reference for case 1: the yaw is unobservable here too (dim 11).
    """
    drift, fields = _calibrated_fields()
    return uj.System(CALIBRATED_STATES, _calibrated_outputs(), known=fields, drift=drift,
                     domain=CALIBRATED_DOMAIN, name="visual_inertial_partial:calibrated_full_imu")


def yaw_symmetry(x):
    """Rotation about gravity (global z) of case 1's state: ``r``, ``v`` turn, ``q -> e_z q``.

    ``x``: (12,) state ``[r, v, q, g, B]``; returns the (12,) field (per radian of yaw).
    """
    return jnp.concatenate([jnp.stack([-x[1], x[0], 0.0 * x[0], -x[4], x[3], 0.0 * x[0]]),
                            0.5 * _left_z(x[6:10]), jnp.zeros(2)])


LOCAL_STATES = ("Fx", "Fy", "Fz", "Vx", "Vy", "Vz", "Gx", "Gy", "Gz", "B")
LOCAL_DOMAIN = {"Fx": (-1.0, 1.0), "Fy": (-1.0, 1.0), "Fz": (2.0, 4.0),
                "Vx": (-1.0, 1.0), "Vy": (-1.0, 1.0), "Vz": (-1.0, 1.0),
                "Gx": (-3.0, 3.0), "Gy": (-3.0, 3.0), "Gz": (-10.0, -8.0), "B": (-0.5, 0.5)}


def calibrated_one_acc_local():
    """Case 1 in the camera frame: ``[F, V, G, B]`` (10 states), the yaw-free reduction of
    :func:`calibrated_one_acc`.

    ``F = R^T (0 - r)`` (the feature), ``V = R^T v``, ``G = -g R^T e_z`` (gravity), for a
    unit ``q``: the 12 states less the yaw and ``|q|`` (12 - 2 = 10), so "every function but
    the yaw observable" of case 1 reads "every state observable" here (dim 10)::

        F' = -Omega x F - V,   V' = -Omega x V + G + [a_x - B, A_y, A_z],   G' = -Omega x G,
        B' = 0,   y = [F_x / F_z, F_y / F_z]

    Polynomial dynamics (no quaternion), so its Lie derivatives are cheaper than those of
    the 12-state form; ``a_x`` known, ``A_y, A_z, Omega_x, Omega_y, Omega_z`` unknown.
    """

    def drift(x):
        V, G, B = x[3:6], x[6:9], x[9]
        return jnp.concatenate([-V, G - B * jnp.eye(3)[0], jnp.zeros(4)])

    def acc(i):
        def f(x):
            return jnp.concatenate([jnp.zeros(3), jnp.eye(3)[i], jnp.zeros(4)])

        return f

    def gyro(i):
        def f(x):
            e = jnp.broadcast_to(jnp.eye(3)[i], (3, 3))
            return jnp.concatenate([-jnp.cross(e, x[0:9].reshape((3, 3))).reshape(-1), jnp.zeros(1)])

        return f

    unknown = {"A_y": acc(1), "A_z": acc(2), "Omega_x": gyro(0), "Omega_y": gyro(1),
               "Omega_z": gyro(2)}
    outputs = {"u": lambda x: x[0] / x[2], "v": lambda x: x[1] / x[2]}
    return uj.System(LOCAL_STATES, outputs, known={"a_x": acc(0)}, unknown=unknown, drift=drift,
                     domain=LOCAL_DOMAIN, name="visual_inertial_partial:calibrated_one_acc_local")


# ------------------------------------------------------------------ cases 2, 3: uncalibrated, local
def _uncalibrated_states(n_acc, n_f):
    names = ["Vx", "Vy", "Vz", "Gx", "Gy", "Gz", "wx", "wy", "wz", "Px", "Py", "Pz",
             "qct", "qcx", "qcy", "qcz"]
    names += [f"B{i + 1}" for i in range(n_acc)]
    for j in range(1, n_f + 1):
        names += [f"F{j}x", f"F{j}y", f"F{j}z"]
    return tuple(names)


def _uncalibrated_domain(n_acc, n_f):
    d = {"Vx": (-1.0, 1.0), "Vy": (-1.0, 1.0), "Vz": (-1.0, 1.0),
         "Gx": (-3.0, 3.0), "Gy": (-3.0, 3.0), "Gz": (-10.0, -8.0),
         "wx": (-1.0, 1.0), "wy": (-1.0, 1.0), "wz": (-1.0, 1.0),
         "Px": (-0.3, 0.3), "Py": (-0.3, 0.3), "Pz": (-0.3, 0.3),
         "qct": (0.5, 1.5), "qcx": (-0.5, 0.5), "qcy": (-0.5, 0.5), "qcz": (-0.5, 0.5)}
    d.update({f"B{i + 1}": (-0.5, 0.5) for i in range(n_acc)})
    for j in range(1, n_f + 1):
        d.update({f"F{j}x": (-1.0, 1.0), f"F{j}y": (-1.0, 1.0), f"F{j}z": (2.0, 4.0)})
    return d


def _uncalibrated(n_acc, n_f, name):
    """The System of case 2 (``n_acc = 1``) or 3 (``n_acc = 2``) with ``n_f`` features."""
    if n_f < 1 or int(n_f) != n_f:
        raise uj.ModelError(f"n_f must be a positive integer (number of features), got {n_f!r}")
    n_f = int(n_f)
    nb = 16 + n_acc  # start of the features
    n = nb + 3 * n_f

    def parts(x):
        V, G, w, P, qc = x[0:3], x[3:6], x[6:9], x[9:12], x[12:16]
        return V, G, w, P, qc, x[16:nb], x[nb:].reshape((n_f, 3))

    def pad(dV=None, dw=None):
        z3 = jnp.zeros(3)
        return jnp.concatenate([z3 if dV is None else dV, z3, z3 if dw is None else dw,
                                jnp.zeros(n - 9)])

    def drift(x):
        V, G, w, P, qc, B, F = parts(x)
        cols = _rotation_columns(qc)
        dV = -jnp.cross(w, V) + G - jnp.cross(w, jnp.cross(w, P))
        for i in range(n_acc):
            dV = dV - B[i] * cols[i]
        dF = -jnp.cross(jnp.broadcast_to(w, F.shape), F) - V
        return jnp.concatenate([dV, -jnp.cross(w, G), jnp.zeros(3 + 3 + 4 + n_acc),
                                dF.reshape(-1)])

    def acc(i):
        def f(x):
            return pad(dV=_rotation_columns(x[12:16])[i])

        f.__doc__ = f"Accelerometer axis {i + 1}: R(q_c) e_{i + 1} in the V rows."
        return f

    def ang_acc(i):
        def f(x):
            e = jnp.eye(3)[i]
            return pad(dV=-jnp.cross(e, x[9:12]), dw=e)

        f.__doc__ = f"Angular acceleration W_{i + 1}: omega' = e_{i + 1}, V' = -e_{i + 1} x P."
        return f

    known = {f"a_{i + 1}": acc(i) for i in range(n_acc)}
    unknown = {f"A_{i + 1}": acc(i) for i in range(n_acc, 3)}
    unknown.update({k: ang_acc(i) for i, k in enumerate(("W_x", "W_y", "W_z"))})
    outputs = {}
    for j in range(n_f):
        outputs[f"u{j + 1}"] = lambda x, j=j: x[nb + 3 * j] / x[nb + 3 * j + 2]
        outputs[f"v{j + 1}"] = lambda x, j=j: x[nb + 3 * j + 1] / x[nb + 3 * j + 2]
    outputs["qc_norm"] = lambda x: jnp.sum(x[12:16] ** 2)
    states = _uncalibrated_states(n_acc, n_f)
    assert len(states) == n
    # one accelerometer: the frame may turn about its axis unseen (verified by the analyses)
    symmetries = {"internal_rotation": internal_rotation} if n_acc == 1 else {}
    return uj.System(states, outputs, known=known, unknown=unknown, drift=drift,
                     domain=_uncalibrated_domain(n_acc, n_f),
                     name=f"visual_inertial_partial:{name}", symmetries=symmetries)


def uncalibrated_one_acc(n_f=2):
    """Case 2 of 004 section 11.2.2: uncalibrated camera, one accelerometer (``a_1`` known),
    ``A_2, A_3, W_x, W_y, W_z`` unknown, ``n_f`` features (23 states for 2).

    Published: ``Delta^k`` (k >= 2) contains a single vector, the rotation about the
    accelerometer axis (:func:`internal_rotation`): dim ``n - 1``.
    """
    return _uncalibrated(1, n_f, "uncalibrated_one_acc")


def uncalibrated_two_acc(n_f=2):
    """Case 3 of 004 section 11.2.2: uncalibrated camera, two orthogonal accelerometers
    (``a_1, a_2`` known), ``A_3, W_x, W_y, W_z`` unknown, ``n_f`` features (24 states for 2).

    Published: the full IMU's observability properties at k = 2; in these local coordinates
    every state is observable (dim ``n``).
    """
    return _uncalibrated(2, n_f, "uncalibrated_two_acc")


def internal_rotation(x):
    """Case 2's symmetry: the accelerometer frame turns about its measuring axis.

    ``q_c' = 1/2 q_c * [0, e_1]`` (right product, per radian), every other state fixed.
    ``x``: a state of :func:`uncalibrated_one_acc` (any ``n_f``); returns a field of its size.
    """
    return jnp.concatenate([jnp.zeros(12), 0.5 * _right_pure(x[12:16], 0), jnp.zeros(x.shape[0] - 16)])


#: Published results (004 section 11.2.2 = 001 section V-B, from refs [28, 29] there), in the
#: coordinates of this file (module docstring). ``k``: the order the paper computed to (the
#: EORC runs to ``k_max``).
PUBLISHED = {
    # case 1 in its yaw-free 10 coordinates; "k": the EORC stops at the first order where
    # every state is observable, so k = 7 also says "not before 7"
    "calibrated_one_acc_local": {"source": "004 section 11.2.2 case 1 (001 section V-B)",
                                 "method": "eorc", "dim": 10, "k": 7, "k_max": 7,
                                 "observable": list(LOCAL_STATES)},
    # case 1 in its 12 global coordinates to the paper's order (a few seconds since the
    # analyses evaluate the expression graph): every function but the yaw, first at k = 7
    # (a sufficient verdict: the yaw is not declared here, so the EORC cannot stop at its bound)
    "calibrated_one_acc": {"source": "004 section 11.2.2 case 1 (001 section V-B)", "method": "eorc",
                           "dim": 11, "k_max": 7, "k_first": 7, "observable": ["rz", "vz", "g", "B"],
                           "symmetries": ["yaw_symmetry"]},
}

#: Cases 2 and 3: the paper's verdicts at its order k = 2, NOT reproduced at that order in the
#: coordinates of this file (the papers' own formulation is not available): the EORC at k = 2
#: falls short here (case 2: dims 5, 9, 13; case 3: 5, 9, 14). The verdicts themselves are
#: reached at higher orders, with 2 features: case 2 dim n - 1 = 22 from k = 10 (exactly the
#: q_c components unobservable, the internal rotation in the null space), case 3 every state
#: observable at k = 7 (tests/test_visual_inertial_partial.py). Kept apart from PUBLISHED so
#: that the reproduction table lists what this formulation reproduces at the paper's order.
#: Without the camera offset and the biases (visual_inertial_no_offset.py) case 3 reaches
#: its verdict at k = 2 and case 2 at k = 3.
NOT_REPRODUCED = {
    "uncalibrated_one_acc": {"source": "004 section 11.2.2 case 2 (001 section V-B)", "method": "eorc",
                             "dim": 22, "k_max": 2,
                             "observable": [s for s in _uncalibrated_states(1, 2) if not s.startswith("qc")],
                             "symmetries": ["internal_rotation"]},
    "uncalibrated_two_acc": {"source": "004 section 11.2.2 case 3 (001 section V-B)", "method": "eorc",
                             "dim": 24, "k_max": 2, "observable": list(_uncalibrated_states(2, 2))},
}
