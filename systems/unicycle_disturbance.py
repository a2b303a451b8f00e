# uio-jax: models
"""Unicycle pushed by a disturbance along a fixed direction gamma (seed 003).

Martinelli, "The Unicycle in Presence of a Single Disturbance: Observability Properties",
eq. 2.1 (and 4.5 when gamma is unknown)::

    xv'     = v cos(theta) + w cos(gamma)
    yv'     = v sin(theta) + w sin(gamma)
    theta'  = omega
    gamma'  = 0                       (only when gamma is an unknown constant)

v and omega are known (odometry), w is the unknown disturbance. Outputs, as in section 4:
``r2 = xv^2 + yv^2`` (range), ``tan_beta = (yv - xv tan theta) / (xv + yv tan theta)``
(bearing of the origin in the local frame) and ``tan_phi = yv / xv`` (bearing of the vehicle
from the origin). gamma, when known, is the simulation value 0.7 pi of section 5.
"""

import math

import jax.numpy as jnp

import uio_jax as uj

GAMMA = 0.7 * math.pi
DOMAIN = {"xv": (0.5, 1.5), "yv": (0.5, 1.5)}


def _r2(x):
    return x[0] ** 2 + x[1] ** 2


def _tan_beta(x):
    t = jnp.tan(x[2])
    return (x[1] - x[0] * t) / (x[0] + x[1] * t)


def _tan_phi(x):
    return x[1] / x[0]


OUTPUTS = {"r2": _r2, "tan_beta": _tan_beta, "tan_phi": _tan_phi}


def _pad(vec, n):
    return jnp.concatenate([vec, jnp.zeros(n - 3)]) if n > 3 else vec


def _system(output, disturbance, gamma_known, name):
    n = 3 if gamma_known else 4
    states = ("xv", "yv", "theta") if gamma_known else ("xv", "yv", "theta", "gamma")

    def v_field(x):
        return _pad(jnp.stack([jnp.cos(x[2]), jnp.sin(x[2]), 0.0 * x[2]]), n)

    def omega_field(x):
        return _pad(jnp.array([0.0, 0.0, 1.0]), n)

    def w_field(x):
        g = GAMMA if gamma_known else x[3]
        return _pad(jnp.stack([jnp.cos(g), jnp.sin(g), 0.0 * x[2]]), n)

    unknown = {"w": w_field} if disturbance else {}
    return uj.System(states, {output: OUTPUTS[output]}, known={"v": v_field, "omega": omega_field},
                     unknown=unknown, domain=DOMAIN, angles=states[2:], name=f"unicycle_disturbance:{name}")


def no_disturbance_range():
    """No disturbance, y = r^2 (ORC; 003 section 4, last paragraph)."""
    return _system("r2", False, True, "no_disturbance_range")


def no_disturbance_bearing():
    """No disturbance, y = tan beta (ORC)."""
    return _system("tan_beta", False, True, "no_disturbance_bearing")


def no_disturbance_phi():
    """No disturbance, y = tan phi (ORC)."""
    return _system("tan_phi", False, True, "no_disturbance_phi")


def gamma_known_range():
    """Disturbance along a known gamma, y = r^2 (003 section 4.1)."""
    return _system("r2", True, True, "gamma_known_range")


def gamma_known_bearing():
    """Disturbance along a known gamma, y = tan beta (003 section 4.1)."""
    return _system("tan_beta", True, True, "gamma_known_bearing")


def gamma_known_phi():
    """Disturbance along a known gamma, y = tan phi (003 section 4.1)."""
    return _system("tan_phi", True, True, "gamma_known_phi")


def gamma_unknown_range():
    """Disturbance along an unknown constant gamma, y = r^2 (003 section 4.2)."""
    return _system("r2", True, False, "gamma_unknown_range")


def gamma_unknown_bearing():
    """Disturbance along an unknown constant gamma, y = tan beta (003 section 4.2)."""
    return _system("tan_beta", True, False, "gamma_unknown_bearing")


def gamma_unknown_phi():
    """Disturbance along an unknown constant gamma, y = tan phi (003 section 4.2)."""
    return _system("tan_phi", True, False, "gamma_unknown_phi")


def rotation_symmetry(x):
    """Rotation about the origin, for 3 states (no disturbance): [-yv, xv, 1]."""
    return jnp.array([-x[1], x[0], 1.0])


def rotation_symmetry_gamma(x):
    """Rotation about the origin carrying gamma along: [-yv, xv, 1, 1] (003 section 4)."""
    return jnp.array([-x[1], x[0], 1.0, 1.0])


#: Published results (003 section 4 and Table 1).
PUBLISHED = {
    "no_disturbance_range": {"source": "003 section 4 (text after Table 1)", "method": "orc",
                             "dim": 2, "symmetries": ["rotation_symmetry"]},
    "no_disturbance_bearing": {"source": "003 section 4 (text after Table 1)", "method": "orc",
                               "dim": 2, "symmetries": ["rotation_symmetry"]},
    "no_disturbance_phi": {"source": "003 section 4 (text after Table 1)", "method": "orc",
                           "dim": 3, "observable": ["xv", "yv", "theta"]},
    "gamma_known_range": {"source": "003 section 4.1", "method": "single_ui", "dims": [1, 2, 3],
                          "dim": 3, "m_prime": 0, "observable": ["xv", "yv", "theta"]},
    "gamma_known_bearing": {"source": "003 section 4.1", "method": "single_ui", "dims": [1, 2, 3],
                            "dim": 3, "m_prime": 0, "observable": ["xv", "yv", "theta"]},
    "gamma_known_phi": {"source": "003 section 4.1", "method": "single_ui", "dims": [1, 2, 3],
                        "dim": 3, "m_prime": 0, "observable": ["xv", "yv", "theta"]},
    "gamma_unknown_range": {"source": "003 section 4.2", "method": "single_ui",
                            "dims": [1, 2, 3, 3], "dim": 3, "m_prime": 0, "m_star": 2,
                            "observable": [], "symmetries": ["rotation_symmetry_gamma"]},
    "gamma_unknown_bearing": {"source": "003 section 4.2", "method": "single_ui",
                              "dims": [1, 2, 3, 3], "dim": 3, "m_prime": 0, "m_star": 2,
                              "observable": [], "symmetries": ["rotation_symmetry_gamma"]},
    "gamma_unknown_phi": {"source": "003 section 4.2", "method": "single_ui", "dims": [1, 2, 4],
                          "dim": 4, "m_prime": 0, "observable": ["xv", "yv", "theta", "gamma"]},
}


# ---------------------------------------------------------------------------------------
# Monte Carlo experiments (003 section 5).
#
# From the paper: Euler step 5e-4 s, 10 s; v = 0.1 m/s; omega ~ N(2 pi/10, (6 pi/10)^2) and
# w ~ N(0.05, 0.005^2) drawn every step; gamma = 0.7 pi; odometry noise std 1% of the true
# values; one output every 2.5e-2 s (50 steps), range std 1 cm, bearings std 1 deg. EKF on
# [xv, yv, theta, w, w1] (+ gamma when unknown), w' = w1, w1' = 0 + noise.
# Left open by the paper, chosen here (tested in the filter's design runs, "baseline"; docs/benchmarks/ekf.md):
#   true start (xv, yv, theta) = (1 m, 0, 0); initial estimate = truth + N(0, P0) with
#   P0 std (xv, yv, theta, [gamma], w, w1) = (5 cm, 5 cm, 5 deg, [5 deg], 0.01 m/s,
#   1e-4 m/s^2); process noise on w and w1: spectral density 1e-8 each; the white part of
#   w (std 0.005 per step) enters Q along [cos gamma, sin gamma].
# The range is read as r = sqrt(xv^2 + yv^2) (the analysis uses r^2: same observability);
# the bearing phi = atan2(yv, xv) of the vehicle from the origin, beta = bearing of the
# origin in the vehicle frame (the analysis uses their tangents).
# ---------------------------------------------------------------------------------------
_DT = 5e-4
_DEG = math.pi / 180.0
EXPERIMENT_NOTES = (
    "003 section 5. Chosen here (not in the paper): true start (xv, yv, theta) = (1, 0, 0); "
    "estimate starts at truth + N(0, P0), P0 std (5 cm, 5 cm, 5 deg, [gamma 5 deg], w 0.01 m/s, "
    "w1 1e-4 m/s^2); spectral density 1e-8 on w and w1."
)


def _unicycle_inputs(istate, z):
    u = jnp.stack([0.1 + 0.0 * z[0], 2 * math.pi / 10 + (6 * math.pi / 10) * z[0]])
    w = jnp.stack([0.05 + 0.005 * z[1]])
    return istate, u, w


def _unicycle_w_mean(istate, w):
    # the filter's w estimates the smooth part of the disturbance: its mean 0.05 m/s
    return 0.05 + 0.0 * w


def _unicycle_known_std(u):
    return 0.01 * jnp.abs(u)


def _range(x):
    return jnp.sqrt(x[0] ** 2 + x[1] ** 2)


def _phi(x):
    return jnp.arctan2(x[1], x[0])


def _beta(x):
    s, c = jnp.sin(x[2]), jnp.cos(x[2])
    return jnp.arctan2(x[0] * s - x[1] * c, -x[0] * c - x[1] * s)


_EXPERIMENTS = {}  # one object per experiment: runs of the same one share compiled code


def _experiment(output, gamma_known):
    key = (output, gamma_known)
    if key not in _EXPERIMENTS:
        _EXPERIMENTS[key] = _make_experiment(output, gamma_known)
    return _EXPERIMENTS[key]


def _make_experiment(output, gamma_known):
    from uio_jax import Experiment, Measurement, Quantity

    system = {("r", True): gamma_known_range, ("r", False): gamma_unknown_range,
              ("phi", True): gamma_known_phi, ("phi", False): gamma_unknown_phi,
              ("beta", True): gamma_known_bearing, ("beta", False): gamma_unknown_bearing,
              }[(output, gamma_known)]()
    meas = {"r": Measurement("range", _range, 0.01, 50),
            "phi": Measurement("bearing phi", _phi, _DEG, 50, angle=True),
            "beta": Measurement("bearing beta", _beta, _DEG, 50, angle=True)}[output]
    x0 = (1.0, 0.0, 0.0) if gamma_known else (1.0, 0.0, 0.0, GAMMA)
    prior = (0.05, 0.05, 5 * _DEG) + (() if gamma_known else (5 * _DEG,)) + (0.01, 1e-4)
    tag = f"{'range' if output == 'r' else output}_gamma_{'known' if gamma_known else 'unknown'}"
    # the bearing of the vehicle from the origin: its error is the error along the rotation
    # about the origin (the unobservable direction with range output and gamma unknown)
    rot_obs = not (output in ("r", "beta") and not gamma_known)
    quantities = (Quantity("bearing phi", _phi, angle=True, unit="rad", observable=rot_obs),
                  Quantity("range", _range, unit="m", observable=True))
    return Experiment(
        name=f"unicycle_disturbance:{tag}", system=system, dt=_DT, n_steps=20000, x0=x0,
        inputs=_unicycle_inputs, istate0=(), n_input_normals=2, known_std=_unicycle_known_std,
        measurements=(meas,), w0=(0.05,), w_white_std=(0.005,), order=2, q_aug=(1e-8, 1e-8),
        prior_std=prior, quantities=quantities, nees_states=("xv", "yv", "theta"),
        record_every=1, w_reference=_unicycle_w_mean, notes=EXPERIMENT_NOTES,
        units={"xv": "m", "yv": "m", "w": "m/s"})


def range_gamma_known_experiment():
    """003 section 5, range output, gamma known: 5-state EKF (fig. 3 left)."""
    return _experiment("r", True)


def range_gamma_unknown_experiment():
    """003 section 5, range output, gamma unknown: 6-state EKF (fig. 3 right)."""
    return _experiment("r", False)


def phi_gamma_known_experiment():
    """003 section 5, bearing of the vehicle from the origin (phi), gamma known (fig. 5)."""
    return _experiment("phi", True)


def phi_gamma_unknown_experiment():
    """003 section 5, bearing phi, gamma unknown: still observable (fig. 5 right)."""
    return _experiment("phi", False)


def beta_gamma_known_experiment():
    """003 section 5, bearing of the origin in the vehicle frame (beta), gamma known (fig. 4)."""
    return _experiment("beta", True)


def beta_gamma_unknown_experiment():
    """003 section 5, bearing beta, gamma unknown (fig. 4 right)."""
    return _experiment("beta", False)
