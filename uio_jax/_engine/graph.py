"""One expression graph per model: scalar nodes with shared subexpressions.

The first verdict on a model must not wait for XLA to compile programs that run once
(``docs/benchmarks/engine.md``). The exact symbolic route is fast because it works on one
expression graph in which every subexpression exists once; this module is that graph,
without a computer algebra system's simplifier:

* **Nodes** are scalars, numbered in creation order, so the operands of a node always
  have smaller numbers (the numbering is a topological order). A node is ``(op, args,
  param)``: a state coordinate ``x`` (param: its index), a constant ``c`` (param: the
  float64 value), or an operation on earlier nodes (``add``, ``mul``, ``div``, ``neg``,
  ``ipow`` with an integer exponent, elementary functions, comparisons, ``select``).
* **Hash-consing**: a node is created once; asking again for the same ``(op, args,
  param)`` returns the same number. ``add`` and ``mul`` order their operands, so
  ``a + b`` and ``b + a`` are one node.
* **Local rules only**: constants are folded, ``0 + a = a``, ``1 * a = a``, ``0 * a = 0``,
  ``-(-a) = a``, ``a ** 1 = a``. Nothing is expanded or factored: the graph of a Lie
  derivative is a few nodes per node of the function it differentiates.
* **Symbolic directional derivatives** (:meth:`Graph.jvp`): ``d phi . v`` for a tangent
  ``v`` given as one node per coordinate, by the chain rule node by node, memoized per
  tangent (the rules: :mod:`.graph_derivatives`): ``L_v phi`` and ``L_v psi`` share the
  derivative of every subexpression of ``phi`` and ``psi`` that they share. A Lie
  derivative of order ``k`` costs ``O(size)`` new nodes per order.

Evaluation is elsewhere: :mod:`.graph_numpy` (float64 values and gradients over many
states, numpy), :mod:`.graph_exact` (exact arithmetic modulo a prime, and mpmath at
extended precision, for the certificate's weak decisions). The translation of a model's
JAX functions into the graph is :mod:`.graph_trace`.
"""

import math
from fractions import Fraction

import numpy as np

from .graph_derivatives import derivative
from .graph_ops import BINARY as BINARY  # the operation sets, imported from here too
from .graph_ops import PIECEWISE_CONSTANT as PIECEWISE_CONSTANT
from .graph_ops import RATIONAL_OPS as RATIONAL_OPS
from .graph_ops import UNARY as UNARY

_FOLD = {
    "neg": lambda a: -a, "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp,
    "log": np.log, "sqrt": np.sqrt, "tanh": np.tanh, "atan": np.arctan, "asin": np.arcsin,
    "acos": np.arccos, "sinh": np.sinh, "cosh": np.cosh, "asinh": np.arcsinh,
    "acosh": np.arccosh, "atanh": np.arctanh, "abs": np.abs, "log1p": np.log1p,
    "expm1": np.expm1, "logistic": lambda a: 1.0 / (1.0 + np.exp(-a)),
    "erf": lambda a: np.float64(math.erf(a)), "cbrt": np.cbrt, "sign": np.sign,
    "floor": np.floor, "ceil": np.ceil, "round": np.round, "not": lambda a: np.float64(a == 0),
    "add": lambda a, b: a + b, "mul": lambda a, b: a * b, "div": lambda a, b: a / b,
    "pow": lambda a, b: a ** b, "atan2": np.arctan2, "lt": lambda a, b: np.float64(a < b),
    "le": lambda a, b: np.float64(a <= b), "gt": lambda a, b: np.float64(a > b),
    "ge": lambda a, b: np.float64(a >= b), "eq": lambda a, b: np.float64(a == b),
    "ne": lambda a, b: np.float64(a != b), "and": lambda a, b: np.float64(bool(a) and bool(b)),
    "or": lambda a, b: np.float64(bool(a) or bool(b)),
}


#: the folds that stay exact on exact constants (:class:`~fractions.Fraction` arithmetic)
_EXACT_FOLD = {"neg": lambda a: -a, "add": lambda a, b: a + b, "mul": lambda a, b: a * b,
               "div": lambda a, b: a / b, "abs": abs}


def exact_literal(value):
    """The exact rational a constant stands for, or None when it has none.

    An int or a :class:`~fractions.Fraction` is itself. A finite float is read as the
    shortest decimal that rounds to it (``repr``): a model's literal ``1.3`` means ``13/10``,
    not the binary float nearest to it, and ``1/7`` written in Python is the decimal
    ``0.14285714285714285``. NaN and infinities have none.
    """
    if isinstance(value, Fraction):
        return value
    if isinstance(value, (int, np.integer, bool, np.bool_)):
        return Fraction(int(value))
    v = float(value)
    if not math.isfinite(v):
        return None
    return Fraction(repr(v)) if v != 0.0 else Fraction(0)


class Graph:
    """A hash-consed graph of scalar expressions in ``n`` state coordinates.

    Args:
        n: number of state coordinates; nodes ``x(0)..x(n-1)`` are created first.

    Attributes:
        op: ``op[i]``, the operation of node ``i`` (a short string, see the module doc).
        args: ``args[i]``, the operand nodes of node ``i`` (all ``< i``).
        param: ``param[i]``: the value of a constant, the index of a coordinate, the
            exponent of an ``ipow``; None otherwise.
        zero, one: the constant nodes 0 and 1.
        facts: per kind, facts derived from the nodes and kept by evaluators.
    """

    def __init__(self, n: int):
        self.n = int(n)
        self.op: list[str] = []
        self.args: list[tuple] = []
        self.param: list = []
        self._intern: dict = {}
        self._tangents: dict = {}
        #: facts about nodes that evaluators derive once and keep (node -> value, per
        #: kind): they never change, since a node never changes
        self.facts: dict = {}
        self.zero = self.const(0.0)
        self.one = self.const(1.0)
        self.coords = tuple(self._node("x", (), i) for i in range(self.n))

    def __len__(self) -> int:
        return len(self.op)

    # ------------------------------------------------------------------ construction
    def _node(self, op, args, param=None, key=None) -> int:
        key = (op, args, param) if key is None else key
        found = self._intern.get(key)
        if found is not None:
            return found
        i = len(self.op)
        self.op.append(op)
        self.args.append(args)
        self.param.append(param)
        self._intern[key] = i
        return i

    def x(self, i: int) -> int:
        """The node of state coordinate ``i``."""
        return self.coords[i]

    def const(self, value) -> int:
        """The node of a constant: exact when ``value`` is an int, a :class:`~fractions.Fraction`
        or a finite float (a float literal means its shortest decimal: ``1.3`` is ``13/10``,
        :func:`exact_literal`); ``-0.0`` is ``0``. Non-finite values are constants known in
        float64 only."""
        exact = exact_literal(value)
        if exact is None:
            return self.inexact_const(value)
        return self._node("c", (), exact)

    def inexact_const(self, value) -> int:
        """The node of a constant known in float64 only (a non-rational function of exact
        constants, ``sin(0.3)``, or a non-finite value): the graphs it enters are not rational
        (:meth:`is_rational`), so no exact decision uses it."""
        v = float(value)
        if v != v:  # NaN: one node (NaN != NaN would defeat the table)
            v = "nan"
        return self._node("c", (), v, key=("c~", (), v))

    def value_of(self, i: int) -> float:
        """The float64 value of constant node ``i``."""
        p = self.param[i]
        if p == "nan":
            return math.nan
        return float(p)

    def exact_value(self, i: int):
        """The exact value of constant node ``i`` (a :class:`~fractions.Fraction`), None for a
        constant known in float64 only."""
        p = self.param[i]
        return p if isinstance(p, Fraction) else None

    def _fold(self, op, *args):
        if not all(self.op[a] == "c" for a in args):
            return None
        exact = [self.exact_value(a) for a in args]
        if op in _EXACT_FOLD and all(e is not None for e in exact):
            try:
                return self.const(_EXACT_FOLD[op](*exact))
            except ZeroDivisionError:
                pass
        with np.errstate(all="ignore"):
            v = _FOLD[op](*(np.float64(self.value_of(a)) for a in args))
        if op in PIECEWISE_CONSTANT and all(e is not None for e in exact) and math.isfinite(v):
            return self.const(Fraction(float(v)))  # a comparison or a rounding: exact
        return self.inexact_const(v)

    def add(self, a: int, b: int) -> int:
        """``a + b``."""
        if a == self.zero:
            return b
        if b == self.zero:
            return a
        return self._commutative("add", a, b)

    def _commutative(self, op, a, b) -> int:
        """``op(a, b)`` for ``add`` or ``mul``: folded when both are constants, else one node
        for both orders of the operands."""
        folded = self._fold(op, a, b)
        if folded is not None:
            return folded
        return self._node(op, (a, b) if a <= b else (b, a))

    def sub(self, a: int, b: int) -> int:
        """``a - b`` (``a + (-b)``)."""
        return self.add(a, self.neg(b))

    def neg(self, a: int) -> int:
        """``-a``."""
        if self.op[a] == "neg":
            return self.args[a][0]
        folded = self._fold("neg", a)
        return folded if folded is not None else self._node("neg", (a,))

    def mul(self, a: int, b: int) -> int:
        """``a * b``."""
        if a == self.zero or b == self.zero:
            return self.zero
        if a == self.one:
            return b
        if b == self.one:
            return a
        if self.op[a] == "c" and self.param[a] == -1.0:  # (a constant times -1 folds in neg)
            return self.neg(b)
        if self.op[b] == "c" and self.param[b] == -1.0:
            return self.neg(a)
        return self._commutative("mul", a, b)

    def div(self, a: int, b: int) -> int:
        """``a / b``."""
        if b == self.one:
            return a
        if a == self.zero and b != self.zero:
            return self.zero
        folded = self._fold("div", a, b)
        return folded if folded is not None else self._node("div", (a, b))

    def ipow(self, a: int, k: int) -> int:
        """``a ** k`` for an integer ``k``."""
        k = int(k)
        if k == 0:
            return self.one
        if k == 1:
            return a
        if self.op[a] == "c":
            exact = self.exact_value(a)
            if exact is not None and (exact != 0 or k > 0):
                return self.const(exact ** k)
            with np.errstate(all="ignore"):
                return self.inexact_const(np.float64(self.value_of(a)) ** k)
        return self._node("ipow", (a,), k)

    def unary(self, op: str, a: int) -> int:
        """An elementary function of one operand (``sin``, ``exp``, ...; see :data:`UNARY`)."""
        if op == "neg":
            return self.neg(a)
        folded = self._fold(op, a)
        return folded if folded is not None else self._node(op, (a,))

    def binary(self, op: str, a: int, b: int) -> int:
        """An operation of two operands (see :data:`BINARY`)."""
        if op == "add":
            return self.add(a, b)
        if op == "mul":
            return self.mul(a, b)
        if op == "div":
            return self.div(a, b)
        if op == "pow":
            e = self.exact_value(b) if self.op[b] == "c" else None
            if e is not None and e.denominator == 1 and abs(e) < 2**31:
                return self.ipow(a, int(e))
            if e == Fraction(1, 2):
                return self.unary("sqrt", a)
            if self.op[b] != "c":  # u^v = exp(v log u): an exponential and a logarithmic kind
                return self.unary("exp", self.mul(b, self.unary("log", a)))
        folded = self._fold(op, a, b)
        return folded if folded is not None else self._node(op, (a, b))

    def select(self, pred: int, if_false: int, if_true: int) -> int:
        """``if_true`` where ``pred`` is nonzero, else ``if_false`` (JAX's ``select_n``)."""
        if if_false == if_true:
            return if_true
        if self.op[pred] == "c":
            return if_true if self.value_of(pred) != 0 else if_false
        return self._node("select", (pred, if_false, if_true))

    def dot(self, a, b) -> int:
        """``sum_i a[i] * b[i]`` of two sequences of nodes (0 when empty)."""
        out = self.zero
        for u, v in zip(a, b):
            out = self.add(out, self.mul(u, v))
        return out

    def solve(self, B, columns):
        """``B^-1 c`` for each column ``c`` of ``columns``, by the adjugate:
        ``B^-1 = adj(B) / det(B)``, ``adj(B)_ij = (-1)^(i+j) M_ji`` (``M_ji``: the minor
        without row ``j`` and column ``i``), minors by Laplace expansion memoized on their
        rows and columns (``2^m`` of them at most: ``m`` is the number of unknown inputs).

        Args:
            B: ``m x m`` nodes (a list of rows), generically invertible.
            columns: a list of columns, each ``m`` nodes.

        Returns:
            one list of ``m`` nodes per column.
        """
        m = len(B)
        minors = {}

        def minor(rows, cols):  # det of B[rows][:, cols], expanded along its first row
            if not rows:
                return self.one
            key = (rows, cols)
            if key not in minors:
                acc = self.zero
                r, rest = rows[0], rows[1:]
                for k, c in enumerate(cols):
                    if B[r][c] == self.zero:
                        continue
                    term = self.mul(B[r][c], minor(rest, cols[:k] + cols[k + 1:]))
                    acc = self.add(acc, term) if k % 2 == 0 else self.sub(acc, term)
                minors[key] = acc
            return minors[key]

        every = tuple(range(m))
        det = minor(every, every)
        adj = [[None] * m for _ in range(m)]
        for i in range(m):
            for j in range(m):
                cof = minor(every[:j] + every[j + 1:], every[:i] + every[i + 1:])
                adj[i][j] = cof if (i + j) % 2 == 0 else self.neg(cof)
        return [[self.div(self.dot(adj[i], c), det) for i in range(m)] for c in columns]

    def import_nodes(self, source: "Graph", roots, coord_map) -> list[int]:
        """The nodes ``roots`` of another graph, rebuilt in this one.

        Args:
            source: the graph ``roots`` live in.
            roots: node numbers of ``source``.
            coord_map: per coordinate of ``source``, the node of this graph it becomes
                (a coordinate, a constant, any expression).

        Returns:
            one node of this graph per root (memoized per source and coordinate map, so
            shared subexpressions stay shared).
        """
        memo = self._tangents.setdefault(("import", source, tuple(coord_map)), {})
        sop, sargs, sparam = source.op, source.args, source.param
        for k in source.reachable(roots, known=memo):
            op, a = sop[k], sargs[k]
            if op == "x":
                memo[k] = coord_map[sparam[k]]
            elif op == "c":
                exact = source.exact_value(k)
                memo[k] = self.const(exact) if exact is not None else self.inexact_const(source.value_of(k))
            elif op == "ipow":
                memo[k] = self.ipow(memo[a[0]], sparam[k])
            elif op == "select":
                memo[k] = self.select(memo[a[0]], memo[a[1]], memo[a[2]])
            elif len(a) == 2:
                memo[k] = self.binary(op, memo[a[0]], memo[a[1]])
            else:
                memo[k] = self.unary(op, memo[a[0]])
        return [memo[r] for r in roots]

    # ------------------------------------------------------------------ structure
    def reachable(self, roots, known=()) -> list[int]:
        """Every node the ``roots`` depend on (themselves included), ascending.

        ``known``: nodes to leave out together with everything reached only through them
        (a cache whose every node came with its operands: the walk stops there, so a
        growing graph is not walked again from the bottom at every call).
        """
        seen = set()
        stack = [r for r in roots]
        args = self.args
        while stack:
            i = stack.pop()
            if i in seen or i in known:
                continue
            seen.add(i)
            stack.extend(args[i])
        return sorted(seen)

    def is_rational(self, roots) -> bool:
        """Whether every node behind ``roots`` is a rational operation (:data:`RATIONAL_OPS`)
        on exact constants."""
        return all(self.is_rational_node(i) for i in self.reachable(roots))

    def is_rational_node(self, i: int) -> bool:
        """Whether node ``i`` is a rational operation (:data:`RATIONAL_OPS`; a constant: an
        exact one)."""
        op = self.op[i]
        return op in RATIONAL_OPS and (op != "c" or isinstance(self.param[i], Fraction))

    # ------------------------------------------------------------------ derivatives
    def jvp(self, roots, tangent) -> list[int]:
        """Directional derivatives ``d r . v`` of the nodes ``roots``.

        Args:
            roots: node numbers (scalars).
            tangent: ``n`` nodes, the direction ``v`` (one per state coordinate).

        Returns:
            one node per root: ``sum_i (d r / d x_i) v_i``, built by the chain rule node by
            node and memoized per tangent (derivatives of shared subexpressions are shared).
        """
        tangent = tuple(tangent)
        if len(tangent) != self.n:
            raise ValueError(f"tangent has {len(tangent)} entries, expected {self.n}")
        memo = self._tangents.setdefault(tangent, {})
        for i in self.reachable(roots, known=memo):  # ascending: operands first
            memo[i] = derivative(self, i, memo, tangent)
        return [memo[r] for r in roots]


__all__ = ["Graph", "RATIONAL_OPS", "PIECEWISE_CONSTANT", "UNARY", "BINARY"]
