"""The observable space of a finished analysis, as a Report reads it.

A Report asks about the original state ``x (n,)``: its unobservable directions, whether a
function of it is observable, the singular values at the samples (:class:`Space`, answered by
:class:`SampledSpace` from a finished Context); :class:`ReportView` is what it reads of the System.
"""

import dataclasses
from collections.abc import Mapping
from typing import Protocol

import numpy as np

from ..._engine import graph_exact
from ..._errors import ModelError
from ..._model.smooth_inputs import known_coordinates


@dataclasses.dataclass(frozen=True)
class ReportView:
    """What a Report reads of a System (names only): the first ``n`` states of a System
    whose other coordinates are known or extension coordinates (:func:`report_view`)."""

    states: tuple
    name: str
    notes: tuple
    joint_param_names: tuple
    known: tuple


def report_view(system, n) -> ReportView:
    """The :class:`ReportView` of the first ``n`` coordinates of ``system``."""
    return ReportView(tuple(system.states[:n]), system.name, tuple(system.notes),
                      tuple(system.joint_param_names), tuple(system.known))


@dataclasses.dataclass(frozen=True)
class Projection:
    """A span's answer on the original state (the EORC's and the extended general solution's
    span lives on more coordinates): the states reported, the dimension and the verdicts
    there, and the :class:`Space` the report queries (``view``: a :class:`ReportView`, or the
    analysed System itself)."""

    view: ReportView
    dim: int
    observable: Mapping
    space: "Space"


def system_known(system) -> bool:
    """Whether the (original) System behind a report has known inputs."""
    return bool(getattr(system, "known", ()))


@dataclasses.dataclass(frozen=True)
class SpanParts:
    """What the closed forms of a report (:mod:`uio_jax._analysis.followups.observable_functions`) read
    of its final codistribution.

    Attributes:
        builder: the node builder of the analysed System (its expression graph: ``builder.graph``).
        nodes: the kept generators (Nodes), their gradients independent.
        names: the names of the analysed coordinates (``N`` of them).
        n: the coordinates the report is about (its states and parameters: the first ``n``).
        dim: the dimension of the span on those.
        settler: the analysis' :class:`~uio_jax._analysis.decisions.settle.Settler` (exact decisions).
        roots: the graph nodes of the analysed System's outputs and fields.
        box: ``(lo, hi)`` of the analysed coordinates.
        system: the analysed System (whose coordinates the span lives on).
        original: the System whose states are the report's ``n`` coordinates (the System
            before the extension, with its unknown inputs, for the EORC and an extended
            general solution), on which a found symmetry is verified; None for a
            time-varying model.
    """

    builder: object
    nodes: tuple
    names: tuple
    n: int
    dim: int
    settler: object
    roots: tuple
    box: tuple
    system: object = None
    original: object = None


class Space(Protocol):
    """What a Report asks of the final codistribution (``Report._space``), about the
    original state ``x (n,)``: :class:`SampledSpace` is the one implementation."""

    def unobservable_directions(self, x, at=None) -> np.ndarray:
        """``(n, n - dim)`` orthonormal columns: the annihilator of the span on ``dx``."""

    def is_observable(self, fn) -> bool:
        """Whether ``d fn`` (``fn: x (n,) -> ()``) lies in the span at the samples."""

    def sample_singular_values(self) -> np.ndarray:
        """``(S_used, r)`` ratios ``s_i / s_1`` of the kept generators."""

    @property
    def domain(self) -> Mapping:
        """The sampling box ``name -> (lo, hi)`` of the analysed coordinates."""

    def rank_ratio_at(self, z) -> float | None:
        """``s_r / s_1`` of the kept generators at the original state ``z (n,)``."""


#: Decimal digits of the unobservable directions at a state where float64 cannot separate
#: the kept generators (:meth:`SampledSpace.unobservable_directions`).
EXTENDED_DIGITS = 60


class SampledSpace(Space):
    """The final codistribution of a Context, queried by a Report about the original state.

    The codistribution lives on the ``N`` coordinates of ``ctx.system``; the Report's state is
    its first ``n`` (``n = N`` for the ORC and the single-input analysis; for the EORC the
    extended state ``[x; xi]``, whose extra coordinates are set to ``fill``: one generic point
    of their boxes, drawn once, seeded; the centre of every box can be singular).

    Args:
        ctx: the finished analysis (a :class:`~uio_jax._analysis.decisions.context.Context`).
        n: coordinates of the original state (default: all of ``ctx.system``'s).
        dim: dimension of the span intersected with ``span{dx_1..dx_n}`` (default: the
            rank, the whole span when ``n = N``).
        original: the System whose states are the first ``n`` coordinates
            (:attr:`SpanParts.original`; default ``ctx.system`` when ``n = N``).
    """

    def __init__(self, ctx, n=None, dim=None, original=None):
        self._ctx = ctx
        self._nodes = tuple(ctx.codist.nodes)
        self._N = ctx.system.n
        self._n = self._N if n is None else int(n)
        self._original = original if original is not None else (ctx.system if self._n == self._N else None)
        self._dim = len(self._nodes) if dim is None else int(dim)
        lo, hi = ctx.system.box()
        rng = np.random.default_rng(0x5FACE)
        self._fill = lo[self._n:] + rng.random(self._N - self._n) * (hi[self._n:] - lo[self._n:])
        # the known coordinates right after the reported ones (the time of a time-varying
        # System, the jets of smooth known inputs) at the centre of their box: the directions
        # are stated at that time (:meth:`known_point`), which the caller may choose
        known = min(known_coordinates(ctx.system), self._N - self._n) if self._n < self._N else 0
        self._known_names = tuple(ctx.system.states[self._n:self._n + known])
        self._fill[:known] = 0.5 * (lo[self._n:self._n + known] + hi[self._n:self._n + known])

    def parts(self) -> SpanParts:
        """The final codistribution's parts (:class:`SpanParts`)."""
        ctx = self._ctx
        nodes = [*ctx.output_nodes(), *(ctx.field_node(f) for f in ctx.system.fields())]
        roots = tuple(e for nd in nodes for e in ((nd.expr,) if isinstance(nd.expr, int) else nd.expr))
        return SpanParts(ctx.builder, self._nodes, tuple(ctx.system.states), self._n, self._dim,
                         ctx.settler, roots, ctx.system.box(), ctx.system, self._original)

    def known_point(self) -> dict:
        """``{name: value}`` of the known coordinates the directions are computed at (the
        time of a time-varying System: the centre of its box unless given)."""
        return {name: float(self._fill[i]) for i, name in enumerate(self._known_names)}

    def unobservable_directions(self, x, at=None) -> np.ndarray:
        """Annihilator in R^n of the span intersected with ``span{dx_1..dx_n}`` at ``x``.

        With ``G (r, N)`` the row-normalized gradients of the kept generators at
        ``[x; fill]``: for ``n = N`` the null space of ``G`` (its right singular vectors past
        ``r``). Otherwise, with ``Q`` an orthonormal basis of the row space of ``G`` and
        ``P = I - Q^T Q``, a covector ``[a; 0]`` lies in the span iff ``P[:, :n] a = 0``; the
        right singular vectors of ``P[:, :n]`` for its ``n - dim`` largest singular values
        span the annihilator of the intersection.

        Args:
            x: original state, ``(n,)``.
            at: the value of the first known coordinate (the time), default that of
                :meth:`known_point`.

        Returns:
            ``(n, n - dim)``, orthonormal columns.
        """
        n, N = self._n, self._N
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (n,):
            raise ModelError(f"state must have shape ({n},), got {x.shape}")
        if not np.isfinite(x).all():
            raise ModelError("state contains NaN/inf")
        r = len(self._nodes)
        if N > n and self._dim == n:
            return np.zeros((n, 0))
        if r == 0:
            return np.eye(n)
        fill = self._fill.copy()
        if at is not None:
            if not self._known_names:
                raise ModelError("this report's model does not depend on time: no time to give")
            if not np.isfinite(float(at)):
                raise ModelError(f"the time must be a finite number, got {at!r}")
            fill[0] = float(at)
        X = np.concatenate([x, fill])
        g = self._ctx.builder.gradients(self._nodes, np.asarray(X, dtype=np.float64)[None])[0]
        if not np.isfinite(g).all():
            raise ModelError("the codistribution is not defined at this state (NaN/inf)")
        g = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        _, sv, vt = np.linalg.svd(g)
        if sv[min(r, N) - 1] < self._ctx.codist.rtol * sv[0]:
            return self._directions_extended(X)
        if N == n:
            return vt[r:].T.copy()
        q = vt[:r]
        P = np.eye(N) - q.T @ q
        _, _, wt = np.linalg.svd(P[:, :n])
        return wt[: n - self._dim].T.copy()

    def _directions_extended(self, X) -> np.ndarray:
        """:meth:`unobservable_directions` in ``dps =`` :data:`EXTENDED_DIGITS` decimal digits
        (mpmath): where the kept generators' smallest directions are under float64's reach at
        ``X`` (``s_r/s_1`` under ``rtol``), their gradients are evaluated in the expression graph
        at ``X`` (its floats taken exactly) and the null space is computed there. A state where
        they are dependent even at ``dps`` digits (``s_r/s_1`` under ``10^-(dps/2)``) is
        singular: refused."""
        dps = EXTENDED_DIGITS
        ev = graph_exact.ExtendedEvaluator(self._ctx.builder.graph, X, dps)
        _, grads = ev.gradients([nd.expr for nd in self._nodes])
        return annihilator_extended(ev.ctx, grads, self._n, self._dim, dps)

    def sample_singular_values(self) -> np.ndarray:
        """``(S_used, r)`` ratios ``s_i / s_1`` of the kept generators at the valid samples."""
        return self._ctx.codist.sample_ratios()

    @property
    def domain(self) -> Mapping:
        """The sampling box ``name -> (lo, hi)`` of the analysed System."""
        return self._ctx.system.domain

    def rank_ratio_at(self, z) -> float | None:
        """``s_r / s_1`` of the kept generators' gradients at the original state ``z (n,)``.

        As in the analysis, the columns are scaled by the box widths and the rows normalized;
        the extra coordinates of a larger analysed state (the EORC's ``[x; xi]``) take the
        value ``fill``. NaN/inf gradients give 0.0 (the point is singular); None when no
        generator was kept.
        """
        if not self._nodes:
            return None
        system = self._ctx.system
        full = np.concatenate([np.asarray(z, dtype=np.float64), self._fill])
        domain = system.domain
        width = np.array([float(domain[v][1]) - float(domain[v][0]) if v in domain else 1.0
                          for v in system.states])
        g = np.asarray(self._ctx.builder.gradients(self._nodes, full[None])[0])
        if not np.isfinite(g).all():
            return 0.0
        g = g * width
        g = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        s = np.linalg.svd(g, compute_uv=False)
        return float(s[-1] / s[0]) if s[0] > 0 else 0.0

    def is_observable(self, fn) -> bool:
        """Whether ``d fn`` (padded with zeros to ``N``) lies in the span at the samples.

        Args:
            fn: callable ``x (n,) -> ()`` of the original state.
        """
        # in the expression graph when fn translates (numpy, a weak vote settled exactly)
        node = function_node(self._ctx.builder, fn, self._n, self._N)
        grads = self._ctx.gradients([node])  # (S, 1, N), zero past n
        member, decision = self._ctx.codist.contains(np.moveaxis(grads, 1, 0), nodes=[node])[0]
        if decision.settled == "undecided":
            esc = self._ctx.codist.record.escalations[-1]
            raise ModelError(f"is_observable: undecided (float64: {esc.float64}; {esc.how}): "
                             "the answer would not be certified")
        return bool(member)


def annihilator_extended(ctx, grads, n, dim, dps) -> np.ndarray:
    """The annihilator ``(n, n - dim)`` of the span of the gradient rows ``grads`` (``r``
    lists of ``N`` mpmath numbers, ``N >= n``) intersected with ``span{dx_1..dx_n}``, in the
    mpmath context ``ctx`` (``dps`` digits): :meth:`SampledSpace.unobservable_directions` at
    that precision.

    Raises:
        ModelError: a zero or non-finite row, or rows dependent even at ``dps`` digits (a
            singular state).
    """
    r, N = len(grads), len(grads[0])
    rows = []
    for row in grads:
        norm = ctx.sqrt(ctx.fsum(v * v for v in row))
        if not ctx.isfinite(norm) or norm == 0:
            raise ModelError("the codistribution is not defined at this state (NaN/inf or a zero gradient)")
        rows.append([v / norm for v in row])
    _, sv, vt = ctx.svd_r(ctx.matrix(rows), full_matrices=True)
    if sv[min(r, N) - 1] < ctx.mpf(10) ** (-dps // 2) * sv[0]:
        raise ModelError(
            f"a singular state: the {r} kept generators are dependent here even at {dps} digits "
            f"(s_r/s_1 = {float(sv[min(r, N) - 1] / sv[0]):.1e}); ask at another state")
    V = np.array([[float(vt[i, j]) for j in range(N)] for i in range(vt.rows)])
    if N == n:
        return V[r:].T.copy()
    q = ctx.matrix([[vt[i, j] for j in range(N)] for i in range(r)])
    P = ctx.eye(N) - q.T * q
    _, _, wt = ctx.svd_r(ctx.matrix([[P[i, j] for j in range(n)] for i in range(N)]), full_matrices=True)
    return np.array([[float(wt[i, j]) for j in range(n)] for i in range(n - dim)]).T.copy()


def function_node(builder, fn, n, N):
    """The graph node of ``fn: x (n,) -> ()`` on the ``N`` analysed coordinates (``fn`` of the
    first ``n``), after checking that it is a callable returning a scalar.

    Raises:
        ModelError: not a callable, a function that fails on a state of length ``n`` or
            does not return a scalar.
    """
    if not callable(fn):
        raise ModelError(f"is_observable needs a callable x -> scalar, got {type(fn).__name__}")
    import jax  # the user's JAX callable
    import jax.numpy as jnp

    with jax.enable_x64(True):
        try:
            out = jax.eval_shape(fn, jax.ShapeDtypeStruct((n,), jnp.float64))
        except Exception as exc:
            raise ModelError(f"function fails on a state of length {n}: "
                             f"{type(exc).__name__}") from None
    if getattr(out, "shape", None) != ():
        raise ModelError(f"function must return a scalar (), got shape {getattr(out, 'shape', None)}")
    of_state = fn if n == N else (lambda X: fn(X[:n]))
    return builder.function(getattr(fn, "__name__", "fn"), of_state)


__all__ = ["ReportView", "report_view", "Projection", "system_known", "Space", "SampledSpace", "annihilator_extended",
           "function_node", "SpanParts"]
