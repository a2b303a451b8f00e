# uio-jax: models
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
# Positions in front of the camera and attitudes within ~35 degrees of the identity, so
# that the feature depth F_z stays away from 0 (where h_u, h_v blow up); the quaternion is
# not normalized (its norm is the output h_const).
DOMAIN = {"x": (0.5, 1.5), "y": (0.5, 1.5), "z": (0.5, 1.5),
          "qt": (0.8, 1.2), "qx": (-0.3, 0.3), "qy": (-0.3, 0.3), "qz": (-0.3, 0.3)}


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


def wind_known():
    """Wind along z treated as one more *known* input (an ORC sanity case, not in 002;
    ``wind_unknown`` is the paper's case, section III-C)."""
    known = dict(KNOWN, w=_wind)
    return uj.System(STATES, OUTPUTS, known=known, domain=DOMAIN, name="vehicle_wind:wind_known")


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
        # "all the observable modes are the components of F ... and the norm of the quaternion"
        "functions": ["x*(qt**2 + qx**2 - qy**2 - qz**2) + 2*y*(qx*qy + qt*qz) + 2*z*(qx*qz - qt*qy)",
                      "2*x*(qx*qy - qt*qz) + y*(qt**2 - qx**2 + qy**2 - qz**2) + 2*z*(qy*qz + qt*qx)",
                      "2*x*(qx*qz + qt*qy) + 2*y*(qy*qz - qt*qx) + z*(qt**2 - qx**2 - qy**2 + qz**2)",
                      "sqrt(qt**2 + qx**2 + qy**2 + qz**2)"],
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


# ---------------------------------------------------------------------------------------
# Monte Carlo experiments (002 section III-D).
#
# From the paper: Euler step 0.01 s, 200 s; start at r = [0.5, 0.5, 0.5] m with zero speed;
# the airspeed V is a random walk (std 1e-4 m/s added per step), Omega ~ N(0, (1 deg/s)^2 I)
# per step, wind magnitude ~ N(0.2, 0.05^2) m/s per step along z; airspeed readings std
# 0.01 m/s, gyroscope std 1 deg/s; camera every 0.1 s with 1 deg noise, point features at
# the origin and at [1, 0, 1]; EKF state [x, y, z, qt, qx, qy, qz, w, w1].
# Chosen here (not in the paper): initial attitude q = identity; the camera reads, per
# feature, the angles asin(F_x/|F|) and asin(F_y/|F|) of its direction F = R^T (p - r) in the
# local frame (std 1 deg): the paper's ratios F_x/F_z, F_y/F_z are singular when F_z = 0,
# which happens here (the wind carries the vehicle through the height z = 1 of the second
# feature after about 2.5 s) and wrecks the filter; the arcsines carry the same
# information (the bearing) and are regular unless a feature lies on the local x or y
# axis. The constraint q*q = 1 is read as a pseudo-output with std 1e-3 at the camera
# rate; prior std 0.1 m per position, (0.01, 0.05, 0.05, 0.05) on (qt, qx, qy, qz) (about
# 5.7 deg per axis), 0.05 m/s on w, 1e-3 m/s^2 on w1; spectral density 1e-8 on w and w1.
#
# What the Monte Carlo finds in the paper's setting (two features of KNOWN position): the
# second feature, off the wind axis, breaks the rotation symmetry about z, so the yaw
# converges too (the paper's remark that the analysis does not depend on the number of
# features holds for features of unknown position); and the wind carries the vehicle 40 m
# up, so the depth (z, the distances) fades with the range. The analysed system itself
# (one feature) is checked by the "hover" experiments: the vehicle flies a small circle
# against the mean wind and stays near the feature; there z, roll and pitch converge with
# wind, the yaw does not, and without wind only the distance converges (002 section III).
# ---------------------------------------------------------------------------------------
_DEG = 0.017453292519943295  # pi / 180
FEATURES = ((0.0, 0.0, 0.0), (1.0, 0.0, 1.0))
EXPERIMENT_NOTES = (
    "002 section III-D. Chosen here (not in the paper): q0 = identity; camera angles "
    "asin(Fx/|F|), asin(Fy/|F|) per feature (the ratios Fx/Fz are singular at Fz = 0); "
    "|q|^2 = 1 read with std 1e-3; prior std 0.1 m per "
    "position, (0.01, 0.05, 0.05, 0.05) on q, 0.05 m/s on w, 1e-3 m/s^2 on w1."
)


def _camera(p, axis):
    def h(X):
        d = jnp.asarray(p) - X[:3]
        c1, c2, c3 = rotation_columns(X)
        F = jnp.stack([c1 @ d, c2 @ d, c3 @ d])  # direction of the feature, local frame
        return jnp.arcsin(F[axis] / jnp.sqrt(F @ F))

    return h


def _normalised_columns(X):
    s = X[3] ** 2 + X[4] ** 2 + X[5] ** 2 + X[6] ** 2
    c1, c2, c3 = rotation_columns(X)
    return c1 / s, c2 / s, c3 / s


def roll(X):
    """Roll of the vehicle (rad), from the normalised quaternion."""
    _, c2, c3 = _normalised_columns(X)
    return jnp.arctan2(c2[2], c3[2])


def pitch(X):
    """Pitch of the vehicle (rad)."""
    c1, _, _ = _normalised_columns(X)
    return jnp.arctan2(-c1[2], jnp.sqrt(c1[0] ** 2 + c1[1] ** 2))


def yaw(X):
    """Yaw of the vehicle about the global z axis (the wind axis) (rad)."""
    c1, _, _ = _normalised_columns(X)
    return jnp.arctan2(c1[1], c1[0])


def _distance(p):
    def d(X):
        return jnp.sqrt(jnp.sum((X[:3] - jnp.asarray(p)) ** 2))

    return d


def _vehicle_inputs(V, z):
    V = V + 1e-4 * z[:3]
    omega = _DEG * z[3:6]
    w = 0.2 + 0.05 * z[6:7]
    return V, jnp.concatenate([omega, V]), w


#: Hovering variant (not in the paper): the airspeed flies a horizontal circle of radius
#: 0.4 m (0.2 m/s, period 4 pi s) and, with wind, cancels the wind's mean along z, so the
#: vehicle stays near the feature and its motion is rich: V = [0.2 cos(t/2), 0.2 sin(t/2),
#: -0.2 (with wind) or 0] in the local frame (the attitude stays within a few degrees).
def _hover_law(wind):
    vz = -0.2 if wind else 0.0

    def law(t, z):
        t = t + 0.01
        V = jnp.stack([0.2 * jnp.cos(0.5 * t[0]), 0.2 * jnp.sin(0.5 * t[0]), vz + 0.0 * t[0]])
        omega = _DEG * z[3:6]
        w = 0.2 + 0.05 * z[6:7]
        return t, jnp.concatenate([omega, V]), w

    return law


def _no_wind(law):
    def inputs(V, z):
        V, u, _ = law(V, z)
        return V, u, jnp.zeros(0)

    return inputs


def _wind_mean(istate, w):
    # the filter's w estimates the smooth part of the wind: its mean 0.2 m/s
    return 0.2 + 0.0 * w


def _vehicle_known_std(u):
    return jnp.concatenate([jnp.full(3, _DEG), jnp.full(3, 0.01)]) + 0.0 * u


_EXPERIMENTS = {}  # one object per experiment: runs of the same one share compiled code


def _vehicle_experiment(wind, features=FEATURES, hover=False, n_steps=20000, tag="",
                        prior_r=0.1, prior_q=0.05):
    key = (wind, features, hover, n_steps, tag, prior_r, prior_q)
    if key not in _EXPERIMENTS:
        _EXPERIMENTS[key] = _make_vehicle_experiment(*key)
    return _EXPERIMENTS[key]


def _make_vehicle_experiment(wind, features, hover, n_steps, tag, prior_r, prior_q):
    from uio_jax import Experiment, Measurement, Quantity

    system = wind_unknown() if wind else no_wind()
    meas = []
    for k, p in enumerate(features):
        meas += [Measurement(f"u{k + 1}", _camera(p, 0), _DEG, 10, angle=True),
                 Measurement(f"v{k + 1}", _camera(p, 1), _DEG, 10, angle=True)]
    meas.append(Measurement("qnorm2", _h_const, 1e-3, 10))
    quantities = [Quantity("roll", roll, angle=True, unit="rad", observable=wind),
                  Quantity("pitch", pitch, angle=True, unit="rad", observable=wind),
                  Quantity("yaw", yaw, angle=True, unit="rad",
                           observable=False if len(features) == 1 else None)]
    quantities += [Quantity(f"distance {k + 1}", _distance(p), unit="m", observable=True)
                   for k, p in enumerate(features)]
    prior = (prior_r,) * 3 + (0.01,) + (prior_q,) * 3 + ((0.05, 1e-3) if wind else ())
    law = _hover_law(wind) if hover else _vehicle_inputs
    name = f"vehicle_wind:{'wind_unknown' if wind else 'no_wind'}{tag}"
    notes = EXPERIMENT_NOTES
    if hover:
        notes += (" Hovering variant (not in the paper): one feature (the analysed output "
                  "set); the airspeed flies a circle of radius 0.4 m at 0.2 m/s and cancels "
                  f"the mean wind along z; {n_steps * 0.01:g} s.")
    return Experiment(
        name=name, system=system, dt=0.01, n_steps=n_steps,
        x0=(0.5, 0.5, 0.5, 1.0, 0.0, 0.0, 0.0),
        inputs=law if wind else _no_wind(law), istate0=(0.0,) if hover else (0.0, 0.0, 0.0),
        n_input_normals=7, known_std=_vehicle_known_std, measurements=tuple(meas),
        w0=(0.2,) if wind else (), w_white_std=(0.05,) if wind else (), order=2,
        q_aug=(1e-8, 1e-8) if wind else (), prior_std=prior, quantities=tuple(quantities),
        nees_states=STATES, record_every=5, notes=notes,
        w_reference=_wind_mean if wind else None,
        units={"x": "m", "y": "m", "z": "m", **dict.fromkeys(STATES[3:], "1"),
               **({"w": "m/s"} if wind else {})})


def wind_unknown_experiment():
    """002 section III-D with wind along z (unknown, time-varying): 9-state EKF, 200 s,
    features at the origin and at [1, 0, 1] (the paper's setting)."""
    return _vehicle_experiment(True)


def no_wind_experiment():
    """002 section III-D without wind: 7-state EKF (no unknown input), two features."""
    return _vehicle_experiment(False)


def wind_unknown_hover_experiment():
    """The analysed system exactly (one feature at the origin), with wind, hovering: the
    airspeed flies a 0.4 m circle and cancels the mean wind, so the vehicle stays near the
    feature (in the paper's setting it drifts 40 m away and depth fades)."""
    return _vehicle_experiment(True, FEATURES[:1], hover=True, n_steps=6000,
                               tag="_hover")


def no_wind_hover_experiment():
    """As ``wind_unknown_hover_experiment`` without wind (7-state EKF)."""
    return _vehicle_experiment(False, FEATURES[:1], hover=True, n_steps=6000,
                               tag="_hover")
