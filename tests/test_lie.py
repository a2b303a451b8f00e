"""Lie calculus by forward-mode AD against hand-computed derivatives; compile caching."""

import jax
import jax.numpy as jnp
import numpy as np

import uio_jax as uj
from uio_jax._calculus import lie as _lie
from uio_jax._calculus.generators import builder_for


def h(x):
    return x[0] ** 2 * jnp.sin(x[1])


def f(x):
    return jnp.stack([x[1], -x[0] * x[1]])


def g(x):
    return jnp.stack([jnp.cos(x[0]), 1.0 + 0.0 * x[0]])


X = jnp.array([0.7, -1.3])


def test_lie_derivative_matches_hand_computation():
    x0, x1 = np.asarray(X)
    dh = np.array([2 * x0 * np.sin(x1), x0**2 * np.cos(x1)])
    expected = dh @ np.array([x1, -x0 * x1])
    assert np.isclose(_lie.lie_derivative(h, f)(X), expected, rtol=1e-14)


def test_lie_bracket_matches_hand_computation():
    x0, x1 = np.asarray(X)
    Jf = np.array([[0.0, 1.0], [-x1, -x0]])
    Jg = np.array([[-np.sin(x0), 0.0], [0.0, 0.0]])
    expected = Jg @ np.array([x1, -x0 * x1]) - Jf @ np.array([np.cos(x0), 1.0])
    np.testing.assert_allclose(_lie.lie_bracket(f, g)(X), expected, rtol=1e-14)


def test_bracket_identity_L_ab_equals_commutator():
    """L_[a,b] h = L_a L_b h - L_b L_a h (with [a, b] = (db/dx) a - (da/dx) b)."""
    lhs = _lie.lie_derivative(h, _lie.lie_bracket(f, g))(X)
    rhs = (_lie.lie_derivative(_lie.lie_derivative(h, g), f)(X)
           - _lie.lie_derivative(_lie.lie_derivative(h, f), g)(X))
    assert np.isclose(lhs, rhs, rtol=1e-12)


def test_block_gradients_equal_one_by_one_gradients():
    fns = (h, _lie.lie_derivative(h, f))
    fields = (f, g)
    block = _lie.lie_derivative_gradients(fns, fields)(X)
    one_by_one = jnp.stack([jax.grad(_lie.lie_derivative(p, v))(X) for p in fns for v in fields])
    np.testing.assert_allclose(block, one_by_one, rtol=1e-13, atol=1e-14)


def test_an_analysis_in_the_expression_graph_compiles_nothing():
    """Every function of this model translates into the expression graph: the analysis
    evaluates it with numpy and compiles no program."""
    s = uj.System(states=("a", "b"), outputs={"y": h}, known={"f": f, "g": g})
    rep = uj.analyze(s, samples=128)
    assert rep.dim == 2 and builder_for(s).stats == []


def erf_inv_output(x):
    """An output with a primitive the expression graph has no rule for (``erf_inv``)."""
    return jax.lax.erf_inv(0.5 * jnp.tanh(x[0])) + x[1] ** 2


def test_second_analysis_of_the_same_system_compiles_nothing():
    """A model outside the graph is compiled by XLA, once per System."""
    s = uj.System(states=("a", "b"), outputs={"y": erf_inv_output}, known={"f": f, "g": g})
    uj.analyze(s, samples=128)
    compiled = len(builder_for(s).stats)
    assert compiled > 0
    uj.analyze(s, samples=128, seed=1)
    assert len(builder_for(s).stats) == compiled
    # every program was really traced and compiled once: equations counted, a positive compile time
    assert all(st.eqns > 0 and 0 < st.compile_s < 600 for st in builder_for(s).stats)


def test_power_nodes_of_the_graph():
    """``Builder.power``: ``L_v^j base`` one node (label ``L_v^j base``), equal to ``j`` nested
    Lie derivatives; ``power_of`` finds ``(base, j)``, also through ``Builder.lie``, whose
    repeated derivatives go through the same power policy."""
    b = builder_for(uj.System(("a", "b"), {"h": h}, known={"f": f}))
    hn, fn = b.scalar("h", h), b.field("f", f)
    p3 = b.power(fn, hn, 3)
    assert p3.label == "L_f^3 h" and b.power(fn, hn, 1).label == "L_f h"
    assert b.power(fn, hn, 3) is p3 and b.power(fn, hn, 0) is hn
    assert b.power_of(p3, fn) == (hn, 3) and b.power_of(hn, fn) == (hn, 0)
    nested = b.lie(fn, b.lie(fn, b.lie(fn, hn)))
    assert nested.label == "L_f L_f L_f h" and b.power_of(nested, fn) == (hn, 3)
    want = _lie.lie_derivative(_lie.lie_derivative(_lie.lie_derivative(h, f), f), f)
    with jax.enable_x64(True):
        x = jnp.asarray(X, dtype=jnp.float64)
        for node in (p3, nested):
            np.testing.assert_allclose(node.fn(x), want(x), rtol=1e-12)
