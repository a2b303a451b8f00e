"""Rank decisions on the gradients of Taylor coefficients modulo random machine-word primes,
with the probability that a decision is wrong bounded (Sedoglavic's test, :mod:`.taylor`).

The rows ``d y_k`` are computed modulo several *lanes*, each a random prime ``p_l`` below
``2^26`` (:mod:`.primes`) and a uniformly random point of ``F_{p_l}^N``
(:mod:`.taylor_word`), kept in one reduced echelon form per lane (:mod:`.word_echelon`).

* **A rise is certain.** Rows dependent over ``Q(z)`` have every minor identically zero, so
  they are dependent modulo any prime at any point where the computation is defined (every
  denominator invertible, else the point is drawn again). A row that raises the rank in one
  lane raises the generic rank; a lane where it does not is wrong there (the fault is caught:
  that lane is dropped).
* **A dependence can be wrong** when, in every lane, the point is a root of a nonzero minor
  ``M`` modulo ``p_l``: ``p_l`` divides every integer coefficient of ``M``'s numerator (the
  *content*: at most ``H / log2 LOW`` primes of the range divide it, ``H`` bits,
  :mod:`.taylor_heights`), or the point is one of its roots (Schwartz-Zippel: at most
  ``D / p_l``, ``D`` its degree, :mod:`.taylor_degrees`). With the lanes drawn independently,
  the probability is at most ``prod_l (D / p_l + ceil(H / 25) / #primes)``. A dependence is
  certified when that bound is below ``max_bound``; otherwise lanes are added (every lane
  drawn again, as many as a bound with fresh random primes needs, the decisions so far replayed
  in the new lanes: a kept row that a new lane does not raise drops that lane, a certified
  dependence that a new lane contradicts ends the decisions, :class:`Undecided`) until it is,
  up to :data:`MAX_LANES`.
* Once the rank is ``N`` every further row is dependent with certainty.
"""

import math

import numpy as np

from .graph_elementary import Singular
from .primes import LOW, prime_count, random_prime, root_conditions
from .taylor_word import Word, WordSquare
from .word_echelon import LaneSpan

#: the most lanes a run may use (a decision needing more is undecided here)
MAX_LANES = 16
#: draws of the lanes where a denominator vanishes or a root does not exist
DRAWS = 4


class Undecided(ArithmeticError):
    """The decisions cannot be certified modulo machine-word primes here (every draw
    singular, a bound more lanes cannot reach, a certified dependence contradicted)."""


def arithmetic_needs(ins):
    """``(conditions, square)``: the congruences of the primes (:func:`.primes.root_conditions`
    of the roots' orders) and whether the arithmetic must hold square roots (``F_p[i]``)."""
    orders = [param[0].denominator for op, _, param in ins if op == "root"]
    return root_conditions(orders), any(b % 2 == 0 for b in orders)


class TaylorRank:
    """The echelon forms of the offered rows, in every lane.

    Args:
        series_of: ``arithmetic -> TaylorSeries`` (one program: the model's).
        ins: the program's instructions (for the arithmetic it needs).
        first: a root node whose order 0 is computed when the lanes are drawn (every
            division and root of the program is met at order 0).
        n: the number of coordinates.
        seed: the seed of the primes and points.
        max_bound: the largest probability bound of one certified dependence.
        lanes: the lanes to start with.
    """

    def __init__(self, series_of, ins, first, n, seed, max_bound, lanes=1):
        self.series_of, self.first, self.n, self.seed = series_of, first, int(n), int(seed)
        self.max_bound = max_bound
        self.conditions, self.square = arithmetic_needs(ins)
        self.count = prime_count(self.conditions)
        self.circle = any(op == "sin" for op, _, _ in ins)
        self.log = []  # (kind, rows_of, outcome) of every decision, in order
        self.rank = 0
        self._kept = []  # the bounds of the kept rows (callables, evaluated when a dependence needs them)
        self._kept_sum = (0, 0, 0.0)  # (rows summed, degree, bits)
        self.error_bound, self.decisions, self.dropped = 0.0, 0, 0
        self._build(lanes)

    # ------------------------------------------------------------------ lanes
    def _build(self, lanes):
        rng = np.random.default_rng([self.seed, 0x7A110, lanes])
        kind = WordSquare if self.square else Word
        for _ in range(DRAWS):
            primes = [random_prime(rng, self.conditions) for _ in range(lanes)]
            points = [rng.integers(0, p, size=self.n) for p in primes]
            arith = kind(primes, points, np.random.default_rng(rng.integers(2**63)))
            series = self.series_of(arith)
            try:
                series.coefficient(self.first, 0)
            except Singular:
                continue
            break
        else:
            raise Undecided("every random point drawn is singular modulo p")
        self.arith, self.series = arith, series
        self.echelons = [LaneSpan(p, self.n) for p in primes]
        self.live = list(range(lanes))
        for kind_, rows_of, outcome in self.log:
            self._replay(kind_, rows_of, outcome)
        if not self.live:
            raise Undecided("no lane drawn again agrees with the rows kept")

    @property
    def primes(self):
        """The primes of the live lanes."""
        return [self.arith.primes[lane] for lane in self.live]

    def _rows(self, rows_of):
        X = np.asarray(rows_of(self.series))
        if X.ndim == 1:  # a row of F_p, the same in every lane
            X = self.arith.embed(np.tile(X, (self.arith.lanes, 1)))
        return self.arith.lane_rows(self.arith.reduce(X))

    def _per_lane(self, rows_of, test: str):
        """Per live lane, the echelon's ``test`` of the rows: ``"add"``, whether they raised its
        rank (kept there), or ``"inside"``, whether they lie in its span."""
        lane_rows = self._rows(rows_of)
        return {lane: getattr(self.echelons[lane], test)(lane_rows[lane][1]) for lane in self.live}

    def _drop(self, lanes):
        for lane in lanes:
            self.live.remove(lane)
            self.dropped += 1

    def _replay(self, kind, rows_of, outcome):
        found = self._per_lane(rows_of, "add" if kind == "offer" else "inside")
        wrong = [lane for lane, v in found.items() if v != outcome]
        if wrong and (outcome is False if kind == "offer" else outcome is True):
            raise Undecided("a dependence certified earlier is contradicted in a new lane")
        self._drop(wrong)

    # ------------------------------------------------------------------ decisions
    def offer(self, rows_of, bounds) -> bool:
        """Offer a row (``rows_of(series) -> (rows, N)`` elements, or ``(N,)`` integers);
        whether it raised the generic rank. ``bounds() -> (degree, bits)``: the row's
        numerator degree and height (asked only when a dependence is to be certified)."""
        self.decisions += 1
        while True:
            found = self._per_lane(rows_of, "add")
            if any(found.values()):
                self._drop([lane for lane, v in found.items() if not v])
                self.log.append(("offer", rows_of, True))
                self.rank += 1
                self._kept.append(bounds)
                return True
            if self._certify(bounds):
                self.log.append(("offer", rows_of, False))
                return False

    def member(self, rows_of, bounds) -> bool:
        """Whether the row lies in the span (a dependence: its bound counted)."""
        self.decisions += 1
        while True:
            found = self._per_lane(rows_of, "inside")
            if not all(found.values()):
                self._drop([lane for lane, v in found.items() if v])
                self.log.append(("member", rows_of, False))
                return False
            if self._certify(bounds):
                self.log.append(("member", rows_of, True))
                return True

    def kept_bounds(self):
        """``(degree, bits)`` summed over the kept rows."""
        done, degree, bits = self._kept_sum
        for bounds in self._kept[done:]:
            d, b = bounds()
            degree, bits = degree + d, bits + b
        self._kept_sum = (len(self._kept), degree, bits)
        return degree, bits

    def _lane_bound(self, p, D, H):
        """``D / p + ceil(H / log2 LOW) / #primes``: a minor of degree ``D`` and ``H`` bits."""
        return min(1.0, D / p + math.ceil(H / math.log2(LOW)) / self.count)

    def _certify(self, bounds) -> bool:
        """Certify a dependence found in every live lane (its bound added), or add lanes
        (False: decide again)."""
        if self.rank >= self.n:
            return True
        degree, bits = bounds()
        kept_degree, kept_bits = self.kept_bounds()
        D = kept_degree + degree
        H = math.lgamma(self.rank + 2) / math.log(2) + kept_bits + bits + (D if self.circle else 0)
        per_lane = [self._lane_bound(p, D, H) for p in self.primes]
        bound = math.prod(per_lane)
        if bound <= self.max_bound:
            self.error_bound += bound
            return True
        fresh = self._lane_bound(LOW, D, H)  # a new lane: a random prime of the range
        if fresh >= 1.0:
            raise Undecided(f"a dependence of degree {D} and {H:.0f} bits is beyond these primes")
        lanes = max(math.ceil(math.log(self.max_bound) / math.log(fresh)) + 1, len(self.arith.primes) + 1)
        if lanes > MAX_LANES:
            raise Undecided(f"a dependence would need {lanes} lanes")
        self._build(lanes)
        return False


__all__ = ["TaylorRank", "Undecided", "MAX_LANES", "arithmetic_needs"]
