"""The steps of Martinelli's general unknown-input solution (:mod:`.general_ui` runs them):
the working system, the closure ``Close``, the reconstructability matrix and the UI extension,
as stated in the module docstring of :mod:`.general_ui` and in ``docs/general_ui.md``."""

import dataclasses

import numpy as np

from ..._calculus.generators import Node
from ..._engine import graph_exact
from ..._engine.graph import Graph
from ..._engine.graph_trace import GraphFunction
from ..._model.derivation import Derivation
from ..._model.graph_system import graph_system
from ..._model.smooth_inputs import known_coordinates, known_outputs, with_input_jets
from ..._model.system import DEFAULT_BOX, System, derived_system
from ..decisions.context import Context
from ..decisions.rank import ZERO_ROW_RTOL, decide_rank


# ------------------------------------------------------------------ zero tests
@dataclasses.dataclass(frozen=True)
class ZeroTest:
    """The evidence of one "vanishes identically" decision: ``zero`` (the decision),
    ``fraction`` of the valid samples agreeing with the float64 vote, ``settled``: how the
    decision was made beyond the vote (``"exact mod p"``, ``"mpmath"``; ``""``: the vote)."""

    what: str
    zero: bool
    fraction: float
    settled: str = ""


def decide_zero(w, ctx, what, exprs, nonzero, fraction) -> bool:
    """A zero test: the float64 vote ``nonzero`` (``fraction`` agreeing) settled again in the
    expression graph (:meth:`uio_jax._analysis.decisions.settle.Settler.vanishes`); recorded in
    ``w.zero_tests``. Returns whether the expressions vanish identically."""
    zero, how = ctx.settler.vanishes(exprs)
    if not how:
        zero = not nonzero
    w.zero_tests.append(ZeroTest(what, zero, fraction, how))
    return zero


def partial_derivative(graph, expr, coordinate):
    """The node ``d expr / d z_coordinate`` (a derivative along a unit tangent)."""
    unit = tuple(graph.one if i == coordinate else graph.zero for i in range(graph.n))
    return graph.jvp([expr], unit)[0]


def nonzero_votes(values, scale, valid):
    """``(nonzero: bool, fraction agreeing)``: ``|values| > ZERO_ROW_RTOL * scale`` by majority."""
    ok = valid & np.isfinite(values) & np.isfinite(scale)
    if not ok.any():
        return False, 0.0
    nz = np.abs(values[ok]) > ZERO_ROW_RTOL * scale[ok]
    frac = float(nz.mean())
    return frac > 0.5, max(frac, 1.0 - frac)


# ------------------------------------------------------------------ the working system
@dataclasses.dataclass
class Working:
    """The system the algorithm works on at one iteration.

    Attributes:
        system: the System on ``[x (n); known coordinates; extension states]``; its drift is
            the augmented drift (``D`` is the Lie derivative along it), its unknown fields
            the current unknown inputs, in order.
        ctx: the Context (samples, builder, gradient cache) on ``system``.
        drift: field node of the augmented drift.
        uis: field nodes of the current unknown inputs.
        origin: per current UI, the index of the original UI it stands for.
        theta: the current observable functions (scalar nodes on ``system``).
        n0: the original state's dimension (the first ``n0`` coordinates).
    """

    system: System
    ctx: Context
    drift: Node
    uis: list
    origin: list
    theta: list
    n0: int
    zero_tests: list = dataclasses.field(default_factory=list)
    #: how each reconstructability decision was made (``"exact mod p"``, ``""``: float64)
    rank_tests: list = dataclasses.field(default_factory=list)
    known: frozenset = frozenset()  # labels of the known coordinates' output functions

    def field_values(self, nodes):
        """Values ``(S, N)`` of field nodes at the samples (one evaluation, cached)."""
        cache = self.__dict__.setdefault("_values", {})
        missing = [nd for nd in nodes if nd not in cache]
        if missing:
            for nd, v in zip(missing, self.ctx.builder.values(missing, self.ctx.xs)):
                cache[nd] = np.asarray(v)
        return [cache[nd] for nd in nodes]


def _working_system(states, outputs, drift, unknown, domain, angles, name, known_count, graph=None):
    """A validated-parts System for the algorithm (no traced checks): of JAX functions, or,
    with ``graph``, of its nodes (outputs name -> node, fields tuples of nodes)."""
    if graph is not None:
        return graph_system(graph, states, outputs, unknown=unknown, drift=drift, domain=domain,
                            angles=angles, name=name, known_coordinates=known_count)
    with derived_system():
        return System(states=tuple(states), outputs=outputs, unknown=unknown, drift=drift,
                      domain=domain, angles=angles, name=name, derivation=Derivation(known_coordinates=known_count))


def _zero_field(n):
    """The zero field of ``n`` coordinates (a function of the state given by its expression)."""
    graph = Graph(n)
    return GraphFunction(graph, (graph.zero,) * n)


def start_working(system, jet_order, samples, seed, rtol, prob_threshold) -> Working:
    """The first working system: ``system`` (joint, autonomous) with the jets of its known
    inputs to ``jet_order`` in the drift; Theta = its outputs (known coordinates included)."""
    sys0 = with_input_jets(system, jet_order)
    if sys0.drift is None:  # no drift, no known input: D is the zero field
        n = sys0.n
        sys0 = _working_system(sys0.states, dict(sys0.outputs), _zero_field(n),
                               dict(sys0.unknown), dict(sys0.domain), sys0.angles, sys0.name,
                               known_coordinates(sys0))
    ctx = Context(sys0, samples, seed, rtol, prob_threshold)
    b = ctx.builder
    drift = b.field("g0", sys0.drift)
    uis = [ctx.field_node(k) for k in sys0.unknown]
    return Working(sys0, ctx, drift, uis, list(range(len(uis))), ctx.output_nodes(),
                   system.n - known_coordinates(system), known=frozenset(known_outputs(sys0)))


# ------------------------------------------------------------------ Close
@dataclasses.dataclass
class Closed:
    """What a closure returns: the span (a forked Context), or an abort."""

    ctx: Context
    aborted: bool = False
    root: Node | None = None
    order: int = 0


def close(w: Working, theta0, fields, guard=(), filter_fields=(), guard_scale=None) -> Closed:
    """``Close(Theta_0, fields; guard, filter)`` of the module docstring on a fresh span.

    Args:
        w: the working system.
        theta0: the scalar nodes to start from (in order).
        fields: the field nodes to differentiate along (the drift-like field first; all are
            plain Lie derivatives on the augmented state).
        guard: field nodes ``G~_k``: abort at the first generator with some
            ``L_{G~_k} theta`` not identically zero.
        filter_fields: field nodes ``g_j``: differentiate only the generators with every
            ``L_{g_j} theta`` identically zero.
        guard_scale: per guard field, the ``(S,)`` norms it is compared with (default its
            own): the raw ``g_k`` behind ``G~_k``, so that a ``G~_k`` that vanishes up to
            round-off is not taken for a field.

    Returns:
        :class:`Closed`.
    """
    ctx = w.ctx.fork()
    kept = ctx.absorb(theta0)
    root = {nd: nd for nd in kept}
    # the known coordinates (time, jets) are in every span with all their derivatives
    # (D u^(r) = u^(r+1), D t = 1; the unknown-input fields have no such component)
    frontier, r = [nd for nd in kept if nd.label not in w.known], 0
    N = w.system.n
    while frontier:
        if guard:
            for theta in frontier:
                if _any_nonzero(w, ctx, theta, guard, guard_scale):
                    return Closed(ctx, True, root[theta], r)
        active = frontier
        if filter_fields:
            active = [th for th in frontier if not _any_nonzero(w, ctx, th, filter_fields)]
        if ctx.dim >= N or not active or not fields:
            break
        nodes, grads = ctx.lie_block(active, fields)
        added = ctx.absorb(nodes, grads)
        index = {nd: i for i, nd in enumerate(nodes)}
        for nd in added:
            root[nd] = root[active[index[nd] // len(fields)]]
        frontier, r = added, r + 1
    return Closed(ctx)


def _any_nonzero(w: Working, ctx: Context, theta, fields, scales=None) -> bool:
    """Whether some ``L_v theta`` (v in ``fields``) is not identically zero at the samples,
    relative to ``|d theta| |v|`` (``|v|``: ``scales[k]``, default the field's own norm)."""
    grad = ctx.gradients([theta])[:, 0]
    gnorm = np.linalg.norm(grad, axis=-1)
    values = w.field_values(fields)
    if scales is None:
        scales = [np.linalg.norm(val, axis=-1) for val in values]
    for v, val, vnorm in zip(fields, values, scales):
        lie = np.einsum("sn,sn->s", grad, val)
        nonzero, frac = nonzero_votes(lie, gnorm * vnorm, ctx.codist.valid)
        expr = ctx.builder.lie(v, theta).expr
        if not decide_zero(w, ctx, f"L_{v.label} {theta.label}", [expr], nonzero, frac):
            return True
    return False


# ------------------------------------------------------------------ reconstructability
def _generic_rank(mats, valid, rtol):
    """Generic rank of a sampled family of matrices ``(S, a, b)`` whose entries are cosines
    (``L_g theta / (|d theta| |g|)``): per-sample singular values, the largest above
    ``ZERO_ROW_RTOL`` sets the scale, ranks by ``rtol`` (:func:`decide_rank`)."""
    if mats.shape[1] == 0 or mats.shape[2] == 0:
        return decide_rank(np.zeros((mats.shape[0], 0)), valid, rtol)
    finite = np.isfinite(mats).all(axis=(1, 2))
    s = np.linalg.svd(np.where(np.isfinite(mats), mats, 0.0), compute_uv=False)
    top = s[:, :1]
    ratios = np.where(top > ZERO_ROW_RTOL, s / np.where(top > 0, top, 1.0), 0.0)
    return decide_rank(ratios, valid & finite, rtol)


@dataclasses.dataclass(frozen=True)
class Reconstructability:
    """Degree of reconstructability ``m``, the identifier rows and the UI columns chosen."""

    m: int
    rows: tuple
    cols: tuple
    fraction: float
    settled: str = ""


def reconstructability(w: Working, theta) -> Reconstructability:
    """``R_ij = L_{g_j} theta_i``: its generic rank ``m``, the first independent rows
    (identifiers) and, among them, the first independent columns. Decided modulo p at a
    random point where the graph is made rational (:func:`_exact_reconstructability`), else
    on the float64 votes of the samples (the entries as cosines)."""
    exact = _exact_reconstructability(w, theta)
    if exact is not None:
        return exact
    ctx = w.ctx
    grads = ctx.gradients(theta)  # (S, r, N)
    vals = np.stack(w.field_values(w.uis), axis=1)  # (S, mw, N)
    R = np.einsum("srn,skn->srk", grads, vals)
    scale = (np.linalg.norm(grads, axis=-1)[:, :, None] * np.linalg.norm(vals, axis=-1)[:, None, :])
    R = R / np.where(scale > 0, scale, 1.0)
    valid, rtol = ctx.codist.valid, ctx.codist.rtol
    full = _generic_rank(R, valid, rtol)
    fractions = [full.fraction]
    rows = []
    for i in range(R.shape[1]):
        if len(rows) == full.rank:
            break
        d = _generic_rank(R[:, rows + [i], :], valid, rtol)
        fractions.append(d.fraction)
        if d.rank > len(rows):
            rows.append(i)
    cols = []
    for k in range(R.shape[2]):
        if len(cols) == len(rows):
            break
        d = _generic_rank(R[:, rows][:, :, cols + [k]], valid, rtol)
        fractions.append(d.fraction)
        if d.rank > len(cols):
            cols.append(k)
    return Reconstructability(len(rows), tuple(rows), tuple(cols), min(fractions))


def _exact_reconstructability(w: Working, theta):
    """:func:`reconstructability` modulo p at the Settler's first point: the rows and
    columns chosen greedily by exact elimination (a row independent at the point is
    independent generically; a dependent one is, unless the point is a root of a nonzero
    minor: each such decision adds its bound to the certificate's). None where the graph is
    not made rational."""
    ctx = w.ctx
    entries = [[ctx.builder.lie(g, th).expr for g in w.uis] for th in theta]
    flat = [e for row in entries for e in row]
    values = ctx.settler.values_mod_p(flat) if flat else []
    if values is None:
        return None
    mw = len(w.uis)
    R = [values[i * mw:(i + 1) * mw] for i in range(len(theta))]
    rows, echelon = [], graph_exact.Echelon()
    for i, row in enumerate(R):
        if echelon.add(row):
            rows.append(i)
    cols, echelon = [], graph_exact.Echelon()
    for k in range(mw):
        if len(cols) == len(rows):
            break
        if echelon.add([R[i][k] for i in rows]):
            cols.append(k)
    ctx.settler.count_bound(flat, len(theta) + mw, max(len(rows), 1))
    return Reconstructability(len(rows), tuple(rows), tuple(cols), 1.0, "exact mod p")


# ------------------------------------------------------------------ UI extension
def lift(graph, source, node, coords):
    """The node ``node`` of the graph ``source`` (a function of the first ``len(coords)``
    coordinates there) as a node of ``graph`` where those coordinates are ``coords``."""
    return graph.import_nodes(source, [node] if isinstance(node, int) else list(node), tuple(coords))


class _Fresh:
    """Names not taken yet: a name taken already gets primes appended (``D1(y)'``)."""

    def __init__(self, taken):
        self.taken = set(taken)

    def __call__(self, nm: str) -> str:
        while nm in self.taken:
            nm += "'"
        self.taken.add(nm)
        return nm


def extend(w: Working, theta_star, order, hat0, hats, tildes, rec, samples, seed, rtol):
    """The UI extension (module docstring) from the aborted guarded closure's root
    ``theta_star`` and ``order``; returns ``(Working, info)`` on the extended system.

    The chains ``v_j^(0..order)`` of the reconstructed inputs' derivatives are first all
    added (:func:`_chain_lengths` finds how far each must go), then the system is rebuilt
    with the kept chains only (:func:`_extended_working`)."""
    fresh = _Fresh(w.system.states)
    ids = [w.theta[i].label for i in rec.rows]  # v_j^(i) = d^(i+1) h~_j / dt^(i+1)
    vnames = [[fresh(f"D{i + 1}({_short(ids[j])})") for i in range(order + 1)] for j in range(len(hats))]
    keep_to, theta_v, full_graph, domain = _chain_lengths(w, theta_star, order, hat0, hats, vnames,
                                                          samples, seed, rtol)
    return _extended_working(w, theta_star, order, hat0, hats, tildes, rec, vnames, ids, keep_to,
                             (theta_v, full_graph), domain, fresh, samples, seed, rtol)


def _chain_lengths(w, theta_star, order, hat0, hats, vnames, samples, seed, rtol):
    """On the full extension ``[z; v_1^(0..order); ..; v_m^(0..order)]``, the highest
    derivative of each chain that ``L_F'^order theta*`` depends on (None: none), by exact zero
    tests: ``(keep_to, theta_v, graph, domain)`` (``theta_v``: that derivative, a Node of the
    full extension's ``graph``; ``domain``: the boxes of every coordinate)."""
    sysw = w.system
    N, m, L = sysw.n, len(hats), order + 1
    src = w.ctx.builder.graph  # the working system's graph: hat0, hats, tildes, theta live there
    flat = [nm for row in vnames for nm in row]
    domain = {**dict(sysw.domain), **{nm: DEFAULT_BOX for nm in flat}}
    gf = Graph(N + m * L)
    z = gf.coords[:N]
    v = [gf.coords[N + j * L:N + (j + 1) * L] for j in range(m)]
    dz = lift(gf, src, hat0.expr, z)
    for j in range(m):
        dz = [gf.add(a, gf.mul(v[j][0], c)) for a, c in zip(dz, lift(gf, src, hats[j].expr, z))]
    drift_full = tuple(dz) + tuple(e for j in range(m) for e in (*v[j][1:], gf.zero))
    full = _working_system(sysw.states + tuple(flat), {"theta*": lift(gf, src, theta_star.expr, z)[0]},
                           drift_full, {}, domain, sysw.angles, sysw.name, known_coordinates(sysw), graph=gf)
    ctx_full = Context(full, samples, seed, rtol, w.ctx.prob_threshold)
    b = ctx_full.builder
    theta_v = b.power(b.field("F'", full.drift), b.scalar("theta*", full.outputs["theta*"]), order)
    grad = ctx_full.gradients([theta_v])[:, 0]  # (S, N + m L)
    gnorm = np.linalg.norm(grad, axis=-1)
    keep_to = []
    for j in range(m):
        top = None
        for i in range(L):
            c = N + j * L + i
            nz, frac = nonzero_votes(grad[:, c], gnorm, ctx_full.codist.valid)
            expr = partial_derivative(gf, theta_v.expr, c)
            if not decide_zero(w, ctx_full, f"d theta*/d {vnames[j][i]}", [expr], nz, frac):
                top = i
        keep_to.append(top)
    return keep_to, theta_v, b.graph, domain


def _extended_working(w, theta_star, order, hat0, hats, tildes, rec, vnames, ids, keep_to, theta_v_in, domain,
                      fresh, samples, seed, rtol):
    """The extended system with the kept chains only (``keep_to``, :func:`_chain_lengths`):
    its drift, its new unknown inputs (a chain's next derivative, or the rescaled field where
    a chain is empty; the unreconstructed fields ``G~``), its outputs (the working ones, the
    chains' coordinates, ``theta_v``, given with its graph); ``(Working, info)``."""
    theta_v, full_graph = theta_v_in
    sysw = w.system
    N, m, L = sysw.n, len(hats), order + 1
    src = w.ctx.builder.graph
    names_ui = [list(sysw.unknown)[c] for c in rec.cols] + \
               [k for i, k in enumerate(sysw.unknown) if i not in rec.cols]
    kept_names = [vnames[j][: keep_to[j] + 1] for j in range(m) if keep_to[j] is not None]
    kept_flat = [nm for row in kept_names for nm in row]
    pos_full = {nm: N + j * L + i for j in range(m) for i, nm in enumerate(vnames[j])}
    Nn = N + len(kept_flat)
    kept_index = {nm: N + i for i, nm in enumerate(kept_flat)}
    chains = [(j, [kept_index[nm] for nm in vnames[j][: keep_to[j] + 1]])
              for j in range(m) if keep_to[j] is not None]
    dropped = [j for j in range(m) if keep_to[j] is None]

    gn = Graph(Nn)
    Z = gn.coords
    hat_new = [lift(gn, src, h.expr, Z[:N]) for h in hats]
    dz = lift(gn, src, hat0.expr, Z[:N])
    tail = [gn.zero] * (Nn - N)
    for j, idx in chains:
        dz = [gn.add(a, gn.mul(Z[idx[0]], c)) for a, c in zip(dz, hat_new[j])]
        for a, b_ in zip(idx[:-1], idx[1:]):
            tail[a - N] = Z[b_]
    drift_new = tuple(dz) + tuple(tail)
    embed = [gn.zero] * (N + m * L)  # the final state in the full one (dropped coordinates: 0)
    embed[:N] = Z[:N]
    for nm, i in kept_index.items():
        embed[pos_full[nm]] = Z[i]
    pad = (gn.zero,) * (Nn - N)

    new_uis, new_origin = {}, []
    order_idx = list(rec.cols) + [i for i in range(len(w.uis)) if i not in rec.cols]
    for j in range(m):
        top = -1 if keep_to[j] is None else keep_to[j]
        nm = fresh(f"D{top + 2}({_short(ids[j])})")  # the new unknown input
        if keep_to[j] is None:
            new_uis[nm] = tuple(hat_new[j]) + pad
        else:
            unit = kept_index[vnames[j][keep_to[j]]]
            new_uis[nm] = tuple(gn.one if i == unit else gn.zero for i in range(Nn))
        new_origin.append(w.origin[order_idx[j]])
    for k, t in enumerate(tildes):
        nm = fresh(f"{names_ui[m + k]}~")
        new_uis[nm] = tuple(lift(gn, src, t.expr, Z[:N])) + pad
        new_origin.append(w.origin[order_idx[m + k]])
    outputs = {th.label: lift(gn, src, th.expr, Z[:N])[0] for th in w.theta}
    for nm in kept_flat:
        outputs[nm] = Z[kept_index[nm]]
    outputs["theta_v"] = lift(gn, full_graph, theta_v.expr, embed)[0]
    domain_new = {k: v for k, v in domain.items() if k in sysw.states or k in kept_flat}
    new_sys = _working_system(sysw.states + tuple(kept_flat), outputs, drift_new, new_uis,
                              domain_new, sysw.angles, sysw.name, known_coordinates(sysw), graph=gn)
    ctx = Context(new_sys, samples, seed, rtol, w.ctx.prob_threshold)
    nb = ctx.builder
    uis = [ctx.field_node(k) for k in new_uis]
    theta = ctx.output_nodes()
    info = {"order": order, "root": theta_star.label, "theta_v": theta_v.label,
            "new_states": kept_flat, "ui_without_chain": [names_ui[j] for j in dropped]}
    return Working(new_sys, ctx, nb.field("g0", new_sys.drift), uis, new_origin, theta, w.n0,
                   w.zero_tests, w.rank_tests, w.known), info


def _short(label: str) -> str:
    """A label fit for a coordinate name (long generator labels are cut)."""
    return label if len(label) <= 24 else label[:21] + "..."
