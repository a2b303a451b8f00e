"""A model's JAX function as nodes of the expression graph (:mod:`.graph`).

The function is traced once to a jaxpr (``jax.make_jaxpr``: a fraction of a millisecond
for a model function) and the jaxpr is walked by the one interpreter
(:func:`uio_jax._engine.interpreter.interpret`) with the rule table of
:mod:`.graph_rules`. A primitive without a rule, or one that would need the value of a
state, raises :class:`~uio_jax._engine.graph_values.Untranslatable`: the graph is the
only evaluator of the analyses, so such a model is refused where it is built
(:func:`untranslatable_message` says which primitive). A :class:`GraphFunction` is a
function of the state given by its expression: the Systems the analyses derive (extended
systems, UI extensions) are built of them on a graph, never traced.

**Functions that build their own expression.** A function with an ``emit`` method is not
traced: ``fn.emit(*args)`` receives each argument as a numpy object array of
:class:`~uio_jax._engine.graph_values.GraphScalar` (its shape; a scalar argument a 0-d array)
and returns its result built of them (numbers for constants; a sequence for a vector), or
None where it cannot (a wrapper around a JAX callable: then the whole function is traced).
:class:`GraphFunction`, the declarative models' expressions (:mod:`uio_jax._io`) and the
wrappers the System derives from them (:mod:`uio_jax._model.joint`, :mod:`uio_jax._model.time`)
do: a model that is not a Python program reaches the graph without importing JAX, which is
imported here, once, the first time a function must be traced.
"""

import numpy as np

from .._errors import ModelError
from .graph import Graph
from .graph_values import GraphScalar, Untranslatable, as_nodes, node_of, object_array


class GraphFunction:
    """A function of the state given by its expression in a graph.

    A System built of such functions (:func:`uio_jax._model.graph_system.graph_system`)
    shares their graph: its expressions are these, nothing is traced. Called on a numpy
    state, it evaluates the expression there (numpy).

    Args:
        graph: the graph of ``expr``, whose ``n`` coordinates are the state.
        expr: an int (scalar) or a tuple of ints (a field).
    """

    __slots__ = ("graph", "expr", "shape", "__weakref__")
    #: builds its own expression (:func:`trace_to_graph`)
    graph_native = True

    def __init__(self, graph, expr):
        self.graph, self.expr = graph, expr
        self.shape = () if isinstance(expr, int) else (len(expr),)

    def emit(self, x):
        """The expression at the state ``x`` (``graph.n`` :class:`GraphScalar`): the nodes
        imported into ``x``'s graph (the same nodes when ``x`` are this graph's coordinates)."""
        if x.shape != (self.graph.n,):
            return None
        target = x.reshape(-1)[0].graph if x.size else self.graph
        coords = tuple(v.node for v in x.reshape(-1))
        roots = [self.expr] if self.shape == () else list(self.expr)
        if target is not self.graph or coords != target.coords:
            roots = target.import_nodes(self.graph, roots, coords)
        out = [GraphScalar(target, k) for k in roots]
        return out[0] if self.shape == () else out

    def __call__(self, x):
        from .graph_numpy import evaluate

        roots = [self.expr] if self.shape == () else list(self.expr)
        values = evaluate(self.graph, roots, np.asarray(x, dtype=np.float64).reshape(1, -1), gradients=False)
        return values[0, 0] if self.shape == () else values[0]


class FunctionOfSlice:
    """``z -> fn(z[start:])``: a function of some trailing coordinates as a function of all of
    them; it builds its own expression (``emit``) when ``fn`` does, else it is traced.

    Args:
        fn: a function of the coordinates ``z[start:]``.
        start: the first coordinate ``fn`` reads.
    """

    __slots__ = ("fn", "start", "__weakref__")

    def __init__(self, fn, start: int):
        self.fn, self.start = fn, int(start)

    @property
    def graph_native(self) -> bool:
        return graph_native(self.fn)

    def __call__(self, z):
        return self.fn(z[self.start:])

    def emit(self, z):
        """``fn``'s expression at ``z[start:]``, when ``fn`` builds its own; else None."""
        return self.fn.emit(z[self.start:]) if graph_native(self.fn) else None


def untranslatable_message(what, exc) -> str:
    """One line refusing ``what`` (e.g. ``"output 'y'"``) for the primitive of ``exc`` (an
    :class:`~uio_jax._engine.graph_values.Untranslatable`)."""
    from .graph_rules import RULES

    detail = str(exc).removeprefix(exc.primitive).removeprefix(": ")
    supported = ", ".join(sorted(RULES))
    return (f"{what}: the expression graph has no rule for the JAX primitive '{exc.primitive}'"
            f"{f' ({detail})' if detail else ''} (supported: {supported})")


def trace_to_graph(graph: Graph, fn, arg_nodes, arg_shapes):
    """The outputs of ``fn`` as graph nodes.

    Args:
        graph: the graph to add nodes to.
        fn: a JAX-traceable function of ``len(arg_shapes)`` float64 arrays.
        arg_nodes: per argument, a sequence of node numbers (its elements, row-major);
            None for an argument traced but not given as nodes (never used here).
        arg_shapes: per argument, its shape.

    Returns:
        ``(out, out_dtype)``: numpy object array of node numbers in the output's shape, and
        the output's dtype.

    Raises:
        Untranslatable: a primitive without a rule or a value that depends on the state
            where a constant is needed.
        IndexOutOfRange: a constant index past the end of an array.
    """
    out = emitted(graph, fn, arg_nodes, arg_shapes)
    if out is not None:
        return out, np.dtype(np.float64)
    import jax  # a JAX callable: traced (the first one imports JAX)
    import jax.numpy as jnp

    from .graph_rules import RULES
    from .interpreter import interpret

    with jax.enable_x64(True):
        closed = jax.make_jaxpr(fn)(*[jax.ShapeDtypeStruct(s, jnp.float64) for s in arg_shapes])
    args = [object_array(list(nodes), shape) for nodes, shape in zip(arg_nodes, arg_shapes)]
    consts = [np.asarray(c) for c in closed.consts]
    with np.errstate(all="ignore"):  # constants such as 1/0 fold to inf, as in XLA
        (out,) = interpret(closed.jaxpr, consts, args, RULES, graph)
    dtype = closed.out_avals[0].dtype
    return as_nodes(graph, out), dtype


def emitted(graph: Graph, fn, arg_nodes, arg_shapes):
    """The outputs of a function that builds its own expression (``fn.emit``, see the module
    doc) as a numpy object array of node numbers, or None when ``fn`` has no ``emit`` or its
    ``emit`` declines (returns None)."""
    emit = getattr(fn, "emit", None)
    if emit is None:
        return None
    args = [object_array([GraphScalar(graph, k) for k in nodes], shape) for nodes, shape in zip(arg_nodes, arg_shapes)]
    with np.errstate(all="ignore"):  # constants such as 1/0 fold to inf, as in XLA
        result = emit(*args)
    if result is None:
        return None
    if isinstance(result, np.ndarray):
        shape, values = result.shape, list(result.reshape(-1))
    elif isinstance(result, (list, tuple)):
        shape, values = (len(result),), list(result)
    else:
        shape, values = (), [result]
    return object_array([node_of(graph, v) for v in values], shape)


def graph_native(fn) -> bool:
    """Whether ``fn`` builds its own expression (``fn.graph_native``: a declarative model's
    function, a :class:`GraphFunction`, a wrapper of one) rather than being a JAX callable
    that is traced."""
    return bool(getattr(fn, "graph_native", False))


def translate(graph: Graph, fn, shape, extra=()):
    """The expression of a model function ``fn(x, *extra)`` in ``graph``.

    Args:
        graph: the graph of the state ``x`` (its ``n`` coordinates).
        fn: ``x (n,) -> shape`` (a JAX-traceable function).
        shape: the expected output shape: ``()`` for a scalar, ``(n,)`` for a field.
        extra: shapes of further arguments (parameters, time), whose elements are taken
            as the coordinates after ``x``: ``graph.n`` must count them.

    Returns:
        an int (scalar) or a tuple of ints (one per output element); None when ``fn`` does
        not run on these arguments or its output shape differs.

    Raises:
        Untranslatable: the graph has no rule for a primitive of ``fn``.
        IndexOutOfRange: ``fn`` indexes an argument past its end with a constant index.
    """
    if fn is None:
        return None
    shapes = [(graph.n - sum(int(np.prod(e)) for e in extra),)] + [tuple(e) for e in extra]
    nodes, at = [], 0
    for sh in shapes:
        size = int(np.prod(sh))
        nodes.append(graph.coords[at:at + size])
        at += size
    try:
        out, _ = trace_to_graph(graph, fn, nodes, shapes)
    except Untranslatable:
        raise
    except NotImplementedError as exc:
        raise Untranslatable(getattr(exc, "primitive", type(exc).__name__), str(exc)) from None
    except (TypeError, ValueError):  # the function does not run on these arguments
        return None
    if tuple(out.shape) != tuple(shape):
        return None
    return int(out.reshape(())) if tuple(shape) == () else tuple(int(k) for k in out.reshape(-1))


def translate_or_refuse(graph: Graph, fn, shape, what, extra=()):
    """:func:`translate`, refusing in one line (:class:`~uio_jax.ModelError`, ``what`` names
    the function) a function with a primitive the graph has no rule for or of another shape."""
    try:
        expr = translate(graph, fn, shape, extra)
    except Untranslatable as exc:
        raise ModelError(untranslatable_message(what, exc)) from None
    if expr is None:
        raise ModelError(f"{what} does not translate into the expression graph (it fails on traced "
                         f"arguments or does not return shape {tuple(shape)})")
    return expr


__all__ = ["FunctionOfSlice", "GraphFunction", "emitted", "graph_native", "untranslatable_message",
           "translate_or_refuse", "trace_to_graph", "translate"]
