# uio-jax: models
"""Unicycle with a GPS: the simple 2D localization problem (seed 004 section 11.2.1, 001 section V-A).

Martinelli, INRIA RR-8608 (004) eq. 34, 36 (= MED 2015 (001) eq. 11, 12)::

    xv'    = v cos(theta)
    yv'    = v sin(theta)
    theta' = omega
    y      = [xv, yv]

State ``[xv, yv, theta]``; the GPS gives the position. With v and omega known the ORC gives
full observability at the first order (``L_v h_x = cos theta``, ``L_v h_y = sin theta``).
With both inputs unknown (``m_u = 0``, ``m_w = 2``, ``g_1 = [cos, sin, 0]``,
``g_2 = [0, 0, 1]``) the EORC on ``x^(1) = [xv, yv, theta, v, omega]`` gives
``Omega-bar_1 = span{[1,0,0,0,0], [0,1,0,0,0], [0,0,-v sin, cos, 0], [0,0,v cos, sin, 0]}``
(4 generators): theta (and v) are observable at k = 1, omega is not (its ``e`` spans
``Delta^1 = Omega-bar_1^perp``).
"""

import jax.numpy as jnp

import uio_jax as uj

STATES = ("xv", "yv", "theta")
OUTPUTS = {"h_x": lambda x: x[0], "h_y": lambda x: x[1]}
DOMAIN = {"xv": (-2.0, 2.0), "yv": (-2.0, 2.0)}


def _v_field(x):
    return jnp.stack([jnp.cos(x[2]), jnp.sin(x[2]), 0.0 * x[2]])


def _omega_field(x):
    return jnp.array([0.0, 0.0, 1.0])


FIELDS = {"v": _v_field, "omega": _omega_field}


def _system(unknown, name):
    known = {k: f for k, f in FIELDS.items() if k not in unknown}
    unk = {k: f for k, f in FIELDS.items() if k in unknown}
    return uj.System(STATES, OUTPUTS, known=known, unknown=unk, domain=DOMAIN,
                     angles=("theta",), name=f"gps:{name}")


def inputs_known():
    """v and omega known: ORC (004 section 11.2.1, first case)."""
    return _system((), "inputs_known")


def inputs_unknown():
    """v and omega unknown: EORC on ``[xv, yv, theta, v, omega]`` (004 section 11.2.1)."""
    return _system(("v", "omega"), "inputs_unknown")


def omega_unknown():
    """v known, omega unknown (one unknown input: single_ui / EORC cross-check)."""
    return _system(("omega",), "omega_unknown")


def v_unknown():
    """omega known, v unknown (one unknown input: single_ui / EORC cross-check)."""
    return _system(("v",), "v_unknown")


#: Published results (004 section 11.2.1 = 001 section V-A). ``dims`` are per step m
#: (ORC) or per order k = 0, 1 (EORC, dimension on the original state); ``augmented_ranks``
#: the ranks of Omega-bar_0, Omega-bar_1 printed in the paper.
PUBLISHED = {
    "inputs_known": {"source": "004 section 11.2.1 (001 section V-A)", "method": "orc",
                     "dims": [2, 3], "dim": 3, "observable": ["xv", "yv", "theta"]},
    "inputs_unknown": {"source": "004 section 11.2.1 (001 section V-A)", "method": "eorc",
                       "dims": [2, 3], "dim": 3, "k": 1, "augmented_ranks": [2, 4],
                       "observable": ["xv", "yv", "theta"], "functions": ["xv", "yv", "theta"]},
}
