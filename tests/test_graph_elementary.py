"""The elementary functions made rational modulo p (``uio_jax._engine.graph_elementary``)
and the independence of their generators (``graph_independence``).

Identities of the real functions must hold exactly on the variety (``sin^2 + cos^2 = 1``,
``tanh = sinh / cosh``, ``sqrt(u)^2 = u``, the derivative rules), and a relation between
generators (``sin x`` with ``sin 2x``) must be found, so that such a model is never decided as
if they were independent. At the analysis level: the ``sin`` chain of the issue (fully
observable, float64 alone rejected its last direction) and a model whose two outputs are one
function written two ways.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj
from uio_jax._engine.graph import Graph
from uio_jax._engine.graph_exact import PRIME, ModularEvaluator
from uio_jax._engine.graph_independence import generator_keys, independent


def _at_random_point(g, roots, seed=1):
    rng = np.random.default_rng(seed)
    for _ in range(20):  # a point where a square root exists
        point = [int(v) for v in rng.integers(1, 2**62, size=g.n)]
        ev = ModularEvaluator(g, [point])
        try:
            return ev.gradients(roots)
        except ArithmeticError:
            continue
    raise AssertionError("no point")


def test_identities_hold_exactly_on_the_variety():
    g = Graph(2)
    x, y = g.coords
    u = g.add(g.mul(x, y), g.const(0.3))
    sin, cos = g.unary("sin", u), g.unary("cos", u)
    E = g.unary("exp", y)
    zero_exprs = [
        g.sub(g.add(g.ipow(sin, 2), g.ipow(cos, 2)), g.one),                      # circle
        g.sub(g.unary("tan", u), g.div(sin, cos)),                                 # tan = s / c
        g.sub(g.unary("tanh", y), g.div(g.unary("sinh", y), g.unary("cosh", y))),  # tanh
        g.sub(g.ipow(g.unary("sqrt", g.add(g.ipow(x, 2), g.one)), 2), g.add(g.ipow(x, 2), g.one)),
        g.sub(g.unary("expm1", y), g.sub(E, g.one)),
        g.sub(g.mul(g.unary("logistic", y), g.add(g.one, E)), E),
        g.sub(g.binary("pow", x, g.const(1.5)), g.mul(x, g.unary("sqrt", x))),
    ]
    values, grads = _at_random_point(g, zero_exprs)
    assert all(int(v) % PRIME == 0 for v in values[0])
    assert all(int(v) % PRIME == 0 for v in grads[0].reshape(-1))


def test_the_derivative_rules_hold_on_the_variety():
    """``d sin u = cos u du``, ``d log x = dx / x``, ``d atan x = dx / (1 + x^2)``."""
    g = Graph(2)
    x, y = g.coords
    u = g.mul(x, y)
    exprs = [g.unary("sin", u), g.unary("cos", u), g.unary("log", x), g.unary("atan", x)]
    values, grads = _at_random_point(g, exprs)
    p = PRIME
    xv, yv = _at_random_point(g, [x, y])[0][0]
    cos = int(values[0][1])
    assert [int(v) % p for v in grads[0][0]] == [cos * yv % p, cos * xv % p]
    assert int(grads[0][2][0]) % p == pow(int(xv), -1, p)
    assert int(grads[0][3][0]) % p == pow(1 + int(xv) ** 2, -1, p)


@pytest.mark.parametrize("build, related", [
    (lambda g, x, y: [g.unary("sin", x), g.unary("cos", x), g.unary("sin", y)], False),
    (lambda g, x, y: [g.unary("sin", x), g.unary("sin", g.mul(g.const(2), x))], True),
    (lambda g, x, y: [g.unary("exp", x), g.unary("exp", g.neg(x))], True),
    (lambda g, x, y: [g.unary("exp", x), g.unary("log", x)], False),
    (lambda g, x, y: [g.unary("log", x), g.unary("log", g.mul(x, x))], True),
    (lambda g, x, y: [g.binary("atan2", x, y), g.unary("atan", g.div(x, y))], True),
    (lambda g, x, y: [g.unary("asin", x), g.unary("acos", x)], True),
    (lambda g, x, y: [g.unary("atan", x), g.unary("sin", g.unary("atan", x))], True),
    (lambda g, x, y: [g.unary("exp", g.mul(x, y)), g.unary("sin", g.mul(x, y))], False),
    (lambda g, x, y: [g.unary("sin", g.sub(x, y)), g.unary("sin", x), g.unary("cos", y)], True),
], ids=["sin_x_cos_x_sin_y", "sin_x_sin_2x", "exp_u_exp_minus_u", "exp_x_log_x", "log_x_log_x2",
        "atan2_atan", "asin_acos", "atan_sin_atan", "exp_and_sin_of_one_argument", "angle_difference"])
def test_relations_between_generators_are_found(build, related):
    g = Graph(2)
    roots = build(g, *g.coords)
    ok, why = independent(g, generator_keys(g, roots), np.random.default_rng(0))
    assert ok is not related, why


def test_the_sin_chain_is_fully_observable_and_exact():
    """``x_i' = x_{i+1} + 0.1 sin(x_i) x_0``, ``y = x_0`` (n = 20): the gradients of
    ``L_f^k y`` are unit lower-triangular, so every state is observable; float64 rejected the
    last direction (dim 19, "exact") until the sin nodes were made rational and the stopping
    step's rejection was settled modulo p."""
    n = 20

    def drift(x):
        return jnp.concatenate([x[1:], jnp.zeros(1)]) + 0.1 * jnp.sin(x) * x[0]

    system = uj.System(states=tuple(f"x{i}" for i in range(n)), outputs={"y": lambda x: x[0]}, drift=drift)
    rep = uj.analyze(system, samples=256)
    assert rep.dim == n and rep.exact


def test_one_function_written_two_ways_is_one_direction():
    """``y1 = sin(x1 - x2)``, ``y2 = sin x1 cos x2 - cos x1 sin x2``: one function, dim 1. The
    generators are related (the angle difference), so the model is not decided as if
    ``sin(x1 - x2)`` were independent of ``sin x1``, ``cos x2``."""
    system = uj.System(states=("x1", "x2"), outputs={
        "y1": lambda x: jnp.sin(x[0] - x[1]),
        "y2": lambda x: jnp.sin(x[0]) * jnp.cos(x[1]) - jnp.cos(x[0]) * jnp.sin(x[1])})
    rep = uj.analyze(system, samples=256)
    assert rep.dim == 1 and rep.observable == {"x1": False, "x2": False}


def test_directions_where_float64_cannot_separate_the_generators():
    """``y = x1``, ``x1' = x1 + 1e-14 x2``: dim 2 (``x2 = (y' - y) / 1e-14``), ``x3`` hidden. At
    any state the two kept gradients are ``(1, 0, 0)`` and ``(1, 1e-14, 0)``: ``s_2/s_1`` is
    under float64's ``rtol``, so the directions were refused; they are computed in extended
    precision at that state instead (the null space ``e_3``)."""
    system = uj.System(("x1", "x2", "x3"), {"y": lambda x: x[0]},
                       drift=lambda x: jnp.array([x[0] + 1e-14 * x[1], 0.0, 0.0]))
    rep = uj.analyze(system, samples=256)
    assert rep.dim == 2 and rep.exact
    d = rep.unobservable_directions([1.0, 0.7, 0.9])
    assert d.shape == (3, 1) and np.allclose(np.abs(d[:, 0]), [0.0, 0.0, 1.0], atol=1e-12)
