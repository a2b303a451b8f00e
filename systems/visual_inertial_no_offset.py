# uio-jax: models
"""Vi-SfM with partial input knowledge at the paper's orders: camera at the accelerometers.

004 section 11.2.2 (= 001 section V-B) summarizes three cases of the visual-inertial
structure from motion with a partly missing IMU and gives, for the two uncalibrated ones, the
EORC's verdicts at order k = 2: with two orthogonal accelerometers (case 3) "exactly the same
properties" as the full IMU; with one (case 2) "Delta^k, for every k >= 2, contains a single
vector", the rotation about the accelerometer axis. The state of its refs. [28, 29] is not
given; ``visual_inertial_partial.py`` writes the uncalibrated cases with a camera offset and
biases and does not reach those orders (k = 10 and 7). This file writes them so that they do.

**The formulation** (global frame with z up and its origin at feature 1, gravity known, no
bias, the camera centre at the accelerometers' origin, ``n_f`` point features, default 4)::

    x = [r (3), v (3), q (4), q_c (4), F_2 .. F_nf (3 each)]        n = 11 + 3 n_f  (23 for 4)

    r'   = v                                      (accelerometer frame origin, global)
    v'   = R(q) A - g e_z                          (A: specific force, accelerometer frame)
    q'   = 1/2 q * [0, omega]                      (attitude of the accelerometer frame)
    q_c' = 0,  F_j' = 0                            (camera -> accelerometer rotation; features)
    F_j^c = R(q_c)^T R(q)^T (F_j - r),  F_1 = 0    (feature j in the camera frame)
    y    = [F_jx^c / F_jz^c, F_jy^c / F_jz^c]_{j = 1..nf},  |q|^2,  |q_c|^2

``R(q)`` is homogeneous (quadratic) in q as in the other Vi-SfM files; both quaternion norms
are constant along the dynamics and measured by the constraint outputs. ``g = 9.81`` is a
known constant. The inputs are the six IMU readings ``A_1, A_2, A_3`` (fields ``R(q) e_i`` in
the velocity rows) and ``omega_1, omega_2, omega_3`` (``1/2 q * [0, e_i]`` in the q rows):

* :func:`full_imu`: all six known (ORC), the reference;
* :func:`two_acc` (case 3): ``A_1, A_2`` known; ``A_3`` and the three gyroscopes unknown;
* :func:`one_acc` (case 2): ``A_1`` known; ``A_2, A_3`` and the gyroscopes unknown.

**Symmetries**, declared (the analyses verify them exactly before using them):
``yaw_symmetry``, the rotation of the scene about the gravity axis through feature 1 (``r``,
``v``, ``F_j`` turn about z, ``q -> e_z q``): unobservable whatever the inputs; and, in case 2
only, ``internal_rotation``, the accelerometer frame turning about its measuring axis while
the camera stays put (``q -> q * rot(e_1)``, ``q_c -> rot(e_1)^-1 * q_c``: ``R(q) R(q_c)`` is
unchanged, ``R(q) e_1`` too, and ``R(q) e_2``, ``R(q) e_3`` turn into each other, absorbed by
the unknown ``A_2``, ``A_3``; the gyroscope fields are carried among themselves by constant
structure coefficients). A verified symmetry bounds the EORC's dimension at every order
(``uio_jax/_analysis/symmetry.py``), so an EORC that reaches the bound stops with an exact
verdict.

**What the EORC gives** (``tests/test_visual_inertial_no_offset.py``; 4 features):

* full IMU (ORC): dim 22 = n - 1, the yaw the only unobservable direction;
* case 3 (two accelerometers): dims 10, 15, 22 at k = 0, 1, 2: the full IMU's 22 at k = 2, as
  published, and the bound of the yaw, so the verdict is exact;
* case 2 (one accelerometer): dims 10, 15, 20, 21 at k = 0..3: at k = 3 exactly the yaw and the
  internal rotation are unobservable (dim 21 = n - 2, the bound of the two symmetries, exact);
  at k = 2 one more direction remains. The paper's "for every k >= 2" holds here from k = 3.

Why case 2 needs k = 3 (measured; the ranks are exact modulo p): the known accelerometer
field moves only ``v`` and no output depends on ``v``, so the Lie derivatives along it start
at order 2, with the 8 functions ``L_{A_1} L_{f0} y`` of the state alone; each order brings 5
new unknown coordinates (``A_2, A_3, omega`` and their derivatives). The rank of the extended
codistribution grows 10, 18, 28, 34 on 23, 28, 33, 38 coordinates (k = 0..3): at k = 2 the
null space has one direction on the states besides the two symmetries, a combination that
moves every state (not a symmetry: the order-3 derivatives separate it). With two known
accelerometers the 8 more functions ``L_{A_2} L_{f0} y`` and one unknown less give rank 29
on 31 coordinates at k = 2: only the yaw on the states. ``scripts/visfm_formulations.py``
repeats this in five other formulations with 2 to 6 features: case 2 never before k = 3.
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
#: Number of point features of the published dimension (23 = 11 + 3 * 4).
N_FEATURES = 4


_rotation_columns = _quaternion.rotation_columns


def transpose_times(q, w):
    """``R(q)^T w`` for a quaternion ``q`` (4,) and a vector ``w`` (3,): (3,)."""
    return jnp.stack([c @ w for c in _rotation_columns(q)])


right_pure = _quaternion.right_pure


def left_pure(q, i):
    """``[0, e_i] * q`` (pure unit quaternion on the left), (4,)."""
    qt, qx, qy, qz = q[0], q[1], q[2], q[3]
    return [jnp.stack([-qx, qt, -qz, qy]), jnp.stack([-qy, qz, qt, -qx]),
            jnp.stack([-qz, -qy, qx, qt])][i]


def states(n_f=N_FEATURES) -> tuple:
    """State names: ``r, v, q, q_c`` and features 2..n_f (feature 1 is the origin)."""
    names = ["rx", "ry", "rz", "vx", "vy", "vz", "qt", "qx", "qy", "qz", "ct", "cx", "cy", "cz"]
    for j in range(2, n_f + 1):
        names += [f"F{j}x", f"F{j}y", f"F{j}z"]
    return tuple(names)


def _domain(n_f):
    """Sampling box: the camera about 3 below the features, attitudes near level (z up, the
    camera looking up), so that every feature is in front of the camera."""
    d = {"rx": (-0.5, 0.5), "ry": (-0.5, 0.5), "rz": (-4.0, -2.0),
         "vx": (-1.0, 1.0), "vy": (-1.0, 1.0), "vz": (-1.0, 1.0),
         "qt": (0.8, 1.2), "qx": (-0.15, 0.15), "qy": (-0.15, 0.15), "qz": (-0.15, 0.15),
         "ct": (0.8, 1.2), "cx": (-0.15, 0.15), "cy": (-0.15, 0.15), "cz": (-0.15, 0.15)}
    for j in range(2, n_f + 1):
        d.update({f"F{j}x": (-1.0, 1.0), f"F{j}y": (-1.0, 1.0), f"F{j}z": (-0.5, 0.5)})
    return d


def features(x) -> jnp.ndarray:
    """The features in the global frame, ``(n_f, 3)``: feature 1 at the origin, then ``F_2..``."""
    return jnp.concatenate([jnp.zeros((1, 3)), x[14:].reshape((-1, 3))])


def camera_features(x):
    """``F_j^c = R(q_c)^T R(q)^T (F_j - r)`` for every feature, ``(n_f, 3)``."""
    q, qc = x[6:10], x[10:14]
    return jnp.stack([transpose_times(qc, transpose_times(q, f - x[0:3])) for f in features(x)])


def _check_features(n_f):
    if isinstance(n_f, bool) or int(n_f) != n_f or n_f < 1:
        raise uj.ModelError(f"n_f must be a positive integer (number of features), got {n_f!r}")
    return int(n_f)


def _fields(n):
    """Drift and the six IMU fields (``A_1..A_3``, ``omega_1..omega_3``) of an ``n``-state model."""

    def drift(x):
        return jnp.concatenate([x[3:6], jnp.stack([0.0 * x[0], 0.0 * x[0], -GRAVITY + 0.0 * x[0]]),
                                jnp.zeros(n - 6)])

    def acc(i):
        def f(x):
            return jnp.concatenate([jnp.zeros(3), _rotation_columns(x[6:10])[i], jnp.zeros(n - 6)])

        f.__doc__ = f"Accelerometer axis {i + 1}: the column R(q) e_{i + 1} in the velocity rows."
        return f

    def gyro(i):
        def f(x):
            return jnp.concatenate([jnp.zeros(6), 0.5 * right_pure(x[6:10], i), jnp.zeros(n - 10)])

        f.__doc__ = f"Gyroscope axis {i + 1}: q' = 1/2 q * [0, e_{i + 1}]."
        return f

    fields = {f"A_{i + 1}": acc(i) for i in range(3)}
    fields.update({f"omega_{i + 1}": gyro(i) for i in range(3)})
    return drift, fields


def _outputs(n_f):
    outputs = {}
    for j in range(n_f):
        outputs[f"u{j + 1}"] = lambda x, j=j: camera_features(x)[j, 0] / camera_features(x)[j, 2]
        outputs[f"v{j + 1}"] = lambda x, j=j: camera_features(x)[j, 1] / camera_features(x)[j, 2]
    outputs["q_norm"] = lambda x: jnp.sum(x[6:10] ** 2)
    outputs["qc_norm"] = lambda x: jnp.sum(x[10:14] ** 2)
    return outputs


def _system(n_known, n_f, name):
    """``A_1 .. A_{n_known}`` known (``n_known = 3``: the gyroscopes too), the rest unknown."""
    n_f = _check_features(n_f)
    names = states(n_f)
    drift, fields = _fields(len(names))
    known_names = [f"A_{i + 1}" for i in range(n_known)] + (
        [f"omega_{i + 1}" for i in range(3)] if n_known == 3 else [])
    known = {k: fields[k] for k in known_names}
    unknown = {k: f for k, f in fields.items() if k not in known}
    symmetries = {"yaw_symmetry": yaw_symmetry}
    if n_known == 1:
        symmetries["internal_rotation"] = internal_rotation
    return uj.System(names, _outputs(n_f), known=known, unknown=unknown, drift=drift,
                     domain=_domain(n_f), name=f"visual_inertial_no_offset:{name}",
                     symmetries=symmetries)


def full_imu(n_f=N_FEATURES):
    """The reference: three accelerometers and three gyroscopes known (ORC), ``n_f`` features
    (23 states for 4). Every function of the state but the yaw is observable: dim ``n - 1``."""
    return _system(3, n_f, "full_imu")


def two_acc(n_f=N_FEATURES):
    """Case 3 of 004 section 11.2.2: two orthogonal accelerometers (``A_1, A_2`` known),
    ``A_3, omega_1, omega_2, omega_3`` unknown, ``n_f`` features (23 states for 4).

    Published: the full IMU's properties at k = 2. Here: dim ``n - 1`` (the yaw) at k = 2.
    """
    return _system(2, n_f, "two_acc")


def one_acc(n_f=N_FEATURES):
    """Case 2 of 004 section 11.2.2: one accelerometer (``A_1`` known), ``A_2, A_3`` and the
    three gyroscopes unknown, ``n_f`` features (23 states for 4).

    Published: for every k >= 2, one unobservable vector besides the full IMU's, the rotation
    about the accelerometer axis (:func:`internal_rotation`). Here: dim ``n - 2`` from k = 3.
    """
    return _system(1, n_f, "one_acc")


def yaw_symmetry(x):
    """Rotation of the scene about the gravity axis through feature 1 (per radian).

    ``r``, ``v`` and ``F_j`` turn about global z, ``q -> e_z q`` (left product), ``q_c`` fixed.
    ``x``: a state of any of this file's models; returns a field of its size.
    """
    def about_z(w):
        return jnp.stack([-w[1], w[0], 0.0 * w[0]])

    feats = [about_z(f) for f in x[14:].reshape((-1, 3))]
    return jnp.concatenate([about_z(x[0:3]), about_z(x[3:6]), 0.5 * left_pure(x[6:10], 2),
                            jnp.zeros(4), *feats])


def internal_rotation(x):
    """Case 2's symmetry: the accelerometer frame turns about its measuring axis ``e_1``, the
    camera does not move (per radian).

    ``q' = 1/2 q * [0, e_1]``, ``q_c' = -1/2 [0, e_1] * q_c``: ``R(q) R(q_c)`` and ``R(q) e_1``
    are unchanged. ``x``: a state of :func:`one_acc` (any ``n_f``); returns a field of its size.
    """
    return jnp.concatenate([jnp.zeros(6), 0.5 * right_pure(x[6:10], 0),
                            -0.5 * left_pure(x[10:14], 0), jnp.zeros(x.shape[0] - 14)])


#: Published results (004 section 11.2.2 = 001 section V-B, refs [28, 29] there), in the
#: coordinates of this file (4 features). ``k_first``: the first order at which the published
#: verdict holds. Case 3 runs to the paper's order k = 2; case 2 to its own stop (the bound of
#: its verified symmetries, k = 3), the published k = 2 a documented difference.
_FIELD_ANSATZ = ("its directions move most of its 23 coordinates (18 in case 2): the degree-1 field ansatz is "
                 "past its bound of 120 unknowns")
PUBLISHED = {
    "full_imu": {"source": "004 section 11.2.2 (the full IMU's properties; yaw not observable)",
                 "method": "orc", "dim": 22, "exact": True,
                 "observable": ["rz", "vz", "ct", "cx", "cy", "cz", "F2z", "F3z", "F4z"],
                 "symmetries": ["yaw_symmetry"],
                 "differs": {"closed-form symmetries found": {"ours": "0 of 1", "why": _FIELD_ANSATZ}}},
    "two_acc": {"source": "004 section 11.2.2 case 3 (001 section V-B)", "method": "eorc",
                "dim": 22, "k_max": 2, "k_first": 2, "exact": True,
                "observable": ["rz", "vz", "ct", "cx", "cy", "cz", "F2z", "F3z", "F4z"],
                "symmetries": ["yaw_symmetry"],
                "differs": {"closed-form symmetries found": {"ours": "0 of 1", "why": _FIELD_ANSATZ}}},
    "one_acc": {"source": "004 section 11.2.2 case 2 (001 section V-B)", "method": "eorc",
                "dim": 21, "k_first": 2, "exact": True,
                "observable": ["rz", "vz", "F2z", "F3z", "F4z"],
                "symmetries": ["yaw_symmetry", "internal_rotation"],
                "differs": {"k_first": {"ours": 3, "why": "see REPRODUCTION_NOTES"},
                            "closed-form symmetries found": {"ours": "0 of 2", "why": _FIELD_ANSATZ}}},
}

#: What ``scripts/reproduce_papers.py`` writes under the table (``docs/reproduction.md``).
REPRODUCTION_NOTES = """
**Vi-SfM with partial input knowledge at the paper's orders (004 section 11.2.2, cases 2
and 3).** The paper does not give its state; this file's formulation (camera centre at the
accelerometers' origin, no bias, gravity known, four point features, origin at feature 1:
23 states, the published dimension) reproduces case 3 at the published order: with two
orthogonal accelerometers and no gyroscope the EORC at k = 2 has the full IMU's span (22 of
23, the yaw the only unobservable direction), exact because it meets the bound of the
verified yaw symmetry. Case 2 (one accelerometer) has exactly the two published
unobservable directions, the yaw and the rotation of the accelerometer frame about its own
axis, from k = 3 on (exact, the bound of the two verified symmetries), not from k = 2: at
k = 2 one more direction, a mixture that moves every state, is left, and the third
derivatives of the bearings remove it. The ranks show where the order goes (an account of
the computation, not a proof about other formulations): the known accelerometer acts
on the velocity only and the outputs do not depend on the velocity, so its Lie derivatives
start at order 2 with eight functions of the state, while every order adds five unknown
coordinates (two specific forces, three angular rates or their derivatives); the rank of
the extended codistribution grows 10, 18, 28, 34 over 23, 28, 33, 38 coordinates. A second
known accelerometer adds eight more such functions and removes one unknown coordinate
(rank 29 over 31 at k = 2, only the yaw left on the states).

Every formulation tried needs k = 3 or more for case 2 (`scripts/visfm_formulations.py`;
the orders below hold for three to six features): this one, its local form with the
attitude kept for gravity and the local form with the gravity vector as a state and its
norm measured (k = 3); gravity of unknown magnitude, global or local (k = 4, and case 3
then needs k = 3); an unknown camera-accelerometer offset (case 2 at k = 6, case 3 at
k = 4). With two features every formulation is later still (case 3 at k = 4 or more). An independent
computation (`scripts/eorc_jet_oracle.py`: every Lie derivative word kept, gradients by
nilpotent jets, ranks modulo another prime) gives the same dimensions 10, 15, 20, 21 for
case 2 and 10, 15, 22 for case 3. Case 1 (`visual_inertial_partial.py`, 12 states with
the gravity magnitude and an accelerometer bias) is reproduced at its published order
k = 7, in its yaw-free form (the `k` row) and in its 12 global coordinates (every function
but the yaw, first at k = 7).

**Closed-form symmetries (`Report.symmetries`).** The yaw and the internal rotation are
declared here and verified, but not found by the field ansatz: the unobservable directions
of this formulation move most of its 23 coordinates (18 in case 2), and the degree-1 field
ansatz on them is past its bound of 120 unknowns (`docs/observable_functions.md`); the
report says "0 of 1" ("0 of 2") and the declared symmetries give the directions.
"""
