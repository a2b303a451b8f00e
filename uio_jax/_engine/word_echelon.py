"""Rows of ``F_p^n`` in reduced echelon form for a machine-word prime (``p < 2^26``, int64
numpy arrays): the rank of a growing list of rows and whether a row lies in their span, as
:class:`uio_jax._engine.graph_exact.Echelon` does with Python integers.

Each kept row has a pivot column where it is 1 and every other kept row 0, so a row is
reduced in one step, ``v - v[pivots] R`` (a matrix product of at most
:data:`~uio_jax._engine.primes.LAZY_TERMS` terms per block, reduced once), and keeping a row
clears its pivot column in the others (``O(r n)``).
"""

import numpy as np

from .primes import LAZY_TERMS


class WordEchelon:
    """Reduced echelon form over ``F_p``.

    Args:
        p: a prime below ``2^26``.
        n: the row length.
    """

    def __init__(self, p: int, n: int):
        self.p, self.n = int(p), int(n)
        self._R = np.zeros((8, self.n), dtype=np.int64)  # the kept rows, capacity doubling
        self.pivots: list[int] = []

    @property
    def rank(self) -> int:
        return len(self.pivots)

    @property
    def R(self) -> np.ndarray:
        return self._R[:self.rank]

    def reduce(self, row) -> np.ndarray:
        """The remainder of ``row`` after eliminating the pivot columns (zero iff in the span):
        only the kept rows whose pivot is nonzero in ``row`` take part."""
        p = self.p
        v = np.asarray(row, dtype=np.int64) % p
        if not self.pivots:
            return v
        f = v[self.pivots]
        used = np.flatnonzero(f)
        if not len(used):
            return v
        f, R = (f, self._R[:len(f)]) if len(used) == len(f) else (f[used], self._R[used])
        for lo in range(0, len(f), LAZY_TERMS):
            v = v - np.einsum("j,jw->w", f[lo:lo + LAZY_TERMS], R[lo:lo + LAZY_TERMS]) % p
        return v % p

    def add(self, row) -> bool:
        """Append ``row``; whether it raised the rank. Keeping it clears its pivot column in
        the kept rows where that column is nonzero, over the columns where it is nonzero (the
        rows of a sparse model stay sparse: one column in a few rows)."""
        v = self.reduce(row)
        nonzero = np.flatnonzero(v)
        if not len(nonzero):
            return False
        p, c, r = self.p, int(nonzero[0]), self.rank
        v = v * pow(int(v[c]), -1, p) % p
        if r:
            hit = np.flatnonzero(self._R[:r, c])
            if 2 * len(hit) > r and 2 * len(nonzero) > self.n:  # dense: in place
                R = self._R[:r]
                R -= R[:, c:c + 1] * v % p
                R %= p
            elif len(hit):
                block = np.ix_(hit, nonzero)
                self._R[block] = (self._R[block] - self._R[hit, c][:, None] * v[nonzero] % p) % p
        if r == len(self._R):
            self._R = np.concatenate([self._R, np.zeros_like(self._R)])
        self._R[r] = v
        self.pivots.append(c)
        return True


class LaneSpan:
    """The span of one lane's rows over ``F_p`` or ``F_{p^2} = F_p[i]``
    (:meth:`uio_jax._engine.taylor_word.WordSquare.lane_rows`): rows of ``F_p`` (``(1, n)``)
    in an echelon form of width ``n`` while every row is one; from the first other row on
    (``(2, 2n)``, a row and ``i`` times it over ``F_p``), every row realified in one of width
    ``2n`` (the rows kept so far entered again as ``[w | 0]`` and ``[0 | w]``).

    Args:
        p: the prime.
        n: the row length over the field.
    """

    def __init__(self, p: int, n: int):
        self.p, self.n = int(p), int(n)
        self.plain = WordEchelon(p, n)
        self.real = None
        self._kept = []  # the plain rows kept, for the switch

    def _realified(self, rows):
        if rows.shape[1] == 2 * self.n:
            return rows
        zero = np.zeros(self.n, dtype=np.int64)
        return np.array([np.concatenate([w, zero]) for w in rows] + [np.concatenate([zero, w]) for w in rows])

    def _switch(self):
        if self.real is None:
            self.real = WordEchelon(self.p, 2 * self.n)
            for r in self._realified(np.array(self._kept, dtype=np.int64).reshape(-1, self.n)):
                self.real.add(r)

    def add(self, rows) -> bool:
        """Append the rows of one element row; whether they raised the rank."""
        if self.real is None and rows.shape[1] == self.n:
            rose = self.plain.add(rows[0])
            if rose:
                self._kept.append(np.asarray(rows[0], dtype=np.int64) % self.p)
            return rose
        self._switch()
        return sum(self.real.add(r) for r in self._realified(rows)) > 0

    def inside(self, rows) -> bool:
        """Whether the rows of one element row lie in the span."""
        if self.real is None and rows.shape[1] == self.n:
            return not self.plain.reduce(rows[0]).any()
        self._switch()
        return not any(self.real.reduce(r).any() for r in self._realified(rows))


__all__ = ["WordEchelon", "LaneSpan"]
