"""Machine-word modular arithmetic for the Taylor engine: residues modulo several random
primes below ``2^26`` (:mod:`.primes`), one *lane* per (prime, point), as int64 numpy arrays
(rows first, :mod:`.taylor_arithmetic`).

A product of two residues is below ``2^52``: the Cauchy sums ``sum_j v_j M_j`` of the
recurrences are int64 matrix products over up to :data:`~uio_jax._engine.primes.LAZY_TERMS`
terms, reduced once (longer sums in blocks of that many).

:class:`Word` is the field ``F_p`` of each lane. :class:`WordSquare` is ``F_{p^2} = F_p[i]``,
``i^2 = -1`` (``p = 3 mod 4``), for models with square roots: every element of ``F_p`` has its
square roots there, so a root of a range ``sqrt((lx - px)^2 + (ly - py)^2)`` exists at every
point (in ``F_p`` it exists at half of them, and a model with 400 ranges never finds a
point where all do). Its rows are the real parts of the lanes, then their imaginary parts:
sums and scalings by rational constants act on both alike; products, inverses and roots
combine them.

**Why the rank is the real one.** A root ``r = u^(1/b)`` is an algebraic function of the
point: the gradients of the Taylor coefficients are rational functions of the coordinates and
of the roots (``r^b = u`` reduced), equal to the real ones on a real branch. Their rank over
the function field ``Q(z)(r)`` does not depend on the branch (the conjugate branches differ
by an automorphism over ``Q(z)``, which maps minors to minors), so the rank on any branch,
over any field where the roots live, is the real generic rank, unless the point is a root of
a nonzero minor (Schwartz-Zippel on the variety of the roots, the root counted as a
generator, :mod:`.taylor_degrees`). The branch of each square root is drawn at random, so
that no choice of sign correlates with the minors. Odd roots are unique in ``F_p`` for the
primes drawn (``gcd(b, p - 1) = 1``); a root of an element outside ``F_p`` exists for half of
the points and is drawn again elsewhere.
"""

from fractions import Fraction

import numpy as np

from .graph_elementary import NotSquare, Singular
from .primes import LAZY_TERMS


def _column(a, ndim):
    """``a (rows,)`` shaped to broadcast against an array of ``ndim`` axes."""
    return a.reshape((-1,) + (1,) * (ndim - 1))


def _lazy_dot(v, M, mod):
    """``sum_j v[..., j] M[..., j, :] mod p`` per row (``mod (rows,)``; any axes between the
    rows and ``j``), unreduced over blocks of :data:`~uio_jax._engine.primes.LAZY_TERMS` terms."""
    J, m = v.shape[-1], _column(mod, v.ndim)
    if J <= LAZY_TERMS:
        return np.einsum("...j,...jw->...w", v, M) % m
    out = 0
    for lo in range(0, J, LAZY_TERMS):
        out = out + np.einsum("...j,...jw->...w", v[..., lo:lo + LAZY_TERMS], M[..., lo:lo + LAZY_TERMS, :]) % m
    return out % m


def _power(v, e, mod):
    """``v^e mod p`` per row (``v, e, mod`` of shape ``(rows,)``; ``e >= 0``)."""
    if v.size <= 64:  # a few residues: Python's pow
        return np.array([pow(int(a), int(b), int(m)) for a, b, m in zip(v, e, mod)], dtype=np.int64)
    out = np.ones_like(v)
    base = v % mod
    e = np.array(e, dtype=np.int64)
    while e.any():
        odd = (e & 1).astype(bool)
        out = np.where(odd, out * base % mod, out)
        base = base * base % mod
        e >>= 1
    return out


class Word:
    """Residues modulo one prime per lane (int64).

    Args:
        primes: ``L`` primes ``= 3 mod 4`` below ``2^26``.
        points: ``(L, N)`` integers, the coordinates at ``t = 0`` (reduced modulo each
            lane's prime).
        rng: a numpy Generator for the generators' values and the roots' branches.
    """

    dtype = np.int64

    def __init__(self, primes, points, rng):
        self.primes = [int(p) for p in primes]
        self.lanes = len(self.primes)
        self.mod = np.array(self.primes, dtype=np.int64)
        self.rng = rng
        self.values = {}  # generator key -> its values (rows,)
        pts = np.array([[int(v) % p for v in row] for row, p in zip(points, self.primes)], dtype=np.int64)
        self.points = self.embed(pts.reshape(self.lanes, -1))
        self._scalars = {}
        self.row_mod = np.tile(self.mod, self.rows // self.lanes)

    @property
    def rows(self) -> int:
        return len(self.mod)

    def embed(self, a):
        """Lane values ``(L, ...)`` of ``F_p`` as elements."""
        return a

    def reduce(self, a):
        return a % _column(self.row_mod, a.ndim)

    def scalar(self, value: Fraction):
        """A rational constant modulo each lane's prime ``(rows,)``.

        Raises:
            Singular: its denominator is divisible by a lane's prime.
        """
        found = self._scalars.get(value)
        if found is None:
            value = Fraction(value)
            out = []
            for p in self.primes:
                den = value.denominator % p
                if den == 0:
                    raise Singular("a constant's denominator vanishes modulo p")
                out.append(value.numerator % p * pow(den, -1, p) % p)
            found = self._scalars[value] = np.tile(np.array(out, dtype=np.int64), self.rows // self.lanes)
        return found

    def element(self, value: Fraction):
        return self.scalar(value)

    def mul(self, a, b):
        return self.reduce(a * b)

    def dot(self, v, M):
        """``sum_j v[..., j] M[..., j, :]``: ``v (rows, .., J)``, ``M (rows, .., J, C)`` ->
        ``(rows, .., C)``."""
        return _lazy_dot(v, M, self.row_mod)

    def scalar_dot(self, v, M):
        """:meth:`dot` with per-row multipliers ``v`` (rational constants)."""
        return _lazy_dot(v, M, self.row_mod)

    def inverse(self, a):
        """Elementwise inverses of ``(rows,)`` elements.

        Raises:
            Singular: one is zero (a denominator vanishes at the point).
        """
        a = self.reduce(a)
        if not a.all():
            raise Singular("division by zero modulo p")
        return _power(a, self.mod - 2, self.mod)

    def _random(self):
        """Uniform residues, one per lane ``(L,)``."""
        return self.rng.integers(0, self.mod[:self.lanes])

    def _draw(self, key, make):
        found = self.values.get(key)
        if found is None:
            found = self.values[key] = make()
        return found

    def circle(self, key, u0):
        """A point ``(s, c)`` of the circle per lane, ``s = 2t/(1+t^2)``, ``c = (1-t^2)/(1+t^2)``
        at a random ``t`` (``1 + t^2`` never vanishes: ``-1`` is not a square)."""
        def make():
            mod = self.mod[:self.lanes]
            t = self._random()
            inv = _power((1 + t * t) % mod, mod - 2, mod)
            return self.embed(2 * t * inv % mod), self.embed((1 - t * t) % mod * inv % mod)
        return self._draw(key, make)

    def exponential(self, key, u0):
        """A random nonzero value of ``exp u`` per lane."""
        return self._draw(key, lambda: self.embed(np.maximum(self._random(), 1)))

    def free(self, key, kind, values):
        """A random value of a logarithmic kind's generator per lane."""
        return self._draw(key, lambda: self.embed(self._random()))

    def _odd_root(self, a, b):
        """The unique ``b``-th root in ``F_p`` (``b`` odd, prime to ``p - 1``) of ``(L,)``."""
        mod = self.mod[:self.lanes]
        e = np.array([pow(b, -1, p - 1) for p in self.primes], dtype=np.int64)
        return _power(a % mod, e, mod)

    def _sign(self, r, key):
        """``r`` or ``-r`` per lane, drawn once per root ``key`` (the branch of a square root:
        the same in every program of the lane)."""
        flip = self._draw(("sign",) + tuple(key), lambda: self.rng.integers(0, 2, size=self.lanes).astype(bool))
        flip = _column(np.tile(flip, self.rows // self.lanes), r.ndim)
        return np.where(flip, (-r) % _column(self.row_mod, r.ndim), r)

    def root(self, a, b: int, key=("root",)):
        """``a^(1/b)`` of ``(rows,)`` elements (``b = 2^e b'``): the odd root, then ``e``
        square roots, each of a random branch.

        Raises:
            NotSquare: a square root that does not exist here (drawn again elsewhere).
        """
        e = (b & -b).bit_length() - 1
        r = self._odd_root(a, b >> e) if b >> e > 1 else self.reduce(a)
        for level in range(e):
            r = self._sign(self._square_root(r), tuple(key) + (level,))
        return r

    def _square_root(self, a):
        mod = self.mod
        r = _power(a, (mod + 1) // 4, mod)
        if (r * r % mod != a % mod).any():
            raise NotSquare("the argument of a square root has no root modulo p here")
        return r

    def lane_rows(self, X):
        """Per lane, ``(prime, rows over F_p)`` of elements ``X (rows, N)``: the row itself."""
        return [(p, X[lane][None]) for lane, p in enumerate(self.primes)]


class WordSquare(Word):
    """``F_{p^2} = F_p[i]`` per lane (``i^2 = -1``): rows ``[real parts; imaginary parts]``."""

    def embed(self, a):
        return np.concatenate([a, np.zeros_like(a)])

    @property
    def rows(self) -> int:
        return 2 * self.lanes

    def element(self, value: Fraction):
        c = super().scalar(value)[:self.lanes]
        return np.concatenate([c, np.zeros_like(c)])

    def _halves(self, a):
        n = self.lanes
        return (a[:n], a[n:]) if len(a) == 2 * n else (a, np.zeros_like(a))

    def mul(self, a, b):
        (ar, ai), (br, bi) = self._halves(a), self._halves(b)
        return self.reduce(np.concatenate([ar * br - ai * bi, ar * bi + ai * br]))

    def dot(self, v, M):
        n, mod = self.lanes, self.mod
        vr, vi, Mr, Mi = v[:n], v[n:], M[:n], M[n:]
        re = _lazy_dot(vr, Mr, mod) - _lazy_dot(vi, Mi, mod)
        im = _lazy_dot(vr, Mi, mod) + _lazy_dot(vi, Mr, mod)
        return self.reduce(np.concatenate([re, im]))

    def inverse(self, a):
        """``(x + yi)^-1 = (x - yi) / (x^2 + y^2)``.

        Raises:
            Singular: an element is zero.
        """
        x, y = self._halves(self.reduce(a))
        mod = self.mod[:self.lanes]
        norm = (x * x + y * y) % mod
        if not norm.all():
            raise Singular("division by zero modulo p")
        inv = _power(norm, mod - 2, mod)
        return np.concatenate([x * inv % mod, (-y) * inv % mod])

    def _odd_root(self, a, b):
        x, y = self._halves(self.reduce(a))
        if y.any():
            raise NotSquare("a root of odd order of an element outside F_p")
        return np.concatenate([super()._odd_root(x, b), np.zeros_like(x)])

    def _square_root(self, a):
        """Square roots in ``F_{p^2}``: of ``x`` in ``F_p``, ``sqrt x`` or ``i sqrt(-x)``; of
        ``x + yi`` (``y != 0``), ``c + (y / 2c) i`` with ``c^2 = (x + n) / 2`` or
        ``(x - n) / 2``, ``n^2 = x^2 + y^2`` (exactly one of them is a square: their product
        ``-y^2 / 4`` is not).

        Raises:
            NotSquare: ``x^2 + y^2`` is not a square in ``F_p`` (``x + yi`` is not a square).
        """
        mod = self.mod
        e = (mod + 1) // 4

        def sqrt(v):
            return _power(v % mod, e, mod)

        x, y = self._halves(self.reduce(a))
        r0, i0 = sqrt(x), sqrt(-x)
        real = r0 * r0 % mod == x
        norm = (x * x + y * y) % mod
        n = sqrt(norm)
        if ((n * n % mod != norm) & (y != 0)).any():
            raise NotSquare("an element of F_p^2 without a square root")
        half = (mod + 1) // 2
        t, t2 = (x + n) * half % mod, (x - n) * half % mod
        c = sqrt(t)
        c = np.where(c * c % mod == t, c, sqrt(t2))
        c = np.where(y == 0, 1, c)
        d = y * _power(2 * c % mod, mod - 2, mod) % mod
        re = np.where(y == 0, np.where(real, r0, 0), c)
        im = np.where(y == 0, np.where(real, 0, i0), d)
        return np.concatenate([re, im])

    def lane_rows(self, X):
        """Per lane, the row of ``X`` over ``F_p``: a real or purely imaginary row as its
        ``F_p`` part (``(1, N)``: ``i`` is a unit, and the rank over ``F_{p^2}`` of rows of
        ``F_p`` is their rank over ``F_p``), any other as the two rows spanning it and ``i``
        times it, ``[re | im]`` and ``[-im | re]`` (``(2, 2N)``: the ``F_p``-rank of these is
        twice the ``F_{p^2}``-rank)."""
        n = self.lanes
        out = []
        for lane, p in enumerate(self.primes):
            re, im = X[lane], X[n + lane]
            if not im.any() or not re.any():
                out.append((p, (re if re.any() else im)[None]))
            else:
                out.append((p, np.stack([np.concatenate([re, im]), np.concatenate([(-im) % p, re])])))
        return out


__all__ = ["Word", "WordSquare"]
