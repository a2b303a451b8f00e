"""The observable space of an analysis decided by the Taylor route
(:mod:`.taylor_route`), as a Report reads it (:class:`~uio_jax._analysis.decisions.space.Space`).

The kept generators are output Taylor coefficients ``y_k[h_i]``, never built as graph
nodes: their gradients at a state are computed again by the Taylor engine, in float64
(:class:`uio_jax._engine.taylor.Float`), in mpmath where float64 cannot separate them
(:class:`~uio_jax._engine.taylor.Extended`), and modulo p at the analysis' random point for
``is_observable`` (an exact membership test, its Schwartz-Zippel bound reported).
"""

from collections.abc import Mapping

import numpy as np

from ..._engine import graph_elementary, graph_exact
from ..._engine.taylor import Extended, Float, TaylorSeries, Unsupported
from ..._engine.taylor_degrees import TaylorDegrees
from ..._errors import ModelError
from ..results.evidence import Certificate
from ..results.kinds import Arithmetic
from .sampled_rank import ratios
from .space import EXTENDED_DIGITS, Space, annihilator_extended, function_node

#: The float64 margins and singular values are taken at this many sampled states at most
#: (they decide nothing), and at one from :data:`MARGIN_ONE_FROM` coordinates on: each sample
#: costs as much as the exact decisions (one series, the same program), which dominate there.
MARGIN_SAMPLES = 4
MARGIN_ONE_FROM = 100
#: Decimal digits of the directions where float64 cannot separate the kept gradients, tried
#: in turn: the rows of deep orders can be separated by 70 decades at a generic state.
EXTENDED_PRECISIONS = (EXTENDED_DIGITS, 4 * EXTENDED_DIGITS, 16 * EXTENDED_DIGITS)


class TaylorSpace(Space):
    """The span of the kept ``d y_k[h_i]`` (``problem``, ``orders``: the route's model and its
    decisions; ``ctx``: the analysis context, for the samples, the box and the graph)."""

    def __init__(self, ctx, problem, orders):
        self._ctx, self._problem, self._orders = ctx, problem, orders
        self._kept = list(orders.kept)
        self._top = max((k for k, _ in self._kept), default=0)
        self.rtol = ctx.codist.rtol
        lo, hi = ctx.system.box()
        self._width = hi - lo
        xs = ctx.xs[ctx.defined[:len(ctx.xs)]][:MARGIN_SAMPLES if ctx.system.n < MARGIN_ONE_FROM else 1]
        self.samples = xs
        with np.errstate(all="ignore"):  # deep orders may overflow at a sample: dropped there
            self.grads = self._gradients(Float(xs)) if len(xs) else np.zeros((0, len(self._kept), ctx.system.n))

    def _gradients(self, arithmetic):
        """``(P, r, N)``: the gradients of the kept coefficients at ``arithmetic``'s points."""
        series = self._problem.series(arithmetic, orders=self._top)
        rows = [series.coefficient(self._problem.outputs[i], k)[:, 1:] for k, i in self._kept]
        if not rows:
            return np.zeros((len(arithmetic.points), 0, self._problem.n), dtype=arithmetic.dtype)
        return np.stack(rows, axis=1)

    def unobservable_directions(self, x, at=None) -> np.ndarray:
        """The null space ``(n, n - dim)`` of the kept gradients at the state ``x (n,)`` (in
        mpmath where float64 cannot separate them, at the digits of :data:`EXTENDED_PRECISIONS`
        in turn: refused only at a state singular at the last)."""
        n = self._problem.n
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (n,):
            raise ModelError(f"state must have shape ({n},), got {x.shape}")
        if not np.isfinite(x).all():
            raise ModelError("state contains NaN/inf")
        if at is not None:
            raise ModelError("this report's model does not depend on time: no time to give")
        r = len(self._kept)
        if r == 0:
            return np.eye(n)
        if r == n:
            return np.zeros((n, 0))
        with np.errstate(all="ignore"):
            g = self._gradients(Float(x[None]))[0]
        if not np.isfinite(g).all():
            raise ModelError("the codistribution is not defined at this state (NaN/inf)")
        g = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        _, sv, vt = np.linalg.svd(g)
        if sv[min(r, n) - 1] >= self.rtol * sv[0]:
            return vt[r:].T.copy()
        for dps in EXTENDED_PRECISIONS:  # deep orders are ill-conditioned, not singular
            ar = Extended(x[None], dps)
            grads = [list(row) for row in self._gradients(ar)[0]]
            try:
                return annihilator_extended(ar.ctx, grads, n, r, dps)
            except ModelError:
                if dps == EXTENDED_PRECISIONS[-1]:
                    raise

    def is_observable(self, fn) -> bool:
        """Whether ``d fn`` lies in the span, decided modulo p at the analysis' random point
        (a membership: its bound is added to the certificate's error bound).

        Raises:
            ModelError: as :func:`~uio_jax._analysis.decisions.space.function_node`; a function with a
                node outside the exact route (no Taylor rule, or not made rational).
        """
        n = self._problem.n
        node = function_node(self._ctx.builder, fn, n, n)
        if self._ctx.settler.arithmetic([node.expr]) is not Arithmetic.EXACT:
            raise ModelError("is_observable: the function uses an operation that is not decided exactly here")
        try:
            return self._member(node.expr, self._orders.arith)
        except Unsupported as exc:
            raise ModelError(f"is_observable: {exc}") from None
        except graph_elementary.Singular:
            raise ModelError("is_observable: the function's denominator vanishes at the analysis' point") from None
        except ArithmeticError as exc:  # taylor_rank.Undecided
            raise ModelError(f"is_observable: not decided modulo machine-word primes ({exc})") from None

    def naming_graph(self):
        """``(graph, roots, names)``: the model's expression graph, the nodes of its outputs
        and fields (where the candidates of named functions are read), the coordinates' names."""
        p = self._problem
        roots = list(p.outputs) + [e for f in p.fields for e in f if e is not None]
        return p.graph, roots, tuple(self._ctx.system.states)

    def rows_at_point(self, nodes):
        """``{node: gradient row}`` modulo ``p = 2^127 - 1`` at one random point of the nodes
        made rational and defined there (the others left out): rows to tell the named
        functions apart (an independence at a point is certain); their membership in the span
        is :meth:`member`'s."""
        graph = self._problem.graph
        rng = np.random.default_rng([int(self._ctx.seed), 0x9A111])
        point = [int(v) for v in rng.integers(1, 2**62, size=graph.n)]
        ev = graph_exact.ModularEvaluator(graph, [point])
        out = {}
        for node in nodes:
            if self._ctx.settler.arithmetic([node]) is not Arithmetic.EXACT:
                continue
            try:
                ev.evaluate([node])
            except (graph_elementary.Singular, ValueError):
                continue
            out[node] = [int(v) for v in ev.row(node, 0)]
        return out

    def member(self, node) -> bool:
        """Whether the gradient of the graph node ``node`` (a function of the coordinates)
        lies in the span: the route's own exact membership in every lane, its bound counted in
        :attr:`error_bound` (False where it is not decided)."""
        try:
            return self._member(node, self._orders.rank.arith)
        except (Unsupported, graph_elementary.Singular, ArithmeticError):
            return False

    def _member(self, expr, arith) -> bool:
        """The exact membership of ``d expr`` in the span (the route's own, in every lane), its
        output series first built in ``arith``; raises what the series raises."""
        problem, rank = self._problem, self._orders.rank

        def series_at(arithmetic):
            return TaylorSeries(problem.graph, problem.fields, problem.inputs, [expr], arithmetic, 0)

        series = series_at(arith)
        slot = series.slot[expr]
        bounds = TaylorDegrees.of(series, 0)
        return rank.member(lambda s: series_at(s.ar).coefficient(expr, 0)[:, 1:],
                           lambda: (bounds.degree(slot, 0), bounds.row_bits(slot, 0)))

    @property
    def error_bound(self) -> float:
        """The sum of the bounds of the decisions made at the analysis' point so far."""
        return self._orders.error_bound

    def sample_singular_values(self) -> np.ndarray:
        """``(S_used, r)`` ratios ``s_i / s_1`` at the margin samples (box-scaled columns)."""
        if not len(self._kept):
            return np.zeros((len(self.samples), 0))
        with np.errstate(all="ignore"):
            r = ratios(self.grads * self._width)
        return r[np.isfinite(r).all(axis=1)]

    @property
    def domain(self) -> Mapping:
        return self._ctx.system.domain

    def rank_ratio_at(self, z) -> float | None:
        """``s_r / s_1`` of the kept gradients at ``z (n,)`` (box-scaled columns, unit rows)."""
        if not self._kept:
            return None
        with np.errstate(all="ignore"):
            g = self._gradients(Float(np.asarray(z, dtype=np.float64)[None]))[0] * self._width
        if not np.isfinite(g).all():
            return 0.0
        g = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        s = np.linalg.svd(g, compute_uv=False)
        return float(s[-1] / s[0]) if s[0] > 0 else 0.0


def taylor_certificate(ctx, space: TaylorSpace, orders) -> Certificate:
    """The certificate of a Taylor-route analysis: every decision exact (modulo p at one
    random point), the float64 margins at :data:`MARGIN_SAMPLES` sampled states."""
    r = ratios_at = space.sample_singular_values()
    used = len(ratios_at)
    last = r[:, -1] if r.shape[1] else np.ones(used)
    fraction = float(np.mean(last >= space.rtol)) if used else 1.0
    conditioning = float(last.min()) if used else 1.0
    return Certificate(
        samples=ctx.samples, used=used, dropped=len(space.samples) - used, fraction=fraction,
        min_fraction=1.0, sigma_r_min=1.0, sigma_next_max=0.0, rtol=space.rtol, decisions=orders.decisions,
        conditioning=conditioning, capped=ctx.samples - len(space.samples), exact_decisions=orders.decisions,
        error_bound=orders.error_bound, prime=orders.rank.primes[0], prob_threshold=ctx.prob_threshold,
        screen_only=True)


__all__ = ["TaylorSpace", "taylor_certificate", "MARGIN_SAMPLES"]
