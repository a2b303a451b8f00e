"""Generic-input output series: the rank test of STRIKE-GOLDD / StrikePy, without nested brackets.

For a system without unknown inputs, ``x' = f0(x) + sum_i f_i(x) u_i(t)``, ``y = h(x)``
(parameters included as states with ``p' = 0``), take the known inputs to be a *generic*
analytic input: ``u_i(t) = sum_k a_ik t^k`` with random coefficients ``a_ik`` drawn once
from the seed. Along the solution from ``x``, the output has the Taylor series
``y(t) = sum_k y_k(x) t^k`` with ``y_k = y^(k)(0) / k!``; ``y^(k)`` is the k-th time
derivative of the output, the function whose gradient STRIKE-GOLDD stacks into its
observability-identifiability matrix (there with symbolic ``u, u', ..., u^(k-1)``).
The rank at order K is

    r_K = rank [ dy_0 ; dy_1 ; ... ; dy_K ]    (p (K + 1) rows, n columns)

evaluated at every sampled state and certified like every other rank of the package.
For generic inputs ``r_K`` reaches the dimension of the observation space of
Hermann-Krener (the ORC's final codistribution): the ORC and this test give the same
final dimension and the same observable states, but the steps differ (ORC step m holds
every Lie derivative of order <= m along each field separately; order K here holds only
the combinations that appear in ``y^(K)``). Sedoglavic (2002), "A probabilistic algorithm
to test local algebraic observability in polynomial time", uses the same test.

Stopping: the increments ``r_K - r_(K-1)`` never increase (the observability indices of
the output filtration), so the first order that adds nothing closes the span; otherwise
the rank reaches n, or the cap (``max_order``, default n) is hit.

Cost: the coefficients are expressions of the System's graph (:class:`GraphCoefficients`),
their gradients evaluated by numpy: only the combinations in ``y^(K)`` are formed.
"""

import hashlib
import math

import numpy as np

from ..._engine.graph import Graph
from ..._errors import OptionError
from ..decisions.context import Context
from .driver import Cap, Recursion, StopReason, iterate


def check_applicable(system) -> None:
    """The series test needs every input known (unknown inputs: single_ui or EORC)."""
    if system.unknown:
        raise OptionError(
            f"method 'series' needs every input known, but {', '.join(system.unknown)} is unknown; "
            "use method='auto' (single_ui or EORC)"
        )


def input_coefficients(system, orders: int, seed: int) -> np.ndarray:
    """Coefficients ``a`` of shape ``(m_u, orders + 1)`` of the generic input (seeded).

    ``u_i(t) = sum_k a[i, k] t^k``; standard normal coefficients, the same for every
    sampled state (one generic input; its coefficients avoid the measure-zero set where
    the rank drops with probability 1).
    """
    rng = np.random.default_rng([seed, 0x5E41E5])
    # order by order, so that a[:, k] does not depend on how many orders are drawn
    cols = [rng.standard_normal(len(system.known)) for _ in range(orders + 1)]
    return np.stack(cols, axis=1).reshape(len(system.known), orders + 1)


class _Series:
    """Nodes ``y_k[h]`` of one System and generic input (expressions of its graph, built
    order by order on demand: :class:`GraphCoefficients`)."""

    def __init__(self, ctx: Context, seed: int, cap: int):
        self.system = ctx.system
        self.builder = ctx.builder
        self.a = input_coefficients(self.system, cap + 1, seed)
        self.tag = hashlib.sha256(self.a.tobytes()).hexdigest()[:16]
        self.outs = ctx.output_nodes()
        self.nodes = {}
        self.coefficients = GraphCoefficients.of(ctx, self.a, cap)

    def node(self, k, i):
        """The node ``y_k[h_i]`` (memoized by the builder)."""
        if (k, i) not in self.nodes:
            h = self.outs[i]
            if k == 0:
                self.nodes[k, i] = h
                return h
            self.nodes[k, i] = self.builder.node(
                ("series", self.tag, k, h.label),
                lambda: self.builder.make(f"y_{k}[{h.label}]", "scalar", k, self.coefficients.order(k)[i]))
        return self.nodes[k, i]

    def gradients(self, ctx: Context, k_lo, k_hi):
        """Gradients of every ``y_k`` for ``k_lo <= k <= k_hi`` at ``ctx``'s samples:
        ``(S, (k_hi - k_lo + 1) p, n)``."""
        p = len(self.outs)
        nodes = tuple(self.node(k, i) for k in range(k_lo, k_hi + 1) for i in range(p))
        return nodes, ctx.gradients(nodes)


class GraphCoefficients:
    """The coefficients ``y_k`` of every output as expressions of the System's graph,
    built order by order on demand.

    In a graph on ``[x; t]``: the generic input ``u_i(t) = sum_k a_ik t^k`` (Horner), the
    field ``F = [f0 + sum_i u_i(t) f_i; 1]``, ``y^(k) = L_F^k h`` by repeated symbolic
    derivatives; then ``t = 0`` (the expressions imported back into the System's graph)
    and ``y_k = y^(k) / k!``.
    """

    @classmethod
    def of(cls, ctx: Context, a, cap):
        """The coefficients of ``ctx``'s System."""
        system, g = ctx.system, ctx.builder.graph
        outs = ctx.output_nodes()
        known = [ctx.field_node(k) for k in system.known]
        drift = ctx.field_node("f0") if system.drift is not None else None
        return cls(g, [h.expr for h in outs], None if drift is None else drift.expr,
                   [f.expr for f in known], a, cap)

    def __init__(self, g, outs, drift, known, a, cap):
        n = g.n
        self.g, self.gt = g, Graph(n + 1)
        gt = self.gt
        x, t = gt.coords[:n], gt.x(n)
        F = list(gt.import_nodes(g, list(drift), x)) if drift is not None else [gt.zero] * n
        for i, f in enumerate(known):
            u = gt.zero
            for c in reversed(a[i, :cap + 1]):  # Horner: u = a_i0 + t (a_i1 + t (...))
                u = gt.add(gt.const(float(c)), gt.mul(t, u))
            F = [gt.add(Fj, gt.mul(u, fj)) for Fj, fj in zip(F, gt.import_nodes(g, list(f), x))]
        self.tangent = tuple(F) + (gt.one,)
        self.levels = [gt.import_nodes(g, list(outs), x)]  # y^(k) on [x; t]
        self.at_zero = tuple(g.coords) + (g.zero,)
        self.done = {}

    def order(self, k):
        """``[y_k[h] for h in outputs]``: nodes of the System's graph."""
        while len(self.levels) <= k:
            self.levels.append(self.gt.jvp(self.levels[-1], self.tangent))
        if k not in self.done:
            back = self.g.import_nodes(self.gt, self.levels[k], self.at_zero)
            self.done[k] = [self.g.div(e, self.g.const(math.factorial(k))) for e in back]
        return self.done[k]


class SeriesOrders(Recursion):
    """The orders ``k = 0, 1, ...`` of the series test as a
    :class:`~uio_jax._analysis.recursions.driver.Recursion`: step k absorbs ``dy_k`` (``p`` rows
    ``(S, p, n)``), ``Omega_k = span{dy_0 .. dy_k}``.

    Orders are evaluated in blocks (:meth:`_Series.gradients`): the first block reaches the
    fewest orders that could reach rank n, ``ceil(n / p) - 1``, a later one the fewest more
    orders that could reach rank n if every order added what the last one did (2 at least).

    Args:
        ctx: the analysis context.
        series: the nodes of the ``y_k``.
        cap: the highest order.
    """

    def __init__(self, ctx: Context, series: "_Series", cap: int):
        self.ctx, self.series, self.cap = ctx, series, cap
        n, p = ctx.system.n, len(ctx.system.outputs)
        self.chunk = max(1, math.ceil(n / max(p, 1)))
        self.computed, self.by_order, self.added = -1, {}, None

    def _order(self, k):
        """Nodes and gradients ``(S, p, n)`` of ``y_k``, evaluating the block from k on if
        it is not evaluated yet."""
        if k > self.computed:
            n, p = self.ctx.system.n, len(self.ctx.system.outputs)
            if self.added is not None:
                # an order adds at most what the last one added (non-increasing increments):
                # reaching rank n needs at least this many more orders (2 at least)
                self.chunk = max(2, math.ceil((n - self.ctx.dim) / len(self.added)))
            hi = min(self.cap, max(k + self.chunk - 1, k))
            nodes, grads = self.series.gradients(self.ctx, k, hi)
            for j in range(k, hi + 1):
                sl = slice((j - k) * p, (j - k + 1) * p)
                self.by_order[j] = (nodes[sl], grads[:, sl])
            self.computed = hi
        return self.by_order.pop(k)

    def init(self):
        """Omega_0 = span{dy_0} = span{dh}."""
        return self.step(0)

    def step(self, k):
        """Omega_k = Omega_{k-1} + span{dy_k}."""
        nodes, grads = self._order(k)
        self.added = self.ctx.absorb(list(nodes), grads)
        return self.ctx.step(k, self.added)

    def terminate(self, k, history):
        """Full rank n, else order k added nothing (no later order can)."""
        n = self.ctx.system.n
        if self.ctx.dim >= n:
            return StopReason.FULL_RANK_ORDER.stop(n=n, k=k)
        if not self.added:
            return StopReason.SPAN_CLOSED.stop(k=k)
        return None


#: The note of a series report on a model with known inputs.
SERIES_NOTE = ("series: rank of the output Taylor coefficients y_0..y_K along a generic known input "
               "(STRIKE-GOLDD's test); its final span equals the ORC's, its per-order dims are not the ORC's steps")


def run_series(ctx: Context, *, seed: int, max_order=None):
    """Absorb ``dy_k`` order by order (:class:`SeriesOrders`), on the decision samples of
    ``ctx`` (the final span is certified on all of them when the report is built).

    Returns:
        ``(history, stop, k_reached)``: one Step per order ``k = 0..K`` (``Step.dim =
        rank [dy_0; ..; dy_k]``), the :class:`~uio_jax._analysis.recursions.driver.Stop`, ``K``.
    """
    n = ctx.system.n
    cap = n if max_order is None else int(max_order)
    series = _Series(ctx, seed, cap)
    out = iterate(SeriesOrders(ctx, series, cap), cap=Cap(cap, StopReason.MAX_ORDER.stop(max_order=cap)))
    return out.history, out.stop, out.m


def series_report(ctx: Context, *, seed: int, notes=(), max_order=None):
    """Run the generic-input series test on ``ctx`` and build its Report."""
    check_applicable(ctx.system)
    history, reason, k = run_series(ctx, seed=seed, max_order=max_order)
    notes = list(notes)
    if ctx.system.known:
        notes.append(SERIES_NOTE)
    return ctx.report("series", history, reason, notes=notes, details={"order": k})


__all__ = ["series_report", "run_series", "input_coefficients", "check_applicable", "SERIES_NOTE",
           "GraphCoefficients"]
