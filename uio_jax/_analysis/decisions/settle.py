"""Weak rank decisions, settled again beyond float64.

Every rank decision of an analysis is a vote of the sampled states (:mod:`.rank`): a
candidate raises the rank at a sample when its distance ``rho`` to the span (unit-scaled)
exceeds ``rtol``. Float64 cannot settle a decision whose evidence sits near ``rtol``: a
genuine direction of size 1e-8 after scaling, or round-off of a high-order derivative
that reaches it. Such a decision is **weak** (:func:`is_weak`) when

* the median of ``rho`` over the valid samples lies between 1e-13 and 1e-6 (with
  ``rtol = 1e-8``; :data:`WEAK_BELOW`, :data:`WEAK_ABOVE`): genuine directions of our
  models mostly sit at 1e-4..1 and round-off at 1e-16..1e-13 after scaling, but a genuine
  direction of a deep Lie derivative can come out at 1e-12 (order 13 of the 16-state
  visual-inertial model ``gyro_z_unknown``: median 1e-12.03, proved independent modulo p),
  so the band reaches well under ``rtol``; or
* the agreeing fraction of samples is below :data:`WEAK_FRACTION` (rank is the same at
  almost every state: a split vote means the evidence is near the tolerance somewhere
  on a large part of the domain, not a thin singular set).

A weak decision is settled again (:class:`Settler`) in the System's expression graph at
:data:`POINTS` random points:

* **exact modular arithmetic** when every node involved is rational: the rank of the
  gradients modulo ``p = 2^127 - 1`` at random points of ``F_p^n``
  (:class:`uio_jax._engine.graph_exact.ModularEvaluator`). A point where the candidate
  raises the rank proves it raises the generic rank (a point's rank never exceeds the
  generic one); "does not raise" holds unless every point is a root of a nonzero minor,
  with probability at most ``(D / p)^points``, ``D`` the minor's degree bound
  (Schwartz-Zippel; :attr:`Escalation.bound`, certified below :data:`MAX_BOUND`: points
  are added, up to :data:`MAX_POINTS`, while a deep derivative's ``D`` needs them);
* **extended precision** otherwise (mpmath at :data:`DIGITS` = 30 and 60 decimal digits at
  states of the sampling box): a genuine distance keeps its value between the two
  precisions, round-off shrinks below ``10^-(0.6 digits)``; a gradient whose norm is under
  that size is zero (its direction is rounding noise, never a row). Extended precision is
  also the arithmetic of a rational graph whose roots have no common point modulo ``p``
  (``sqrt(x)`` with ``sqrt(7 x)``: 7 is no square modulo ``2^127 - 1``).

Neither can decide (the points are singular; the two precisions disagree): the decision is **undecided**. The float64
majority is kept for the rest of the run, and the report says that its verdicts are not
certified (:attr:`uio_jax.Certificate.undecided`). Every escalation is recorded
(:class:`Escalation`) in the certificate.

A clear float64 vote that the rank rises is also checked exactly when the model is rational
(``Settler.settle(..., exact_only=True)``, from :meth:`uio_jax._analysis.decisions.rank.Codistribution._decide`):
round-off of a deep derivative can fake a rise with a clear vote, and one wrong generator
corrupts every later decision. A confirmation is counted (``Certificate.verified``), a
contradiction recorded as an escalation.
"""

import math

import numpy as np

from ..._calculus.generators import builder_for
from ..._engine import graph_elementary, graph_exact, graph_independence
from ..results.evidence import Escalation, Finding, Settlement
from ..results.kinds import Arithmetic

#: A decision is weak when the median ``log10 rho`` lies between ``log10 rtol`` minus
#: :data:`WEAK_BELOW` and plus :data:`WEAK_ABOVE` decades: from 1e-13 (round-off of our
#: scaled gradients mostly stays under it; a genuine direction of a deep Lie derivative can
#: be as small as 1e-12) to 1e-6. Below the band a rejection is taken as round-off, except
#: at a step that keeps nothing (:meth:`~uio_jax._analysis.decisions.rank.Codistribution.absorb`,
#: ``confirm_empty``), where every rejection is settled exactly (rational models).
WEAK_BELOW = 5.0
WEAK_ABOVE = 2.0

#: A decision is weak when fewer than this fraction of the valid samples agree.
WEAK_FRACTION = 0.9

#: Random points of an escalation: one settles a decision (a witness of independence is
#: certain; a dependence holds with a Schwartz-Zippel bound ``D / p``, ``p = 2^127 - 1``,
#: far below :data:`MAX_BOUND` for the degrees our graphs reach; above it the decision is
#: undecided). mpmath uses this many points too.
POINTS = 1

#: At most this many points settle a dependence modulo ``p`` (more are drawn, after
#: :data:`POINTS`, while the degree bound needs them: ``(D / p)^points <= MAX_BOUND``).
MAX_POINTS = 4

#: Most draws of one modular point where square roots' arguments are no squares modulo p
#: (each root halves the chance of a draw: 64 draws fail with probability ``(1 - 2^-r)^64``,
#: under 1e-3 up to ``r = 3`` roots).
SQUARE_DRAWS = 64

#: Decimal digits of the two mpmath evaluations.
DIGITS = (30, 60)

#: A dependence found modulo ``p`` is certified when the probability bound that every
#: point is a root of a nonzero minor stays below this (else: undecided).
MAX_BOUND = 1e-9

#: The default probability of correctness of the exact decisions (StructuralIdentifiability.jl's
#: default is 0.99; ours is stricter, and costs nothing: ``D / p`` is about 1e-30 per point).
DEFAULT_PROB_THRESHOLD = 0.999999

#: The number of modular dependences an analysis is assumed to decide at most: each gets
#: ``1 / DECISIONS_BUDGET`` of the allowed error ``1 - prob_threshold``.
DECISIONS_BUDGET = 10**6


def median_decades(rho, valid, rtol) -> float:
    """``median(log10 rho) - log10 rtol`` over the valid samples (rho = 0 counts as -inf)."""
    r = np.asarray(rho)[np.asarray(valid)]
    if r.size == 0:
        return math.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        logs = np.sort(np.log10(r))  # np.median's value (NaN first), at a tenth of its cost
        k = logs.size // 2
        mid = logs[-1] if np.isnan(logs[-1]) else logs[k] if logs.size % 2 else (logs[k - 1] + logs[k]) / 2
        return float(mid - math.log10(rtol))


def is_weak(rho, valid, rtol, fraction) -> bool:
    """Whether a vote needs settling (module docstring): its median between
    :data:`WEAK_BELOW` decades under ``rtol`` and :data:`WEAK_ABOVE` over it, or an agreeing
    ``fraction`` below :data:`WEAK_FRACTION`."""
    return -WEAK_BELOW < median_decades(rho, valid, rtol) < WEAK_ABOVE or fraction < WEAK_FRACTION


class Settler:
    """Settles weak decisions of one analysis in its System's expression graph.

    The points are drawn once per Settler and every node evaluated there is kept
    (:class:`~uio_jax._engine.graph_exact.ModularEvaluator`,
    :class:`~uio_jax._engine.graph_exact.ExtendedEvaluator`): the escalations of one
    analysis evaluate each generator once.

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph` of the System.
        lo, hi: the sampling box ``(n,)`` (mpmath points are drawn in it; the columns are
            scaled by its widths, as in the float64 test).
        seed: seed of the points.
        prob_threshold: the probability of correctness asked for: a dependence modulo p is
            certified when its bound is under ``(1 - prob_threshold) / DECISIONS_BUDGET``
            (and :data:`MAX_BOUND`), so that the union bound over the decisions of an
            analysis, :attr:`error_bound`, stays under ``1 - prob_threshold``.

    Attributes:
        error_bound: the sum of the probability bounds of the dependences found modulo p
            (each question once): the probability that one of them is wrong.
    """

    def __init__(self, graph, lo, hi, seed, prob_threshold: float = DEFAULT_PROB_THRESHOLD):
        self.graph = graph
        self.max_bound = min(MAX_BOUND, (1.0 - prob_threshold) / DECISIONS_BUDGET)
        self.error_bound = 0.0
        self.lo, self.hi = np.asarray(lo, float), np.asarray(hi, float)
        self.rng = np.random.default_rng([int(seed), 0x5E771E])
        self._modular = {}  # point number -> ModularEvaluator at that point
        self._echelons = {}  # point -> {kept expressions: Echelon}
        self._rational_nodes = set()  # nodes known to be rational (or made rational)
        self._pointed = set()  # nodes whose roots exist at a modular point found
        self._rootless = set()  # roots with no common point modulo p found (with others)
        self._generators = {}  # the elementary generators met so far, checked independent
        #: why the graph is not made rational, where a relation between its elementary
        #: functions was found ("" otherwise)
        self.not_rational = ""
        self._degrees = {}  # node -> degree bounds (graph_exact.degrees)
        self._extended = None  # per point, one ExtendedEvaluator per precision
        self._answers = {}  # (kept expressions, candidate expression) -> settled Escalation

    def settle(self, kept, candidate, float64: str, exact_only: bool = False,
               vote: Finding | None = None) -> Escalation | None:
        """Does ``candidate`` raise the generic rank of ``span{d k : k in kept}``?

        Args:
            kept: the Nodes of the span (their gradients independent).
            candidate: the Node tested.
            float64: the float64 vote and its evidence, for the record.
            exact_only: settle only where exact modular arithmetic applies (a rational
                graph); None otherwise (a clear float64 vote being verified).
            vote: the float64 vote itself (:class:`Finding`), None where there was none.
        """
        what = f"{candidate.label} against rank {len(kept)}"
        exprs = [nd.expr for nd in kept] + [candidate.expr]
        known = self._answers.get(tuple(exprs))
        if known is not None:  # the same question again (the final span re-decided): the
            return known       # same answer, the same record (kept once in a certificate)
        arithmetic = self.arithmetic(exprs)
        if arithmetic is not Arithmetic.EXACT and exact_only:
            return None
        coords = self.graph.coords  # a membership of d z_i (ctx.unit_nodes), not a generator that is z_i
        unit = coords.index(candidate.expr) if candidate.expr in coords else None
        unit = unit if unit is not None and candidate.label == f"e_{unit}" else None
        record = {"what": what, "float64": float64, "vote": vote, "coordinate": unit}
        if arithmetic is Arithmetic.EXACT:
            answer = self._settle_modular(record, exprs)
        else:
            answer = self._settle_extended(record, exprs)
        self._answers[tuple(exprs)] = answer
        return answer

    def arithmetic(self, exprs, roots_in_extension: bool = False) -> Arithmetic:
        """The arithmetic of decisions on the graph nodes ``exprs`` and on what is built from
        them (every derivative of a node made rational is made rational): the one place where
        it is chosen. :attr:`Arithmetic.EXACT` (modulo p) where every node behind them is
        rational or an elementary function made rational by independent generators, and a
        point modulo ``p = 2^127 - 1`` where their roots exist is found (:meth:`_has_point`;
        not asked with ``roots_in_extension``: the Taylor route takes roots in ``F_p[i]``,
        where every residue has its square roots); :attr:`Arithmetic.EXTENDED` (mpmath at
        two precisions) otherwise."""
        exprs = [e for e in exprs if e is not None]
        rational = self._rational(exprs) and (roots_in_extension or self._has_point(exprs))
        return Arithmetic.EXACT if rational else Arithmetic.EXTENDED

    def vanishes(self, exprs) -> tuple[bool, str]:
        """Whether the graph nodes ``exprs`` all vanish identically (a zero test of the general
        solution), decided beyond float64: ``(zero, how)``.

        Modulo p where the graph is made rational: a nonzero value at a random point proves
        "not zero"; zero values are "zero" with probability bound ``D / p`` per point (points
        added while the degree bound needs them, as for a dependence; the bound is added to
        :attr:`error_bound`). Elsewhere mpmath at two precisions (zero when under
        ``10^-(0.6 digits)`` at both, nonzero when the two agree on a larger value).
        ``how`` is ``""`` where neither applies (no expression, or the precisions disagree):
        the caller's float64 vote stands.
        """
        exprs = [e for e in exprs if e is not None]
        if not exprs:
            return True, "exact mod p"
        if self.arithmetic(exprs) is Arithmetic.EXACT:
            p, degree = graph_exact.PRIME, None
            for point in range(MAX_POINTS):
                ev = self._modular_evaluator(point, exprs)
                if ev is None:
                    return False, ""
                if any(int(ev.V[e][0]) % p for e in exprs):
                    return False, "exact mod p"
                if degree is None:
                    degree = max(num + den for num, den in graph_exact.degrees(self.graph, exprs, self._degrees))
                bound = min(1.0, degree / p) ** (point + 1)
                if bound <= self.max_bound:
                    self.error_bound += bound
                    return True, "exact mod p"
            return False, ""
        self._extended_points()
        verdicts = set()
        for spans in self._extended:
            values = [[abs(span.ev.gradients([e])[0][0]) for e in exprs] for span in spans]
            tiny1, tiny2 = [10.0 ** (-0.6 * d) for d in DIGITS]
            if all(v < tiny2 for v in values[1]) and all(v < tiny1 for v in values[0]):
                verdicts.add(True)
            elif any(v > tiny1 and abs(a - v) <= 1e-6 * v for a, v in zip(values[0], values[1])):
                verdicts.add(False)
            else:
                return False, ""
        return (verdicts == {True}), "mpmath"

    def values_mod_p(self, exprs):
        """The residues of the graph nodes ``exprs`` at the first random point modulo p, or
        None where the graph is not made rational (or every point drawn is singular)."""
        if self.arithmetic(exprs) is not Arithmetic.EXACT:
            return None
        ev = self._modular_evaluator(0, exprs)
        return None if ev is None else [int(ev.V[e][0]) % graph_exact.PRIME for e in exprs]

    def add_bound(self, bound: float) -> None:
        """Charge the probability bound of decisions made elsewhere for this analysis (the
        verification of its symmetries, :mod:`.symmetry`) to :attr:`error_bound`."""
        self.error_bound += float(bound)

    def values_extended(self, exprs) -> list:
        """The values (mpmath numbers, at the higher precision of :data:`DIGITS`) of the graph
        nodes ``exprs`` at the first extended-precision point, drawn in the box."""
        self._extended_points()
        ev = self._extended[0][-1].ev
        return list(ev.gradients(list(exprs))[0])

    def count_bound(self, exprs, minors: int, size: int) -> None:
        """Add to :attr:`error_bound` the Schwartz-Zippel bound of ``minors`` decisions, each
        on a minor of at most ``size`` rows of the nodes ``exprs``, taken at one point."""
        if minors and exprs:
            degree = max(num + den for num, den in graph_exact.degrees(self.graph, exprs, self._degrees))
            self.error_bound += minors * min(1.0, size * degree / graph_exact.PRIME)

    def _rational(self, exprs) -> bool:
        """Whether the nodes behind ``exprs`` are rational, or elementary functions made
        rational by independent generators (:mod:`uio_jax._engine.graph_elementary`; the
        independence is checked once per new set of generators). Memoized per node: the
        graphs of successive decisions share most of their nodes."""
        if self.not_rational:
            return False
        known = self._rational_nodes
        new = self.graph.reachable(exprs, known=known)
        if not new:
            return True
        if not all(graph_elementary.rationalizable(self.graph, k) for k in new):
            return False
        keys = graph_independence.generator_keys(self.graph, exprs, nodes=new)
        if keys.keys() - self._generators.keys():
            self._generators.update(keys)
            ok, self.not_rational = graph_independence.independent(self.graph, self._generators, self.rng)
            if not ok:
                return False
        known.update(new)
        return True

    def _has_point(self, exprs) -> bool:
        """Whether a point of ``F_p^n`` is found where the roots behind ``exprs`` exist: roots
        whose arguments are never squares together modulo p have no point of their variety
        there (``8.4/G`` and ``G/4.8``: their product 7/4 is no square modulo 2^127 - 1), and
        :data:`SQUARE_DRAWS` draws miss the one point in ``2^k`` of ``k`` unrelated roots
        for large ``k``. Memoized per node, as :meth:`_rational`: the roots of a failure are
        remembered, and only what is built on them is refused."""
        new = self.graph.reachable(exprs, known=self._pointed)
        roots = {k for k in new if self.graph.op[k] in graph_elementary.ALGEBRAIC}
        if roots & self._rootless:
            return False
        if roots and self._modular_evaluator(0, exprs) is None:
            self._rootless |= roots
            return False
        self._pointed.update(new)
        return True

    # ------------------------------------------------------------------ modulo p
    def _modular_evaluator(self, point: int, exprs):
        """The :class:`~uio_jax._engine.graph_exact.ModularEvaluator` of random point
        ``point`` of ``F_p^n`` with ``exprs`` evaluated (the point drawn again where a
        denominator vanishes, at most four times, or where a square root's argument is no
        square modulo p, which half the points are per root: at most :data:`SQUARE_DRAWS`
        times); None if every draw is singular."""
        singular = not_square = 0
        while singular < 4 and not_square < SQUARE_DRAWS:
            if self._modular.get(point) is None:
                # uniform modulo p (three 63-bit words, 189 bits, reduced: the bias is
                # below 2^-60), so that the Schwartz-Zippel bound D / p of a point holds
                words = self.rng.integers(0, 2**63, size=(self.graph.n, 3))
                draw = [((int(a) << 126) | (int(b) << 63) | int(c)) % graph_exact.PRIME for a, b, c in words]
                self._modular[point] = graph_exact.ModularEvaluator(self.graph, [draw])
            try:
                self._modular[point].evaluate(exprs)
                return self._modular[point]
            except graph_elementary.NotSquare:
                not_square += 1
            except graph_exact.Singular:
                singular += 1
            self._modular[point], self._echelons[point] = None, {}
        return None

    def _echelon(self, point: int, kept: tuple, evaluator):
        """The echelon form of the kept rows at ``point`` (cached by the kept expressions;
        a longer list of kept rows extends the form of its longest cached prefix)."""
        cache = self._echelons.setdefault(point, {})
        found = cache.get(kept)
        if found is not None:
            return found
        k = len(kept)
        while k and kept[:k] not in cache:
            k -= 1
        ech = cache[kept[:k]].copy() if k else graph_exact.Echelon()
        for i in range(k, len(kept)):
            ech.add(evaluator.row(kept[i], 0))
        cache[kept] = ech
        return ech

    def _settle_modular(self, record, exprs):
        """Independent at a point where the kept rows have full rank: certain. Dependent at
        every point so far: certified when ``(D / p)^points <= MAX_BOUND``, so points are
        added (up to :data:`MAX_POINTS`) while the degree bound ``D`` needs them. Kept rows
        of lower rank at a point (they are independent generically, so this is a root of
        one of their minors, or they are not): undecided."""
        p = graph_exact.PRIME
        r = len(exprs) - 1
        kept = tuple(exprs[:r])
        needed, degree, point = POINTS, None, 0
        while True:
            evaluator = self._modular_evaluator(point, exprs)
            if evaluator is None:
                return Escalation(**record, how=Settlement.EXACT, detail=": every point drawn was singular",
                                  result=Finding.UNDECIDED)
            ech = self._echelon(point, kept, evaluator)
            point += 1
            at = f" = 2^127 - 1 at {point} point{'s' if point > 1 else ''}"
            if ech.rank < r:
                return Escalation(**record, how=Settlement.EXACT, result=Finding.UNDECIDED,
                                  detail=at + f": the span has rank {ech.rank} < {r} there")
            if any(ech.reduce(evaluator.row(exprs[r], 0))):
                return Escalation(**record, how=Settlement.EXACT, detail=at, result=Finding.INDEPENDENT, bound=0.0)
            if point < needed:
                continue
            if degree is None:
                degree = sum(num + den for num, den in graph_exact.degrees(self.graph, exprs, self._degrees))
            bound = min(1.0, degree / p) ** point
            if bound <= self.max_bound:
                self.error_bound += bound
                return Escalation(**record, how=Settlement.EXACT, detail=at, result=Finding.DEPENDENT, bound=bound)
            needed = math.ceil(math.log(self.max_bound) / math.log(degree / p)) if degree < p else math.inf
            if needed > MAX_POINTS:
                return Escalation(**record, how=Settlement.EXACT, detail=at + f": degree bound {degree} too large",
                                  result=Finding.UNDECIDED, bound=bound)

    # ------------------------------------------------------------------ mpmath
    def _extended_points(self):
        """The mpmath evaluators (per point, one per precision), drawn once in the box."""
        if self._extended is None:
            scale = self.hi - self.lo
            points = [self.lo + self.rng.random(self.graph.n) * scale for _ in range(POINTS)]
            self._extended = [[_Orthonormal(graph_exact.ExtendedEvaluator(self.graph, pt, d), scale)
                               for d in DIGITS] for pt in points]

    def _settle_extended(self, record, exprs):
        r = len(exprs) - 1
        self._extended_points()
        independent = dependent = 0
        for spans in self._extended:
            rho1, rho2 = [span.distance(exprs[:r], exprs[r]) for span in spans]
            tiny1, tiny2 = [10.0 ** (-0.6 * d) for d in DIGITS]
            if rho1 is None or rho2 is None:
                continue  # the span is degenerate at this point
            if rho1 < tiny1 and rho2 < tiny2:
                dependent += 1
            elif rho2 > tiny1 and abs(rho1 - rho2) <= 1e-6 * rho2:
                independent += 1
                break  # one point where it is independent proves it
        digits = f" at {DIGITS[0]} and {DIGITS[1]} digits"
        if independent:
            return Escalation(**record, how=Settlement.EXTENDED, detail=digits, result=Finding.INDEPENDENT)
        if dependent == POINTS:
            return Escalation(**record, how=Settlement.EXTENDED, detail=digits + f" at {POINTS} points",
                              result=Finding.DEPENDENT)
        return Escalation(**record, how=Settlement.EXTENDED, detail=digits + ": the two precisions disagree",
                          result=Finding.UNDECIDED)


def model_roots(system, builder) -> list:
    """The graph nodes of ``system``'s outputs and fields (its drift, known and unknown input
    fields), in ``builder``'s graph: what every generator of an analysis is built from."""
    nodes = [*(builder.scalar(k, fn) for k, fn in system.outputs.items()),
             *(builder.field(label, fn) for label, fn in system.fields().items())]
    return [e for nd in nodes for e in ((nd.expr,) if isinstance(nd.expr, int) else nd.expr) if e is not None]


def new_settler(system, seed, prob_threshold=DEFAULT_PROB_THRESHOLD) -> Settler:
    """The :class:`~uio_jax._analysis.decisions.settle.Settler` of one analysis of ``system``
    (its graph, its sampling box)."""
    lo, hi = system.box()
    return Settler(builder_for(system).graph, lo, hi, seed, prob_threshold)


class _Orthonormal:
    """The kept rows at one point in mpmath, orthonormalized once (Gram-Schmidt, twice) and
    cached by the kept expressions: a longer list extends its longest cached prefix.

    Args:
        evaluator: the :class:`~uio_jax._engine.graph_exact.ExtendedEvaluator` of the point.
        scale: the column scale (box widths), as in the float64 test.
    """

    def __init__(self, evaluator, scale):
        self.ev = evaluator
        ctx = evaluator.ctx
        self.scale = [ctx.mpf(float(s)) for s in scale]
        self.tiny = ctx.mpf(10) ** (-int(0.6 * ctx.dps))
        self.cache = {(): []}  # kept expressions -> orthonormal rows (None: degenerate)

    def _residual(self, basis, expr):
        """``(rho, unit residual)`` of the scaled, unit-normalized gradient of ``expr``."""
        ctx = self.ev.ctx
        row = [g * s for g, s in zip(self.ev.gradients([expr])[1][0], self.scale)]
        norm = ctx.sqrt(ctx.fsum(v * v for v in row))
        if norm < self.tiny:  # a zero gradient computed with rounding (its direction is noise)
            return ctx.mpf(0), None
        v = [x / norm for x in row]
        for _ in range(2):
            for b in basis:
                c = ctx.fdot(v, b)
                v = [x - c * y for x, y in zip(v, b)]
        rho = ctx.sqrt(ctx.fsum(x * x for x in v))
        return rho, ([x / rho for x in v] if rho > 0 else None)

    def basis(self, kept: tuple):
        found = self.cache.get(kept)
        if found is not None or kept in self.cache:
            return found
        k = len(kept) - 1
        while kept[:k] not in self.cache:
            k -= 1
        basis = self.cache[kept[:k]]
        for i in range(k, len(kept)):
            if basis is None:
                break
            rho, direction = self._residual(basis, kept[i])
            basis = None if rho < self.tiny else basis + [direction]
            self.cache[kept[:i + 1]] = basis
        return basis

    def distance(self, kept, candidate):
        """Distance of the candidate to the span of the kept rows (a float), None when the
        kept rows are dependent at this point."""
        basis = self.basis(tuple(kept))
        if basis is None:
            return None
        return float(self._residual(basis, candidate)[0])


__all__ = ["model_roots", "new_settler", "DEFAULT_PROB_THRESHOLD", "DECISIONS_BUDGET", "WEAK_BELOW", "WEAK_ABOVE",
           "WEAK_FRACTION", "POINTS", "MAX_POINTS", "DIGITS", "MAX_BOUND", "SQUARE_DRAWS",
           "Settler", "is_weak", "median_decades"]
