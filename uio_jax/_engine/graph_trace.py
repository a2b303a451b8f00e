"""A model's JAX function as nodes of the expression graph (:mod:`.graph`).

The function is traced once to a jaxpr (``jax.make_jaxpr``: a fraction of a millisecond
for a model function) and the jaxpr is walked by the one interpreter
(:func:`uio_jax._engine.interpreter.interpret`) with the rule table of
:mod:`.graph_rules`. A primitive without a rule, or one that would need the value of a
state, raises :class:`~uio_jax._engine.graph_rules.Untranslatable`: :func:`translate`
then returns None and the caller keeps the XLA route for that function (the engine
decides, never the user). :class:`Expressed` functions let closures built on graph nodes
translate by importing their expressions.
"""

import contextvars

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend.core import Primitive

from .graph import Graph
from .graph_rules import RULES, as_nodes
from .interpreter import interpret

#: True while :func:`trace_to_graph` traces a function: an :class:`Expressed` function
#: called then stands for its expression (:data:`expression_p`), not for its JAX code.
_TRANSLATING = contextvars.ContextVar("uio_jax_translating", default=False)

#: The primitive an :class:`Expressed` function binds while a function is translated:
#: one operand (the state it is called on), parameter ``source`` (the Expressed). Only
#: the graph translation has a rule for it.
expression_p = Primitive("uio_jax_expression")


@expression_p.def_abstract_eval
def _expression_shape(x, *, source):
    return jax.core.ShapedArray(source.shape, jnp.float64)


class Expressed:
    """A function of the state that knows its expression in a graph.

    Calling it runs the JAX function ``fn``; while a function that calls it is translated
    into a graph (:func:`trace_to_graph`), it stands for ``expr`` instead: the translation
    imports the expression with the state it was called on (:meth:`Graph.import_nodes`),
    so closures built on Lie derivatives, rescaled fields or solves translate without
    tracing their derivatives again.

    Args:
        fn: the JAX function ``x (n,) -> shape``.
        graph: the graph of ``expr``, whose ``n`` coordinates are ``x``.
        expr: an int (scalar) or a tuple of ints.
    """

    __slots__ = ("fn", "graph", "expr", "shape", "__name__", "__weakref__")

    def __init__(self, fn, graph, expr):
        self.fn, self.graph, self.expr = fn, graph, expr
        self.shape = () if isinstance(expr, int) else (len(expr),)
        self.__name__ = getattr(fn, "__name__", "expressed")

    def __call__(self, x):
        if _TRANSLATING.get():
            return expression_p.bind(x, source=self)
        return self.fn(x)


def expressed(fn, graph, expr):
    """``fn`` as an :class:`Expressed` function (``fn`` itself when ``expr`` is None)."""
    if expr is None or fn is None:
        return fn
    if isinstance(fn, Expressed):
        fn = fn.fn
    return Expressed(fn, graph, expr)


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
    if isinstance(fn, Expressed) and fn.graph is graph and len(arg_shapes) == 1 \
            and tuple(arg_nodes[0]) == graph.coords:
        return np.array(fn.expr, dtype=object).reshape(fn.shape), np.dtype(np.float64)
    token = _TRANSLATING.set(True)
    try:
        with jax.enable_x64(True):
            closed = jax.make_jaxpr(fn)(*[jax.ShapeDtypeStruct(s, jnp.float64) for s in arg_shapes])
    finally:
        _TRANSLATING.reset(token)
    args = []
    for nodes, shape in zip(arg_nodes, arg_shapes):
        arr = np.empty(len(nodes), dtype=object)
        arr[:] = list(nodes)
        args.append(arr.reshape(shape))
    consts = [np.asarray(c) for c in closed.consts]
    with np.errstate(all="ignore"):  # constants such as 1/0 fold to inf, as in XLA
        (out,) = interpret(closed.jaxpr, consts, args, RULES, graph)
    dtype = closed.out_avals[0].dtype
    return as_nodes(graph, out), dtype


def translate(graph: Graph, fn, shape, extra=()):
    """The expression of a model function ``fn(x, *extra)`` in ``graph``, or None.

    Args:
        graph: the graph of the state ``x`` (its ``n`` coordinates).
        fn: ``x (n,) -> shape`` (a JAX-traceable function).
        shape: the expected output shape: ``()`` for a scalar, ``(n,)`` for a field.
        extra: shapes of further arguments (parameters, time), whose elements are taken
            as the coordinates after ``x``: ``graph.n`` must count them.

    Returns:
        an int (scalar) or a tuple of ints (one per output element); None when the graph has
        no rule for a primitive of ``fn`` or the output shape differs.

    Raises:
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
    except NotImplementedError:  # Untranslatable, or a transformation of an Expressed
        return None
    except (TypeError, ValueError):  # the function does not run on these arguments
        return None
    if tuple(out.shape) != tuple(shape):
        return None
    return int(out.reshape(())) if tuple(shape) == () else tuple(int(k) for k in out.reshape(-1))


__all__ = ["Expressed", "expressed", "expression_p",
           "trace_to_graph", "translate"]
