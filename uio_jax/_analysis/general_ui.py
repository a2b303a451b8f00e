"""Martinelli's general analytic solution of unknown-input observability (several UIs, drift).

System ``x' = g0(x, t) + sum_j w_j g_j(x)``, outputs ``h(x)`` (no feedthrough), where
``g0 = f0 + sum_i u_i f_i`` holds the known inputs as generic smooth functions of time (their
jets are known coordinates, :mod:`uio_jax._model.smooth_inputs`) and an explicit time
dependence (the time coordinate, ``t' = 1``). ``D`` below is the Lie derivative along this
augmented drift: the total time derivative. Every rank, zero test and membership is decided
at the sampled states (:mod:`uio_jax._analysis.rank`), the jets and the time being known
coordinates whose differentials are in every span. Sources: arXiv 2201.07610 (Algorithm
5.1/6.1) and Martinelli's TUIO6; the algorithm as implemented is stated in
``docs/general_ui.md``.

**Close(Theta_0, [F_0, F_1..F_q]; guard, filter)**: insert Theta_0 (independent members, each
its own *root*); pass r processes the generators added in pass r - 1 (pass 0: Theta_0): if
``guard(theta)`` holds, abort with (root of theta, ``ord = r``); if ``filter(theta)`` fails,
skip it; else absorb ``L_{F_a} theta`` for every field (children inherit the root). Stop when a
pass adds nothing; without a guard also at full rank (with a guard, full rank is no
certificate: every remaining generator must still pass the guard).

**Reconstructability**: ``R_ij = L_{g_j} theta_i`` over the current Theta; ``m`` = its generic
rank (degree of reconstructability); the first independent rows are the UI identifiers
``h~``, the first independent columns among them the reconstructable UIs (moved first).
Canonic: ``m = mw``. Rescaled fields ``g^0, g^_k, G~_k``: :mod:`uio_jax._calculus.rescaled`.

**Main loop** (at most :data:`ITERATION_CAP` iterations)::

    Theta <- Close(h, [])
    loop:  m, identifiers;  Theta <- Close(Theta, [])
      m = mw:               Omega = Close(Theta, [g^0, g^_1..g^_mw])            finish
      every G~_k = 0:       Omega = Close(Theta, [g^0, g^_1..g^_m])             finish
      guarded Close(Theta, [g^0, g^_1..g^_m]; guard: some L_{G~_k} theta != 0):
          no abort:         Omega = its result                                   finish
          abort (theta*, ord): its result is discarded;
            m = 0:  Theta <- Close(Theta, [g0]; filter: every L_{g_j} theta = 0)
            m >= 1: UI extension: states v_j^(0..ord) with x' = g^0 + sum_j v_j^(0) g^_j and
                    v_j^(i)' = v_j^(i+1), theta_v = D^ord theta*; keep v_j^(0..i_j) (i_j: the
                    highest one theta_v depends on; none: v_j is the new UI along (g^_j, 0));
                    the new UIs are d v_j^(i_j)/dt (unit fields) and G~_k;
                    Theta <- Theta + {kept v} + {theta_v}

**Outputs**: the dimension of ``Omega`` on the original state, ``dim = rank(Omega) + n -
rank([Omega; e_1..e_n])`` (every extension state and known coordinate is observable), the
observable components, the degree of reconstructability, canonic or not, the extension, and
which unknown inputs are reconstructable and observable. The answer is exact for known
inputs that are generic smooth functions of time (``known_inputs="smooth"``); systems without
known inputs have one meaning only.
"""

import contextlib
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from .._calculus.generators import Node, builder_for
from .._calculus.rescaled import rescaled_fields
from .._errors import OptionError
from .._model.smooth_inputs import jet_names, known_coordinates, known_outputs, with_input_jets
from .._model.system import DEFAULT_BOX, System, derived_system
from .._progress import announce_step
from .context import Context, SampledSpace, report_view
from .driver import StopReason
from .eorc import extended_system
from .rank import ZERO_ROW_RTOL, decide_rank
from .report import Report, Step

#: At most this many iterations of the main loop (TUIO6's bound).
ITERATION_CAP = 30

#: Jets of the smooth known inputs are kept to order ``n + JET_MARGIN`` at first; when a
#: generator that was differentiated depends on the highest jet, the analysis is run again
#: with twice the order (the truncation ``u^(R+1) = 0`` could have mattered).
JET_MARGIN = 3

#: How many times the jet order is doubled before the report says it may be truncated.
JET_RETRIES = 2

#: Programs of the general solution above this many equations are compiled at XLA
#: optimization level 0: each runs once, and level 0 halves the compile time of the large
#: ones (TUIO6's TAC-2025 case: 120 s -> 74 s cold; ``docs/benchmarks/general_ui.md``).
LARGE_GRAPH = 1000


def check_applicable(system: System, known_inputs: str):
    """Raise OptionError when ``method='general_ui'`` does not answer the question asked.

    The general solution is established for known inputs that are generic smooth functions
    of time; for switchable known inputs (the default) no statement is known when there is
    a drift or more than one unknown input, and with one unknown input and no drift the
    switchable answer is ``single_ui``'s.
    """
    if system.known and known_inputs != "smooth":
        raise OptionError(
            "method 'general_ui' answers for known inputs that are generic smooth functions of "
            "time: pass known_inputs='smooth'; for switchable known inputs (the default) use "
            "method='single_ui' (one unknown input, no drift) or 'eorc' (sufficient only)")


# ------------------------------------------------------------------ zero tests
@dataclasses.dataclass(frozen=True)
class ZeroTest:
    """The evidence of one "vanishes identically" decision: ``zero`` by majority of the
    valid samples, ``fraction`` of them agreeing."""

    what: str
    zero: bool
    fraction: float


def _nonzero_votes(values, scale, valid):
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
    known: frozenset = frozenset()  # labels of the known coordinates' output functions

    def field_values(self, nodes):
        """Values ``(S, N)`` of field nodes at the samples (one evaluation, cached)."""
        cache = self.__dict__.setdefault("_values", {})
        missing = [nd for nd in nodes if nd not in cache]
        if missing:
            for nd, v in zip(missing, self.ctx.builder.values(missing, self.ctx.xs)):
                cache[nd] = np.asarray(v)
        return [cache[nd] for nd in nodes]


def _working_system(states, outputs, drift, unknown, domain, angles, name, known_count, params):
    """A validated-parts System for the algorithm (no traced checks)."""
    with derived_system():
        system = System(states=tuple(states), outputs=outputs, unknown=unknown, drift=drift,
                        domain=domain, angles=angles, name=name)
    object.__setattr__(system, "_known_coordinates", known_count)
    object.__setattr__(system, "_as_params", params)
    return system


def _start(system, jet_order, samples, seed, rtol) -> Working:
    """The first working system: ``system`` (joint, autonomous) with the jets of its known
    inputs to ``jet_order`` in the drift; Theta = its outputs (known coordinates included)."""
    sys0 = with_input_jets(system, jet_order)
    if sys0.drift is None:  # no drift, no known input: D is the zero field
        n = sys0.n
        sys0 = _working_system(sys0.states, dict(sys0.outputs), lambda z: jnp.zeros(n, z.dtype),
                               dict(sys0.unknown), dict(sys0.domain), sys0.angles, sys0.name,
                               known_coordinates(sys0), sys0.joint_param_names)
    own = sys0 is not with_input_jets(system, jet_order)
    # the System's builder is shared with the other analyses: see _one_off_programs
    ctx = _context(sys0, samples, seed, rtol) if own else Context(sys0, samples, seed, rtol)
    b = ctx.builder
    drift = b.field("g0", sys0.drift)
    uis = [ctx.field_node(k) for k in sys0.unknown]
    return Working(sys0, ctx, drift, uis, list(range(len(uis))), ctx.output_nodes(),
                   system.n - known_coordinates(system), known=frozenset(known_outputs(sys0)))


def _context(system, samples, seed, rtol) -> Context:
    """A Context on one of the algorithm's own Systems, whose builder compiles large
    programs at level 0 (:data:`LARGE_GRAPH`)."""
    ctx = Context(system, samples, seed, rtol)
    ctx.builder.large_graph = LARGE_GRAPH
    return ctx


@contextlib.contextmanager
def _one_off_programs(system):
    """While the block runs, the builder of the System the analysis starts on (possibly the
    user's, shared with the other analyses) compiles at :data:`LARGE_GRAPH`; restored after."""
    builder = builder_for(system)
    before = builder.large_graph
    builder.large_graph = LARGE_GRAPH
    try:
        yield
    finally:
        builder.large_graph = before


# ------------------------------------------------------------------ Close
@dataclasses.dataclass
class Closed:
    """What a closure returns: the span (a forked Context), or an abort."""

    ctx: Context
    aborted: bool = False
    root: Node | None = None
    order: int = 0
    passes: int = 0


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
                    return Closed(ctx, True, root[theta], r, r)
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
    return Closed(ctx, passes=r)


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
        nonzero, frac = _nonzero_votes(lie, gnorm * vnorm, ctx.codist.valid)
        w.zero_tests.append(ZeroTest(f"L_{v.label} {theta.label}", not nonzero, frac))
        if nonzero:
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


def reconstructability(w: Working, theta) -> Reconstructability:
    """``R_ij = L_{g_j} theta_i`` at the samples (as cosines), its generic rank ``m``, the
    first independent rows (identifiers) and, among them, the first independent columns."""
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


# ------------------------------------------------------------------ UI extension
def _lift(fn, N):
    """``fn`` of the first ``N`` coordinates, as a function of a longer state."""
    return lambda Z: fn(Z[:N])


def extend(w: Working, theta_star, order, hat0, hats, tildes, rec, samples, seed, rtol):
    """The UI extension (module docstring) from the aborted guarded closure's root
    ``theta_star`` and ``order``; returns ``(Working, info)`` on the extended system."""
    sysw = w.system
    N, m = sysw.n, len(hats)
    names_ui = [list(sysw.unknown)[c] for c in rec.cols] + \
               [k for i, k in enumerate(sysw.unknown) if i not in rec.cols]
    taken = set(sysw.states)

    def fresh(nm):
        while nm in taken:
            nm += "'"
        taken.add(nm)
        return nm

    ids = [w.theta[i].label for i in rec.rows]  # v_j^(i) = d^(i+1) h~_j / dt^(i+1)
    vnames = [[fresh(f"D{i + 1}({_short(ids[j])})") for i in range(order + 1)] for j in range(m)]
    L = order + 1
    hat0_fn, hat_fns = hat0.fn, [h.fn for h in hats]

    def drift_full(Z):  # on [z; v_1^(0..ord); ..; v_m^(0..ord)]
        z, v = Z[:N], Z[N:].reshape((m, L))
        dz = hat0_fn(z)
        for j in range(m):
            dz = dz + v[j, 0] * hat_fns[j](z)
        chain = jnp.concatenate([v[:, 1:], jnp.zeros((m, 1), Z.dtype)], axis=1)
        return jnp.concatenate([dz, chain.reshape(-1)])

    domain = dict(sysw.domain)
    flat = [nm for row in vnames for nm in row]
    domain.update({nm: DEFAULT_BOX for nm in flat})
    star = _lift(theta_star.fn, N)
    full = _working_system(sysw.states + tuple(flat), {"theta*": star}, drift_full, {}, domain,
                           sysw.angles, sysw.name, known_coordinates(sysw), sysw.joint_param_names)
    ctx_full = _context(full, samples, seed, rtol)
    b = ctx_full.builder
    theta_v = b.power(b.field("F'", drift_full), b.scalar("theta*", star), order)
    grad = ctx_full.gradients([theta_v])[:, 0]  # (S, N + m L)
    gnorm = np.linalg.norm(grad, axis=-1)
    keep_to = []
    for j in range(m):
        top = None
        for i in range(L):
            nz, _ = _nonzero_votes(grad[:, N + j * L + i], gnorm, ctx_full.codist.valid)
            if nz:
                top = i
        keep_to.append(top)
    # the final extended system: kept chains only
    kept_names = [vnames[j][: keep_to[j] + 1] for j in range(m) if keep_to[j] is not None]
    kept_flat = [nm for row in kept_names for nm in row]
    pos_full = {nm: N + j * L + i for j in range(m) for i, nm in enumerate(vnames[j])}
    Nn = N + len(kept_flat)
    kept_index = {nm: N + i for i, nm in enumerate(kept_flat)}
    chains = [(j, [kept_index[nm] for nm in vnames[j][: keep_to[j] + 1]])
              for j in range(m) if keep_to[j] is not None]
    dropped = [j for j in range(m) if keep_to[j] is None]

    def drift_new(Z):
        z = Z[:N]
        dz = hat0_fn(z)
        tail = jnp.zeros(Nn - N, Z.dtype)
        for j, idx in chains:
            dz = dz + Z[idx[0]] * hat_fns[j](z)
            for a, b_ in zip(idx[:-1], idx[1:]):
                tail = tail.at[a - N].set(Z[b_])
        return jnp.concatenate([dz, tail])

    def embed(Z):  # the final state into the full one (dropped coordinates: 0)
        X = jnp.zeros(N + m * L, Z.dtype).at[:N].set(Z[:N])
        for nm, i in kept_index.items():
            X = X.at[pos_full[nm]].set(Z[i])
        return X

    new_uis, new_origin = {}, []
    order_idx = list(rec.cols) + [i for i in range(len(w.uis)) if i not in rec.cols]
    for j in range(m):
        top = -1 if keep_to[j] is None else keep_to[j]
        nm = fresh(f"D{top + 2}({_short(ids[j])})")  # the new unknown input
        if keep_to[j] is None:
            new_uis[nm] = (lambda f: lambda Z: jnp.concatenate([f(Z[:N]), jnp.zeros(Nn - N, Z.dtype)]))(hat_fns[j])
        else:
            unit = kept_index[vnames[j][keep_to[j]]]
            new_uis[nm] = (lambda u: lambda Z: jnp.zeros(Nn, Z.dtype).at[u].set(1.0))(unit)
        new_origin.append(w.origin[order_idx[j]])
    for k, t in enumerate(tildes):
        nm = fresh(f"{names_ui[m + k]}~")
        new_uis[nm] = (lambda f: lambda Z: jnp.concatenate([f(Z[:N]), jnp.zeros(Nn - N, Z.dtype)]))(t.fn)
        new_origin.append(w.origin[order_idx[m + k]])
    outputs = {th.label: _lift(th.fn, N) for th in w.theta}
    for nm in kept_flat:
        outputs[nm] = (lambda i: lambda Z: Z[i])(kept_index[nm])
    tv = theta_v.fn
    outputs["theta_v"] = lambda Z: tv(embed(Z))
    domain_new = {k: v for k, v in domain.items() if k in sysw.states or k in kept_flat}
    new_sys = _working_system(sysw.states + tuple(kept_flat), outputs, drift_new, new_uis,
                              domain_new, sysw.angles, sysw.name, known_coordinates(sysw),
                              sysw.joint_param_names)
    ctx = _context(new_sys, samples, seed, rtol)
    nb = ctx.builder
    uis = [ctx.field_node(k) for k in new_uis]
    theta = ctx.output_nodes()
    info = {"order": order, "root": theta_star.label, "theta_v": theta_v.label,
            "new_states": kept_flat, "ui_without_chain": [names_ui[j] for j in dropped]}
    return Working(new_sys, ctx, nb.field("g0", drift_new), uis, new_origin, theta, w.n0,
                   w.zero_tests, w.known), info


def _short(label: str) -> str:
    """A label fit for a coordinate name (long generator labels are cut)."""
    return label if len(label) <= 24 else label[:21] + "..."


# ------------------------------------------------------------------ the main loop
@dataclasses.dataclass
class Outcome:
    """The finished analysis: the final working system and span, and the trace."""

    w: Working
    omega: Context
    trace: list
    history: list
    stop: object
    initially_canonic: bool
    canonic: bool
    extended: bool
    degree: int
    spent: list  # Contexts whose decisions count for the certificate


def _dim_step(w, ctx, it, added, extra):
    """A Step of the main loop: the dimension of ``ctx``'s span on the original state."""
    _, dim = ctx.coordinates(w.system.n, w.n0)
    fraction = min((d.fraction for d in ctx.codist.acceptances), default=1.0)
    labels = tuple(nd.label for nd in added if nd.label not in w.known)
    return announce_step(Step(it, dim, labels, fraction, extra))


def run(system, *, samples, seed, rtol, jet_order) -> Outcome:
    """The main loop of the module docstring on ``system`` (joint, autonomous)."""
    w = _start(system, jet_order, samples, seed, rtol)
    mw = len(w.uis)
    trace, history, spent = [], [], []
    c = close(w, w.theta, [])
    w.theta = list(c.ctx.codist.nodes)
    if mw == 0:
        omega = close(w, w.theta, [w.drift]).ctx
        history.append(_dim_step(w, omega, 0, omega.codist.nodes, {"action": "closure along g0"}))
        return Outcome(w, omega, trace, history, StopReason.CLOSURE_CONVERGED.stop(m=0),
                       True, True, False, 0, spent)
    initially = None
    extended = False
    for it in range(ITERATION_CAP):
        spent.append(c.ctx)
        rec = reconstructability(w, w.theta)
        m = rec.m
        if initially is None:
            initially = m == mw
        order_idx = list(rec.cols) + [i for i in range(mw) if i not in rec.cols]
        ui_names = list(w.system.unknown)
        entry = {"iteration": it, "m": m, "identifiers": [w.theta[i].label for i in rec.rows],
                 "reconstructable": [ui_names[i] for i in rec.cols],
                 "canonic": m == mw, "fraction": rec.fraction}
        trace.append(entry)
        fields_ordered = [w.uis[i] for i in order_idx]
        if m >= 1:
            hat0, hats, tildes = rescaled_fields(
                w.ctx.builder, w.drift, fields_ordered, [w.theta[i] for i in rec.rows],
                [ui_names[i] for i in order_idx])
        else:
            hat0, hats, tildes = w.drift, [], fields_ordered
        if m == mw:
            entry["action"] = "canonic: closure under the rescaled fields"
            omega = close(w, w.theta, [hat0] + hats).ctx
            history.append(_dim_step(w, omega, it, omega.codist.nodes, {"m": m, "canonic": True}))
            return Outcome(w, omega, trace, history, StopReason.CANONIC_CLOSURE.stop(m=it),
                           initially, True, extended, m, spent)
        tilde_vals = w.field_values(tildes)
        raw_norms = [np.linalg.norm(v, axis=-1) for v in w.field_values(fields_ordered[m:])]
        if all(_field_zero(w, v, ref) for v, ref in zip(tilde_vals, raw_norms)):
            entry["action"] = "every unreconstructed field vanishes: closure"
            omega = close(w, w.theta, [hat0] + hats).ctx
            history.append(_dim_step(w, omega, it, omega.codist.nodes, {"m": m, "canonic": False}))
            return Outcome(w, omega, trace, history, StopReason.REMAINING_UIS_VANISH.stop(m=it),
                           initially, False, extended, m, spent)
        guarded = close(w, w.theta, [hat0] + hats, guard=tildes, guard_scale=raw_norms)
        spent.append(guarded.ctx)
        if not guarded.aborted:
            entry["action"] = "guarded closure converged"
            omega = guarded.ctx
            history.append(_dim_step(w, omega, it, omega.codist.nodes, {"m": m, "canonic": False}))
            return Outcome(w, omega, trace, history, StopReason.GUARD_PASSED.stop(m=it),
                           initially, False, extended, m, spent)
        entry.update({"aborted_at_order": guarded.order, "root": guarded.root.label})
        if m == 0:
            entry["action"] = "m = 0: closure of the UI-free generators along g0"
            before = len(w.theta)
            c = close(w, w.theta, [w.drift], filter_fields=w.uis)
            w.theta = list(c.ctx.codist.nodes)
            history.append(_dim_step(w, c.ctx, it, w.theta[before:], {"m": 0, "canonic": False}))
            if len(w.theta) == before:  # no progress: cannot happen for a generic system
                entry["action"] += " (added nothing)"
                return Outcome(w, c.ctx, trace, history, StopReason.GENERAL_STALLED.stop(m=it),
                               initially, False, extended, m, spent)
            continue
        extended = True
        w, info = extend(w, guarded.root, guarded.order, hat0, hats, tildes, rec, samples, seed, rtol)
        entry["action"] = "UI extension"
        entry["extension"] = info
        c = close(w, w.theta, [])
        w.theta = list(c.ctx.codist.nodes)
        history.append(_dim_step(w, c.ctx, it, w.theta, {"m": m, "canonic": False,
                                                         "extension": len(info["new_states"])}))
    return Outcome(w, c.ctx, trace, history, StopReason.GENERAL_CAP.stop(cap=ITERATION_CAP),
                   initially, False, extended, trace[-1]["m"], spent)


def _field_zero(w, val, ref) -> bool:
    """A field ``G~_k`` identically zero at the samples: ``|G~_k| <= ZERO_ROW_RTOL |g_k|``
    (``ref``: the ``(S,)`` norms of the raw field ``g_k`` it was projected from) by majority."""
    norms = np.linalg.norm(val, axis=-1)
    nz, frac = _nonzero_votes(norms, ref, w.ctx.codist.valid)
    w.zero_tests.append(ZeroTest("G~ vanishes", not nz, frac))
    return not nz


# ------------------------------------------------------------------ observable UIs
def observable_inputs(out: Outcome, full: bool = False) -> dict:
    """Which final unknown inputs ``w~_k`` can be computed: ``dw~_k`` in
    ``span{d theta, d(D theta + sum_j w~_j L_{g_j} theta): theta in Omega}`` on ``[z; w~]``.

    ``full``: every original state is observable (then, with a canonic system, every final
    unknown input is, without the test)."""
    w = out.w
    if not w.uis:
        return {}
    if out.canonic and full:
        # canonic (B invertible, m = m_w) and every coordinate observable: D h~ = a + B w~
        # gives w~ = B^-1 (D h~ - a), a function of observable quantities
        return {k: True for k in w.system.unknown}
    ext = extended_system(w.system, 1)
    ctx = _context(ext, w.ctx.samples, 0, w.ctx.codist.rtol)
    N = w.system.n
    b = ctx.builder
    lifted = [b.scalar(nd.label, _lift(nd.fn, N)) for nd in out.omega.codist.nodes]
    F0 = b.field("F0", ext.drift)
    ctx.absorb(lifted)
    ctx.absorb_lie(lifted, [F0])
    members, _ = ctx.coordinates(ext.n, N)
    out.spent.append(ctx)
    return dict(zip(w.system.unknown, members[N:]))


# ------------------------------------------------------------------ the report
def general_ui_report(system, *, samples, seed, rtol, known_inputs="smooth", notes=(),
                      report_system=None) -> Report:
    """Run the general solution on ``system`` (joint; time as a known coordinate) and build
    the Report on the original state.

    Args:
        system: the System the analyses run on (:meth:`System.autonomous`).
        samples, seed, rtol: the sampling certificate's options.
        known_inputs: the meaning of the known inputs (must be ``"smooth"`` when there are
            any, :func:`check_applicable`).
        notes: notes to carry.
        report_system: the System whose states the Report lists (default ``system``
            without its known coordinates).

    Returns:
        :class:`~uio_jax.Report` with ``method="general_ui"``; ``details``: ``m`` (final
        degree of reconstructability), ``initially_canonic``, ``canonic``, ``ui_extension``,
        ``unknown_inputs_reconstructable`` (original names), ``unknown_inputs_observable``
        (final unknown inputs -> bool), ``final_unknown_inputs`` (final unknown input ->
        the original one it stands for), ``trace`` (one entry per iteration),
        ``jet_order`` (with known inputs).
    """
    check_applicable(system, known_inputs)
    n = system.n - known_coordinates(system)
    jet = n + JET_MARGIN
    with jax.enable_x64(True):
        for attempt in range(JET_RETRIES + 1):
            with _one_off_programs(with_input_jets(system, jet)):
                out = run(system, samples=samples, seed=seed, rtol=rtol, jet_order=jet)
            if not system.known or not _top_jet_used(out, system, jet) or attempt == JET_RETRIES:
                break
            jet = 2 * jet
        truncated = bool(system.known) and _top_jet_used(out, system, jet)
        omega = out.omega
        omega.certify()  # the final span at every sample; the verdicts read there
        members, dim = omega.coordinates(out.w.system.n, n)
        ui_obs = observable_inputs(out, full=all(members))
        for spent in out.spent:
            omega.memberships += [(False, d) for d in spent.codist.acceptances]
            omega.memberships += [(True, d) for d in spent.codist.rejections]
            omega.memberships += spent.memberships
            if spent.codist is not omega.codist:
                omega.codist.escalations.extend(spent.codist.escalations)
    states = system.states[:n]
    observable = dict(zip(states, members[:n]))
    names = list(system.unknown)
    reconstructable = sorted({names[out.w.origin[i]] for i in range(out.degree)},
                             key=names.index) if out.degree else []
    zero_tests = out.w.zero_tests
    weakest = min((t.fraction for t in zero_tests), default=1.0)
    details = {
        "exact": not truncated and out.stop.reason.converged,
        "known_inputs": known_inputs if system.known else "none",
        "m": out.degree,
        "initially_canonic": out.initially_canonic,
        "canonic": out.canonic,
        "ui_extension": out.extended,
        "unknown_inputs_reconstructable": reconstructable,
        "unknown_inputs_observable": ui_obs,
        "final_unknown_inputs": {k: names[out.w.origin[i]] for i, k in enumerate(ui_obs)},
        "zero_tests": len(zero_tests),
        "zero_test_min_fraction": weakest,
        "trace": out.trace,
    }
    if system.known:
        details["jet_order"] = jet
    notes = list(notes)
    if system.known:
        notes.append(
            "known inputs taken as generic smooth functions of time (known_inputs='smooth'): "
            "the exact answer of the general solution for that meaning")
    if truncated:
        notes.append(f"a differentiated generator depends on the highest jet u^({jet}) kept: "
                     "the answer may be incomplete")
    if weakest < 0.9:
        notes.append(f"weak zero test: a 'vanishes identically' decision was backed by only "
                     f"{100 * weakest:.0f}% of the samples")
    space = SampledSpace(omega, n=n, dim=dim)
    return omega.report("general_ui", out.history, out.stop.message, notes=notes,
                        details=details, system=report_system or report_view(system, n),
                        dim=dim, observable=observable, space=space,
                        known_inputs=known_inputs)


def _top_jet_used(out: Outcome, system, jet) -> bool:
    """Whether a generator of Omega depends on a highest jet ``u_i^(jet)`` (other than that
    coordinate itself)."""
    ctx = out.omega
    N0 = system.n
    mu = len(system.known)
    top = [N0 + i * (jet + 1) + jet for i in range(mu)]
    coordinates = set(jet_names(system, jet))
    nodes = [nd for nd in ctx.codist.nodes if nd.label not in coordinates]
    if not nodes:
        return False
    grads = ctx.gradients(nodes)
    norms = np.linalg.norm(grads, axis=-1)
    for c in top:
        for i in range(len(nodes)):
            nz, _ = _nonzero_votes(grads[:, i, c], norms[:, i], ctx.codist.valid)
            if nz:
                return True
    return False
