"""Labelled, memoized nodes: the scalar functions and vector fields of an analysis.

Every function the recursions build (``L_f h``, ``[phi, g] / L_g^1``, ...) is a
:class:`Node` with a readable label. The :class:`Builder` memoizes nodes by
``(operation, operand labels)``, so each is created once per System.

**Two representations, one choice.** A node has a JAX callable (``fn``) and, when the
model's functions translate into the System's expression graph
(:mod:`uio_jax._engine.graph`, :mod:`uio_jax._engine.graph_trace`), an expression
(``expr``: a graph node for a scalar, one per coordinate for a field). Lie derivatives,
brackets and quotients of nodes with expressions are expressions too (symbolic forward
mode with shared subexpressions), and their values and gradients are evaluated by numpy
over the samples (:mod:`uio_jax._engine.graph_numpy`): no program is compiled, which is
what a first call needs. The evaluation of a node without an expression (a model with a
primitive the graph has no rule for, a program written for XLA) is compiled by XLA as
before (:meth:`Builder._evaluate`), once per System and shape. The choice is per
evaluation and automatic: the graph whenever every node asked for has an expression.
"""

import functools
import hashlib
import math
import os
import weakref
from dataclasses import dataclass

import jax
import numpy as np

from .._engine import graph_numpy as _graph_numpy
from .._engine import program_cache as _program_cache
from .._engine.graph import Graph
from .._engine.graph_rules import IndexOutOfRange
from .._engine.graph_trace import expressed, translate
from . import lie as _lie
from .powers import lie_power


@dataclass(frozen=True, eq=False)
class Node:
    """A scalar function (``kind='scalar'``) or a vector field (``kind='field'``).

    Attributes:
        label: readable name, e.g. ``"L_f4 h_u"`` or ``"[phi1_v, g]/L_g^1"``.
        fn: the callable, ``x (n,) -> ()`` or ``(n,)``.
        kind: ``"scalar"`` or ``"field"``.
        depth: number of differentiations behind it (a measure of trace size).
        sig: structural signature (the operation tree down to the model's named outputs
            and fields, hashed); empty for a node of unknown provenance. Programs of
            nodes that all have one can be kept on disk (:mod:`uio_jax._program_cache`).
        expr: the node in the System's expression graph (an int for a scalar, a tuple of
            ``n`` ints for a field), or None when it has none (evaluated by XLA).
    """

    label: str
    fn: object
    kind: str
    depth: int = 0
    sig: str = ""
    expr: object = None

    def __repr__(self):
        return f"Node({self.label!r})"


class Builder:
    """Creates and memoizes the nodes of one System."""

    def __init__(self, system=None, n=None):
        self._system = weakref.ref(system) if system is not None else (lambda: None)
        n = system.n if system is not None else n
        #: the System's expression graph (None without a state dimension): the one its
        #: validation built, or a new one
        self.graph = getattr(system, "_graph", None) or (Graph(n) if n is not None else None)
        self._nodes: dict[tuple, Node] = {}
        self._gradient_cache: dict = {}  # states key -> {expr: (S, n)}
        self._gradient_bytes = 0
        #: ``(states key, WalkMemo)``: node arrays kept between walks at the latest states
        self._walk_memo = (None, None)
        self._compiled: dict[tuple, object] = {}
        self._powers: dict[tuple, tuple] = {}  # (node, field label) -> (base node, j)
        self.stats: list[CompileStat] = []
        #: Programs with more jaxpr equations than this are compiled at XLA optimization
        #: level 0 (:data:`LARGE_GRAPH` by default; an analysis whose programs all run once
        #: may lower it).
        self.large_graph = LARGE_GRAPH

    def _get(self, key, make):
        node = self._nodes.get(key)
        if node is None:
            node = make()
            self._nodes[key] = node
        return node

    def node(self, key, make) -> Node:
        """The node memoized under ``key`` (a tuple), created by ``make()`` the first time."""
        return self._get(key, make)

    def scalar(self, label, fn) -> Node:
        """A named scalar function given by the user (an output)."""
        return self._get(("scalar", label), lambda: self.make(label, fn, "scalar", 0, _sig("out", label),
                                                              self.translate(fn, ())))

    def field(self, label, fn) -> Node:
        """A named vector field given by the user."""
        return self._get(("field", label), lambda: self.make(label, fn, "field", 0, _sig("field", label),
                                                             self.translate(fn, (self.graph.n,))))

    def function(self, label, fn) -> Node:
        """A scalar function of the state not memoized by name (``Report.is_observable``)."""
        return self.make(label, fn, "scalar", 0, "", self.translate(fn, ()))

    def make(self, label, fn, kind, depth=0, sig="", expr=None) -> Node:
        """A Node; with an expression its callable becomes an
        :class:`~uio_jax._engine.graph_trace.Expressed` function, so that closures built on
        it (the systems of a UI extension) translate into a graph by importing it."""
        return Node(label, expressed(fn, self.graph, expr), kind, depth, sig, expr)

    def translate(self, fn, shape):
        """The expression of a model function ``x (n,) -> shape`` in the System's graph:
        an int (scalar) or a tuple of ints (field); None when the graph has no rule for one
        of its primitives (the node is then evaluated by XLA). The System's validation
        already translated its own functions (:meth:`uio_jax.System.expression`).
        """
        g = self.graph
        if g is None or fn is None or not graph_route_enabled():
            return None
        system = self._system()
        if system is not None and getattr(system, "_graph", None) is g:
            return system.expression(fn, shape)
        try:
            return translate(g, fn, shape)
        except IndexOutOfRange:
            return None

    def _jvp(self, exprs, v):
        """Graph nodes ``d e . v`` of the expressions ``exprs`` along the field node ``v``."""
        return self.graph.jvp(exprs, v.expr)

    def lie(self, v: Node, phi: Node) -> Node:
        """``L_v phi``.

        Repeated derivatives along the same field, ``L_v^j base``, are evaluated by the one
        power policy (:func:`uio_jax._calculus.powers.lie_power` with ``taylor_from =``
        :data:`TAYLOR_FROM`): below it ``j`` nested ``jvp``, from ``j = TAYLOR_FROM`` on one
        Taylor pass along the flow of ``v`` (the traced graph grows linearly in ``j``
        instead of geometrically: a 35-state model needs ``j`` ~ 15).
        """
        key = ("lie", v.label, phi.label)
        node = self._nodes.get(key)
        if node is not None:
            return node
        base, j = self.power_of(phi, v)
        fn = lie_power(base.fn, v.fn, j + 1, taylor_from=TAYLOR_FROM)
        expr = self._jvp([phi.expr], v)[0] if _both(phi, v) else None
        node = self.make(f"L_{_wrap(v.label)} {phi.label}", fn, "scalar", phi.depth + v.depth + 1,
                         _sig("lie", v.sig, phi.sig), expr)
        self._nodes[key] = node
        self._powers[(node, v.label)] = (base, j + 1)
        return node

    def power(self, v: Node, base: Node, j: int, depth=None) -> Node:
        """The power node ``L_v^j base`` (label ``L_v^j base``, ``L_v base`` for ``j = 1``).

        One node of the graph whatever ``j``, evaluated by the one power policy
        (:func:`uio_jax._calculus.powers.lie_power`, Taylor from ``j = 1``): ``L_v`` of it
        is the power ``j + 1`` of the same base, never a nested word. ``depth`` defaults to
        ``base.depth + j``.
        """
        if j == 0:
            return base
        key = ("power", v.label, base.label, j)
        node = self._nodes.get(key)
        if node is None:
            label = f"L_{_wrap(v.label)}{'' if j == 1 else f'^{j}'} {base.label}"
            expr = None
            if _both(base, v):
                expr = base.expr
                for _ in range(j):
                    expr = self._jvp([expr], v)[0]
            node = self.make(label, lie_power(base.fn, v.fn, j), "scalar",
                             base.depth + j if depth is None else depth,
                             _sig("power", v.sig, base.sig, str(j)), expr)
            self._nodes[key] = node
            self._powers[(node, v.label)] = (base, j)
        return node

    def power_of(self, phi: Node, v: Node) -> tuple:
        """``(base, j)`` with ``phi = L_v^j base`` in this graph (``(phi, 0)``: not a power of v)."""
        return self._powers.get((phi, v.label), (phi, 0))

    def bracket(self, a: Node, b: Node) -> Node:
        """``[a, b] = (db/dx) a - (da/dx) b``."""

        def make():
            expr = None
            if _both(a, b):
                g = self.graph
                db_a, da_b = g.jvp(b.expr, a.expr), g.jvp(a.expr, b.expr)
                expr = tuple(g.sub(p, q) for p, q in zip(db_a, da_b))
            return self.make(f"[{a.label}, {b.label}]", _lie.lie_bracket(a.fn, b.fn), "field",
                             max(a.depth, b.depth) + 1, _sig("bracket", a.sig, b.sig), expr)

        return self._get(("bracket", a.label, b.label), make)

    def scaled(self, v: Node, s: Node, label=None) -> Node:
        """The field ``v / s``."""

        def make():
            expr = None
            if _both(v, s):
                expr = tuple(self.graph.div(c, s.expr) for c in v.expr)
            return self.make(label or f"{_wrap(v.label)}/{_wrap(s.label)}", _lie.scaled_field(v.fn, s.fn),
                             "field", max(v.depth, s.depth), _sig("scaled", v.sig, s.sig), expr)

        return self._get(("scaled", v.label, s.label), make)

    def ratio(self, num: Node, den: Node, power=1, label=None) -> Node:
        """The scalar ``num / den**power``."""

        def make():
            expr = None
            if _both(num, den):
                expr = self.graph.div(num.expr, self.graph.ipow(den.expr, power))
            return self.make(label or f"{_wrap(num.label)}/({den.label})^{power}",
                             _lie.ratio(num.fn, den.fn, power), "scalar", max(num.depth, den.depth),
                             _sig("ratio", num.sig, den.sig, str(power)), expr)

        return self._get(("ratio", num.label, den.label, power), make)

    def _evaluate(self, key, make, xs, streamed=False):
        """Evaluate the vmapped function ``make()`` at ``xs``, compiling once per key/shape.

        Large graphs (nested Lie derivatives) are compiled with XLA's backend optimization
        level 0: it roughly halves compile time, which dominates for these one-off
        functions, at the cost of a slower (still millisecond-scale) execution. With the
        persistent compilation cache on, the traced program is also kept on disk
        (:mod:`uio_jax._program_cache`) and a later process skips the tracing. Trace size
        and compile time are recorded in ``self.stats`` for the benchmarks.

        ``streamed``: compile for one batch of :data:`STREAM_BATCH` samples with
        :data:`STREAM_OPTIONS` and run the batches one after the other (see there: for
        programs whose per-sample intermediates are large, such as Jacobians of deep
        Taylor passes). The program is then the same for every sample count, so a run on
        a subset of the samples reuses it.
        """
        example = xs[:STREAM_BATCH] if streamed else xs
        ck = (key, tuple(example.shape))
        compiled = self._compiled.get(ck)
        with jax.enable_x64(True):
            if compiled is None:
                kind, *groups = key
                parts = [kind] + [",".join(nd.sig for nd in g) if all(nd.sig for nd in g) else ""
                                  for g in groups]
                system = self._system()
                if system is None:
                    parts = [""]  # not keyable without the model's fingerprint
                compiled, t = _program_cache.compile_program(
                    system, parts, lambda batch: _program_cache.vmapped(make(), batch),
                    example, functools.partial(_streamed_options if streamed else _large_graph_options,
                                               threshold=self.large_graph))
                self._compiled[ck] = compiled
                self.stats.append(CompileStat(_key_label(key), t.eqns, t.trace_s, t.compile_s, t.from_disk))
            if streamed:
                return _in_batches(compiled, xs, example.shape[0])
            return compiled(xs)

    def gradients(self, nodes, xs) -> np.ndarray:
        """Gradients of scalar ``nodes`` at the states ``xs``.

        Args:
            nodes: sequence of scalar Nodes (c of them).
            xs: states, shape ``(S, n)``, float64.

        Returns:
            numpy array of shape ``(S, c, n)`` (NaN/inf where a function is undefined).
        """
        nodes = tuple(nodes)
        if _graphed(nodes):
            return self._graph_gradients(nodes, np.asarray(xs, dtype=np.float64))
        make = lambda: _lie.stacked_gradients(tuple(nd.fn for nd in nodes))
        return np.asarray(self._evaluate(("grad", nodes), make, xs))

    def _graph_gradients(self, nodes, xs):
        """Gradients ``(S, c, n)`` of nodes with expressions, by numpy over the graph.

        The gradients already evaluated at the same states (a warm call of ``analyze`` with
        the same samples and seed) are kept, up to :data:`GRADIENT_CACHE_BYTES` per System:
        a warm call evaluates nothing twice. Successive calls at the same states share a
        :class:`~uio_jax._engine.graph_numpy.WalkMemo` (the latest states only): an order
        that differentiates the last one's generators walks its new layer of the graph,
        not the whole graph again.
        """
        key = _states_key(xs)
        cache = self._gradient_cache.get(key)
        if cache is None:
            if self._gradient_bytes > GRADIENT_CACHE_BYTES:
                self._gradient_cache.clear()
                self._gradient_bytes = 0
            cache = self._gradient_cache[key] = {}
        missing = [nd for nd in dict.fromkeys(nodes) if nd.expr not in cache]
        if missing:
            if self._walk_memo[0] != key:
                self._walk_memo = (key, _graph_numpy.WalkMemo())
            grads = _graph_numpy.evaluate(self.graph, [nd.expr for nd in missing], xs,
                                          memo=self._walk_memo[1])[1]
            for i, nd in enumerate(missing):
                cache[nd.expr] = grads[:, i]
            self._gradient_bytes += grads.nbytes
        return np.stack([cache[nd.expr] for nd in nodes], axis=1)

    def values(self, nodes, xs) -> list:
        """Values of nodes (scalars or fields) at the states ``xs``.

        Returns:
            list of numpy arrays, ``(S,)`` for a scalar node and ``(S, n)`` for a field.
        """
        nodes = tuple(nodes)
        if _graphed(nodes):
            roots = [e for nd in nodes for e in ((nd.expr,) if nd.kind == "scalar" else nd.expr)]
            vals = _graph_numpy.evaluate(self.graph, roots, np.asarray(xs), gradients=False)
            out, at = [], 0
            for nd in nodes:
                width = 1 if nd.kind == "scalar" else len(nd.expr)
                out.append(vals[:, at] if nd.kind == "scalar" else vals[:, at:at + width])
                at += width
            return out
        fns = tuple(nd.fn for nd in nodes)
        make = lambda: (lambda x: tuple(f(x) for f in fns))
        return [np.asarray(v) for v in self._evaluate(("values", nodes), make, xs)]

    def program(self, kind, nodes, make, xs, streamed=False) -> np.ndarray:
        """Evaluate ``jax.vmap(make())`` at ``xs``, a program about the scalar ``nodes``.

        Compiled once per ``(kind, nodes, shape)`` like the built-in evaluations, and kept
        on disk by the program cache when every node has a signature. ``streamed``: see
        :meth:`_evaluate`.
        """
        return np.asarray(self._evaluate((kind, tuple(nodes)), make, xs, streamed))

    def lie_block(self, phis, fields, xs):
        """All ``L_v phi`` for ``phi in phis`` (scalar nodes), ``v in fields`` (field nodes).

        Args:
            phis: scalar Nodes.
            fields: field Nodes.
            xs: states ``(S, n)``.

        Returns:
            ``(nodes, grads)``: the memoized Nodes (phi-major order) and their gradients
            at ``xs``, numpy ``(S, len(phis) * len(fields), n)``.
        """
        phis, fields = tuple(phis), tuple(fields)
        nodes = [self.lie(v, phi) for phi in phis for v in fields]
        if not nodes:
            return nodes, np.zeros((xs.shape[0], 0, xs.shape[1]))
        if _graphed(nodes):
            return nodes, self.gradients(nodes, xs)
        make = lambda: _lie.lie_derivative_gradients(
            tuple(p.fn for p in phis), tuple(v.fn for v in fields))
        return nodes, np.asarray(self._evaluate(("block", phis, fields), make, xs))


def graph_route_enabled() -> bool:
    """Whether nodes get expressions in the graph (the default). ``UIO_JAX_ENGINE=xla`` in
    the environment sends every evaluation to XLA instead: a switch to compare the two
    routes and to test the compiled one, read when a Builder translates a function."""
    return os.environ.get("UIO_JAX_ENGINE", "auto") != "xla"


#: Bytes of gradients a Builder keeps between calls (evaluated at the same states).
GRADIENT_CACHE_BYTES = 256 * 2**20


def _states_key(xs) -> bytes:
    """A digest of the sampled states ``xs`` (the key of the gradients evaluated there)."""
    return hashlib.blake2b(xs.tobytes(), digest_size=16).digest() + repr(xs.shape).encode()


#: Graphs with more jaxpr equations than this are compiled at XLA optimization level 0.
LARGE_GRAPH = 20000

#: ``L_v^j base`` with ``j`` at least this is one Taylor pass rather than nested jvp.
TAYLOR_FROM = 3


@dataclass(frozen=True)
class CompileStat:
    """Trace size and compile cost of one jitted evaluation (for benchmarks).

    ``from_disk``: the traced program came from the program cache (``trace_s`` is 0).
    """

    what: str
    eqns: int
    trace_s: float
    compile_s: float
    from_disk: bool = False


#: Samples per call of a streamed program (compiled for this many, run batch after batch).
#: A smaller batch keeps more of each intermediate ``(batch, n tangents, K + 1, ...)`` in
#: the caches; measured on the series Jacobians (``docs/benchmarks/eorc.md``).
STREAM_BATCH = 8

#: XLA options of a streamed program (compile about 25 % faster, same run time; the
#: measurements in ``docs/benchmarks/eorc.md``).
STREAM_OPTIONS = _program_cache.FAST_COMPILE


def _in_batches(compiled, xs, batch):
    """``compiled`` (a program for ``batch`` samples) over all of ``xs`` ``(S, n)``, batch by
    batch; the last batch is padded with the first samples, their rows dropped. Numpy
    ``(S, ...)``."""
    xs = np.asarray(xs)
    count = xs.shape[0]
    pad = -count % batch
    if pad:
        xs = np.concatenate([xs, np.resize(xs, (pad,) + xs.shape[1:])])
    outs = [compiled(xs[i:i + batch]) for i in range(0, xs.shape[0], batch)]
    return np.concatenate([np.asarray(o) for o in outs])[:count]


def _streamed_options(traced, threshold=None):
    """``(eqns, XLA options)`` of a streamed program (level 0 too above the threshold)."""
    eqns, options = _large_graph_options(traced, threshold)
    return eqns, {**(options or {}), **STREAM_OPTIONS}


def _large_graph_options(traced, threshold=None):
    """``(eqns, XLA options)``: optimization level 0 above ``threshold`` (default
    :data:`LARGE_GRAPH`) equations."""
    eqns = _count_eqns(traced.jaxpr.jaxpr)
    limit = LARGE_GRAPH if threshold is None else threshold
    return eqns, ({"xla_backend_optimization_level": 0} if eqns > limit else None)


def _sig(op, *operands) -> str:
    """Signature of a node made by ``op`` from operands (their signatures, or plain names).

    Empty when an operand has none (provenance unknown).
    """
    if any(not o for o in operands):
        return ""
    return hashlib.sha256(repr((op, operands)).encode()).hexdigest()[:32]


def _count_eqns(jaxpr) -> int:
    """Equations of a jaxpr, sub-jaxprs included."""
    return jaxpr_sizes(jaxpr)[0]


def jaxpr_sizes(jaxpr) -> tuple[int, int]:
    """``(equations, array elements their outputs hold)`` of a jaxpr, sub-jaxprs included."""
    eqns = elements = 0
    for eqn in jaxpr.eqns:
        eqns += 1
        elements += sum(math.prod(getattr(v.aval, "shape", ())) for v in eqn.outvars)
        for param in eqn.params.values():
            sub = getattr(param, "jaxpr", None)
            if sub is not None:
                e, el = jaxpr_sizes(getattr(sub, "jaxpr", sub))
                eqns, elements = eqns + e, elements + el
    return eqns, elements


def _key_label(key) -> str:
    kind, *rest = key
    parts = []
    for group in rest:
        parts.append(",".join(nd.label for nd in group))
    return f"{kind}[{' | '.join(parts)}]"


def _both(*nodes) -> bool:
    """Whether every node has an expression in the graph."""
    return all(nd.expr is not None for nd in nodes)


def _graphed(nodes) -> bool:
    """Whether the nodes are evaluated in the graph (every one has an expression)."""
    return bool(nodes) and _both(*nodes)


def _wrap(label: str) -> str:
    return label if (" " not in label and "/" not in label) else f"({label})"


_BUILDERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def builder_for(system) -> Builder:
    """The (cached) Builder of a System: the same System reuses its nodes and jit caches."""
    b = _BUILDERS.get(system)
    if b is None:
        b = Builder(system)
        _BUILDERS[system] = b
    return b
