"""Loops with a static trip count unrolled into the expression graph (``uio_jax._engine.graph_loops``)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax import lax

import uio_jax as uj
from uio_jax._engine.graph import Graph
from uio_jax._engine.graph_numpy import evaluate
from uio_jax._engine.graph_trace import translate


def fori(x):
    return lax.fori_loop(0, 4, lambda i, c: c + 0.1 * jnp.sin(c) * x[1] * i, x[0])


def scanned(x):  # carry and stacked outputs, reversed
    carry, ys = lax.scan(lambda c, a: (c * a + x[1], c * x[0]), x[0], jnp.array([1.0, 0.5, 2.0]), reverse=True)
    return carry + ys.sum() + ys[0]


def while_const(x):  # bounds computed from constants: a while loop with a constant condition
    return lax.fori_loop(jnp.int32(0), jnp.int32(3), lambda i, c: c * x[0] + x[1], x[1])


def indexed_where(x):  # a condition on the loop counter choosing a state: nodes, not numbers
    return lax.fori_loop(0, 3, lambda i, acc: acc.at[i].set(jnp.where(i < 2, x[i % 2] * 3.0, 0.0)),
                         jnp.zeros(3)).sum() + x[0]


def wrapped_index(x):  # (i + 1) % n: a primitive without a rule ('rem') on constants only
    return lax.fori_loop(0, 2, lambda i, c: c + x[(i + 1) % 2] ** 2, 0.0)


@pytest.mark.parametrize("fn", [fori, scanned, while_const, indexed_where, wrapped_index])
def test_loops_translate_with_jax_values_and_gradients(fn):
    g = Graph(2)
    expr = translate(g, fn, ())
    xs = np.array([[0.7, 1.3], [1.1, 0.6]])
    values, grads = evaluate(g, [expr], xs)
    with jax.enable_x64(True):
        want = np.asarray(jax.vmap(fn)(jnp.asarray(xs)))
        want_grads = np.asarray(jax.vmap(jax.grad(fn))(jnp.asarray(xs)))
    np.testing.assert_allclose(values[:, 0], want, rtol=1e-12)
    np.testing.assert_allclose(grads[:, 0], want_grads, rtol=1e-12)


def test_a_state_dependent_loop_is_refused_in_one_line():
    def until(x):
        return lax.while_loop(lambda c: c < x[1], lambda c: c * 2.0, x[0])

    with pytest.raises(uj.ModelError, match="output 'y': the expression graph has no rule for the JAX "
                                            "primitive 'while' .a loop condition that depends on the state."):
        uj.System(("a", "b"), {"y": until})


def test_a_model_with_a_loop_is_analysed():
    s = uj.System(("a", "b"), {"y": lambda x: x[0]}, drift=lambda x: jnp.stack([x[1], -fori(x)]))
    assert uj.analyze(s, samples=64).dim == 2
