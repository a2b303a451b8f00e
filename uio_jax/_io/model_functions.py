"""The functions of a declarative model's System: compiled expression trees as functions of
``z = [x; p; t]`` (and of the System's arguments ``x``, ``(x, p)``, ``(x, t)``, ``(x, p, t)``).

Each is a small object, not a closure, that runs the same compiled closures
(:mod:`uio_jax._io.expression_functions`) on numpy arrays (numpy, no JAX), on anything else
(``jnp``), and on graph nodes (``emit``: its own expression, without importing JAX). The
general form's input fields ``d f / d u_i`` at ``u = w = 0`` are derivatives: ``jax.jvp`` on
JAX arrays, numpy first-order jets on numpy arrays, dual numbers over graph nodes
(:class:`Dual`) for ``emit``.
"""

import numpy as np

from .expression_functions import GRAPH_OPS, NUMPY_OPS, Ops, is_graph_value, jax_ops, trig_funcs
from .jets import JET_OPS, Jet, jet_parts


def _numpy_rows(fns, z):
    with np.errstate(all="ignore"):
        return np.array([0.0 if f is None else float(f(z, NUMPY_OPS)) for f in fns], dtype=np.float64)


def _jax_rows(fns, z):
    import jax.numpy as jnp

    dtype = jnp.result_type(z.dtype, float)
    return jnp.stack([jnp.asarray(0.0 if f is None else f(z, jax_ops()), dtype=dtype) for f in fns])


def _graph_rows(fns, z):
    return [0.0 if f is None else f(z, GRAPH_OPS) for f in fns]


class RowsFunction:
    """``z -> [row_k(z)]``: one compiled tree per row, None for a row that is 0
    (:func:`uio_jax._io.affine.vector_function`)."""

    __slots__ = ("fns", "__weakref__")
    graph_native = True

    def __init__(self, fns):
        self.fns = list(fns)

    def __call__(self, z):
        return _numpy_rows(self.fns, z) if isinstance(z, np.ndarray) else _jax_rows(self.fns, z)

    def emit(self, z):
        """The rows' expressions at ``z`` (graph nodes)."""
        return _graph_rows(self.fns, z)


def _flat(parts, xp):
    return xp.concatenate([xp.reshape(xp.asarray(a), -1) for a in parts])


class Joined:
    """A function of ``z`` as a function of the System's arguments: ``(x)``, ``(x, p)``,
    ``(x, t)`` or ``(x, p, t)`` -> ``fn`` of their concatenation ``z``
    (:func:`uio_jax._io.affine.system_callables`)."""

    __slots__ = ("fn", "arity", "__weakref__")

    def __init__(self, fn, arity):
        self.fn, self.arity = fn, arity

    @property
    def graph_native(self) -> bool:
        return bool(getattr(self.fn, "graph_native", False))

    def __call__(self, *parts):
        if len(parts) != self.arity:
            raise TypeError(f"takes {self.arity} positional arguments but {len(parts)} were given")
        if all(isinstance(a, (np.ndarray, np.generic)) for a in parts):
            return self.fn(_flat(parts, np).astype(np.float64))
        import jax.numpy as jnp

        return self.fn(_flat(parts, jnp))

    def emit(self, *parts):
        """``fn``'s expression at the concatenation of the arguments (graph nodes)."""
        if len(parts) != self.arity or not self.graph_native:
            return None
        return self.fn.emit(np.concatenate([np.asarray(a, dtype=object).reshape(-1) for a in parts]))


class GeneralDrift:
    """``z -> f(z, r = 0)`` padded with zeros to ``n`` rows: the drift of the general form
    (``fns``: the compiled rows of ``f`` reading ``[z; r]``, ``nrest`` inputs ``r``)."""

    __slots__ = ("fns", "nrest", "n", "__weakref__")
    graph_native = True

    def __init__(self, fns, nrest, n):
        self.fns, self.nrest, self.n = fns, nrest, n

    def _pad(self, rows, xp):
        extra = self.n - len(self.fns)
        if not extra:
            return rows
        return xp.concatenate([rows, xp.zeros(extra, dtype=rows.dtype)])

    def __call__(self, z):
        if isinstance(z, np.ndarray):
            return self._pad(_numpy_rows(self.fns, np.concatenate([z, np.zeros(self.nrest)])), np)
        import jax.numpy as jnp

        zz = jnp.concatenate([z, jnp.zeros(self.nrest, dtype=z.dtype)])
        return self._pad(_jax_rows(self.fns, zz), jnp)

    def emit(self, z):
        """The drift's expression at ``z`` (graph nodes; the inputs are the node 0)."""
        zero = z.reshape(-1)[0].constant(0.0)
        zz = list(z) + [zero] * self.nrest
        return _graph_rows(self.fns, zz) + [0.0] * (self.n - len(self.fns))


class InputField(GeneralDrift):
    """``z -> d f / d r_i (z, r = 0)`` padded with zeros to ``n`` rows: the field of the
    ``i``-th unpromoted input of the general form."""

    __slots__ = ("i",)

    def __init__(self, fns, nrest, n, i):
        super().__init__(fns, nrest, n)
        self.i = i

    def __call__(self, z):
        nrest, i = self.nrest, self.i
        if isinstance(z, np.ndarray):  # one-off numpy evaluation: a first-order jet
            zz = [np.float64(c) for c in z] + [Jet.seed(0.0, nrest, j) for j in range(nrest)]
            with np.errstate(all="ignore"):
                cols = [jet_parts(0.0 if f is None else f(zz, JET_OPS), (), nrest)[1][i] for f in self.fns]
            return self._pad(np.array(cols, dtype=np.float64), np)
        import jax
        import jax.numpy as jnp

        r0 = jnp.zeros(nrest, dtype=z.dtype)
        e = r0.at[i].set(1.0)
        tangent = jax.jvp(lambda r: _jax_rows(self.fns, jnp.concatenate([z, r])), (r0,), (e,))[1]
        return self._pad(tangent, jnp)

    def emit(self, z):
        """The field's expression at ``z``: the tangents of dual numbers (graph nodes)."""
        zero = z.reshape(-1)[0].constant(0.0)
        zz = [Dual(v, 0.0) for v in z] + [Dual(zero, 1.0 if j == self.i else 0.0) for j in range(self.nrest)]
        rows = [0.0 if f is None else f(zz, DUAL_OPS) for f in self.fns]
        return [r.t if isinstance(r, Dual) else 0.0 for r in rows] + [0.0] * (self.n - len(self.fns))


class UnitField:
    """``z -> e_j`` (``n`` rows): the field of the derivative of a promoted input."""

    __slots__ = ("n", "j", "__weakref__")
    graph_native = True

    def __init__(self, n, j):
        self.n, self.j = n, j

    def __call__(self, z):
        if isinstance(z, np.ndarray):
            out = np.zeros(self.n)
            out[self.j] = 1.0
            return out
        import jax.numpy as jnp

        return jnp.zeros(self.n, dtype=jnp.result_type(z.dtype, float)).at[self.j].set(1.0)

    def emit(self, z):
        return [1.0 if k == self.j else 0.0 for k in range(self.n)]


# ----------------------------------------------------------------------------- dual numbers
def _is_zero(t) -> bool:
    """A tangent known to be 0 without a node (the plain number 0)."""
    return not is_graph_value(t) and not isinstance(t, Dual) and t == 0.0


def _scale(t, c):
    """``t * c`` for a tangent ``t``; 0 stays the number 0."""
    return 0.0 if _is_zero(t) else t * c


def _sum(a, b):
    return b if _is_zero(a) else a if _is_zero(b) else a + b


def _over(t, d):
    """``t / d`` for a tangent ``t``; 0 stays the number 0."""
    return 0.0 if _is_zero(t) else t / d


class Dual:
    """A value ``v`` with its tangent ``t`` (graph nodes or numbers) for the general form's
    input fields: ``d f / d r_i`` is the tangent of ``f`` at ``r = 0`` with ``r_i``'s tangent 1
    (forward mode; a tangent that is the number 0 makes no node)."""

    __slots__ = ("v", "t")
    __array_ufunc__ = None

    def __init__(self, v, t):
        self.v, self.t = v, t

    @staticmethod
    def of(a) -> "Dual":
        return a if isinstance(a, Dual) else Dual(a, 0.0)

    def __add__(self, b):
        b = Dual.of(b)
        return Dual(self.v + b.v, _sum(self.t, b.t))

    __radd__ = __add__

    def __neg__(self):
        return Dual(-self.v, 0.0 if _is_zero(self.t) else -self.t)

    def __pos__(self):
        return self

    def __sub__(self, b):
        return self + (-Dual.of(b))

    def __rsub__(self, a):
        return Dual.of(a) + (-self)

    def __mul__(self, b):
        b = Dual.of(b)
        return Dual(self.v * b.v, _sum(_scale(self.t, b.v), _scale(b.t, self.v)))

    __rmul__ = __mul__

    def __truediv__(self, b):
        b = Dual.of(b)
        q = self.v / b.v
        return Dual(q, _over(_sum(self.t, 0.0 if _is_zero(b.t) else -(b.t * q)), b.v))

    def __rtruediv__(self, a):
        return Dual.of(a) / self


def _dual_unary(name, slope):
    """The function ``name`` of :data:`GRAPH_OPS` on duals, ``slope(v, f)`` its derivative
    from the operand ``v`` and the value ``f``."""
    def f(a):
        fn = _GRAPH_MATH[name]
        if not isinstance(a, Dual):
            return fn(a)
        value = fn(a.v)
        return Dual(value, 0.0 if _is_zero(a.t) else _scale(a.t, slope(a.v, value)))

    return f


_GRAPH_MATH = GRAPH_OPS.funcs  # name -> function on graph nodes and numbers


class _DualMath:
    """The numpy-like functions of :func:`trig_funcs` on :class:`Dual` numbers."""

    def __init__(self):
        g = _GRAPH_MATH
        slopes = {
            "sin": lambda v, f: g["cos"](v), "cos": lambda v, f: -g["sin"](v),
            "tan": lambda v, f: 1.0 + f * f, "asin": lambda v, f: 1.0 / g["sqrt"](1.0 - v * v),
            "acos": lambda v, f: -1.0 / g["sqrt"](1.0 - v * v), "atan": lambda v, f: 1.0 / (1.0 + v * v),
            "sinh": lambda v, f: g["cosh"](v), "cosh": lambda v, f: g["sinh"](v),
            "tanh": lambda v, f: 1.0 - f * f, "asinh": lambda v, f: 1.0 / g["sqrt"](v * v + 1.0),
            "acosh": lambda v, f: 1.0 / g["sqrt"](v * v - 1.0), "atanh": lambda v, f: 1.0 / (1.0 - v * v),
            "exp": lambda v, f: f, "log": lambda v, f: 1.0 / v, "sqrt": lambda v, f: 0.5 / f,
            "abs": lambda v, f: g["sign"](v), "sign": lambda v, f: 0.0,
        }
        numpy_names = {"asin": "arcsin", "acos": "arccos", "atan": "arctan", "asinh": "arcsinh",
                       "acosh": "arccosh", "atanh": "arctanh"}
        for name, slope in slopes.items():
            setattr(self, numpy_names.get(name, name), _dual_unary(name, slope))

    @staticmethod
    def arctan2(y, x):
        if not isinstance(y, Dual) and not isinstance(x, Dual):
            return _GRAPH_MATH["atan2"](y, x)
        y, x = Dual.of(y), Dual.of(x)
        value = _GRAPH_MATH["atan2"](y.v, x.v)
        t = _sum(_scale(y.t, x.v), 0.0 if _is_zero(x.t) else -(x.t * y.v))
        return Dual(value, _over(t, x.v * x.v + y.v * y.v))


def _dual_ipow(a, k):
    if not isinstance(a, Dual):
        return GRAPH_OPS.ipow(a, k)
    return Dual(GRAPH_OPS.ipow(a.v, k), _scale(a.t, k * GRAPH_OPS.ipow(a.v, k - 1)) if k else 0.0)


def _dual_power(a, b):
    if not isinstance(a, Dual) and not isinstance(b, Dual):
        return GRAPH_OPS.power(a, b)
    a, b = Dual.of(a), Dual.of(b)
    value = GRAPH_OPS.power(a.v, b.v)
    ta = _scale(a.t, b.v * GRAPH_OPS.power(a.v, b.v - 1.0)) if not _is_zero(a.t) else 0.0
    tb = _scale(b.t, value * _GRAPH_MATH["log"](a.v)) if not _is_zero(b.t) else 0.0
    return Dual(value, _sum(ta, tb))


def _dual_extreme(op):
    def f(a, b):
        if isinstance(a, Dual) or isinstance(b, Dual):
            a, b = Dual.of(a), Dual.of(b)
            if not (_is_zero(a.t) and _is_zero(b.t)):  # an input inside min/max is promoted
                raise ValueError("an unpromoted input inside min/max")
            return Dual(op(a.v, b.v), 0.0)
        return op(a, b)

    return f


def _dual_asarray(a):
    return a if isinstance(a, Dual) else GRAPH_OPS.asarray(a)


_DUAL_MATH = _DualMath()
#: The :class:`~uio_jax._io.expression_functions.Ops` of dual numbers over graph nodes.
DUAL_OPS = Ops(trig_funcs(_DUAL_MATH), _dual_ipow, _dual_power, _dual_extreme(GRAPH_OPS.minimum),
               _dual_extreme(GRAPH_OPS.maximum), _dual_asarray)


__all__ = ["DUAL_OPS", "Dual", "GeneralDrift", "InputField", "Joined", "RowsFunction", "UnitField"]
