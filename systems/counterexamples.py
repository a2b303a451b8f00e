# uio-jax: models
"""Small systems whose answer is known by hand: regression cases of the analyses.

``drift_example``: a drift and one unknown input (the single-input algorithm of 004 does not
apply with drift; the EORC does)::

    x1' = x2 + w,   x2' = 0,   y = x1.

``y' = x2 + w``: any change of x2 is hidden by the unknown w (``x2 + w`` is all that
reaches y), so x2 is unobservable at every order. With ``x^(k) = [x1, x2, w, .., w^(k-1)]``,
``Omega-bar_k = span{dx1, d(x2 + w), dw^(1), .., dw^(k-1)}``: dim 1 on the original state.

``single_ui_stop_rule``: the counterexample to the stop rule of 002 / 004 section 9 (README,
"A correction to the papers' stopping rule")::

    x0' = u + x1 w,   x1' = x0 x2 u,   x2' = 0,   y = x0.

The published rule stops at ``m* = 0`` with ``Omega_0 = span{dx0}`` (dim 1). The EORC:
``F0 = [x1 w, 0, 0, w^(1), ..]``, ``L_u h = 1``, ``L_F0 h = x1 w``: ``Omega-bar_1 =
span{dx0, d(x1 w)}``, dim 1 on the original state; at order 2 ``L_F0 L_F0 h = x1 w^(1)`` and
``L_u L_F0 h = x0 x2 w`` join: ``Omega-bar_2`` has rank 4 on ``[x0, x1, x2, w, w^(1)]`` and
its intersection with ``span{dx}`` has dim 2 (``dx0`` and one combination of ``dx1, dx2``):
the published stop at m* = 0 misses a direction.
"""

import jax.numpy as jnp

import uio_jax as uj


def drift_example():
    """``x1' = x2 + w, x2' = 0, y = x1`` (drift ``[x2, 0]``, ``g = [1, 0]``): x2 unobservable."""
    return uj.System(
        states=("x1", "x2"),
        outputs={"y": lambda x: x[0]},
        unknown={"w": lambda x: jnp.array([1.0, 0.0])},
        drift=lambda x: jnp.stack([x[1], 0.0 * x[1]]),
        name="counterexamples:drift_example",
    )


def single_ui_stop_rule():
    """``x0' = u + x1 w, x1' = x0 x2 u, x2' = 0, y = x0`` (one known u, one unknown w)."""
    return uj.System(
        states=("x0", "x1", "x2"),
        outputs={"y": lambda x: x[0]},
        known={"u": lambda x: jnp.stack([1.0 + 0.0 * x[0], x[0] * x[2], 0.0 * x[0]])},
        unknown={"w": lambda x: jnp.stack([x[1], 0.0 * x[0], 0.0 * x[0]])},
        name="counterexamples:single_ui_stop_rule",
    )


#: Results derived by hand (module docstring); "dims" per order k = 0, 1, 2, ... (EORC).
PUBLISHED = {
    "drift_example": {"source": "uio_jax issue 4 (hand derivation, module docstring)",
                      "method": "eorc", "dim": 1, "observable": ["x1"]},
    "single_ui_stop_rule": {"source": "uio_jax single-UI issue (README: correction to the stop rule)",
                            "method": "eorc", "dims": [1, 1, 2], "dim": 2,
                            "observable": ["x0"]},
}
