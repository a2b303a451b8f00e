"""Extended observability rank criterion (EORC): any number of unknown inputs, drift allowed.

Martinelli, INRIA RR-8608 (004) sections 4-6 and MED 2015 (001) section IV, Algorithm 1.

**Extended system** (004 eq. 4-7). With ``m_w`` unknown inputs ``w = [w_1..w_mw]`` the state
is augmented by the inputs and their time derivatives up to order ``K - 1``::

    x^(K) = [x; w; w^(1); ...; w^(K-1)]                       (n + K m_w)
    F0    = [f0(x) + sum_j g_j(x) w_j; w^(1); ...; w^(K-1); 0]   (extended drift)
    F_i   = [f_i(x); 0]                                        (known fields)

and the output is still ``h(x)``. ``Omega-bar_k`` is the span of the gradients (with respect
to the whole extended state) of every Lie derivative of the outputs along ``F0, F_1..F_mu``
of order ``<= k`` (001 Algorithm 1)::

    Omega-bar_0 = span{dh},   Omega-bar_k = Omega-bar_{k-1} + sum_{v in {F0, F_i}} L_v Omega-bar_{k-1}.

``x_j`` satisfies the EORC at order k when ``e_j`` (padded with zeros) lies in
``Omega-bar_k``; then ``x_j`` is weakly locally observable (001 Proposition 4). It is a
sufficient condition only: a component not shown observable up to ``k_max`` may become so
at a higher order.

**One extension, every order.** By Proposition 2 of 004 the Lie derivatives of order
``<= k`` computed in ``Sigma^(k)`` and in ``Sigma^(K)`` (``K >= k``) coincide, and by Lemma 1
they do not depend on ``w^(f)``, ``f >= k``: the order-``<= k`` part of one run on
``Sigma^(k_max)`` *is* ``Omega-bar_k`` of the k-th extension (padded with zero columns).
So the extension is built once, at ``K = k_max``, and an ORC-like recursion runs on it with
step ``k`` = order ``k``.

**Pruning.** As in :mod:`uio_jax._orc`, only the generators kept at order ``k - 1`` are
differentiated at order ``k``: if ``dc = sum_i a_i dk_i`` (``a_i`` functions of the
extended state) then ``L_v dc = sum_i (L_v a_i) dk_i + a_i d L_v k_i``, and ``L_v k_i`` was
formed at the step after ``k_i`` was kept, at order ``<= k``. The argument holds in
``Sigma^(K)`` for every order ``<= K`` (the truncation ``dw^(K-1)/dt = 0`` only changes
orders ``> K``). If no generator is kept at some order ``k <= K``, ``Omega-bar`` is
invariant under every ``L_v`` and no higher order (in any extension) adds anything.

**Per order k** the report gives: the rank of ``Omega-bar_k`` (augmented rank, out of
``n + k m_w``), the dimension on the original state ::

    dim_k = rank(Omega-bar_k) + n - rank([Omega-bar_k; e_1..e_n])
          = dim(Omega-bar_k  intersected with  span{dx_1..dx_n}),

the state components with ``e_j`` in ``Omega-bar_k``, and the extended coordinates
(unknown inputs and their derivatives, ``w^(d)`` with ``d < k``) whose ``e`` lies in
``Omega-bar_k``: those are observable too, so the disturbance can be estimated.
For a single unknown input and no drift, Theorem 1 of 004 gives
``Omega-bar_k = [Omega_k, 0] + span{d L_G^1 h .. d L_G^k h}``, so ``dim_k = dim Omega_k``.

**Evaluation, and why it scales.** The order-k generators are mostly ``L_F0^j`` of a
short word (each order brings ``w^(k-1)`` in through the drift). Nested ``jax.jvp`` traces
``L_F0^j psi`` in a graph growing like ``2.5^j`` (measured: 65k jaxpr equations and ~100 s
of XLA compile for the vehicle at j = 8 with ``jax.experimental.jet``, worse with nested
jvp). So a generator is kept as a structure (``("pow", base, j)`` = ``L_F0^j base``,
``("lie", F_i, parent)``) and ``L_F0`` of a power raises the power; a whole chain is one
Taylor pass along the flow of ``F0`` in stacked-coefficient arithmetic
(:mod:`uio_jax._taylor`, a graph growing linearly in j: ~1.4k equations at j = 8), with
``jax.experimental.jet`` and then nested jvp as fallbacks for primitives without a rule.
Per order, one jitted block evaluates the gradients of all children of the frontier,
``d(L_v phi) = H_phi v + (dv)^T dphi`` for ``v`` in ``F0, F_1..F_mu``: one reverse pass
of ``phi`` and one forward-over-reverse Hessian-vector product per field (not ``N``
forward tangents of every child: 5-7x less work on the vehicle); compiled blocks are
cached per extended System, so a second analysis of the same System compiles nothing.
Where the frontier repeats its pattern (the drift children of the last frontier kept
alone, as in the higher orders of the vehicle in wind), the blocks of the next orders (up to
:data:`CHAIN_ORDERS`) are one *chain* program: one Taylor pass to the highest power, the
Jacobian of all the powers and its Hessian-vector products. It compiles about as fast as
the highest order's block alone (vehicle to k = 8 cold: 69-70 s -> 47.5-47.8 s) and runs
0-20 % slower than the blocks it replaces; an order whose frontier leaves the pattern gets
its own block again.

**Sampling.** The extended coordinates are sampled, like states without a given domain, in
``uio_jax._system.DEFAULT_BOX`` = (0.5, 1.5): positive, away from 0, where inputs such as a
speed make the rank drop (a vehicle at rest shows no heading). For analytic models the
generic rank is the same on every open set of the extended space.
"""

import copy
import math
import time
import weakref

import jax
import jax.numpy as jnp
import numpy as np

from .._calculus.generators import Node, jaxpr_sizes
from .._calculus.lie import lie_derivative
from .._engine.program_cache import FAST_COMPILE, compile_program, vmapped
from .._engine.taylor import lie_powers
from .._errors import ModelError
from .._model.system import DEFAULT_BOX, System, derived_system
from .._progress import announce_step
from .context import Context
from .report import Report, Step

#: Name of the extended drift field in generator labels.
DRIFT_LABEL = "F0"

_EXTENSIONS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def default_k_max(system: System) -> int:
    """Default highest order: ``n + 2`` (the bound of the single-input case, 004 section 9)."""
    return system.n + 2


def input_names(system: System, K: int) -> tuple[str, ...]:
    """Names of the extended coordinates ``w, w^(1), .., w^(K-1)`` (order-major).

    Each unknown input keeps its name for order 0 and gets ``^(d)`` for its d-th derivative;
    a clash with a state name gets a ``'`` appended.

    Returns:
        ``K * m_w`` names, ordered ``[w_1..w_mw, w_1^(1)..w_mw^(1), ...]`` as in 004 eq. 4.
    """
    taken = set(system.states)
    out = []
    for d in range(K):
        for w in system.unknown:
            nm = w if d == 0 else f"{w}^({d})"
            while nm in taken:
                nm += "'"
            taken.add(nm)
            out.append(nm)
    return tuple(out)


def extended_system(system: System, K: int) -> System:
    """``Sigma^(K)`` of 004 section 4 as a :class:`~uio_jax.System` (cached per System and K).

    Args:
        system: the original System (``n`` states, ``m_w`` unknown inputs, ``m_u`` known).
        K: number of input orders in the extension (``K >= 1``).

    Returns:
        A System with ``n + K m_w`` states (``states + input_names``), the same outputs
        (functions of the first n coordinates), the known fields padded with zeros, the
        extended drift ``F0`` (eq. 6) and no unknown input (the last derivatives
        ``w^(K)`` enter only through unit vectors along which every Lie derivative of
        order ``<= K`` vanishes, Proposition 1 of 004).
    """
    per = _EXTENSIONS.setdefault(system, {})
    ext = per.get(K)
    if ext is not None:
        return ext
    n, mw = system.n, len(system.unknown)
    names = input_names(system, K)
    N = n + K * mw
    drift, gs = system.drift, tuple(system.unknown.values())

    def F0(X):
        x, xi = X[:n], X[n:]
        w = xi[:mw]
        dx = jnp.zeros(n, dtype=X.dtype) if drift is None else drift(x)
        for j, g in enumerate(gs):
            dx = dx + g(x) * w[j]
        tail = jnp.concatenate([xi[mw:], jnp.zeros(mw, dtype=X.dtype)])
        return jnp.concatenate([dx, tail])

    def pad_field(f):
        def F(X):
            return jnp.concatenate([f(X[:n]), jnp.zeros(N - n, dtype=X.dtype)])

        return F

    def pad_output(h):
        def H(X):
            return h(X[:n])

        return H

    domain = dict(system.domain)
    domain.update({nm: DEFAULT_BOX for nm in names})
    with derived_system():  # the parts are the validated system's functions, padded
        ext = System(
            states=system.states + names,
            outputs={k: pad_output(h) for k, h in system.outputs.items()},
            known={k: pad_field(f) for k, f in system.known.items()},
            drift=F0,
            domain=domain,
            angles=system.angles,
            name=f"{system.name or 'system'} extended to order {K}",
        )
    per[K] = ext
    return ext


# ---------------------------------------------------------------------------------------
# Lie derivatives along the extended drift by Taylor mode (jax.experimental.jet)
# ---------------------------------------------------------------------------------------
def _flow_derivatives(F, x, order):
    """Time derivatives ``x^(1)..x^(order)`` at t = 0 of the flow ``x' = F(x)``, ``x(0) = x``.

    ``x^(i+1) = d^i/dt^i F(x(t))``: one ``jet`` of F per order, fed with the derivatives
    found so far (jet's derivative convention, ``x(t) = sum_i x^(i) t^i / i!``).

    Args:
        F: field ``(N,) -> (N,)``; x: ``(N,)``; order: >= 1.

    Returns:
        list of ``order`` arrays ``(N,)``.
    """
    from jax.experimental.jet import jet

    series = [F(x)]
    for _ in range(1, order):
        _, out = jet(F, (x,), (tuple(series),))
        series.append(out[-1])
    return series


def lie_power(psi, F, j):
    """``x -> L_F^j psi (x)`` by Taylor mode: ``d^j/dt^j psi(x(t))`` along the flow of F.

    Nested ``jax.jvp`` traces ``L_F^j psi`` in a graph that grows like ``2.5^j`` (each
    level doubles the previous one, common sub-expressions are not shared); the Taylor
    recursion of :func:`_flow_derivatives` grows like ``j^2`` (Griewank & Walther,
    "Evaluating Derivatives", ch. 13).
    """
    from jax.experimental.jet import jet

    if j == 0:
        return psi

    def power(x):
        series = _flow_derivatives(F, x, j)
        _, out = jet(psi, (x,), (tuple(series),))
        return out[j - 1]

    return power


def _taylor_power(psi, F, j):
    """``L_F^j psi`` by stacked-coefficient Taylor arithmetic (:mod:`uio_jax._taylor`)."""
    if j == 0:
        return psi
    powers = lie_powers(psi, F, j)

    def power(x):
        return powers(x)[j]

    return power


#: Ways to evaluate ``L_F0^j``, tried in this order (a model primitive without a rule in
#: one falls back to the next).
_MODES = ("taylor", "jet", "nested")

def _nested_power(psi, F, j):
    """``L_F^j psi`` by nested ``jax.jvp`` (fallback when a primitive has no jet rule)."""
    fn = psi
    for _ in range(j):
        fn = lie_derivative(fn, F)
    return fn


def _fork(codist):
    """An independent copy of a Codistribution (arrays copied, decisions lists fresh)."""
    c = copy.copy(codist)
    c.valid = codist.valid.copy()
    c.grads = codist.grads.copy()
    c.basis = codist.basis.copy()
    c.ref = codist.ref.copy()
    c.nodes = list(codist.nodes)
    c.rejections, c.acceptances = [], []
    return c


_RUNS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()

#: XLA options of the gradient blocks (:data:`uio_jax._program_cache.FAST_COMPILE`).
#: Measured, fresh processes, 4096 samples: vehicle in wind to k = 8 cold 86 -> 64 s,
#: visual-inertial to k = 3 cold 105 -> 56 s; warm times equal.
_BLOCK_OPTIONS = FAST_COMPILE

#: Samples per step when a block runs over the samples in batches (``lax.map`` of
#: ``vmap``); see :data:`STREAM_ELEMENTS`.
STREAM_BATCH = 256

#: Per-sample size of a block's intermediates (array elements per jaxpr equation, per
#: sample) from which the run's *later* blocks go over the samples in batches of
#: :data:`STREAM_BATCH`. A block is memory-bound when its intermediates are large: at 4096
#: samples each one streams through memory, in batches of 256 it stays in the caches.
#: Measured, 4096 samples, warm block seconds all at once -> in batches: vehicle in wind,
#: powers j = 4, 5, 6 (40, 57, 76 elements per equation) 0.22 -> 0.15, 0.38 -> 0.29,
#: 0.50 -> 0.37 s, compile equal; its k = 2, 3 blocks (11, 18) equal; the
#: visual-inertial k = 3 block (12: 30 000 small equations, the per-batch loop costs more
#: than the caches give) 0.42 -> 0.52 s and compile 34 -> 40 s. Sizes grow with the order,
#: so the measurement of order k decides for orders > k (no block is traced twice): after
#: the vehicle's k = 3 block (18), the visual-inertial blocks stay whole (<= 12).
STREAM_ELEMENTS = 16


#: Most orders one chain program covers (:meth:`_Eorc._chain_length`). A chain is a
#: guess about the frontiers to come; when the run stops earlier (a drift child rejected,
#: every state observable), the chain has compiled and computed the higher powers for
#: nothing, and its compile time grows with its top power. Four rows cover the vehicle's
#: orders 5-8 in one program; the visual-inertial model at its default k_max = 18 (one
#: generator per order from order 4 on, nothing new at order 10) would otherwise compile
#: and run a chain to order 18.
CHAIN_ORDERS = 4


def _block_options(traced, samples):
    """``(eqns, XLA options, facts)`` of a traced block vmapped over ``samples``: facts
    ``{"elements": mean array elements an equation outputs, per sample}``."""
    eqns, elements = jaxpr_sizes(traced.jaxpr.jaxpr)
    return eqns, _BLOCK_OPTIONS, {"elements": elements / (max(eqns, 1) * samples)}


def _children_gradients(x, derivatives, fields):
    """Gradients of the children ``L_v phi`` of generators, for every field ``v``.

    ``d(L_v phi) = d(dphi . v) = H_phi v + (dv)^T dphi``: ``H_phi v`` is a
    forward-over-reverse product (``jax.jvp`` of each derivative function along ``v(x)``,
    vmapped over the fields); ``(dv)^T dphi`` comes from one ``jax.vjp`` per field (which
    also gives ``v(x)``), its pullback vmapped over every generator's gradient at once (the
    fields traced once, however many generators: vehicle in wind, k = 1, 2 blocks compile
    0.7-1.0 s faster each than with one vjp per generator).

    Args:
        x: ``(N,)`` extended state.
        derivatives: functions ``x -> (r, N)``, the gradients of ``r`` generators each
            (``jax.grad`` of one generator with a leading axis, or ``jax.jacrev`` of
            several powers).
        fields: the ``F`` fields ``(N,) -> (N,)``.

    Returns:
        ``(R, F, N)``: row ``i`` = generator ``i`` of the derivatives in order (``R`` =
        sum of their ``r``), its children in the order of ``fields``.
    """
    values, pulls = zip(*(jax.vjp(v, x) for v in fields))
    V = jnp.stack(values)  # (F, N)
    grads, hvs = [], []
    for d in derivatives:
        dphi, hv = jax.vmap(lambda t, d=d: jax.jvp(d, (x,), (t,)))(V)  # (F, r, N) each
        grads.append(dphi[0])
        hvs.append(jnp.swapaxes(hv, 0, 1))
    D = jnp.concatenate(grads)  # (R, N): every generator's gradient, pulled back once
    jtg = jnp.stack([jax.vmap(lambda g, p=pull: p(g)[0])(D) for pull in pulls], 1)
    return jnp.concatenate(hvs) + jtg


class _Eorc:
    """State of one EORC run: the Context on ``Sigma^(K)`` and the per-order evidence.

    Generators are kept as structures, so that their functions can be rebuilt with or
    without Taylor mode: ``("out", h)``, ``("lie", v, parent)`` (``L_v parent`` by one
    ``jax.jvp``, v a known field) and ``("pow", base, j)`` (``L_F0^j base`` by
    :func:`lie_power`). ``L_F0`` of a ``pow`` node raises its power instead of nesting.
    The jitted gradient evaluators are cached per extended System, so a second analysis
    of the same System compiles nothing.
    """

    def __init__(self, system, K, samples, seed, rtol):
        self.system = system
        self.K = K
        self.n = system.n
        self.mw = len(system.unknown)
        self.ext = extended_system(system, K)
        self.names = input_names(system, K)
        self.ctx = Context(self.ext, samples, seed, rtol)
        self.cache = _RUNS.setdefault(self.ext, {"struct": {}, "fns": {}, "blocks": {},
                                                   "mode": _MODES[0], "compiled": {},
                                                   "stream_after": math.inf})
        self.struct = self.cache["struct"]
        for k, h in self.ext.outputs.items():
            self.struct.setdefault(k, ("out", h))
        self.known = tuple(self.ext.known.items())
        self.extra_decisions = []  # (member, RankDecision) of the dim-on-x tests
        self.compile_s = []  # seconds spent tracing + compiling, per order
        self.steps = []  # per order: frontier size, candidates, compile and eval seconds
        self.frontiers = {}  # order k -> labels of the frontier whose children it formed
        self.chain = None  # the chain program in use (see dispatch)

    # ------------------------------------------------------------------ generators
    def _fn(self, label):
        """The function of a generator (memoized per Taylor-mode setting)."""
        mode = self.cache["mode"]
        key = (label, mode)
        fn = self.cache["fns"].get(key)
        if fn is None:
            kind = self.struct[label]
            if kind[0] == "out":
                fn = kind[1]
            elif kind[0] == "lie":
                fn = lie_derivative(self._fn(kind[2]), self.ext.known[kind[1]])
            else:
                power = {"taylor": _taylor_power, "jet": lie_power, "nested": _nested_power}[mode]
                fn = power(self._fn(kind[1]), self.ext.drift, kind[2])
            self.cache["fns"][key] = fn
        return fn

    def _node(self, label, depth):
        """The generator's Node, memoized in the System's builder (so a second analysis
        finds the compiled programs of the first). Labels name the structure uniquely
        (``self.struct``); the function also depends on the mode."""
        mode = self.cache["mode"]
        return self.ctx.builder.node(
            ("eorc", label, mode),
            lambda: Node(label, self._fn(label), "scalar", depth, f"eorc:{mode}:{label}"))

    def _children(self, phi):
        """Labels of ``L_F0 phi`` then ``L_{F_i} phi`` (registering their structures)."""
        return self._child_labels(phi.label)

    def _child_labels(self, label):
        """:meth:`_children` of the generator named ``label``."""
        base, j = self._power_of(label)
        up = f"L_{DRIFT_LABEL}{'' if j == 0 else '^' + str(j + 1)} {base}"
        self.struct.setdefault(up, ("pow", base, j + 1))
        out = [up]
        for name, _ in self.known:
            lbl = f"L_{name} {label}"
            self.struct.setdefault(lbl, ("lie", name, label))
            out.append(lbl)
        return out

    def _fields(self):
        """The extended drift then the known fields, as in the order of the children."""
        return (self.ext.drift,) + tuple(f for _, f in self.known)

    def _power_of(self, label):
        """``(base, j)`` with the generator ``label`` = ``L_F0^j base`` (``j = 0``: itself)."""
        kind = self.struct[label]
        return (kind[1], kind[2]) if kind[0] == "pow" else (label, 0)

    def _block(self, phis, batch=None):
        """Jitted ``xs (S, N) -> (S, c, N)``: gradients of every child of ``phis``.

        For a generator ``phi`` and a field ``v`` (``F0`` then the known ``F_i``)::

            d(L_v phi) = d(dphi . v) = H_phi v + (dv)^T dphi          (N,)

        ``H_phi v`` is one forward-over-reverse Hessian-vector product (``jax.jvp`` of
        ``jax.grad(phi)`` along ``v(x)``) and ``(dv)^T dphi`` one pullback of each field
        (:func:`_children_gradients`). One reverse pass of ``phi`` (a Taylor pass for
        powers) serves all ``1 + m_u`` children, instead of ``N`` forward tangents of each
        child (``jax.jacfwd``): measured 5-7x faster on the vehicle in wind at every order.

        Without known fields the only child of ``phi = L_F0^j base`` is the power
        ``L_F0^(j+1) base``, whose gradient is one reverse pass: no second derivative,
        whose graph compiles slower and slower with j (StrikePy's TS model, k = 6:
        compile 46 s as a Hessian-vector product, 25 s so; run 0.08 s either way).
        """
        key = (tuple(p.label for p in phis), self.cache["mode"], batch)
        fn = self.cache["blocks"].get(key)
        if fn is not None:
            return fn
        if not self.known:  # every child is L_F0 phi = L_F0^(j+1) base (phi a power or an output)
            ups = [jax.grad(self._fn(self._children(p)[0])) for p in phis]

            def children(x):
                return jnp.stack([g(x) for g in ups])
        else:
            grads = [lambda x, g=jax.grad(self._fn(p.label)): g(x)[None] for p in phis]
            fields = self._fields()

            def children(x):  # (P (1 + m_u), N)
                return _children_gradients(x, grads, fields).reshape(-1, x.shape[0])

        fn = vmapped(children, batch)
        self.cache["blocks"][key] = fn
        return fn

    def _chain_block(self, labels, m, batch=None):
        """Jitted ``xs (S, N) -> (S, m, P (1 + m_u), N)``: the blocks of ``m`` orders in one
        program, for the frontiers ``{L_F0^i phi_1, .., L_F0^i phi_P}``, ``i = 0..m-1``
        (``phi_p`` = ``labels[p]`` = ``L_F0^(j_p) base_p``): row ``i`` holds the gradients
        of the children of every ``L_F0^i phi_p``, as :meth:`_block` of that frontier would
        give them (the children of ``phi_1`` first).

        One Taylor pass of each ``base_p`` to order ``j_p + m - 1`` gives its powers; their
        gradients are one reverse pass each (``jax.jacrev``, vmapped over the ``m`` rows),
        and the Hessian-vector products along the fields are one ``jax.jvp`` of that
        Jacobian per field. Without known fields the rows are the gradients of
        ``L_F0^(j_p+1+i) base_p`` (a pass to order ``j_p + m``, no second derivative).

        The trace is about as large as the block of the highest order alone, so the ``m``
        orders compile once instead of ``m`` times (vehicle in wind, orders 5-8: 4 237
        equations, 8.9 s, against 30 s for their four blocks); each row costs about as much
        to run as the highest order's block (the reverse passes of the lower powers run
        through the whole pass: orders 5-8 1.96 s against 1.65 s as blocks), so the chain
        is used only where the frontier pattern repeats, for a few orders at a time (see
        :meth:`_chain_length`).
        """
        key = (("chain", labels, m), self.cache["mode"], batch)
        fn = self.cache["blocks"].get(key)
        if fn is not None:
            return fn
        # per generator: the Jacobian x -> (m, N) of its m powers (without known fields:
        # of the m powers above them, the only children)
        first = 1 if not self.known else 0
        jacs = []
        for label in labels:
            base, j = self._power_of(label)
            powers = lie_powers(self._fn(base), self.ext.drift, j + m - 1 + first)
            jacs.append(jax.jacrev(lambda x, powers=powers, j=j + first: powers(x)[j:]))
        fields = self._fields()

        def children(x):  # (m, P (1 + m_u), N), row i: the frontier L_F0^i phi_1..phi_P
            if not self.known:
                return jnp.stack([jac(x) for jac in jacs], axis=1)
            per = _children_gradients(x, jacs, fields)  # (P m, 1 + m_u, N)
            per = per.reshape(len(jacs), m, *per.shape[1:])
            return jnp.swapaxes(per, 0, 1).reshape(m, -1, x.shape[0])

        fn = vmapped(children, batch)
        self.cache["blocks"][key] = fn
        return fn

    def dispatch(self, frontier, k):
        """Start the gradient block of order ``k``: the children of ``frontier``.

        Compiled if needed; all samples at once, or in batches of :data:`STREAM_BATCH`
        after an order whose block measured :data:`STREAM_ELEMENTS` or more. Where the
        frontier pattern repeats (:meth:`_chain_length`), one program computes the blocks
        of the next orders (:meth:`_chain_block`, at most :data:`CHAIN_ORDERS`) and the
        later orders take their rows from it as long as their frontier is the one it
        assumed.

        JAX runs the block asynchronously: the caller can do the rank work of the current
        order while it computes, then hand the result to :meth:`absorb_children`.

        Returns:
            ``(frontier, key, compile_s, t_start, grads, row)`` with ``grads`` a JAX array
            ``(S, c, N)`` still being computed and ``row`` the order's row in a chain
            program (None: a block of its own).
        """
        labels = tuple(p.label for p in frontier)
        self.frontiers[k] = labels
        chain = self.chain
        if chain is not None:
            row = k - chain["k0"]
            if 0 < row < chain["m"] and labels == chain["labels"][row]:
                return (list(frontier), chain["key"], 0.0, time.perf_counter(),
                        chain["grads"][:, row], row)
            self.chain = None  # the frontier left the assumed pattern
        xs = self.ctx.xs
        t0 = time.perf_counter()
        while True:
            m = self._chain_length(labels, k)
            batch = STREAM_BATCH if k > self.cache["stream_after"] and len(xs) > STREAM_BATCH else None
            program = ("chain", labels, m) if m else labels
            key = (program, self.cache["mode"], xs.shape, batch)
            compiled = self.cache["compiled"].get(key)
            if compiled is not None:
                break
            if m:
                parts = ["eorc-chain", self.cache["mode"], f"batch {batch}", f"orders {m}",
                         "\n".join(labels)]
                make = lambda b, batch=batch, m=m: self._chain_block(labels, m, b or batch)  # noqa: E731
            else:
                parts = ["eorc-block", self.cache["mode"], f"batch {batch}", "\n".join(labels)]
                make = lambda b, batch=batch: self._block(frontier, b or batch)  # noqa: E731
            try:
                compiled, timing = compile_program(
                    self.ext, parts, make, xs, lambda traced: _block_options(traced, len(xs)))
                self.cache["compiled"][key] = compiled
                if batch is None and timing.facts.get("elements", 0.0) >= STREAM_ELEMENTS:
                    self.cache["stream_after"] = min(self.cache["stream_after"], k)
                break
            except (NotImplementedError, KeyError, TypeError, ValueError):  # no rule
                mode = self.cache["mode"]
                if mode == _MODES[-1]:
                    raise
                self.cache["mode"] = _MODES[_MODES.index(mode) + 1]
                self.cache["blocks"].clear()
                self.cache["compiled"].clear()
        t1 = time.perf_counter()
        with jax.enable_x64(True):
            grads = compiled(xs)
        if not m:
            return list(frontier), key, t1 - t0, t1, grads, None
        chain_labels = [labels]
        for _ in range(m - 1):
            chain_labels.append(self._drift_children(chain_labels[-1]))
        self.chain = {"k0": k, "m": m, "labels": chain_labels, "key": key, "grads": grads}
        return list(frontier), key, t1 - t0, t1, grads[:, 0], 0

    def _chain_length(self, labels, k):
        """Orders ``k..min(K, k + CHAIN_ORDERS - 1)`` in one chain program
        (:meth:`_chain_block`): their number, or 0 (a block of this order alone).

        A chain is a guess that every later frontier is the drift children of the one
        before (each ``L_F0 phi`` kept, every ``L_{F_i} phi`` rejected), as in the higher
        orders of the vehicle in wind (one generator) or of StrikePy's
        ``TS_unknown_inputs_reparameterized`` (two, no known field). It is made when that
        already happened once: order ``k``'s frontier is the drift children of order
        ``k - 1``'s, in order. If a later frontier differs, the chain is dropped and that
        order gets its own block. Only in Taylor mode (the fallbacks evaluate single
        powers), and for two orders or more. At most :data:`CHAIN_ORDERS` orders: where the
        pattern goes on, the next chain starts after this one by the same rule.
        """
        previous = self.frontiers.get(k - 1)
        if (self.cache["mode"] != "taylor" or k >= self.K or not labels
                or previous is None or labels != self._drift_children(previous)):
            return 0
        return min(self.K - k + 1, CHAIN_ORDERS)

    def _drift_children(self, labels):
        """Labels of ``L_F0 phi`` for each generator of ``labels`` (a tuple, in order)."""
        return tuple(self._child_labels(label)[0] for label in labels)

    def absorb_children(self, frontier, k, started=None):
        """Form ``L_v phi`` for every phi of the frontier and v in ``F0, F_i``; absorb them.

        ``started``: the :meth:`dispatch` of the same frontier, if it was started earlier
        (its ``eval_s`` then includes the work done meanwhile).
        """
        if not frontier:
            return []
        if started is None:
            started = self.dispatch(frontier, k)
        frontier, key, compile_s, t1, pending, row = started
        labels = [lbl for phi in frontier for lbl in self._children(phi)]
        grads = np.asarray(pending)
        self.compile_s.append(compile_s)
        self.steps.append({"k": k, "frontier": len(frontier), "candidates": len(labels),
                           "compile_s": compile_s, "eval_s": time.perf_counter() - t1,
                           "key": key, "chain_row": row})
        nodes = [self._node(lbl, k) for lbl in labels]
        return self.ctx.absorb(nodes, grads)

    def coordinates(self, k, meanwhile=None):
        """What ``Omega-bar_k`` says about the coordinates of ``Sigma^(k)``, certified.

        The unit covectors ``e_1..e_{n + k m_w}`` are tested against the span once
        (:meth:`~uio_jax._rank.Codistribution.test_units`); that
        one test decides every membership and starts the dimension on the original state::

            dim_k = rank(Omega-bar) + n - rank([Omega-bar; e_1..e_n]),

        for which ``e_1..e_n`` are absorbed one by one into a copy of the codistribution
        (each one that raises the generic rank removes one dimension).

        ``meanwhile()`` is called once the memberships are known and some state is not
        observable, before the dimension is computed (the run starts the next order's
        block there, so that it computes during this host-side rank work).

        Returns:
            ``(states, inputs, dim)``: names of the states and of the input coordinates
            (orders < k) whose ``e`` lies in Omega-bar, and ``dim_k``.
        """
        codist = self.ctx.codist
        n = self.n
        N_k = n + k * self.mw
        tested = codist.test_units(N_k)
        results = codist.contains(None, tested)
        self.ctx.memberships.extend(results)
        names = self.ext.states[:N_k]
        states = [s for s, (m, _) in zip(names[:n], results[:n]) if m]
        inputs = [s for s, (m, _) in zip(names[n:], results[n:]) if m]
        if len(states) == n:
            return states, inputs, n
        if meanwhile is not None:
            meanwhile()
        if codist.rank == 0:
            return states, inputs, 0
        fork = _fork(codist)
        first = tested.first(n)
        added = fork.absorb([Node(f"e_{s}", None, "scalar") for s in self.system.states], None,
                            first)
        self.extra_decisions += [(False, d) for d in fork.acceptances]
        self.extra_decisions += [(True, d) for d in fork.rejections]
        return states, inputs, n - len(added)


def run_eorc(system, *, samples, seed, rtol, k_max=None):
    """Run the EORC recursion up to ``k_max``.

    Returns:
        ``(run, history, stop_reason, k_reached)`` where ``run`` is the :class:`_Eorc`.
    """
    K = default_k_max(system) if k_max is None else int(k_max)
    run = _Eorc(system, K, samples, seed, rtol)
    ctx = run.ctx
    history = []
    started = []  # the next order's block, dispatched while this order's rank work runs

    def record(k, added):
        def start_next():  # the next order will run: frontier not empty, k < K, not full
            if k < K and added:
                started.append(run.dispatch(added, k + 1))

        states, inputs, dim = run.coordinates(k, start_next)
        extra = {
            "augmented_rank": ctx.dim,
            "augmented_dim": run.n + k * run.mw,
            "observable_states": tuple(states),
            "observable_inputs": tuple(inputs),
        }
        decided = ctx.codist.acceptances[-len(added):] if added else []
        fraction = min((d.fraction for d in decided), default=1.0)
        history.append(announce_step(Step(k, dim, tuple(nd.label for nd in added), fraction, extra)))
        return len(states) == run.n

    frontier = ctx.absorb([run._node(k, 0) for k in run.ext.outputs])
    full = record(0, frontier)
    k = 0
    while True:
        if full:
            return run, history, f"every state component observable at k={k}", k
        if k >= K:
            return run, history, f"k_max={K} reached", k
        k += 1
        frontier = run.absorb_children(frontier, k, started.pop() if started else None)
        full = record(k, frontier)
        if not frontier and not full:
            return run, history, (
                f"Omega-bar_{k} = Omega-bar_{k - 1}: no higher order (in any extension) adds "
                "a generator"), k


def eorc_report(system, *, samples, seed, rtol, k_max=None, notes=()) -> Report:
    """The EORC of ``system`` as a :class:`~uio_jax.Report` (called by ``analyze``).

    Args:
        system: the original System.
        samples, seed, rtol: sampling certificate options (see :func:`uio_jax.analyze`).
        k_max: highest order (default ``n + 2``).
        notes: notes to carry (e.g. why ``auto`` chose the EORC).

    Returns:
        Report on the ORIGINAL state: ``dim`` = dim of ``Omega-bar_k`` intersected with
        ``span{dx}`` at the last order ``k``; ``history`` has one Step per order
        ``k = 0..k_reached`` (``Step.m = k``; ``extra``: ``augmented_rank``,
        ``augmented_dim``, ``observable_states``, ``observable_inputs``;
        ``Step.fraction`` is the smallest fraction of agreeing samples among the rank
        decisions that kept the order's generators); ``details``:
        ``k``, ``k_max``, ``extended_state``, ``inputs_observable_at`` (first order at
        which each input coordinate is observable).
    """
    if k_max is not None and (isinstance(k_max, bool) or int(k_max) < 1):
        raise ModelError(f"k_max must be a positive integer, got {k_max!r}")
    with jax.enable_x64(True):
        run, history, reason, k = run_eorc(system, samples=samples, seed=seed, rtol=rtol,
                                           k_max=k_max)
        ctx = run.ctx
        last = history[-1]
        observable = {s: s in last.extra["observable_states"] for s in system.states}
        first_seen = {}
        for st in history:
            for nm in st.extra["observable_inputs"]:
                first_seen.setdefault(nm, st.m)
        ctx.memberships.extend(run.extra_decisions)
    notes = list(notes)
    if not all(observable.values()):
        hidden = [s for s, v in observable.items() if not v]
        notes.append(
            f"the EORC is a sufficient condition only: {', '.join(hidden)} not shown "
            f"observable up to order k={k} (k_max={run.K}); a higher order may show more"
        )
    notes.append(
        "extended coordinates (unknown inputs and their derivatives) sampled in "
        f"{DEFAULT_BOX}; unobservable_directions(x) sets them to the centre of that box"
    )
    details = {
        "k": k,
        "k_max": run.K,
        "extended_state": list(run.ext.states[: run.n + max(k, 1) * run.mw]),
        "augmented_ranks": [st.extra["augmented_rank"] for st in history],
        "observable_inputs": {st.m: list(st.extra["observable_inputs"]) for st in history},
        "inputs_observable_at": first_seen,
    }
    return ctx.report("eorc", history, reason, notes=notes, details=details, system=system,
                      dim=last.dim, observable=observable, space=_EorcSpace(run, last.dim))


class _EorcSpace:
    """``Omega-bar_k`` of a finished run, queried by a Report about the original state."""

    def __init__(self, run: _Eorc, dim: int):
        self._run = run
        self._nodes = tuple(run.ctx.codist.nodes)
        self._dim = dim

    def unobservable_directions(self, x) -> np.ndarray:
        """Annihilator in R^n of ``Omega-bar_k`` intersected with ``span{dx}`` at ``x``.

        The extended coordinates are set to the centre of their sampling box (1.0). With
        ``Q`` an orthonormal basis of the row space of ``Omega-bar`` at ``[x, xi_c]`` and
        ``P = I - Q^T Q``, a covector ``[a; 0]`` lies in ``Omega-bar`` iff ``P[:, :n] a = 0``;
        the right singular vectors of ``P[:, :n]`` for its ``n - dim`` largest singular
        values span the annihilator of that intersection.

        Args:
            x: original state, ``(n,)``.

        Returns:
            ``(n, n - dim)``, orthonormal columns.
        """
        run = self._run
        n, N = run.n, run.ext.n
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (n,):
            raise ModelError(f"state must have shape ({n},), got {x.shape}")
        if not np.isfinite(x).all():
            raise ModelError("state contains NaN/inf")
        if self._dim == n:
            return np.zeros((n, 0))
        if not self._nodes:
            return np.eye(n)
        lo, hi = DEFAULT_BOX
        X = np.concatenate([x, np.full(N - n, 0.5 * (lo + hi))])
        with jax.enable_x64(True):
            g = run.ctx.builder.gradients(self._nodes, jnp.asarray(X)[None])[0]
        if not np.isfinite(g).all():
            raise ModelError("the codistribution is not defined at this state (NaN/inf)")
        g = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-300)
        _, _, vt = np.linalg.svd(g)
        q = vt[: len(self._nodes)]
        P = np.eye(N) - q.T @ q
        _, _, wt = np.linalg.svd(P[:, :n])
        return wt[: n - self._dim].T.copy()

    def sample_singular_values(self) -> np.ndarray:
        """``(S_used, r)`` ratios ``s_i / s_1`` of the kept generators of ``Omega-bar_k``."""
        return self._run.ctx.codist.sample_ratios()

    def is_observable(self, fn) -> bool:
        """Whether ``d fn`` (padded with zeros) lies in ``Omega-bar_k`` at the samples.

        Args:
            fn: callable ``x (n,) -> ()`` of the ORIGINAL state.
        """
        if not callable(fn):
            raise ModelError(f"is_observable needs a callable x -> scalar, got {type(fn).__name__}")
        run = self._run
        n, N = run.n, run.ext.n
        with jax.enable_x64(True):
            try:
                out = jax.eval_shape(fn, jax.ShapeDtypeStruct((n,), jnp.float64))
            except Exception as exc:
                raise ModelError(f"function fails on a state of length {n}: "
                                 f"{type(exc).__name__}") from None
            if getattr(out, "shape", None) != ():
                raise ModelError("function must return a scalar (), got shape "
                                 f"{getattr(out, 'shape', None)}")
            xs = run.ctx.xs
            grads = np.asarray(jax.jit(jax.vmap(jax.grad(fn)))(xs[:, :n]))
        cov = np.zeros((1, xs.shape[0], N))
        cov[0, :, :n] = grads
        member, _ = run.ctx.codist.contains(cov)[0]
        return bool(member)
