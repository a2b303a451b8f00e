"""Whitelisted expression trees (:mod:`uio_jax._io.expressions`) compiled to functions.

The tree is walked once into nested closures (:func:`to_function`; integer powers by
``lax.integer_pow``, exact, clean derivatives for negative bases) that take their operations
as an argument (:class:`Ops`): the same compiled tree runs on JAX arrays, on numpy arrays (no
JAX dispatch), on the jets of :mod:`uio_jax._io.affinity`, and on nodes of the expression
graph (:data:`GRAPH_OPS`: the nodes the translation of its JAX version makes, without JAX).
"""

import functools
from collections.abc import Mapping, Sequence

import numpy as np

from .._errors import ExpressionError
from .expressions import ALIASES, CONSTANTS, MAX_INTEGER_POW, Binary, Call, Expr, Name, Num, Unary


class Ops:
    """The arithmetic a compiled expression runs on: one instance per backend.

    ``funcs`` maps every (unaliased) name of :data:`FUNCTIONS` but ``min``/``max``/``pow``
    to a unary or binary function; ``ipow(a, k)`` is an integer power, ``power(a, b)`` a
    general one, ``minimum``/``maximum`` binary.
    """

    def __init__(self, funcs, ipow, power, minimum, maximum, asarray):
        self.funcs, self.ipow, self.power = funcs, ipow, power
        self.minimum, self.maximum, self.asarray = minimum, maximum, asarray


def trig_funcs(m):
    return {
        "sin": m.sin, "cos": m.cos, "tan": m.tan,
        "sec": lambda a: 1.0 / m.cos(a), "csc": lambda a: 1.0 / m.sin(a), "cot": lambda a: 1.0 / m.tan(a),
        "asin": m.arcsin, "acos": m.arccos, "atan": m.arctan, "atan2": m.arctan2,
        "sinh": m.sinh, "cosh": m.cosh, "tanh": m.tanh,
        "asinh": m.arcsinh, "acosh": m.arccosh, "atanh": m.arctanh,
        "exp": m.exp, "log": m.log, "sqrt": m.sqrt, "abs": m.abs, "sign": m.sign,
    }


@functools.cache
def jax_ops() -> Ops:
    """The :class:`Ops` of JAX (``jnp``; ``lax.integer_pow`` for integer powers), built (and
    JAX imported) the first time it is asked for."""
    import jax.numpy as jnp
    from jax import lax

    return Ops(trig_funcs(jnp), lambda a, k: lax.integer_pow(jnp.asarray(a, dtype=float), k),
               lambda a, b: jnp.power(jnp.asarray(a, dtype=float), b), jnp.minimum, jnp.maximum,
               lambda a: jnp.asarray(a))


def is_graph_value(a) -> bool:
    """Whether ``a`` is a node of the expression graph handed to a function that builds its own
    expression (:class:`uio_jax._engine.graph_values.GraphScalar`), not a number."""
    return hasattr(a, "unary")


def _graph_unary(op, np_fn):
    def f(a):
        return a.unary(op) if is_graph_value(a) else np_fn(np.asarray(a))

    return f


def _graph_binary(op, np_fn):
    def f(a, b):
        if is_graph_value(a):
            return a.binary(op, b)
        if is_graph_value(b):
            return b.binary(op, a, swap=True)
        return np_fn(np.asarray(a), np.asarray(b))

    return f


def _graph_extreme(greater):
    def f(a, b):
        if is_graph_value(a):
            return a.extreme(b, greater=greater)
        if is_graph_value(b):
            return b.extreme(a, greater=greater, swap=True)
        return (np.maximum if greater else np.minimum)(a, b)

    return f


class _GraphMath:
    """The numpy-like functions of :func:`trig_funcs` on graph nodes: each makes the node the
    translation of the ``jnp`` function makes (``jnp.arcsin`` is ``asin``, ...); on numbers,
    numpy (as the translation folds constants)."""

    def __init__(self):
        names = {"sin": "sin", "cos": "cos", "tan": "tan", "arcsin": "asin", "arccos": "acos",
                 "arctan": "atan", "sinh": "sinh", "cosh": "cosh", "tanh": "tanh", "arcsinh": "asinh",
                 "arccosh": "acosh", "arctanh": "atanh", "exp": "exp", "log": "log", "sqrt": "sqrt",
                 "abs": "abs", "sign": "sign"}
        for name, op in names.items():
            setattr(self, name, _graph_unary(op, getattr(np, name)))
        self.arctan2 = _graph_binary("atan2", np.arctan2)


def _graph_ipow(a, k):
    return a.ipow(k) if is_graph_value(a) else np.asarray(a, dtype=np.float64) ** k


def _graph_asarray(a):
    return a if is_graph_value(a) else np.asarray(a, dtype=np.float64)


#: The :class:`Ops` of the expression graph: a compiled tree run on graph nodes (see the
#: module doc) returns its node (or a number for a constant).
GRAPH_OPS = Ops(trig_funcs(_GraphMath()), _graph_ipow, _graph_binary("pow", np.power), _graph_extreme(False),
                _graph_extreme(True), _graph_asarray)
NUMPY_OPS = Ops(trig_funcs(np), lambda a, k: np.asarray(a, dtype=np.float64) ** k,
                lambda a, b: np.power(np.asarray(a, dtype=np.float64), b), np.minimum, np.maximum,
                lambda a: np.asarray(a, dtype=np.float64))


def to_function(expr: Expr, names: Sequence[str], constants: Mapping[str, float] | None = None):
    """Compile a tree into ``fn(z) -> scalar`` built from ``jnp`` operations.

    Args:
        expr: the tree.
        names: the meaning of the entries of ``z``: ``Name(names[i])`` reads ``z[i]``
            (``z`` of shape ``(len(names),)``).
        constants: known constants name -> value, folded in as Python floats; ``pi`` and
            ``E`` are added unless ``names`` or ``constants`` define them.

    Returns:
        A function of one array ``z`` returning a scalar (shape ``()``); differentiable and
        jit-able (JAX operations). Called on a plain numpy array it computes the same
        value with numpy (no JAX dispatch; floating-point warnings silenced). No Python
        evaluation of user text happens: the tree is walked once into nested closures.

    Raises:
        ExpressionError: a name that is neither in ``names`` nor a constant.
    """
    return TreeFunction(compile_raw(expr, names, constants))


class TreeFunction:
    """A compiled tree as a function of one array ``z`` (:func:`to_function`): numpy on a numpy
    array, JAX on anything else, its own expression on graph nodes (:meth:`emit`).

    Args:
        raw: the compiled tree, ``raw(z, ops)`` (:func:`compile_raw`).
    """

    __slots__ = ("raw", "__weakref__")
    #: builds its own expression (:mod:`uio_jax._engine.graph_trace`)
    graph_native = True

    def __init__(self, raw):
        self.raw = raw

    def __call__(self, z):
        if isinstance(z, np.ndarray):
            with np.errstate(all="ignore"):
                return np.asarray(self.raw(z, NUMPY_OPS), dtype=np.float64)
        import jax.numpy as jnp

        return jnp.asarray(self.raw(z, jax_ops()))

    def emit(self, z):
        """The expression at ``z`` (graph nodes): a node, or a number for a constant."""
        return self.raw(z, GRAPH_OPS)


def compile_raw(expr: Expr, names: Sequence[str], constants: Mapping[str, float] | None = None):
    """Compile a tree into ``fn(z, ops)``: ``z`` indexable by position, ``ops`` an :class:`Ops`.

    The result may be a Python float when the expression is constant.
    """
    index = {nm: i for i, nm in enumerate(names)}
    consts = dict(CONSTANTS)
    consts.update(constants or {})
    return _compile(expr, index, consts)


def _compile(e: Expr, index, consts):
    if isinstance(e, Num):
        v = e.value
        return lambda z, o: v
    if isinstance(e, Name):
        if e.id in index:
            i = index[e.id]
            return lambda z, o: z[i]
        if e.id in consts:
            v = float(consts[e.id])
            return lambda z, o: v
        raise ExpressionError(f"name {e.id!r} has no value")
    if isinstance(e, Unary):
        a = _compile(e.operand, index, consts)
        return (lambda z, o: -a(z, o)) if e.op == "-" else a
    if isinstance(e, Binary):
        a, b = _compile(e.left, index, consts), _compile(e.right, index, consts)
        if e.op == "+":
            return lambda z, o: a(z, o) + b(z, o)
        if e.op == "-":
            return lambda z, o: a(z, o) - b(z, o)
        if e.op == "*":
            return lambda z, o: a(z, o) * b(z, o)
        if e.op == "/":
            return lambda z, o: o.asarray(a(z, o)) / b(z, o)
        return _power(a, e.right, b)
    if isinstance(e, Call):
        args = [_compile(x, index, consts) for x in e.args]
        func = ALIASES.get(e.func, e.func)
        if func in ("min", "max"):
            def minmax(z, o, func=func):
                op = o.minimum if func == "min" else o.maximum
                out = o.asarray(args[0](z, o))
                for f in args[1:]:
                    out = op(out, f(z, o))
                return out

            return minmax
        if func == "pow":
            return _power(args[0], e.args[1], args[1])
        if len(args) == 1:
            (a,) = args
            return lambda z, o: o.funcs[func](o.asarray(a(z, o)))
        return lambda z, o: o.funcs[func](*(o.asarray(f(z, o)) for f in args))
    raise TypeError(f"not an expression tree: {e!r}")


def _exponent_value(e: Expr):
    """The value of a constant exponent (``2``, ``-1``, ``(-2)``), or None."""
    if isinstance(e, Num):
        return e.value
    if isinstance(e, Unary) and isinstance(e.operand, Num):
        return -e.operand.value if e.op == "-" else e.operand.value
    return None


def _power(base, exponent_expr, exponent):
    k = _exponent_value(exponent_expr)
    if k is not None and k.is_integer() and abs(k) <= MAX_INTEGER_POW:
        k = int(k)
        if k == 0:
            return lambda z, o: o.ipow(base(z, o), 0)
        return lambda z, o: o.ipow(base(z, o), k)
    return lambda z, o: o.power(base(z, o), exponent(z, o))
