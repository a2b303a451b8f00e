"""The derivative rules of the expression graph: the chain rule, node by node.

:meth:`uio_jax._engine.graph.Graph.jvp` walks the nodes below its roots in order and builds
each one's directional derivative here, as new nodes of the same graph (a piecewise-constant
node has derivative 0; ``select`` differentiates its branches). These functions use only
the graph's public constructors and node tables.
"""

import math
from fractions import Fraction

from .graph_ops import PIECEWISE_CONSTANT


def derivative(graph, i, memo, tangent):
    """The node ``d node_i . v`` by the chain rule, from the derivatives ``memo`` (node ->
    its derivative) of its arguments; ``tangent``: the ``n`` nodes of ``v``."""
    op, a = graph.op[i], graph.args[i]
    if op == "c" or op in PIECEWISE_CONSTANT:
        return graph.zero
    if op == "x":
        return tangent[graph.param[i]]
    ta = memo[a[0]]
    if op == "add":
        return graph.add(ta, memo[a[1]])
    if op == "mul":
        return graph.add(graph.mul(ta, a[1]), graph.mul(a[0], memo[a[1]]))
    if op == "select":
        return graph.select(a[0], memo[a[1]], memo[a[2]])
    if len(a) == 2:
        tb = memo[a[1]]
        if ta == graph.zero and tb == graph.zero:
            return graph.zero
        return binary_derivative(graph, op, i, a[0], a[1], ta, tb)
    if ta == graph.zero:
        return graph.zero
    return graph.mul(unary_slope(graph, op, i, a[0]), ta) if op != "neg" else graph.neg(ta)


def unary_slope(graph, op, i, a):
    """``d op(a) / d a`` as a node (``i`` is the node ``op(a)`` itself)."""
    one = graph.one
    if op == "ipow":
        k = graph.param[i]
        return graph.mul(graph.const(k), graph.ipow(a, k - 1))
    if op == "sin":
        return graph.unary("cos", a)
    if op == "cos":
        return graph.neg(graph.unary("sin", a))
    if op == "tan":
        return graph.add(one, graph.ipow(i, 2))
    if op == "exp":
        return i
    if op == "log":
        return graph.div(one, a)
    if op == "sqrt":
        return graph.div(graph.const(0.5), i)
    if op == "tanh":
        return graph.sub(one, graph.ipow(i, 2))
    if op == "atan":
        return graph.div(one, graph.add(one, graph.ipow(a, 2)))
    if op == "asin":
        return graph.div(one, graph.unary("sqrt", graph.sub(one, graph.ipow(a, 2))))
    if op == "acos":
        return graph.neg(graph.div(one, graph.unary("sqrt", graph.sub(one, graph.ipow(a, 2)))))
    if op == "sinh":
        return graph.unary("cosh", a)
    if op == "cosh":
        return graph.unary("sinh", a)
    if op == "asinh":
        return graph.div(one, graph.unary("sqrt", graph.add(graph.ipow(a, 2), one)))
    if op == "acosh":
        return graph.div(one, graph.unary("sqrt", graph.sub(graph.ipow(a, 2), one)))
    if op == "atanh":
        return graph.div(one, graph.sub(one, graph.ipow(a, 2)))
    if op == "abs":
        return graph.unary("sign", a)
    if op == "log1p":
        return graph.div(one, graph.add(one, a))
    if op == "expm1":
        return graph.add(i, one)
    if op == "logistic":
        return graph.mul(i, graph.sub(one, i))
    if op == "erf":
        return graph.mul(graph.inexact_const(2.0 / math.sqrt(math.pi)),
                        graph.unary("exp", graph.neg(graph.ipow(a, 2))))
    if op == "cbrt":
        return graph.div(graph.const(Fraction(1, 3)), graph.ipow(i, 2))
    raise NotImplementedError(f"no derivative for {op}")


def binary_derivative(graph, op, i, a, b, ta, tb):
    """The derivative of node ``i = op(a, b)`` (``div``, ``pow``, ``atan2``) from the
    derivatives ``ta``, ``tb`` of its arguments."""
    if op == "div":  # (ta - (a/b) tb) / b
        return graph.div(graph.sub(ta, graph.mul(i, tb)), b)
    if op == "pow":  # a^b (tb log a + b ta / a)
        return graph.mul(i, graph.add(graph.mul(tb, graph.unary("log", a)),
                                    graph.div(graph.mul(b, ta), a)))
    if op == "atan2":  # (b ta - a tb) / (a^2 + b^2)
        return graph.div(graph.sub(graph.mul(b, ta), graph.mul(a, tb)),
                        graph.add(graph.ipow(a, 2), graph.ipow(b, 2)))
    raise NotImplementedError(f"no derivative for {op}")


__all__ = ["binary_derivative", "derivative", "unary_slope"]
