# uio-jax: models
"""Several unknown inputs, drift, UI extension: test cases of the general analytic solution.

Martinelli's general solution (arXiv 2201.07610; toolbox TUIO6, ``github.com/agomartinelli/TUIO6``;
statement in ``docs/general_ui.md``) for ``x' = f0 + sum u_i f_i + sum w_j g_j``,
``y = h(x)``. Known inputs are generic smooth functions of time ("smooth" meaning) unless an
entry says ``known_inputs = "switchable"``. Every verdict below was derived by hand (the
derivation is in the factory's docstring) and checked with the exact oracle
``scripts/general_ui_oracle.py`` (rational arithmetic at 3 random points) and with an exact EORC
(``scripts/general_ui_oracle.py:eorc``) whose dimension reaches the same value: the EORC is a lower
bound, the hand-made family of indistinguishable states an upper bound.

Public examples: the TAC-2025 case study, the HIV model, the "trivial" and the time-varying
example of TUIO6's ``initialize_system.m`` (TUIO6 prints no verdict: they are derived here), the GPS
unicycle of 004 section 11.2.1 (published). Hand-made: the UI-extension branches
(``extension_kept``, ``extension_dropped``, ``extension_two_kept``, ``guarded_full_rank``) and the known-input
semantics example (``known_gain_*``).

Unknown constant parameters are states with zero dynamics (as in TUIO6).
"""

import jax.numpy as jnp

import uio_jax as uj


def _z(x):
    return 0.0 * x[0]


def tac2025():
    """TUIO6 case study "TAC 2025": 5 states, 2 unknown inputs, drift, y = (x1, x2)::

        x1' = x3,  x2' = x5 + w1 + w2,  x3' = x4 (w1 + w2),  x4' = x4 w2,  x5' = x5 w2.

    By hand: x3 = y1'. With s = w1 + w2: y2' = x5 + s and y1'' = x4 s, so
    ``x4 (y2' - x5) = y1''`` is the one thing known about (x4, x5). Family of indistinguishable
    states: for any constant c take x4 = c x5 (then w2 = x5'/x5 keeps x4' = x4 w2), x5 a root of
    ``c x5 (y2' - x5) = y1''`` and w1 = y2' - x5 - w2: one free constant, so dim 4 (x1, x2, x3
    observable, x4 and x5 not). The guarded closure of the general solution reaches rank 5
    before its guard triggers the UI extension (note section 7.1: stopping there says "all
    observable", wrongly). Exact EORC (smooth): dims 2, 3, 4, 4, 4, 4, 4, 4 for k = 0..7.
    """
    return uj.System(
        states=("x1", "x2", "x3", "x4", "x5"),
        outputs={"y1": lambda x: x[0], "y2": lambda x: x[1]},
        unknown={"w1": lambda x: jnp.stack([_z(x), 1.0 + _z(x), x[3], _z(x), _z(x)]),
                 "w2": lambda x: jnp.stack([_z(x), 1.0 + _z(x), x[3], x[3], x[4]])},
        drift=lambda x: jnp.stack([x[2], x[4], _z(x), _z(x), _z(x)]),
        name="multi_ui:tac2025",
    )


def guarded_full_rank():
    """``tac2025`` without x1, x3 measured instead (4 states, same property)::

        x2' = x5 + w1 + w2,  x3' = x4 (w1 + w2),  x4' = x4 w2,  x5' = x5 w2,  y = (x3, x2).

    Same argument as :func:`tac2025` with y1' in place of y1'': ``x4 (y2' - x5) = y1'`` and x4 = c x5
    for a free constant c: dim 3, x2 and x3 observable. The guarded closure reaches rank 4 = n
    before it aborts (root x2, ord 1); the extension keeps v (theta_v = v / x4 + x5 up to the
    rescaling). Exact EORC (smooth): 2, 3, 3, 3, 3, 3 for k = 0..5.
    """
    return uj.System(
        states=("x2", "x3", "x4", "x5"),
        outputs={"y1": lambda x: x[1], "y2": lambda x: x[0]},
        unknown={"w1": lambda x: jnp.stack([1.0 + _z(x), x[2], _z(x), _z(x)]),
                 "w2": lambda x: jnp.stack([1.0 + _z(x), x[2], x[2], x[3]])},
        drift=lambda x: jnp.stack([x[3], _z(x), _z(x), _z(x)]),
        name="multi_ui:guarded_full_rank",
    )


HIV_STATES = ("T_u", "T_i", "V", "lambda", "rho", "delta", "N", "c")


def hiv():
    """HIV model (TUIO6 ``initialize_system.m``; STRIKE-GOLDD's HIV with the infection rate as an
    unknown input eta): uninfected/infected cells, virions, 5 constant parameters::

        T_u' = lambda - rho T_u - eta T_u V,  T_i' = -delta T_i + eta T_u V,  V' = N delta T_i - c V,
        y = (V, T_u + T_i).

    By hand: y2' = lambda - rho T_u - delta T_i and y1' = N delta T_i - c V. For any delta,
    ``T_u = (lambda - delta y2 - y2') / (rho - delta)``, ``T_i = y2 - T_u = (rho y2 - lambda + y2') /
    (rho - delta)`` and ``N = K (rho - delta) / delta`` (K fixed by y1' + c y1 = N delta T_i) give
    the same outputs, eta following from T_u': one free constant, so dim 7. V, lambda, rho, c
    are observable (the EORC shows it: dims 2, 4, 5, 6, 7 for k = 0..4), T_u, T_i, delta, N
    are not; eta is reconstructable (canonic after one step of the m = 0 branch) but not
    observable, since T_u is not.
    """
    def drift(x):
        Tu, Ti, V, lam, rho, delta, N, c = x
        z = _z(x)
        return jnp.stack([lam - rho * Tu, -delta * Ti, N * delta * Ti - c * V, z, z, z, z, z])

    def eta(x):
        Tu, V = x[0], x[2]
        z = _z(x)
        return jnp.stack([-Tu * V, Tu * V, z, z, z, z, z, z])

    return uj.System(
        states=HIV_STATES,
        outputs={"V": lambda x: x[2], "T_total": lambda x: x[0] + x[1]},
        unknown={"eta": eta}, drift=drift, name="multi_ui:hiv",
    )


def trivial_drift():
    """TUIO6 "TRIVIAL": ``x1' = x2, x2' = w, y = x1``. x2 = y': both observable (dim 2).

    The general solution starts with m = 0 (L_g h = 0) and takes the filtered closure (note
    step 2.6) before the system becomes canonic with identifier x2.
    """
    return uj.System(
        states=("x1", "x2"), outputs={"y": lambda x: x[0]},
        unknown={"w": lambda x: jnp.array([0.0, 1.0])},
        drift=lambda x: jnp.stack([x[1], _z(x)]), name="multi_ui:trivial_drift",
    )


def time_varying():
    """TUIO6's first time-varying example: ``x1' = 1, x2' = w, y = x1 + t x2``.

    At any time t != 0 the split of y between x1 and t x2 is hidden: (x1 + d, x2 - d/t) at time t
    gives the same output with w changed accordingly (x2 is driven by the free w). dim 1
    (only x1 + t x2), no state observable. Exact EORC: 1 at every order.
    """
    return uj.System(
        states=("x1", "x2"), outputs={"y": lambda x, t: x[0] + t * x[1]},
        unknown={"w": lambda x, t: jnp.array([0.0, 1.0])},
        drift=lambda x, t: jnp.stack([1.0 + _z(x), _z(x)]), time="t",
        domain={"t": (0.5, 1.5)}, name="multi_ui:time_varying",
    )


def gps_inputs_unknown():
    """004 section 11.2.1: the GPS unicycle with v and omega both unknown (``systems/gps.py``).

    ``xv' = v cos(theta), yv' = v sin(theta), theta' = omega, y = (xv, yv)``: theta =
    atan2(y2', y1') (v = |y'| != 0), so the state is observable (published); the general
    solution extends once (m = 1 at the start: only the v column is reconstructable).
    """
    return uj.System(
        states=("xv", "yv", "theta"),
        outputs={"h_x": lambda x: x[0], "h_y": lambda x: x[1]},
        unknown={"v": lambda x: jnp.stack([jnp.cos(x[2]), jnp.sin(x[2]), _z(x)]),
                 "omega": lambda x: jnp.array([0.0, 0.0, 1.0])},
        domain={"xv": (-2.0, 2.0), "yv": (-2.0, 2.0)}, angles=("theta",),
        name="multi_ui:gps_inputs_unknown",
    )


def extension_kept():
    """Hand-made: the identifier of w2 appears after two differentiations, through w1::

        x1' = x3,  x2' = w1,  x3' = x4 w1,  x4' = w2,  y = (x1, x2).

    By hand: x3 = y1', and y1'' = x4 w1 = x4 y2', so x4 = y1'' / y2': all four observable
    (dim 4). The general solution: m = 1 (identifier x2); the guarded closure differentiates
    x1 -> x3 -> x4 and aborts at x4 (L_{G2} x4 = 1), root x1, ord 2; theta_v = D^2 x1 = x4 v
    depends on v = y2', so v is kept as a state and its derivative is the new UI; then m = 2
    (canonic). Exact EORC: 2, 3, 4 for k = 0..2.
    """
    return uj.System(
        states=("x1", "x2", "x3", "x4"), outputs={"y1": lambda x: x[0], "y2": lambda x: x[1]},
        unknown={"w1": lambda x: jnp.stack([_z(x), 1.0 + _z(x), x[3], _z(x)]),
                 "w2": lambda x: jnp.array([0.0, 0.0, 0.0, 1.0])},
        drift=lambda x: jnp.stack([x[2], _z(x), _z(x), _z(x)]), name="multi_ui:extension_kept",
    )


def extension_dropped():
    """Hand-made: the identifier of w2 is y1', and the extension chain is deleted::

        x1' = x3,  x2' = w1,  x3' = x4 w1 + w2,  x4' = 0,  y = (x1, x2).

    By hand: x3 = y1', w1 = y2', and y1'' = x4 y2' + w2: any x4 is matched by w2 = y1'' - x4 y2',
    so x4 (a parameter) is unobservable, dim 3 (x1, x2, x3 observable). The general solution:
    m = 1, the guarded closure aborts at x3 (L_{G2} x3 = 1), root x1, ord 1; theta_v = x3 does
    not depend on v, so the chain is deleted and w1 stays a UI; then m = 2 (identifiers x2,
    x3). Exact EORC: 2, 3, 3, 3, 3, 3 for k = 0..5.
    """
    return uj.System(
        states=("x1", "x2", "x3", "x4"), outputs={"y1": lambda x: x[0], "y2": lambda x: x[1]},
        unknown={"w1": lambda x: jnp.stack([_z(x), 1.0 + _z(x), x[3], _z(x)]),
                 "w2": lambda x: jnp.array([0.0, 0.0, 1.0, 0.0])},
        drift=lambda x: jnp.stack([x[2], _z(x), _z(x), _z(x)]), name="multi_ui:extension_dropped",
    )


def extension_two_kept():
    """Hand-made, 3 unknown inputs, never canonic: the extension keeps v and v'::

        x1' = x3,  x2' = w1,  x3' = x4 w1,  x4' = x5,  x5' = x6 w2,  x6' = w3,  y = (x1, x2).

    By hand: x3 = y1', x4 = y1'' / y2' (y1'' = x4 w1, w1 = y2'), x5 = x4'; then x5' = x6 w2 with w2
    free hides x6 (any x6 != 0, w2 = x5' / x6), and w3 = x6' is never seen: dim 5, x6
    unobservable. The general solution: m = 1, the guarded closure aborts at ord 3 (root x1);
    theta_v = D^3 x1 = v x5 + v' x4 depends on v^(1), so v^(0), v^(1) are kept; then m = 2 and the
    guarded closure ends without abort (the system stays non-canonic: w3 is not reconstructable).
    Exact EORC (smooth): 2, 3, 4, 5, 5, 5 for k = 0..5.
    """
    def drift(x):
        z = _z(x)
        return jnp.stack([x[2], z, z, x[4], z, z])

    return uj.System(
        states=("x1", "x2", "x3", "x4", "x5", "x6"),
        outputs={"y1": lambda x: x[0], "y2": lambda x: x[1]},
        unknown={"w1": lambda x: jnp.stack([_z(x), 1.0 + _z(x), x[3], _z(x), _z(x), _z(x)]),
                 "w2": lambda x: jnp.stack([_z(x), _z(x), _z(x), _z(x), x[5], _z(x)]),
                 "w3": lambda x: jnp.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])},
        drift=drift, name="multi_ui:extension_two_kept",
    )


def _known_gain(name):
    return uj.System(
        states=("x1", "x2"), outputs={"y": lambda x: x[0] + x[1]},
        known={"u": lambda x: jnp.stack([x[1], _z(x)])},
        unknown={"w": lambda x: jnp.array([0.0, 1.0])}, name=f"multi_ui:{name}",
    )


def known_gain_smooth():
    """``x1' = x2 u, x2' = w, y = x1 + x2`` with u a smooth known input (note section 6).

    y' = u x2 + w: with u smooth, any smooth x2(t) fits (x1 = y - x2, and x1' = u x2 holds with
    w = x2' = y' - u x2), so only x1 + x2 is observable: dim 1. Exact EORC, smooth meaning: 1 at every order.
    """
    return _known_gain("known_gain_smooth")


def known_gain_switchable():
    """The same system with u switchable (piecewise constant, classical EORC): a jump of u
    changes y' = u x2 + w by (jump) x2, which no smooth w can hide, so x2 (and x1) are observable:
    dim 2 (exact EORC, switchable meaning: 1, 2, 2, 2, 2 for k = 0..4)."""
    return _known_gain("known_gain_switchable")


#: Verdicts (module docstring). ``dim``: dimension of the observable codistribution on the
#: original state; ``observable``: the states with dx_i in it.
PUBLISHED = {
    "tac2025": {"source": "TUIO6 initialize_system.m (case study TAC 2025); verdict derived by hand "
                "(docstring), general-solution oracle and exact EORC (dims 2, 3, 4, 4, ...)",
                "method": "general_ui", "dim": 4, "observable": ["x1", "x2", "x3"],
                "ui_extension": True, "canonic": True},
    "guarded_full_rank": {"source": "hand derivation (docstring): tac2025 without x1; oracle and exact EORC",
                          "method": "general_ui", "dim": 3, "observable": ["x2", "x3"],
                          "ui_extension": True, "canonic": True},
    "hiv": {"source": "TUIO6 initialize_system.m (HIV); verdict derived by hand (docstring), oracle, "
            "exact EORC (dims 2, 4, 5, 6, 7)", "method": "general_ui", "dim": 7,
            "observable": ["V", "lambda", "rho", "c"], "ui_extension": False, "canonic": True},
    "trivial_drift": {"source": "TUIO6 initialize_system.m (TRIVIAL); x2 = y' by hand", "method": "general_ui",
                      "dim": 2, "observable": ["x1", "x2"], "ui_extension": False, "canonic": True},
    "time_varying": {"source": "TUIO6 initialize_system.m (first TIME VARIANT SYSTEM); by hand (docstring)",
                     "method": "general_ui", "dim": 1, "observable": [], "ui_extension": False,
                     "canonic": True},
    "gps_inputs_unknown": {"source": "004 section 11.2.1 (001 section V-A): full observability", "method": "general_ui",
                           "dim": 3, "observable": ["xv", "yv", "theta"], "ui_extension": True,
                           "canonic": True},
    "extension_kept": {"source": "hand derivation (docstring); oracle and exact EORC", "method": "general_ui",
                       "dim": 4, "observable": ["x1", "x2", "x3", "x4"], "ui_extension": True,
                       "canonic": True},
    "extension_dropped": {"source": "hand derivation (docstring); oracle and exact EORC", "method": "general_ui",
                          "dim": 3, "observable": ["x1", "x2", "x3"], "ui_extension": True,
                          "canonic": True},
    "extension_two_kept": {"source": "hand derivation (docstring); oracle and exact EORC", "method": "general_ui",
                           "dim": 5, "observable": ["x1", "x2", "x3", "x4", "x5"], "ui_extension": True,
                           "canonic": False},
    "known_gain_smooth": {"source": "docs/general_ui.md section 6; by hand (docstring)",
                          "method": "general_ui", "known_inputs": "smooth", "dim": 1, "observable": [],
                          "ui_extension": False, "canonic": True},
    "known_gain_switchable": {"source": "docs/general_ui.md section 6; by hand (docstring)",
                              "method": "eorc", "known_inputs": "switchable", "dim": 2,
                              "observable": ["x1", "x2"]},
}
