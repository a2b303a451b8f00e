"""Labelled, memoized nodes: the scalar functions and vector fields of an analysis.

Every function the recursions build (``L_f h``, ``[phi, g] / L_g^1``, ...) is a
:class:`Node` with a readable label. The :class:`Builder` memoizes nodes by
``(operation, operand labels)``, so each closure is created once per System and the jit
caches keyed on function identity keep hitting across steps and across calls of
``analyze`` on the same System. The batched gradient evaluator of a tuple of nodes is
cached the same way.
"""

import weakref
from dataclasses import dataclass

import jax
import numpy as np

from . import _lie


@dataclass(frozen=True, eq=False)
class Node:
    """A scalar function (``kind='scalar'``) or a vector field (``kind='field'``).

    Attributes:
        label: readable name, e.g. ``"L_f4 h_u"`` or ``"[phi1_v, g]/L_g^1"``.
        fn: the callable, ``x (n,) -> ()`` or ``(n,)``.
        kind: ``"scalar"`` or ``"field"``.
        depth: number of differentiations behind it (a measure of trace size).
    """

    label: str
    fn: object
    kind: str
    depth: int = 0

    def __repr__(self):
        return f"Node({self.label!r})"


class Builder:
    """Creates and memoizes the nodes of one System."""

    def __init__(self):
        self._nodes: dict[tuple, Node] = {}
        self._grad_fns: dict[tuple, object] = {}

    def _get(self, key, make):
        node = self._nodes.get(key)
        if node is None:
            node = make()
            self._nodes[key] = node
        return node

    def scalar(self, label, fn) -> Node:
        """A named scalar function given by the user (an output)."""
        return self._get(("scalar", label), lambda: Node(label, fn, "scalar"))

    def field(self, label, fn) -> Node:
        """A named vector field given by the user."""
        return self._get(("field", label), lambda: Node(label, fn, "field"))

    def lie(self, v: Node, phi: Node) -> Node:
        """``L_v phi``."""
        return self._get(
            ("lie", v.label, phi.label),
            lambda: Node(
                f"L_{_wrap(v.label)} {phi.label}",
                _lie.lie_derivative(phi.fn, v.fn),
                "scalar",
                phi.depth + v.depth + 1,
            ),
        )

    def bracket(self, a: Node, b: Node) -> Node:
        """``[a, b]``."""
        return self._get(
            ("bracket", a.label, b.label),
            lambda: Node(
                f"[{a.label}, {b.label}]",
                _lie.lie_bracket(a.fn, b.fn),
                "field",
                max(a.depth, b.depth) + 1,
            ),
        )

    def scaled(self, v: Node, s: Node, label=None) -> Node:
        """The field ``v / s``."""
        return self._get(
            ("scaled", v.label, s.label),
            lambda: Node(
                label or f"{_wrap(v.label)}/{_wrap(s.label)}",
                _lie.scaled_field(v.fn, s.fn),
                "field",
                max(v.depth, s.depth),
            ),
        )

    def ratio(self, num: Node, den: Node, power=1, label=None) -> Node:
        """The scalar ``num / den**power``."""
        return self._get(
            ("ratio", num.label, den.label, power),
            lambda: Node(
                label or f"{_wrap(num.label)}/({den.label})^{power}",
                _lie.ratio(num.fn, den.fn, power),
                "scalar",
                max(num.depth, den.depth),
            ),
        )

    def gradients(self, nodes, xs) -> np.ndarray:
        """Gradients of scalar ``nodes`` at the states ``xs``.

        Args:
            nodes: sequence of scalar Nodes (c of them).
            xs: states, shape ``(S, n)``, float64.

        Returns:
            numpy array of shape ``(S, c, n)`` (NaN/inf where a function is undefined).
        """
        key = tuple(nodes)
        fn = self._grad_fns.get(key)
        if fn is None:
            fn = jax.jit(jax.vmap(_lie.stacked_gradients(tuple(nd.fn for nd in key))))
            self._grad_fns[key] = fn
        with jax.enable_x64(True):
            return np.asarray(fn(xs))


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
        key = ("block", phis, fields)
        fn = self._grad_fns.get(key)
        if fn is None:
            fn = jax.jit(jax.vmap(_lie.lie_derivative_gradients(
                tuple(p.fn for p in phis), tuple(v.fn for v in fields))))
            self._grad_fns[key] = fn
        with jax.enable_x64(True):
            return nodes, np.asarray(fn(xs))


def _wrap(label: str) -> str:
    return label if (" " not in label and "/" not in label) else f"({label})"


_BUILDERS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def builder_for(system) -> Builder:
    """The (cached) Builder of a System: the same System reuses its nodes and jit caches."""
    b = _BUILDERS.get(system)
    if b is None:
        b = Builder()
        _BUILDERS[system] = b
    return b
