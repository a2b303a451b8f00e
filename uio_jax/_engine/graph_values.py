"""The values of the walk that translates a jaxpr into the expression graph, and its errors.

A value is a numpy array of the variable's shape: **concrete** (a numeric dtype: a constant
of the model, an index, a literal) or **symbolic** (``dtype=object``: one graph node number
per element). The rules (:mod:`.graph_rules`, :mod:`.graph_structural`, :mod:`.graph_loops`)
share these helpers and raise these errors.

:class:`GraphScalar` is the value a function that builds its own expression receives instead
(:func:`uio_jax._engine.graph_trace.trace_to_graph`, ``emit``): one node with Python's
arithmetic operators, making exactly the nodes the translation of the same JAX operations
makes (a declarative model's expressions reach the graph without JAX).
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


def object_array(values, shape) -> np.ndarray:
    """The sequence ``values`` (row-major) as a numpy object array of ``shape``, each element
    kept as it is (``np.array`` would make a list of node numbers an integer array)."""
    out = np.empty(len(values), dtype=object)
    out[:] = values
    return out.reshape(shape)


def as_nodes(graph, v):
    """``v`` as an object array of nodes (concrete numbers become constant nodes)."""
    if is_symbolic(v):
        return v
    v = np.asarray(v)
    if np.iscomplexobj(v):
        raise Untranslatable("complex", "complex values")
    return object_array([graph.const(float(x)) for x in v.reshape(-1)], v.shape)


def elementwise(graph, fn, ins):
    """``fn(graph, *nodes)`` per element of the broadcast operands (object arrays)."""
    ops = np.broadcast_arrays(*[as_nodes(graph, v) for v in ins])
    return object_array([fn(*items) for items in zip(*[o.reshape(-1) for o in ops])], ops[0].shape)


def _operator(method: str, reflected: bool = False):
    """The operator ``self <op> other`` (``other <op> self`` when ``reflected``) of
    :class:`GraphScalar`, making the node ``graph.<method>``."""

    def apply(self, other):
        a, b = (self._of(other), self.node) if reflected else (self.node, self._of(other))
        return self._new(getattr(self.graph, method)(a, b))

    return apply


class GraphScalar:
    """A node of a graph with Python's arithmetic operators: ``a + b``, ``a - b``, ``a * b``,
    ``a / b``, ``-a``, ``a ** k`` and the elementary functions (:meth:`unary`,
    :meth:`binary`) make the nodes the translation of the same JAX operations makes
    (:mod:`.graph_rules`): a plain number operand becomes the constant ``graph.const(float)``,
    ``a ** k`` with a Python int ``k`` is ``integer_pow`` (``ipow``), any other exponent
    ``pow``; ``minimum``/``maximum`` select as JAX's ``min``/``max`` do.

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph`.
        node: the node number.
    """

    __slots__ = ("graph", "node")
    __array_ufunc__ = None  # numpy scalars defer to the reflected operators

    def __init__(self, graph, node):
        self.graph, self.node = graph, int(node)

    def __repr__(self):
        return f"GraphScalar({self.node})"

    def _of(self, b) -> int:
        return b.node if isinstance(b, GraphScalar) else self.graph.const(float(b))

    def _new(self, node) -> "GraphScalar":
        return GraphScalar(self.graph, node)

    __add__, __radd__ = _operator("add"), _operator("add", reflected=True)
    __sub__, __rsub__ = _operator("sub"), _operator("sub", reflected=True)
    __mul__, __rmul__ = _operator("mul"), _operator("mul", reflected=True)
    __truediv__, __rtruediv__ = _operator("div"), _operator("div", reflected=True)

    def __neg__(self):
        return self._new(self.graph.neg(self.node))

    def __pos__(self):
        return self

    def __pow__(self, k):
        if isinstance(k, int) and not isinstance(k, bool):
            return self.ipow(k)
        return self.binary("pow", k)

    def __rpow__(self, a):
        return self._new(self.graph.binary("pow", self._of(a), self.node))

    def constant(self, value) -> "GraphScalar":
        """The constant ``value`` as a node of this graph (``graph.const``)."""
        return self._new(self.graph.const(value))

    def ipow(self, k: int) -> "GraphScalar":
        """``self ** k`` for an integer ``k`` (JAX's ``integer_pow``)."""
        return self._new(self.graph.ipow(self.node, int(k)))

    def unary(self, op: str) -> "GraphScalar":
        """The elementary function ``op`` (a graph operation: ``sin``, ``asin``, ...) of ``self``."""
        return self._new(self.graph.unary(op, self.node))

    def binary(self, op: str, b, *, swap: bool = False) -> "GraphScalar":
        """``op(self, b)`` (``op(b, self)`` with ``swap``) for a graph operation of two operands."""
        a, b = (self._of(b), self.node) if swap else (self.node, self._of(b))
        return self._new(self.graph.binary(op, a, b))

    def extreme(self, b, *, greater: bool, swap: bool = False) -> "GraphScalar":
        """``max(self, b)`` (``greater``) or ``min(self, b)`` as JAX's ``max``/``min`` are
        translated (``swap``: the operands in the order ``(b, self)``)."""
        a, b = (self._of(b), self.node) if swap else (self.node, self._of(b))
        g = self.graph
        return self._new(g.select(g.binary("gt" if greater else "lt", a, b), b, a))


def node_of(graph, value) -> int:
    """The node of a value an ``emit`` returned: a :class:`GraphScalar` of ``graph``, or a
    number (its constant node, as :func:`as_nodes` makes it)."""
    if isinstance(value, GraphScalar):
        if value.graph is not graph:
            raise ValueError("a GraphScalar of another graph")
        return value.node
    return graph.const(float(value))


__all__ = ["GraphScalar", "IndexOutOfRange", "Untranslatable", "as_nodes", "elementwise", "is_symbolic",
           "node_of", "object_array"]
