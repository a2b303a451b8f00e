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
