"""The values of the walk that translates a jaxpr into the expression graph, and its errors.

A value is a numpy array of the variable's shape: **concrete** (a numeric dtype: a constant
of the model, an index, a literal) or **symbolic** (``dtype=object``: one graph node number
per element). The rules (:mod:`.graph_rules`, :mod:`.graph_structural`, :mod:`.graph_loops`)
share these helpers and raise these errors.
"""

import numpy as np


class Untranslatable(NotImplementedError):
    """The function uses a primitive (or a pattern) the graph cannot represent."""

    def __init__(self, primitive, detail=""):
        super().__init__(f"{primitive}{': ' + detail if detail else ''}")
        self.primitive = primitive


class IndexOutOfRange(IndexError):
    """A constant index past the end of an array (JAX would clamp it silently)."""


def is_symbolic(v) -> bool:
    """Whether a value of the walk holds graph nodes (an object array)."""
    return isinstance(v, np.ndarray) and v.dtype == object


def as_nodes(graph, v):
    """``v`` as an object array of nodes (concrete numbers become constant nodes)."""
    if is_symbolic(v):
        return v
    v = np.asarray(v)
    if np.iscomplexobj(v):
        raise Untranslatable("complex", "complex values")
    out = np.empty(v.shape, dtype=object)
    flat = out.reshape(-1)
    for k, x in enumerate(v.reshape(-1)):
        flat[k] = graph.const(float(x))
    return out


def elementwise(graph, fn, ins):
    """``fn(graph, *nodes)`` per element of the broadcast operands (object arrays)."""
    ops = np.broadcast_arrays(*[as_nodes(graph, v) for v in ins])
    out = np.empty(ops[0].shape, dtype=object)
    flat = out.reshape(-1)
    for k, items in enumerate(zip(*[o.reshape(-1) for o in ops])):
        flat[k] = fn(*items)
    return out


__all__ = ["IndexOutOfRange", "Untranslatable", "as_nodes", "elementwise", "is_symbolic"]
