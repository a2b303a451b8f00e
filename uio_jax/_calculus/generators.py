"""Labelled, memoized nodes: the scalar functions and vector fields of an analysis.

Every function the recursions build (``L_f h``, ``[phi, g] / L_g^1``, ...) is a
:class:`Node` with a readable label. The :class:`Builder` memoizes nodes by
``(operation, operand labels)``, so each is created once per System.

A node is an expression of the System's expression graph (:mod:`uio_jax._engine.graph`;
the model's functions were translated into it when the System was built,
:mod:`uio_jax._engine.graph_trace`): a graph node for a scalar, one per coordinate for a
field. Lie derivatives, brackets and quotients of nodes are expressions too (symbolic
forward mode with shared subexpressions), and their values and gradients are evaluated by
numpy over the samples (:mod:`uio_jax._engine.graph_numpy`): nothing is compiled.
"""

import hashlib
import weakref
from dataclasses import dataclass

import numpy as np

from .._engine import graph_numpy as _graph_numpy
from .._engine.graph import Graph
from .._engine.graph_trace import translate_or_refuse
from .._engine.graph_values import IndexOutOfRange
from .._errors import ModelError


@dataclass(frozen=True, eq=False)
class Node:
    """A scalar function (``kind='scalar'``) or a vector field (``kind='field'``).

    Attributes:
        label: readable name, e.g. ``"L_f4 h_u"`` or ``"[phi1_v, g]/L_g^1"``.
        kind: ``"scalar"`` or ``"field"``.
        depth: number of differentiations behind it (a measure of the expression's size).
        expr: the node in the System's expression graph (an int for a scalar, a tuple of
            ``n`` ints for a field).
    """

    label: str
    kind: str
    depth: int = 0
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
        self.graph = (system.expression_graph if system is not None else None) or (
            Graph(n) if n is not None else None)
        self._nodes: dict[tuple, Node] = {}
        self._gradient_cache: dict = {}  # states key -> {expr: (S, n)}
        self._gradient_bytes = 0
        #: ``(states key, WalkMemo)``: node arrays kept between walks at the latest states
        self._walk_memo = (None, None)
        self._powers: dict[tuple, tuple] = {}  # (node, field label) -> (base node, j)

    def node(self, key, make) -> Node:
        """The node memoized under ``key`` (a tuple), created by ``make()`` the first time."""
        found = self._nodes.get(key)
        if found is None:
            found = self._nodes[key] = make()
        return found

    def scalar(self, label, fn) -> Node:
        """A named scalar function given by the user (an output)."""
        return self.node(("scalar", label), lambda: self.make(label, "scalar", 0, self.translate(fn, (), label)))

    def field(self, label, fn) -> Node:
        """A named vector field given by the user."""
        return self.node(("field", label),
                         lambda: self.make(label, "field", 0, self.translate(fn, (self.graph.n,), label)))

    def function(self, label, fn) -> Node:
        """A scalar function of the state not memoized by name (``Report.is_observable``)."""
        return self.make(label, "scalar", 0, self.translate(fn, (), label))

    def make(self, label, kind, depth, expr) -> Node:
        """A Node of this Builder's graph."""
        return Node(label, kind, depth, expr)

    def translate(self, fn, shape, label="function"):
        """The expression of a model function ``x (n,) -> shape`` in the System's graph:
        an int (scalar) or a tuple of ints (field). The System's validation already
        translated its own functions (:meth:`uio_jax.System.expression`).

        Raises:
            ModelError: the graph has no rule for a primitive of ``fn``, or ``fn`` does
                not return ``shape`` (one line naming the function and the primitive).
        """
        system = self._system()
        if system is not None and system.expression_graph is self.graph:
            return system.expression(fn, shape)
        try:
            return translate_or_refuse(self.graph, fn, shape, label)
        except IndexOutOfRange as exc:
            raise ModelError(f"{label} indexes outside the state vector: {exc}") from None

    def lie(self, v: Node, phi: Node) -> Node:
        """``L_v phi`` (one symbolic derivative of ``phi``'s expression along ``v``).

        Repeated derivatives along the same field are recorded as powers
        (:meth:`power_of`): ``L_v`` of ``L_v^j base`` is ``L_v^(j+1) base``.
        """
        key = ("lie", v.label, phi.label)
        node = self._nodes.get(key)
        if node is not None:
            return node
        base, j = self.power_of(phi, v)
        node = self.make(f"L_{_wrap(v.label)} {phi.label}", "scalar", phi.depth + v.depth + 1,
                         self.graph.jvp([phi.expr], v.expr)[0])
        self._nodes[key] = node
        self._powers[(node, v.label)] = (base, j + 1)
        return node

    def power(self, v: Node, base: Node, j: int, depth=None) -> Node:
        """The power node ``L_v^j base`` (label ``L_v^j base``, ``L_v base`` for ``j = 1``):
        ``L_v`` of it is the power ``j + 1`` of the same base, never a nested word.
        ``depth`` defaults to ``base.depth + j``.
        """
        if j == 0:
            return base
        key = ("power", v.label, base.label, j)
        node = self._nodes.get(key)
        if node is None:
            label = f"L_{_wrap(v.label)}{'' if j == 1 else f'^{j}'} {base.label}"
            expr = base.expr
            for _ in range(j):
                expr = self.graph.jvp([expr], v.expr)[0]
            node = self.make(label, "scalar", base.depth + j if depth is None else depth, expr)
            self._nodes[key] = node
            self._powers[(node, v.label)] = (base, j)
        return node

    def power_of(self, phi: Node, v: Node) -> tuple:
        """``(base, j)`` with ``phi = L_v^j base`` in this graph (``(phi, 0)``: not a power of v)."""
        return self._powers.get((phi, v.label), (phi, 0))

    def bracket(self, a: Node, b: Node) -> Node:
        """``[a, b] = (db/dx) a - (da/dx) b``."""

        def make():
            g = self.graph
            db_a, da_b = g.jvp(b.expr, a.expr), g.jvp(a.expr, b.expr)
            expr = tuple(g.sub(p, q) for p, q in zip(db_a, da_b))
            return self.make(f"[{a.label}, {b.label}]", "field", max(a.depth, b.depth) + 1, expr)

        return self.node(("bracket", a.label, b.label), make)

    def scaled(self, v: Node, s: Node, label=None) -> Node:
        """The field ``v / s``."""

        def make():
            expr = tuple(self.graph.div(c, s.expr) for c in v.expr)
            return self.make(label or f"{_wrap(v.label)}/{_wrap(s.label)}", "field", max(v.depth, s.depth), expr)

        return self.node(("scaled", v.label, s.label), make)

    def ratio(self, num: Node, den: Node, power=1, label=None) -> Node:
        """The scalar ``num / den**power``."""

        def make():
            expr = self.graph.div(num.expr, self.graph.ipow(den.expr, power))
            return self.make(label or f"{_wrap(num.label)}/({den.label})^{power}", "scalar",
                             max(num.depth, den.depth), expr)

        return self.node(("ratio", num.label, den.label, power), make)

    def gradients(self, nodes, xs) -> np.ndarray:
        """Gradients ``(S, c, n)`` of the scalar ``nodes`` (c of them) at the states ``xs``
        ``(S, n)``, by numpy over the graph (NaN/inf where a function is undefined).

        The gradients already evaluated at the same states (a warm call of ``analyze`` with
        the same samples and seed) are kept, up to :data:`GRADIENT_CACHE_BYTES` per System:
        a warm call evaluates nothing twice. Successive calls at the same states share a
        :class:`~uio_jax._engine.graph_numpy.WalkMemo` (the latest states only): an order
        that differentiates the last one's generators walks its new layer of the graph,
        not the whole graph again.
        """
        nodes = tuple(nodes)
        xs = np.asarray(xs, dtype=np.float64)
        if not nodes:
            return np.zeros((xs.shape[0], 0, xs.shape[1]))
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
        roots = [e for nd in nodes for e in ((nd.expr,) if nd.kind == "scalar" else nd.expr)]
        vals = _graph_numpy.evaluate(self.graph, roots, np.asarray(xs), gradients=False)
        out, at = [], 0
        for nd in nodes:
            width = 1 if nd.kind == "scalar" else len(nd.expr)
            out.append(vals[:, at] if nd.kind == "scalar" else vals[:, at:at + width])
            at += width
        return out

    def lie_block(self, phis, fields, xs):
        """All ``L_v phi`` for ``phi in phis`` (scalar nodes), ``v in fields`` (field nodes).

        Returns:
            ``(nodes, grads)``: the memoized Nodes (phi-major order) and their gradients
            at ``xs``, numpy ``(S, len(phis) * len(fields), n)``.
        """
        nodes = [self.lie(v, phi) for phi in phis for v in fields]
        return nodes, self.gradients(nodes, xs)


#: Bytes of gradients a Builder keeps between calls (evaluated at the same states).
GRADIENT_CACHE_BYTES = 256 * 2**20


def _states_key(xs) -> bytes:
    """A digest of the sampled states ``xs`` (the key of the gradients evaluated there)."""
    return hashlib.blake2b(xs.tobytes(), digest_size=16).digest() + repr(xs.shape).encode()


def _wrap(label: str) -> str:
    return label if (" " not in label and "/" not in label) else f"({label})"


_BUILDERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def builder_for(system) -> Builder:
    """The (cached) Builder of a System: the same System reuses its nodes and gradients."""
    b = _BUILDERS.get(system)
    if b is None:
        b = _BUILDERS[system] = Builder(system)
    return b
