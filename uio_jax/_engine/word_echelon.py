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
        self.R = np.zeros((0, self.n), dtype=np.int64)
        self.pivots: list[int] = []

    @property
    def rank(self) -> int:
        return len(self.pivots)

    def reduce(self, row) -> np.ndarray:
        """The remainder of ``row`` after eliminating the pivot columns (zero iff in the span)."""
        p = self.p
        v = np.asarray(row, dtype=np.int64) % p
        if not self.pivots:
            return v
        f = v[self.pivots]
        for lo in range(0, len(f), LAZY_TERMS):
            v = (v - f[lo:lo + LAZY_TERMS] @ self.R[lo:lo + LAZY_TERMS] % p) % p
        return v

    def add(self, row) -> bool:
        """Append ``row``; whether it raised the rank."""
        v = self.reduce(row)
        nonzero = np.flatnonzero(v)
        if not len(nonzero):
            return False
        p, c = self.p, int(nonzero[0])
        v = v * pow(int(v[c]), -1, p) % p
        if self.pivots:
            self.R = (self.R - np.outer(self.R[:, c], v) % p) % p
        self.R = np.vstack([self.R, v[None]])
        self.pivots.append(c)
        return True


__all__ = ["WordEchelon"]
