"""The ORC of a model without inputs, and the series test, through the output's Taylor
series at one random point modulo p: Sedoglavic's route, for large models.

Without inputs (``z' = F(z)`` on ``z = [x; p]``) the ORC's codistribution after step ``m`` is
``span{d L_F^j h_i : j <= m}``; with every input known, the series test's order ``k`` is
``span{d y_j : j <= k}`` along a generic input (:mod:`.series`). Both are the spans of the
gradients of the output's Taylor coefficients ``y_j = L_F^j h / j!`` at ``t = 0``, which
:class:`uio_jax._engine.taylor.TaylorSeries` computes *numerically*, order by order, with
their gradients, at a random point of ``F_p^N`` (``p = 2^127 - 1``): no symbolic Lie
derivative is built. The symbolic route's graph of ``L_F^j h`` grows with every order (a
single-output chain with parameters: 500 000 nodes and 2.7 GB at 60 variables, out of
memory at 100); here the cost is ``O(|graph| K^2 N)`` for ``K`` orders and ``N``
coordinates, and the memory ``O(|graph| K N)`` (100 variables: 5 s, 0.3 GB).

Every rank decision is exact: a row that raises the rank at the point raises the generic
rank (certain); a row that does not is dependent with probability of error at most
``D / p`` (Schwartz-Zippel, ``D`` the degree bound of the minor,
:class:`uio_jax._engine.taylor_degrees.TaylorDegrees`), summed over the decisions into
``Certificate.error_bound``. The float64 Taylor series at a few sampled states give the
margins and the singular values of the report (:class:`.taylor_space.TaylorSpace`).

:func:`taylor_applicable` says when the engine takes this route (once per analysis):
no unknown input, no known input for the ORC (its steps are the orders only then), every
node with a Taylor rule and made rational with independent generators, and at least
:data:`TAYLOR_MIN_VARIABLES` coordinates.
"""

from fractions import Fraction

import numpy as np

from ..._engine import graph_elementary, graph_exact
from ..._engine.graph import exact_literal
from ..._engine.taylor import Modular, TaylorSeries, Unsupported, program
from ..._engine.taylor_degrees import TaylorDegrees
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
#: Draws of the random point where a denominator vanishes there.
DRAWS = 4


class NotTaken(Exception):
    """The Taylor route cannot decide this model (every point drawn singular, a bound too
    large): the symbolic route runs instead."""


def taylor_applicable(system, graph, roots, arithmetic, method: str) -> bool:
    """Whether ``method`` (``"orc"`` or ``"series"``) on ``system`` takes the Taylor route
    (module docstring): ``roots`` are the graph nodes of its outputs and fields (in ``graph``)
    and ``arithmetic`` the arithmetic of their decisions (the plan's)."""
    if system.unknown or known_coordinates(system) or system.n < TAYLOR_MIN_VARIABLES:
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

    def series(self, arithmetic, orders=None, roots=()):
        return TaylorSeries(self.graph, self.fields, self.inputs, list(self.outputs) + list(roots), arithmetic,
                            self.cap if orders is None else orders)

    def label(self, k, i):
        """``L_f0^k h`` as the ORC names it; ``y_k[h]`` as the series test does."""
        if k == 0:
            return self.names[i]
        return " ".join(["L_f0"] * k + [self.names[i]]) if self.method == "orc" else f"y_{k}[{self.names[i]}]"


def _draw(rng, n):
    words = rng.integers(0, 2**63, size=(n, 3))
    return [((int(a) << 126) | (int(b) << 63) | int(c)) % graph_exact.PRIME for a, b, c in words]


class _Orders:
    """The rows ``d y_k[h_i]`` absorbed order by order at one point modulo p."""

    def __init__(self, problem, seed, max_bound):
        rng = np.random.default_rng([int(seed), 0x7A110])
        for _ in range(DRAWS):
            point = _draw(rng, problem.n)
            draws = graph_elementary.Draws(graph_exact.PRIME, 1, [int(v) % 2**32 for v in point[:64]])
            self.arith = Modular([point], draws)
            self.point = point
            self.series = problem.series(self.arith)
            try:
                self.series.coefficient(problem.outputs[0], 0)
                break
            except graph_elementary.Singular:
                continue
        else:
            raise NotTaken("every random point drawn is singular")
        self.problem, self.max_bound = problem, max_bound
        self.degrees = TaylorDegrees.of(self.series, problem.cap)
        self.echelon = graph_exact.Echelon()
        self.kept, self.kept_degree = [], 0  # (k, i) of the kept rows; sum of their degrees
        self.error_bound, self.decisions = 0.0, 0

    def absorb(self, k, outputs):
        """Offer ``d y_k[h_i]`` for ``i`` in ``outputs``: the ones that raised the rank."""
        added = []
        for i in outputs:
            node = self.problem.outputs[i]
            try:
                row = self.series.coefficient(node, k)[0, 1:]
            except graph_elementary.Singular:
                raise NotTaken("a denominator vanishes at the random point") from None
            degree = self.degrees.degree(self.series.slot[node], k)
            self.decisions += 1
            if self.echelon.add(row):
                added.append(i)
                self.kept.append((k, i))
                self.kept_degree += degree
            else:
                self._bound(self.kept_degree + degree)
        return added

    def member(self, row, degree) -> bool:
        """Whether ``row`` lies in the span (a dependence: its bound counted)."""
        self.decisions += 1
        if any(self.echelon.reduce(row)):
            return False
        self._bound(self.kept_degree + degree)
        return True

    def _bound(self, degree):
        bound = min(1.0, degree / graph_exact.PRIME)
        if bound > self.max_bound:
            raise NotTaken(f"a dependence of degree {degree} would need more points")
        self.error_bound += bound


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
        return Step(k, self.orders.echelon.rank, tuple(self.problem.label(k, i) for i in self.added), 1.0)

    def terminate(self, k, history):
        n, rank = self.problem.n, self.orders.echelon.rank
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
    observable = {}
    for j, name in enumerate(system.states):
        unit = [0] * system.n
        unit[j] = 1
        observable[name] = orders.member(unit, 0)
    space = TaylorSpace(ctx, problem, orders)
    cert = taylor_certificate(ctx, space, orders)
    route = ("decided on the output's Taylor series at a random point modulo p (Sedoglavic's route: "
             f"{k + 1} orders, no symbolic Lie derivative)")
    notes = [why] if why else []
    if method == "series" and system.known:
        notes.append(SERIES_NOTE)
    notes.append(route)
    details = {"order": k} if method == "series" else {}
    return Report(
        method=method, states=system.states, dim=orders.echelon.rank, observable=observable,
        history=tuple(history), certificate=cert,
        generators=tuple(problem.label(kk, i) for kk, i in orders.kept), stop=stop,
        answer=decide_answer(method, stop, details, cert.arithmetic), route=Route.TAYLOR,
        notes=tuple(system.notes) + tuple(notes), details=details,
        system_name=system.name, params=system.joint_param_names,
        known_inputs="switchable" if system.known else "none", semantics=SEMANTICS, space=space)


__all__ = ["TAYLOR_MIN_VARIABLES", "NotTaken", "taylor_applicable", "taylor_report"]
