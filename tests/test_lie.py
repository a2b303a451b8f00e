"""Lie calculus in the expression graph against hand-computed derivatives and JAX autodiff."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj
from uio_jax._calculus.generators import builder_for


def h(x):
    return x[0] ** 2 * jnp.sin(x[1])


def f(x):
    return jnp.stack([x[1], -x[0] * x[1]])


def g(x):
    return jnp.stack([jnp.cos(x[0]), 1.0 + 0.0 * x[0]])


X = np.array([0.7, -1.3])


def _lie(phi, v):
    """``L_v phi`` by JAX autodiff (the reference)."""
    return lambda x: jax.jvp(phi, (x,), (v(x),))[1]


def _at(b, node, x):
    """The value of ``node`` at the state ``x`` (numpy over the graph)."""
    return b.values([node], np.asarray(x)[None])[0][0]


@pytest.fixture
def nodes():
    b = builder_for(uj.System(("a", "b"), {"h": h}, known={"f": f, "g": g}))
    return b, b.scalar("h", h), b.field("f", f), b.field("g", g)


def test_lie_derivative_matches_hand_computation(nodes):
    b, hn, fn, _ = nodes
    x0, x1 = X
    dh = np.array([2 * x0 * np.sin(x1), x0**2 * np.cos(x1)])
    expected = dh @ np.array([x1, -x0 * x1])
    assert np.isclose(_at(b, b.lie(fn, hn), X), expected, rtol=1e-14)


def test_lie_bracket_matches_hand_computation(nodes):
    b, _, fn, gn = nodes
    x0, x1 = X
    Jf = np.array([[0.0, 1.0], [-x1, -x0]])
    Jg = np.array([[-np.sin(x0), 0.0], [0.0, 0.0]])
    expected = Jg @ np.array([x1, -x0 * x1]) - Jf @ np.array([np.cos(x0), 1.0])
    np.testing.assert_allclose(_at(b, b.bracket(fn, gn), X), expected, rtol=1e-14)


def test_bracket_identity_L_ab_equals_commutator(nodes):
    """L_[a,b] h = L_a L_b h - L_b L_a h (with [a, b] = (db/dx) a - (da/dx) b)."""
    b, hn, fn, gn = nodes
    lhs = _at(b, b.lie(b.bracket(fn, gn), hn), X)
    rhs = _at(b, b.lie(fn, b.lie(gn, hn)), X) - _at(b, b.lie(gn, b.lie(fn, hn)), X)
    assert np.isclose(lhs, rhs, rtol=1e-12)


def test_block_gradients_equal_autodiff_gradients(nodes):
    b, hn, fn, gn = nodes
    got_nodes, block = b.lie_block([hn, b.lie(fn, hn)], [fn, gn], X[None])
    fns = (h, _lie(h, f))
    with jax.enable_x64(True):
        want = np.stack([jax.grad(_lie(p, v))(jnp.asarray(X)) for p in fns for v in (f, g)])
    assert [nd.label for nd in got_nodes] == ["L_f h", "L_g h", "L_f L_f h", "L_g L_f h"]
    np.testing.assert_allclose(block[0], want, rtol=1e-12, atol=1e-14)


def test_power_nodes_of_the_graph(nodes):
    """``Builder.power``: ``L_v^j base`` one node (label ``L_v^j base``), equal to ``j`` nested
    Lie derivatives; ``power_of`` finds ``(base, j)``, also through ``Builder.lie``."""
    b, hn, fn, _ = nodes
    p3 = b.power(fn, hn, 3)
    assert p3.label == "L_f^3 h" and b.power(fn, hn, 1).label == "L_f h"
    assert b.power(fn, hn, 3) is p3 and b.power(fn, hn, 0) is hn
    assert b.power_of(p3, fn) == (hn, 3) and b.power_of(hn, fn) == (hn, 0)
    nested = b.lie(fn, b.lie(fn, b.lie(fn, hn)))
    assert nested.label == "L_f L_f L_f h" and b.power_of(nested, fn) == (hn, 3)
    want = _lie(_lie(_lie(h, f), f), f)
    with jax.enable_x64(True):
        for node in (p3, nested):
            np.testing.assert_allclose(_at(b, node, X), want(jnp.asarray(X)), rtol=1e-12)
