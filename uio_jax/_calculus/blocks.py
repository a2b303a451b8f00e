"""Gradient blocks: the gradients of every child ``L_v phi`` of a frontier, order by order.

A recursion that grows a codistribution by Lie derivatives (the EORC,
:mod:`uio_jax._analysis.eorc`) forms, at each order, the children ``L_v phi`` of the
generators ``phi`` it kept at the order before, for ``v`` in a drift ``F0`` and the known
fields ``F_1..F_mu``, and needs their gradients at the samples. This module evaluates them:

* **Generators as nodes.** The children are nodes of the one node graph
  (:class:`~uio_jax._calculus.generators.Builder`): ``L_F0`` of a power ``L_F0^j base`` is
  the power node ``L_F0^(j+1) base`` (one Taylor pass by the one power policy,
  :mod:`uio_jax._calculus.powers`), ``L_{F_i} phi`` a Lie node.
* **A block per order** (:meth:`ChildBlocks.block`): ``d(L_v phi) = H_phi v + (dv)^T dphi``,
  one reverse pass of ``phi`` and one forward-over-reverse Hessian-vector product per field
  (:func:`children_gradients`), all children of the frontier in one jitted program.
* **A chain** (:meth:`ChildBlocks.chain_block`): where the frontier repeats its pattern
  (each ``L_F0 phi`` kept alone), the blocks of the next orders are one program: a Taylor
  pass to the highest power, the Jacobian of all the powers and their Hessian-vector
  products (:class:`Stream` decides, at most :data:`CHAIN_ORDERS` orders).
* **Streaming and asynchronous dispatch** (:class:`Stream`): a block runs over all the
  samples at once or, after a block whose intermediates measured :data:`STREAM_ELEMENTS`
  per sample, in batches of :data:`STREAM_BATCH`; JAX runs it while the caller does the
  rank work of the order before.

The measurements behind these choices are in ``docs/benchmarks/eorc.md``.
Programs are compiled once per System (:func:`blocks_for`) and kept on disk by the program
cache when it is on, so a second analysis of the same System compiles nothing.
"""

import math
import time
import weakref

import jax
import jax.numpy as jnp

from .._engine.program_cache import FAST_COMPILE, compile_program, vmapped
from .generators import Node, jaxpr_sizes
from .powers import taylor_series

#: XLA options of the gradient blocks (faster compiles, equal run times; eorc.md).
BLOCK_OPTIONS = FAST_COMPILE

#: Samples per batch of a streamed block (``lax.map`` of ``vmap``; see STREAM_ELEMENTS).
STREAM_BATCH = 256

#: Per-sample size of a block's intermediates (array elements per jaxpr equation, per
#: sample) from which the *later* blocks of a run go over the samples in batches of
#: :data:`STREAM_BATCH`: a memory-bound block keeps its intermediates in the caches. Sizes
#: grow with the order, so the measurement of order k decides for the orders after it (no
#: block is traced twice). Measurements: ``docs/benchmarks/eorc.md``.
STREAM_ELEMENTS = 16

#: Most orders one chain program covers. A chain is a guess about the frontiers to come;
#: when the run stops earlier it has computed the higher powers for nothing, and its
#: compile time grows with its top power (eorc.md: four rows cover the vehicle's orders 5-8).
CHAIN_ORDERS = 4


def block_options(traced, samples):
    """``(eqns, XLA options, facts)`` of a traced block vmapped over ``samples``: facts
    ``{"elements": mean array elements an equation outputs, per sample}``."""
    eqns, elements = jaxpr_sizes(traced.jaxpr.jaxpr)
    return eqns, BLOCK_OPTIONS, {"elements": elements / (max(eqns, 1) * samples)}


def children_gradients(x, derivatives, fields):
    """Gradients of the children ``L_v phi`` of generators, for every field ``v``.

    ``d(L_v phi) = d(dphi . v) = H_phi v + (dv)^T dphi``: ``H_phi v`` is a
    forward-over-reverse product (``jax.jvp`` of each derivative function along ``v(x)``,
    vmapped over the fields); ``(dv)^T dphi`` comes from one ``jax.vjp`` per field (which
    also gives ``v(x)``), its pullback vmapped over every generator's gradient at once (the
    fields are traced once, however many generators).

    Args:
        x: ``(N,)`` state.
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


class ChildBlocks:
    """The children of generators along a drift and known fields, and their programs.

    One per System (:func:`blocks_for`): the jitted blocks and compiled programs are
    cached here, keyed by the labels of the frontier (labels name nodes uniquely in the
    System's graph).

    Args:
        system: the System the programs are compiled for (the program cache's key).
        builder: its node graph.
        drift: the drift field node ``F0``.
        known: the known field nodes ``F_1..F_mu``.
    """

    def __init__(self, system, builder, drift: Node, known: tuple):
        self._system = weakref.ref(system)
        self.builder = builder
        self.drift = drift
        self.known = tuple(known)
        self.blocks = {}  # (program, batch) -> jitted xs -> gradients
        self.compiled = {}  # (program, xs shape, batch) -> compiled program
        self.stream_after = math.inf  # orders after this one run in batches

    # ------------------------------------------------------------------ generators
    def children(self, phi: Node) -> list:
        """``L_F0 phi`` (a power: ``L_F0^(j+1) base`` for ``phi = L_F0^j base``), then
        ``L_{F_i} phi`` for the known fields, as nodes of the graph."""
        base, j = self.builder.power_of(phi, self.drift)
        up = self.builder.power(self.drift, base, j + 1, depth=phi.depth + 1)
        return [up] + [self.builder.lie(v, phi) for v in self.known]

    def drift_children(self, frontier) -> tuple:
        """``L_F0 phi`` for each generator of ``frontier`` (a tuple, in order)."""
        return tuple(self.children(phi)[0] for phi in frontier)

    def _fields(self):
        """The drift then the known fields, in the order of the children."""
        return (self.drift.fn,) + tuple(v.fn for v in self.known)

    # ------------------------------------------------------------------ programs
    def block(self, phis, batch=None):
        """Jitted ``xs (S, N) -> (S, c, N)``: gradients of every child of ``phis``, the
        children of each ``phi`` in the order of :meth:`children`.

        For ``phi`` and a field ``v``: ``d(L_v phi) = H_phi v + (dv)^T dphi``
        (:func:`children_gradients`): one reverse pass of ``phi`` (a Taylor pass for
        powers) serves all ``1 + m_u`` children, instead of ``N`` forward tangents of each.
        Without known fields the only child of ``phi`` is the power above it, whose
        gradient is one reverse pass: no second derivative (its graph compiles slower and
        slower with the power).
        """
        phis = tuple(phis)
        key = (tuple(p.label for p in phis), batch)
        fn = self.blocks.get(key)
        if fn is not None:
            return fn
        if not self.known:
            ups = [jax.grad(self.children(p)[0].fn) for p in phis]

            def children(x):
                return jnp.stack([g(x) for g in ups])
        else:
            grads = [lambda x, g=jax.grad(p.fn): g(x)[None] for p in phis]
            fields = self._fields()

            def children(x):  # (P (1 + m_u), N)
                return children_gradients(x, grads, fields).reshape(-1, x.shape[0])

        fn = self.blocks[key] = vmapped(children, batch)
        return fn

    def chain_series(self, phis, m, like):
        """Per ``phi_p = L_F0^(j_p) base_p`` of ``phis``: ``(series, j_p')``, the Taylor
        pass of ``base_p`` to the top power a chain of ``m`` orders needs and the index of
        its first row (``j_p``, or ``j_p + 1`` without known fields); None when one base
        has no Taylor pass (:func:`~uio_jax._calculus.powers.taylor_series`)."""
        first = 0 if self.known else 1
        out = []
        for phi in phis:
            base, j = self.builder.power_of(phi, self.drift)
            series = taylor_series(base.fn, self.drift.fn, j + m - 1 + first, like)
            if series is None:
                return None
            out.append((series, j + first))
        return out

    def chain_block(self, phis, m, batch=None):
        """Jitted ``xs (S, N) -> (S, m, P (1 + m_u), N)``: the blocks of ``m`` orders in one
        program, for the frontiers ``{L_F0^i phi_1, .., L_F0^i phi_P}``, ``i = 0..m-1``: row
        ``i`` holds what :meth:`block` of that frontier gives.

        One Taylor pass of each ``base_p`` to power ``j_p + m - 1`` gives its powers; their
        gradients are one reverse pass each (``jax.jacrev`` of the ``m`` powers), and the
        Hessian-vector products along the fields one ``jax.jvp`` of that Jacobian per field.
        Without known fields the rows are the gradients of ``L_F0^(j_p+1+i) base_p``. The
        trace is about as large as the highest order's block alone.
        """
        phis = tuple(phis)
        key = (("chain", tuple(p.label for p in phis), m), batch)
        fn = self.blocks.get(key)
        if fn is not None:
            return fn
        like = jax.ShapeDtypeStruct((self.drift_dim(),), jnp.float64)
        jacs = [jax.jacrev(lambda x, s=series, j=j: s(x)[j:])
                for series, j in self.chain_series(phis, m, like)]
        fields, known = self._fields(), bool(self.known)

        def children(x):  # (m, P (1 + m_u), N), row i: the frontier L_F0^i phi_1..phi_P
            if not known:
                return jnp.stack([jac(x) for jac in jacs], axis=1)
            per = children_gradients(x, jacs, fields)  # (P m, 1 + m_u, N)
            per = per.reshape(len(jacs), m, *per.shape[1:])
            return jnp.swapaxes(per, 0, 1).reshape(m, -1, x.shape[0])

        fn = self.blocks[key] = vmapped(children, batch)
        return fn

    def drift_dim(self) -> int:
        """``N``, the dimension of the System's state."""
        return self._system().n

    def program(self, phis, m, xs, batch, k):
        """The compiled program of :meth:`block` (``m = 0``) or :meth:`chain_block` of
        ``phis`` for the samples ``xs (S, N)``: ``(compiled, compile seconds)``.

        Compiled once per ``(program, shape, batch)``. A block of order ``k`` over all
        samples whose intermediates measure :data:`STREAM_ELEMENTS` or more per sample
        makes the blocks of the orders after ``k`` streamed (:attr:`stream_after`).
        """
        labels = tuple(p.label for p in phis)
        program = ("chain", labels, m) if m else labels
        key = (program, tuple(xs.shape), batch)
        compiled = self.compiled.get(key)
        if compiled is not None:
            return compiled, key, 0.0
        t0 = time.perf_counter()
        if m:
            parts = ["eorc-chain", f"batch {batch}", f"orders {m}", "\n".join(labels)]
            make = lambda b: self.chain_block(phis, m, b or batch)  # noqa: E731
        else:
            parts = ["eorc-block", f"batch {batch}", "\n".join(labels)]
            make = lambda b: self.block(phis, b or batch)  # noqa: E731
        compiled, timing = compile_program(self._system(), parts, make, xs,
                                           lambda traced: block_options(traced, len(xs)))
        self.compiled[key] = compiled
        if batch is None and timing.facts.get("elements", 0.0) >= STREAM_ELEMENTS:
            self.stream_after = min(self.stream_after, k)
        return compiled, key, time.perf_counter() - t0


_BLOCKS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def blocks_for(system, builder, drift: Node, known: tuple) -> ChildBlocks:
    """The (cached) :class:`ChildBlocks` of a System: a second analysis compiles nothing."""
    blocks = _BLOCKS.get(system)
    if blocks is None:
        blocks = _BLOCKS[system] = ChildBlocks(system, builder, drift, known)
    return blocks


class Stream:
    """The gradient blocks of one recursion, order after order (dispatched asynchronously).

    Args:
        blocks: the System's :class:`ChildBlocks`.
        xs: the samples ``(S, N)``.
        last: the highest order of the recursion (a chain ends there).
    """

    def __init__(self, blocks: ChildBlocks, xs, last: int):
        self.blocks = blocks
        self.xs = xs
        self.last = last
        self.frontiers = {}  # order k -> the frontier (nodes) whose children it formed
        self.chain = None  # the chain program in use: k0, m, labels per row, key, grads

    def chain_length(self, frontier, k) -> int:
        """Orders ``k..min(last, k + CHAIN_ORDERS - 1)`` in one chain program: their number,
        or 0 (a block of this order alone).

        A chain is a guess that every later frontier is the drift children of the one
        before (each ``L_F0 phi`` kept, every ``L_{F_i} phi`` rejected). It is made when
        that already happened once: order ``k``'s frontier is the drift children of order
        ``k - 1``'s, in order; and only for two orders or more, where every base has a
        Taylor pass (the other ways evaluate single powers).
        """
        labels = tuple(p.label for p in frontier)
        previous = self.frontiers.get(k - 1)
        if k >= self.last or not labels or previous is None:
            return 0
        if labels != tuple(c.label for c in self.blocks.drift_children(previous)):
            return 0
        m = min(self.last - k + 1, CHAIN_ORDERS)
        like = jax.ShapeDtypeStruct((self.xs.shape[1],), self.xs.dtype)
        return m if self.blocks.chain_series(frontier, m, like) is not None else 0

    def dispatch(self, frontier, k):
        """Start the gradient block of order ``k``: the children of ``frontier``.

        All samples at once, or in batches of :data:`STREAM_BATCH` after an order whose
        block measured :data:`STREAM_ELEMENTS` or more. Where the frontier pattern repeats
        (:meth:`chain_length`) one program computes the blocks of the next orders, and the
        later orders take their rows from it as long as their frontier is the one it
        assumed. JAX runs the program asynchronously.

        Returns:
            ``(frontier, key, compile_s, t_start, grads, row)``: ``grads`` a JAX array
            ``(S, c, N)`` still being computed, ``row`` the order's row in a chain program
            (None: a block of its own).
        """
        labels = tuple(p.label for p in frontier)
        self.frontiers[k] = tuple(frontier)
        chain = self.chain
        if chain is not None:
            row = k - chain["k0"]
            if 0 < row < chain["m"] and labels == chain["labels"][row]:
                return (list(frontier), chain["key"], 0.0, time.perf_counter(),
                        chain["grads"][:, row], row)
            self.chain = None  # the frontier left the assumed pattern
        xs = self.xs
        m = self.chain_length(frontier, k)
        batch = STREAM_BATCH if k > self.blocks.stream_after and len(xs) > STREAM_BATCH else None
        compiled, key, compile_s = self.blocks.program(frontier, m, xs, batch, k)
        t1 = time.perf_counter()
        with jax.enable_x64(True):
            grads = compiled(xs)
        if not m:
            return list(frontier), key, compile_s, t1, grads, None
        rows = [tuple(frontier)]
        for _ in range(m - 1):
            rows.append(self.blocks.drift_children(rows[-1]))
        self.chain = {"k0": k, "m": m, "labels": [tuple(p.label for p in r) for r in rows],
                      "key": key, "grads": grads}
        return list(frontier), key, compile_s, t1, grads[:, 0], 0


__all__ = ["BLOCK_OPTIONS", "STREAM_BATCH", "STREAM_ELEMENTS", "CHAIN_ORDERS", "block_options",
           "children_gradients", "ChildBlocks", "blocks_for", "Stream"]
