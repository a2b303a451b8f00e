"""Second-order forward-mode "jets" ``(value, gradient, Hessian)`` on numpy arrays.

The compiled expression closures (:mod:`uio_jax._io.expression_functions`) take their
operations as an argument; :data:`JET_OPS` runs them on jets, so the Hessian of a model's
right-hand side in its inputs costs milliseconds (no JAX compilation). Used by the affine
split (:mod:`uio_jax._io.affine`); the tests compare the jets with ``jax.hessian``.
"""

import numpy as np

from .expression_functions import Ops, trig_funcs


class Jet:
    """Second-order forward-mode number: value ``v`` (shape ``S``), gradient ``g`` (``S + (m,)``)
    and Hessian ``H`` (``S + (m, m)``) with respect to ``m`` seed variables.

    Arithmetic with plain numbers or numpy arrays of shape ``S`` (constants) is supported;
    the rules are the chain and product rules, so any expression that is affine in the
    seeds gets ``H == 0`` exactly.
    """

    __slots__ = ("v", "g", "H")
    __array_ufunc__ = None  # numpy defers to our reflected operators

    def __init__(self, v, g, H):
        self.v, self.g, self.H = v, g, H

    @staticmethod
    def seed(values, m, a):
        """The seed variable ``a`` (of ``m``) with values ``values`` (shape ``S``)."""
        values = np.asarray(values, dtype=np.float64)
        g = np.zeros(values.shape + (m,))
        g[..., a] = 1.0
        return Jet(values, g, np.zeros(values.shape + (m, m)))

    def __neg__(self):
        return Jet(-self.v, -self.g, -self.H)

    def __pos__(self):
        return self

    def __add__(self, b):
        if isinstance(b, Jet):
            return Jet(self.v + b.v, self.g + b.g, self.H + b.H)
        return Jet(self.v + b, self.g, self.H)

    __radd__ = __add__

    def __sub__(self, b):
        return self + (-b)

    def __rsub__(self, b):
        return (-self) + b

    def __mul__(self, b):
        if isinstance(b, Jet):
            cross = self.g[..., :, None] * b.g[..., None, :]
            return Jet(self.v * b.v, self.g * _c1(b.v) + b.g * _c1(self.v),
                       self.H * _c2(b.v) + b.H * _c2(self.v) + cross + np.swapaxes(cross, -1, -2))
        return Jet(self.v * b, self.g * _c1(b), self.H * _c2(b))

    __rmul__ = __mul__

    def __truediv__(self, b):
        if isinstance(b, Jet):
            return self * _inv(b)
        inv = np.divide(1.0, b)
        return self * inv

    def __rtruediv__(self, a):
        return _inv(self) * a


def _c1(b):
    return np.asarray(b)[..., None]


def _c2(b):
    return np.asarray(b)[..., None, None]


def _chain(x, f, d1, d2):
    """``phi(x)`` for a Jet x, given ``phi(x.v)``, ``phi'(x.v)``, ``phi''(x.v)``."""
    outer = x.g[..., :, None] * x.g[..., None, :]
    return Jet(f, _c1(d1) * x.g, _c2(d1) * x.H + _c2(d2) * outer)


def _inv(x):
    v = x.v
    return _chain(x, 1.0 / v, -1.0 / v**2, 2.0 / v**3)


def _unary(fn, d):
    """A jet function from numpy ``fn`` and ``d(v, f) -> (phi', phi'')``."""

    def jf(x):
        if not isinstance(x, Jet):
            return fn(x)
        f = fn(x.v)
        d1, d2 = d(x.v, f)
        return _chain(x, f, d1, d2)

    return jf


def _ipow(a, k):
    if not isinstance(a, Jet):
        return np.asarray(a, dtype=np.float64) ** k
    if k == 0:
        return np.ones_like(a.v)
    if k == 1:
        return a
    v = a.v
    return _chain(a, v**k, k * v ** (k - 1), k * (k - 1) * v ** (k - 2))


def _power(a, b):
    if not isinstance(b, Jet):
        if not isinstance(a, Jet):
            return np.power(np.asarray(a, dtype=np.float64), b)
        v = a.v
        return _chain(a, np.power(v, b), b * np.power(v, b - 1.0), b * (b - 1.0) * np.power(v, b - 2.0))
    return _JET_MATH.exp(b * _JET_MATH.log(a))


def _select(op):
    def sel(a, b):
        if not isinstance(a, Jet) and not isinstance(b, Jet):
            return op(a, b)
        a, b = _lift(a, b), _lift(b, a)
        first = (a.v <= b.v) if op is np.minimum else (a.v >= b.v)
        return Jet(np.where(first, a.v, b.v), np.where(_c1(first), a.g, b.g), np.where(_c2(first), a.H, b.H))

    return sel


def _lift(a, like):
    if isinstance(a, Jet):
        return a
    v = np.broadcast_to(np.asarray(a, dtype=np.float64), like.v.shape)
    return Jet(v, np.zeros_like(like.g), np.zeros_like(like.H))


def _atan2(y, x):
    if not isinstance(y, Jet) and not isinstance(x, Jet):
        return np.arctan2(y, x)
    j = _JET_MATH.arctan(y / x)  # same derivatives as atan2 where x != 0
    yv = y.v if isinstance(y, Jet) else y
    xv = x.v if isinstance(x, Jet) else x
    return Jet(np.arctan2(yv, xv), j.g, j.H)


class _JetMath:
    """The numpy-like functions of :func:`trig_funcs` for jets."""

    sin = staticmethod(_unary(np.sin, lambda v, f: (np.cos(v), -f)))
    cos = staticmethod(_unary(np.cos, lambda v, f: (-np.sin(v), -f)))
    tan = staticmethod(_unary(np.tan, lambda v, f: (1 + f**2, 2 * f * (1 + f**2))))
    arcsin = staticmethod(_unary(np.arcsin, lambda v, f: (1 / np.sqrt(1 - v**2), v / (1 - v**2) ** 1.5)))
    arccos = staticmethod(_unary(np.arccos, lambda v, f: (-1 / np.sqrt(1 - v**2), -v / (1 - v**2) ** 1.5)))
    arctan = staticmethod(_unary(np.arctan, lambda v, f: (1 / (1 + v**2), -2 * v / (1 + v**2) ** 2)))
    arctan2 = staticmethod(_atan2)
    sinh = staticmethod(_unary(np.sinh, lambda v, f: (np.cosh(v), f)))
    cosh = staticmethod(_unary(np.cosh, lambda v, f: (np.sinh(v), f)))
    tanh = staticmethod(_unary(np.tanh, lambda v, f: (1 - f**2, -2 * f * (1 - f**2))))
    arcsinh = staticmethod(_unary(np.arcsinh, lambda v, f: (1 / np.sqrt(v**2 + 1), -v / (v**2 + 1) ** 1.5)))
    arccosh = staticmethod(_unary(np.arccosh, lambda v, f: (1 / np.sqrt(v**2 - 1), -v / (v**2 - 1) ** 1.5)))
    arctanh = staticmethod(_unary(np.arctanh, lambda v, f: (1 / (1 - v**2), 2 * v / (1 - v**2) ** 2)))
    exp = staticmethod(_unary(np.exp, lambda v, f: (f, f)))
    log = staticmethod(_unary(np.log, lambda v, f: (1 / v, -1 / v**2)))
    sqrt = staticmethod(_unary(np.sqrt, lambda v, f: (0.5 / f, -0.25 / (f * v))))
    abs = staticmethod(_unary(np.abs, lambda v, f: (np.sign(v), 0.0 * v)))
    sign = staticmethod(_unary(np.sign, lambda v, f: (0.0 * v, 0.0 * v)))


_JET_MATH = _JetMath()
#: The :class:`uio_jax._io.expressions.Ops` of jets (numpy, float64).
JET_OPS = Ops(trig_funcs(_JET_MATH), _ipow, _power, _select(np.minimum), _select(np.maximum), lambda a: a)


def jet_parts(out, shape, m):
    """(value, gradient, Hessian) of a jet evaluation that may be a constant."""
    if isinstance(out, Jet):
        return (np.broadcast_to(out.v, shape), np.broadcast_to(out.g, shape + (m,)),
                np.broadcast_to(out.H, shape + (m, m)))
    v = np.broadcast_to(np.asarray(out, dtype=np.float64), shape)
    return v, np.zeros(shape + (m,)), np.zeros(shape + (m, m))
