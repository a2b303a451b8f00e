"""The ORC of a model without inputs, and the series test, through the output's Taylor
series at one random point modulo p: Sedoglavic's route, for large models.

Without inputs (``z' = F(z)`` on ``z = [x; p]``) the ORC's codistribution after step ``m`` is
``span{d L_F^j h_i : j <= m}``; with every input known, the series test's order ``k`` is
``span{d y_j : j <= k}`` along a generic input (:mod:`.series`). Both are the spans of the
gradients of the output's Taylor coefficients ``y_j = L_F^j h / j!`` at ``t = 0``, which
:class:`uio_jax._engine.taylor.TaylorSeries` computes *numerically*, order by order, with
their gradients, at random points of ``F_p^N`` for random primes ``p`` below ``2^26`` (int64
arithmetic): no symbolic Lie derivative is built. The symbolic route's graph of ``L_F^j h``
grows with every order (a single-output chain with parameters: 500 000 nodes and 2.7 GB at
60 variables, out of memory at 100); here the cost is ``O(|products| K^2 N)`` for ``K``
orders and ``N`` coordinates, and the memory ``O(|history| K N)``.

Every rank decision is exact (:class:`uio_jax._engine.taylor_rank.TaylorRank`): a row that
raises the rank at a point raises the generic rank (certain); a row that does not is
dependent with a probability of error bounded from the degree and the height of the minor
(:mod:`uio_jax._engine.taylor_degrees`), with as many primes as that bound needs, summed over
the decisions into ``Certificate.error_bound``. The float64 Taylor series at a few sampled
states give the margins and the singular values of the report (:class:`.taylor_space.TaylorSpace`).

:func:`taylor_applicable` says when the engine takes this route (once per analysis):
no unknown input, no known input for the ORC (its steps are the orders only then), every
node with a Taylor rule and made rational with independent generators, and at least
:data:`TAYLOR_MIN_VARIABLES` coordinates.
"""

from fractions import Fraction

import numpy as np

from ..._engine.graph import exact_literal
from ..._engine.graph_elementary import Singular
from ..._engine.taylor import TaylorSeries, Unsupported, program
from ..._engine.taylor_degrees import TaylorDegrees
from ..._engine.taylor_rank import TaylorRank, Undecided
from ..._model.smooth_inputs import known_coordinates
from ..decisions.answer import decide_answer
from ..decisions.taylor_space import TaylorSpace, taylor_certificate
from ..results.evidence import Step
from ..results.kinds import Arithmetic, Route
from .driver import Cap, Recursion, StopReason, iterate
from .series import SERIES_NOTE, input_coefficients

#: The Taylor route serves models with at least this many coordinates (states and
#: parameters). Smaller ones take the symbolic route: both take under 0.06 s there (the
#: chain of 24 variables: 0.06 s Taylor, 0.21 s symbolic; ``BENCHMARKS.md``), and its
#: generators are graph nodes that the naming of observable functions and the search for
#: symmetries test candidates against (:mod:`.observable_functions`, :mod:`.found_symmetries`).
TAYLOR_MIN_VARIABLES = 24

class NotTaken(Exception):
    """The Taylor route cannot decide this model (every point drawn singular, a bound too
    large): the symbolic route runs instead."""


def taylor_applicable(system, graph, roots, arithmetic, method: str, any_size: bool = False) -> bool:
    """Whether ``method`` (``"orc"`` or ``"series"``) on ``system`` takes the Taylor route
    (module docstring): ``roots`` are the graph nodes of its outputs and fields (in ``graph``)
    and ``arithmetic`` the arithmetic of their decisions (the plan's); ``any_size``: below
    :data:`TAYLOR_MIN_VARIABLES` coordinates too (the symbolic route is not exact there)."""
    if system.unknown or known_coordinates(system) or (system.n < TAYLOR_MIN_VARIABLES and not any_size):
        return False
    if method == "orc" and system.known:
        return False
    if arithmetic is not Arithmetic.EXACT:
        return False
    try:
        program(graph, roots)
    except Unsupported:
        return False
    return True


class _Problem:
    """The model as the Taylor engine takes it: fields, input coefficients, outputs."""

    def __init__(self, ctx, method, seed, cap):
        system = ctx.system
        self.graph, self.n = ctx.builder.graph, system.n
        labels = ["f0"] + list(system.known)
        self.fields = [list(ctx.field_node(lbl).expr) if lbl in system.fields() else [None] * self.n
                       for lbl in labels]
        a = input_coefficients(system, cap + 1, seed) if system.known else np.zeros((0, cap + 2))
        self.inputs = [[exact_literal(float(v)) or Fraction(0) for v in row] for row in a]
        self.outputs = [nd.expr for nd in ctx.output_nodes()]
        self.names = list(system.outputs)
        self.cap = cap
        self.method = method

    def roots(self):
        """The outputs and the fields' entries (the program's roots)."""
        return list(self.outputs) + [v for f in self.fields for v in f if v is not None]

    def series(self, arithmetic, orders=None, roots=()):
        return TaylorSeries(self.graph, self.fields, self.inputs, list(self.outputs) + list(roots), arithmetic,
                            self.cap if orders is None else orders)

    def label(self, k, i):
        """``L_f0^k h`` as the ORC names it; ``y_k[h]`` as the series test does."""
        if k == 0:
            return self.names[i]
        return " ".join(["L_f0"] * k + [self.names[i]]) if self.method == "orc" else f"y_{k}[{self.names[i]}]"


class _Orders:
    """The rows ``d y_k[h_i]`` absorbed order by order, decided modulo random machine-word
    primes at random points (:class:`uio_jax._engine.taylor_rank.TaylorRank`)."""

    def __init__(self, problem, seed, max_bound):
        self.problem = problem
        ins = program(problem.graph, problem.roots())[0]
        try:
            self.rank = TaylorRank(problem.series, ins, problem.outputs[0], problem.n, seed, max_bound)
        except Undecided as exc:
            raise NotTaken(str(exc)) from None
        self.bounds = TaylorDegrees.of(self.rank.series, problem.cap)
        self.kept = []  # (k, i) of the kept rows

    @property
    def dim(self) -> int:
        return self.rank.rank

    @property
    def arith(self):
        return self.rank.arith

    @property
    def error_bound(self) -> float:
        return self.rank.error_bound

    @property
    def decisions(self) -> int:
        return self.rank.decisions

    def absorb(self, k, outputs):
        """Offer ``d y_k[h_i]`` for ``i`` in ``outputs``: the ones that raised the rank."""
        added = []
        for i in outputs:
            node = self.problem.outputs[i]
            slot = self.rank.series.slot[node]
            if self._decide(self.rank.offer, lambda s, node=node: s.coefficient(node, k)[:, 1:],
                            lambda slot=slot: (self.bounds.degree(slot, k), self.bounds.row_bits(slot, k))):
                added.append(i)
                self.kept.append((k, i))
        return added

    def member(self, row) -> bool:
        """Whether ``row`` (``(N,)`` integers) lies in the span (a dependence: its bound counted)."""
        return self._decide(self.rank.member, lambda s: np.asarray(row, dtype=np.int64), lambda: (0, 0.0))

    def _decide(self, how, rows_of, bounds):
        try:
            return how(rows_of, bounds)
        except Undecided as exc:
            raise NotTaken(str(exc)) from None
        except Singular:
            raise NotTaken("a denominator vanishes at the random point") from None


class TaylorOrders(Recursion):
    """The orders ``k = 0, 1, ...`` of the Taylor route as a
    :class:`~uio_jax._analysis.recursions.driver.Recursion`: step k offers ``d y_k[h_i]`` (the ORC only
    for the outputs whose previous coefficient was kept: it differentiates the generators
    kept at the last step) and stops as the ORC or the series test stops.

    Args:
        problem: the model (:class:`_Problem`).
        orders: the decisions at the random point (:class:`_Orders`).
        max_order: the ORC's cap on m (None: none but n); the series' cap is ``problem.cap``.
    """

    def __init__(self, problem, orders, max_order=None):
        self.problem, self.orders, self.max_order = problem, orders, max_order
        self.alive = list(range(len(problem.outputs)))
        self.added = []

    def init(self):
        return self.step(0)

    def step(self, k):
        self.added = self.orders.absorb(k, self.alive)
        if self.problem.method == "orc":
            self.alive = self.added
        return Step(k, self.orders.dim, tuple(self.problem.label(k, i) for i in self.added), 1.0)

    def terminate(self, k, history):
        n, rank = self.problem.n, self.orders.dim
        if self.problem.method == "orc":  # as orc.Orc.terminate
            if k > 0 and not self.added:
                return StopReason.CONVERGED.stop(m=k, prev=k - 1)
            if rank >= n:
                return StopReason.FULL_RANK.stop(n=n, m=k)
            return None
        if rank >= n:  # as series.SeriesOrders.terminate
            return StopReason.FULL_RANK_ORDER.stop(n=n, k=k)
        if not self.added:
            return StopReason.SPAN_CLOSED.stop(k=k)
        return None

    def cap(self) -> Cap:
        """The driver's cap: the ORC's ``max_order`` (else ``n``, never reached: each order
        that does not converge raises the rank), the series' highest order."""
        if self.problem.method == "orc" and self.max_order is None:
            return Cap(self.problem.n, StopReason.STEP_CAP.stop(cap=self.problem.n))
        top = self.max_order if self.problem.method == "orc" else self.problem.cap
        return Cap(top, StopReason.MAX_ORDER.stop(max_order=top))


def taylor_report(ctx, method: str, *, seed: int, why: str = "", max_order=None, notes=()):
    """The Report of the ORC (no input) or the series test on ``ctx``'s System by the Taylor
    route (module docstring).

    Raises:
        NotTaken: the route cannot decide here (the caller runs the symbolic route).
    """
    from ..results.report import SEMANTICS, Report

    system = ctx.system
    cap = system.n if (method == "orc" or max_order is None) else int(max_order)
    problem = _Problem(ctx, method, seed, cap)
    orders = _Orders(problem, seed, ctx.settler.max_bound)
    orders_run = TaylorOrders(problem, orders, max_order if method == "orc" else None)
    out = iterate(orders_run, cap=orders_run.cap())
    history, stop, k = out.history, out.stop, out.m
    observable = {name: orders.member([int(i == j) for i in range(system.n)]) for j, name in enumerate(system.states)}
    space = TaylorSpace(ctx, problem, orders)
    cert = taylor_certificate(ctx, space, orders)
    primes = orders.rank.primes
    route = (f"decided on the output's Taylor series at random points modulo {len(primes)} random "
             f"prime{'s' if len(primes) > 1 else ''} below 2^26 (Sedoglavic's route: {k + 1} orders, no symbolic "
             "Lie derivative)")
    notes = [why] if why else []
    if method == "series" and system.known:
        notes.append(SERIES_NOTE)
    notes.append(route)
    details = {"order": k} if method == "series" else {}
    return Report(
        method=method, states=system.states, dim=orders.dim, observable=observable,
        history=tuple(history), certificate=cert,
        generators=tuple(problem.label(kk, i) for kk, i in orders.kept), stop=stop,
        answer=decide_answer(method, stop, details, cert.arithmetic), route=Route.TAYLOR,
        notes=tuple(system.notes) + tuple(notes), details=details,
        system_name=system.name, params=system.joint_param_names,
        known_inputs="switchable" if system.known else "none", semantics=SEMANTICS, space=space)


__all__ = ["TAYLOR_MIN_VARIABLES", "NotTaken", "taylor_applicable", "taylor_report"]
