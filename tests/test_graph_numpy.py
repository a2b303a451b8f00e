"""The numpy evaluation of the expression graph, with and without a WalkMemo.

Oracle: the same nodes evaluated from the bottom (no memo) at the same states; a memo
changes which nodes a walk visits, never a value or a gradient (the same operations on the
same operands), whatever its budget.
"""

import numpy as np
import pytest

from uio_jax._engine import graph_numpy
from uio_jax._engine.graph import Graph


def _layers(n, orders):
    """A graph and its roots per order: ``L_v^k h`` for a rational-trigonometric ``h`` and
    field ``v`` on ``n`` coordinates (each order differentiates the last one)."""
    g = Graph(n)
    x = g.coords
    h = g.add(g.unary("sin", g.mul(x[0], x[1])), g.div(x[2 % n], g.add(x[0], g.one)))
    v = [g.mul(x[(i + 1) % n], g.unary("cos", x[i])) for i in range(n)]
    layers, roots = [], [h, g.mul(h, x[n - 1])]
    for _ in range(orders):
        layers.append(roots)
        roots = g.jvp(roots, v)
    return g, layers


@pytest.mark.parametrize("n, S", [(3, 64), (40, 1024)])  # dense, and sparse gradient rows
@pytest.mark.parametrize("budget", [graph_numpy.MEMO_BYTES, 0])
def test_a_memo_changes_no_value_and_skips_the_walked_layers(monkeypatch, n, S, budget):
    g, layers = _layers(n, 5)
    xs = np.random.default_rng(0).uniform(0.5, 1.5, size=(S, n))
    walked = []
    real = graph_numpy._walk

    def counting(graph, order, *args, **kwargs):
        walked.append(len(order))
        return real(graph, order, *args, **kwargs)

    monkeypatch.setattr(graph_numpy, "_walk", counting)
    memo = graph_numpy.WalkMemo(budget)
    for roots in layers:
        with_memo = graph_numpy.evaluate(g, roots, xs, memo=memo)
        plain = graph_numpy.evaluate(g, roots, xs)
        np.testing.assert_array_equal(with_memo[0], plain[0])
        np.testing.assert_array_equal(with_memo[1], plain[1])
    memo_walks, plain_walks = walked[0::2], walked[1::2]
    if budget:
        assert memo.nbytes <= budget and memo.values
        assert sum(memo_walks) < 0.7 * sum(plain_walks)  # each layer about once
    else:
        assert memo_walks == plain_walks and not memo.values


@pytest.mark.parametrize("rows", [32, 16])  # other states of the same shape, or another shape
def test_a_memo_for_other_states_starts_over(rows):
    g, layers = _layers(3, 3)
    rng = np.random.default_rng(1)
    memo = graph_numpy.WalkMemo()
    graph_numpy.evaluate(g, layers[0], rng.uniform(size=(32, 3)), memo=memo)
    other = rng.uniform(size=(rows, 3))
    got = graph_numpy.evaluate(g, layers[1], other, memo=memo)
    want = graph_numpy.evaluate(g, layers[1], other)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
    np.testing.assert_array_equal(memo.states, other)
