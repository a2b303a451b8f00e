"""The arithmetics of the Taylor engine (:mod:`.taylor`): one program, the arithmetic a
parameter.

Every array is *rows first*: row ``r`` is one evaluation (a point in float64 or mpmath, a
point modulo one prime in a modular arithmetic), so that a sum, a difference or a scaling by
a rational constant is one numpy operation over all rows, and the engine never looks inside
an element. The operations an arithmetic gives:

* ``reduce(a)``, ``scalar(c)`` (a rational constant as a per-row multiplier ``(rows,)``),
  ``element(c)`` (the constant as an element), ``mul(a, b)`` (elementwise products,
  broadcast over the trailing axes), ``dot(v, M)`` (``sum_j v[:, j] M[:, j]``, the Cauchy
  sums of the recurrences: ``v (rows, J)``, ``M (rows, J, C)``), ``scalar_dot`` (the same with
  ``v`` per-row multipliers), ``inverse``, ``root(v, b)`` (``v^(1/b)``);
* the generators of the elementary functions at ``t = 0``: ``circle``, ``exponential``,
  ``free`` (:mod:`.graph_elementary`).

:class:`Float` (float64), :class:`Extended` (mpmath) and :class:`Modular` (Python integers
modulo one prime, ``2^127 - 1`` by default: the reference arithmetic of the tests) live here;
the machine-word modular arithmetics are :mod:`.taylor_word`.
"""

from fractions import Fraction

import numpy as np

from . import graph_elementary
from .graph_elementary import NotSquare, Singular
from .graph_exact import PRIME, const_mod

#: numpy's functions of the logarithmic kinds (float64 values at real points)
_NUMPY = {"log": np.log, "log1p": np.log1p, "atan": np.arctan, "atanh": np.arctanh, "asin": np.arcsin,
          "acos": np.arccos, "asinh": np.arcsinh, "acosh": np.arccosh}


class _Plain:
    """The operations shared by the arithmetics whose elements are numbers of one numpy
    dtype (no reduction: float64 and mpmath)."""

    dtype = np.float64

    @property
    def rows(self) -> int:
        return len(self.points)

    def reduce(self, a):
        return a

    def element(self, value: Fraction):
        return self.scalar(value)

    def mul(self, a, b):
        return self.reduce(a * b)

    def dot(self, v, M):
        if self.dtype is object:
            return self.reduce(np.matmul(v[..., None, :], M)[..., 0, :])
        return np.einsum("...j,...jw->...w", v, M)

    def scalar_dot(self, v, M):
        return self.dot(v, M)


class Float(_Plain):
    """float64 at real points ``(P, N)`` (the elementary functions at their real values)."""

    def __init__(self, points):
        self.points = np.asarray(points, dtype=np.float64)

    def scalar(self, value: Fraction):
        return float(value)

    def inverse(self, a):
        return 1.0 / a

    def root(self, a, b: int, key=None):
        """The real ``b``-th root (odd ``b``: of either sign)."""
        if b % 2:
            return np.sign(a) * np.abs(a) ** (1.0 / b)
        return a ** (1.0 / b)

    def circle(self, key, u0):
        return np.sin(u0), np.cos(u0)

    def exponential(self, key, u0):
        return np.exp(u0)

    def free(self, key, kind, values):
        if kind == "atan2":
            return np.arctan2(values[0], values[1])
        return _NUMPY[kind](values[0])


class Extended(_Plain):
    """mpmath numbers at ``dps`` decimal digits, at real points ``(P, N)`` (floats taken as
    exact binary numbers)."""

    dtype = object

    def __init__(self, points, dps: int):
        import mpmath

        self.ctx = mpmath.MPContext()
        self.ctx.dps = dps
        self.points = np.array([[self.ctx.mpf(float(v)) for v in row] for row in np.asarray(points, float)],
                               dtype=object)

    def scalar(self, value: Fraction):
        return self.ctx.mpf(value.numerator) / value.denominator

    def inverse(self, a):
        return np.array([1 / v for v in a], dtype=object)

    def root(self, a, b: int, key=None):
        ctx = self.ctx
        return np.array([ctx.sign(v) * ctx.root(abs(v), b) if b % 2 else ctx.root(v, b) for v in a], dtype=object)

    def circle(self, key, u0):
        return (np.array([self.ctx.sin(v) for v in u0], dtype=object),
                np.array([self.ctx.cos(v) for v in u0], dtype=object))

    def exponential(self, key, u0):
        return np.array([self.ctx.exp(v) for v in u0], dtype=object)

    def free(self, key, kind, values):
        if kind == "atan2":
            return np.array([self.ctx.atan2(a, b) for a, b in zip(*values)], dtype=object)
        fn = getattr(self.ctx, kind)
        return np.array([fn(v) for v in values[0]], dtype=object)


class Modular(_Plain):
    """Residues modulo one prime ``p`` (Python integers in numpy object arrays): the reference
    arithmetic (slow; :mod:`.taylor_word` is the fast one).

    Args:
        points: ``(P, N)`` residues, the coordinates at ``t = 0``.
        draws: the :class:`~uio_jax._engine.graph_elementary.Draws` of the generators.
        p: an odd prime.
    """

    dtype = object

    def __init__(self, points, draws, p: int = PRIME):
        self.p = p
        self.points = np.array([[int(v) % p for v in row] for row in points], dtype=object)
        self.draws = draws

    def reduce(self, a):
        return a % self.p

    def scalar(self, value: Fraction):
        return const_mod(value, self.p)

    def inverse(self, a):
        """Elementwise inverse of ``(P,)`` residues.

        Raises:
            Singular: a residue is zero (a denominator vanishes at the point).
        """
        return graph_elementary.inverse_mod_p(a, self.p)

    def root(self, a, b: int, key=None):
        """``b``-th roots: square roots where they exist (``p = 3 mod 4``), odd roots where
        they are unique (``gcd(b, p - 1) = 1``).

        Raises:
            NotSquare: a square root that does not exist, or a root of another order.
        """
        p = self.p
        if b == 2:
            return graph_elementary.sqrt_mod_p(a, p)
        if b % 2 and np.gcd(b, p - 1) == 1:
            e = pow(b, -1, p - 1)
            return np.array([pow(int(v) % p, e, p) for v in a], dtype=object)
        raise NotSquare(f"roots of order {b} are not computed modulo this prime")

    def circle(self, key, u0):
        return self.draws.get(key)

    def exponential(self, key, u0):
        return self.draws.get(key)

    def free(self, key, kind, values):
        """The random value of a logarithmic kind's generator at the points."""
        return self.draws.get(key)


__all__ = ["Float", "Extended", "Modular", "Singular", "NotSquare"]
