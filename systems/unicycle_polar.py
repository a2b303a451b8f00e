# uio-jax: models
"""Unicycle in polar coordinates, one input unknown (seed 004, section 11.1).

Martinelli, "Nonlinear Unknown Input Observability: Extended Observability Rank Criterion
and the Case of a Single Unknown Input", INRIA RR-8608 (2015), eq. 35::

    r'     = v cos(theta - phi)
    phi'   = v sin(theta - phi) / r
    theta' = omega

State ``[r, phi, theta]`` (distance and bearing of the vehicle from the origin, heading).
Outputs: the range ``r`` (cases 1-2), the bearing of the origin in the local frame
``theta - phi`` (cases 3-4; the paper writes pi - (theta - phi), the same information) and
the bearing of the vehicle in the global frame ``phi`` (cases 5-6). In each case one of the
two inputs v, omega is unknown.
"""

import jax.numpy as jnp

import uio_jax as uj

STATES = ("r", "phi", "theta")
DOMAIN = {"r": (0.5, 2.0)}
ANGLES = ("phi", "theta")


def _v_field(x):
    r, phi, theta = x
    return jnp.stack([jnp.cos(theta - phi), jnp.sin(theta - phi) / r, 0.0 * r])


def _omega_field(x):
    return jnp.array([0.0, 0.0, 1.0])


OUTPUTS = {
    "range": {"r": lambda x: x[0]},
    "bearing": {"theta_minus_phi": lambda x: x[2] - x[1]},
    "phi": {"phi": lambda x: x[1]},
}


def _system(output, unknown, name):
    fields = {"v": _v_field, "omega": _omega_field}
    known = {k: f for k, f in fields.items() if k != unknown}
    unk = {unknown: fields[unknown]} if unknown else {}
    return uj.System(STATES, OUTPUTS[output], known=known, unknown=unk, domain=DOMAIN,
                     angles=ANGLES, name=f"unicycle_polar:{name}")


def range_known():
    """y = r, v and omega known (ORC)."""
    return _system("range", None, "range_known")


def bearing_known():
    """y = theta - phi, v and omega known (ORC)."""
    return _system("bearing", None, "bearing_known")


def phi_known():
    """y = phi, v and omega known (ORC)."""
    return _system("phi", None, "phi_known")


def range_v_unknown():
    """004 section 11.1.1: y = r, u = omega, w = v."""
    return _system("range", "v", "range_v_unknown")


def range_omega_unknown():
    """004 section 11.1.2: y = r, u = v, w = omega (L_g h = 0)."""
    return _system("range", "omega", "range_omega_unknown")


def bearing_v_unknown():
    """004 section 11.1.3: y = theta - phi, u = omega, w = v."""
    return _system("bearing", "v", "bearing_v_unknown")


def bearing_omega_unknown():
    """004 section 11.1.4: y = theta - phi, u = v, w = omega."""
    return _system("bearing", "omega", "bearing_omega_unknown")


def phi_v_unknown():
    """004 section 11.1.5: y = phi, u = omega, w = v."""
    return _system("phi", "v", "phi_v_unknown")


def phi_omega_unknown():
    """004 section 11.1.6: y = phi, u = v, w = omega (L_g h = 0)."""
    return _system("phi", "omega", "phi_omega_unknown")


def rotation_symmetry(x):
    """Rotation about the origin: phi and theta shift together (r, theta - phi invariant)."""
    return jnp.array([0.0, 1.0, 1.0])


def scale_symmetry(x):
    """Scaling about the origin: r grows, angles invariant (hidden when v is unknown)."""
    return jnp.array([x[0], 0.0, 0.0])


#: Published results (004 section 11.1). Per-step dims are those printed in the paper;
#: for 11.1.2 and 11.1.6 (L_g h = 0) the paper indexes Omega_1 = span{dh, d L_f h}.
#: Observable components are not printed in the paper; they follow from the printed
#: codistributions (e.g. 11.1.1: Omega* = span{dr, d(phi - theta)/cos^2}) and are checked
#: independently in the tests.
PUBLISHED = {
    "range_known": {"source": "003 section 4 (no disturbance)", "method": "orc", "dim": 2,
                    "observable": ["r"], "symmetries": ["rotation_symmetry"]},
    "bearing_known": {"source": "003 section 4 (no disturbance)", "method": "orc", "dim": 2,
                      "observable": ["r"], "symmetries": ["rotation_symmetry"]},
    "phi_known": {"source": "003 section 4 (no disturbance)", "method": "orc", "dim": 3,
                  "observable": ["r", "phi", "theta"]},
    "range_v_unknown": {"source": "004 section 11.1.1", "method": "single_ui", "dims": [1, 1, 2, 2],
                        "dim": 2, "m_prime": 2, "m_star": 2, "observable": ["r"],
                        "functions": ["r", "theta - phi"],
                        "symmetries": ["rotation_symmetry"]},
    "range_omega_unknown": {"source": "004 section 11.1.2", "method": "single_ui", "dim": 2,
                            "m_prime": 1, "m_star": 1, "observable": ["r"],
                            "symmetries": ["rotation_symmetry"]},
    "bearing_v_unknown": {"source": "004 section 11.1.3", "method": "single_ui", "dims": [1, 1],
                          "dim": 1, "m_prime": 0, "m_star": 0, "observable": [],
                          "symmetries": ["rotation_symmetry", "scale_symmetry"]},
    "bearing_omega_unknown": {"source": "004 section 11.1.4", "method": "single_ui",
                              "dims": [1, 2, 2], "dim": 2, "m_prime": 0, "m_star": 1,
                              "observable": ["r"], "symmetries": ["rotation_symmetry"]},
    "phi_v_unknown": {"source": "004 section 11.1.5", "method": "single_ui", "dims": [1, 1, 2, 2],
                      "dim": 2, "m_prime": 2, "m_star": 2, "observable": ["phi", "theta"],
                      "symmetries": ["scale_symmetry"]},
    "phi_omega_unknown": {"source": "004 section 11.1.6", "method": "single_ui", "dim": 3,
                          "observable": ["r", "phi", "theta"]},
}
