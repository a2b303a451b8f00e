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


def _interleaved():
    """Operands whose coordinates interleave inside the node's: runs (slices) and gaps
    (index arrays), through every two-operand rule."""
    g = Graph(6)
    x = g.coords
    a = g.mul(x[0], x[2])  # coordinates (0, 2)
    b = g.add(x[1], x[3])  # (1, 3)
    c = g.mul(a, b)  # (0, 1, 2, 3): a's rows [0, 2], b's [1, 3]
    d = g.add(x[0], x[1])  # (0, 1): a run of c's rows
    e = g.add(c, d)
    roots = [e, c,
             g.div(e, g.add(x[4], g.one)),
             g.binary("pow", x[4], d),
             g.binary("atan2", e, x[5]),
             g.select(g.binary("lt", x[0], x[1]), a, b),
             g.sub(d, g.mul(x[5], a))]
    return g, roots


def test_sparse_rows_give_the_dense_gradients(monkeypatch):
    """Oracle: the dense walk (every node's gradient over all coordinates) at the same
    states; the sparse one places operand rows by slices and index arrays and sums them in
    place, the same operations on the same numbers."""
    g, roots = _interleaved()
    xs = np.random.default_rng(2).uniform(0.5, 1.5, size=(50, 6))
    monkeypatch.setattr(graph_numpy, "SPARSE_FROM", 10**12)
    monkeypatch.setattr(graph_numpy, "SPARSE_COORDS", 10**6)
    dense = graph_numpy.evaluate(g, roots, xs)
    monkeypatch.setattr(graph_numpy, "SPARSE_COORDS", 1)
    sparse = graph_numpy.evaluate(g, roots, xs)
    np.testing.assert_array_equal(sparse[0], dense[0])
    np.testing.assert_array_equal(sparse[1], dense[1])
    placed = [w for w in g.facts["operand_rows"].values() if w is not None]
    assert any(isinstance(w, slice) for w in placed) and any(isinstance(w, np.ndarray) for w in placed)
    assert np.abs(dense[1]).max() > 0 and np.isfinite(dense[1]).all()


def test_sparse_rows_from_many_coordinates_whatever_the_samples():
    assert graph_numpy._sparse(graph_numpy.SPARSE_COORDS, 1)
    assert not graph_numpy._sparse(graph_numpy.SPARSE_COORDS - 1, 128)
    assert graph_numpy._sparse(8, graph_numpy.SPARSE_FROM // 8)
