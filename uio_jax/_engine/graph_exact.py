"""The expression graph (:mod:`.graph`) evaluated beyond float64: exactly modulo a prime,
or in extended precision with mpmath.

A float64 rank decision can be wrong near its tolerance: a genuine direction whose scaled
singular value is 1e-8 looks like round-off, and round-off in a high-order derivative can
look like a direction. The certificate settles such decisions again here, at a few random
points:

* **Modulo a prime** (:class:`ModularEvaluator`), for graphs made of rational operations
  (:meth:`uio_jax._engine.graph.Graph.is_rational`: its constants are exact rationals, a
  literal read as its decimal value, :func:`uio_jax._engine.graph.exact_literal`). Values
  and forward-mode gradients are computed in the field ``F_p``, ``p = 2^127 - 1``, with
  Python integers (numpy object arrays over the points), every node once per set of
  points. The rank of the gradients at a point of ``F_p^n`` is never above the generic
  rank over the rationals (an identically vanishing minor vanishes modulo ``p`` too), and
  equals it unless the point is a root of a nonzero minor: by the Schwartz-Zippel lemma,
  with probability at most ``D / p`` for a minor of degree ``D`` (:func:`degrees` bounds it).
* **mpmath** (:class:`ExtendedEvaluator`), for any graph: values and gradients in ``dps``
  decimal digits. Repeated at two precisions, a genuine small number keeps its value
  while round-off shrinks with the precision.
"""

import math
from collections import Counter
from fractions import Fraction

import numpy as np

from . import graph_elementary
from .graph import exact_literal
from .graph_elementary import Singular, inverse_mod_p
from .graph_numpy import columns, place_rows
from .graph_ops import unary_slopes

#: The prime of the modular evaluation: the Mersenne prime ``2^127 - 1`` (Python integers;
#: a minor of degree ``D`` vanishes at a random point with probability at most
#: ``D / 1.7e38``).
PRIME = 2**127 - 1


def const_mod(value, p: int = PRIME) -> int:
    """An exact constant (a :class:`~fractions.Fraction`, an int, or a float read as its
    decimal literal, :func:`uio_jax._engine.graph.exact_literal`) modulo ``p``."""
    f = value if isinstance(value, Fraction) else exact_literal(value)
    if f is None:
        raise ValueError("a non-finite constant has no value modulo p")
    return (f.numerator % p) * pow(f.denominator % p, -1, p) % p


class ModularEvaluator:
    """Values and gradients of rational graph nodes at fixed points of ``F_p^n``.

    Every node evaluated is kept, so that successive requests (the escalations of one
    analysis, at the same points) evaluate each node once. Arithmetic on numpy object
    arrays of Python integers: values ``(P,)``; gradients sparse as in the float64 walk
    (:func:`uio_jax._engine.graph_numpy.columns`): ``(c, P)`` over the ``c`` coordinates a
    node depends on (on the EORC's extended states a node depends on a few of them), None
    for a node that depends on none.

    Sums and negations are not reduced modulo ``p`` (a residue plus a residue is a
    representative of their sum): only products, quotients and powers are, and a node
    after :data:`_UNREDUCED_DEPTH` unreduced sums in a row, so the integers stay within a
    few bits of ``p``. What leaves the evaluator (:meth:`row`, :meth:`gradients`) is
    reduced.

    Args:
        graph: the graph.
        points: ``(P, n)`` integers in ``[0, p)``.
        p: an odd prime.
    """

    def __init__(self, graph, points, p: int = PRIME):
        self.graph, self.p = graph, int(p)
        self.points = np.array([[int(v) % self.p for v in row] for row in points], dtype=object)
        self.V, self.G = {}, {}
        self._depth = {}  # node -> unreduced sums on its way since the last reduction
        #: the values of the elementary functions' generators at the points
        #: (:mod:`.graph_elementary`), drawn from the points themselves
        seed = [int(v) % 2**32 for v in self.points.reshape(-1)[:64]]
        self.draws = graph_elementary.Draws(self.p, len(self.points), seed)

    def gradients(self, roots):
        """``values (P, R)`` and ``grads (P, R, n)`` (object arrays of residues).

        Raises:
            Singular: a denominator vanishes at one of the points.
            ValueError: a node is not a rational operation.
        """
        self.evaluate(roots)
        P, n = self.points.shape
        values = np.stack([self.V[r] % self.p for r in roots], axis=1)
        grads = np.zeros((P, len(roots), n), dtype=object)
        for i, r in enumerate(roots):
            grads[:, i] = self.dense(r).T
        return values, grads

    def row(self, root, point: int):
        """The gradient ``(n,)`` of an evaluated node (:meth:`evaluate`) at one point."""
        return self.dense(root)[:, point]

    def dense(self, root):
        """The reduced gradient ``(n, P)`` of an evaluated node."""
        P, n = self.points.shape
        out = np.zeros((n, P), dtype=object)
        g = self.G[root]
        if g is not None:
            out[list(columns(self.graph, [root])[0][root])] = g % self.p
        return out

    def evaluate(self, roots) -> None:
        """Evaluate the nodes behind ``roots`` not evaluated yet (kept in :attr:`V`, :attr:`G`).

        Raises:
            Singular: a denominator vanishes at one of the points.
            ValueError: a node is not a rational operation.
        """
        graph, p = self.graph, self.p
        V, G, depth = self.V, self.G, self._depth
        P = len(self.points)
        ops, args, params = graph.op, graph.args, graph.param
        todo = graph.reachable(roots, known=V)
        cols, where = columns(graph, todo)

        def lift(k, a, factor=None):
            """The operand's gradient (times ``factor``) in the node's rows; None if zero."""
            return place_rows(G[a], factor, where.get((k, a)), len(cols[k]), object)

        def total(ga, gb):
            return ga if gb is None else gb if ga is None else ga + gb

        for k in todo:
            op, a = ops[k], args[k]
            d = 0
            if op == "x":
                v = self.points[:, params[k]].copy()
                g = np.ones((1, P), dtype=object)
            elif op == "c":
                value = graph.exact_value(k)
                if value is None:
                    raise ValueError("a constant known in float64 only has no value modulo p")
                v, g = np.full(P, const_mod(value, p), dtype=object), None
            elif op == "add":
                v = V[a[0]] + V[a[1]]
                g = total(lift(k, a[0]), lift(k, a[1]))
                d = max(depth[a[0]], depth[a[1]]) + 1
            elif op == "neg":
                v, g = -V[a[0]], None if G[a[0]] is None else -G[a[0]]
                d = depth[a[0]] + 1
            elif op == "mul":
                va, vb = V[a[0]], V[a[1]]
                v = (va * vb) % p
                g = total(lift(k, a[0], vb), lift(k, a[1], va))
            elif op == "div":
                inv = inverse_mod_p(V[a[1]], p)
                v = (V[a[0]] * inv) % p
                g = total(lift(k, a[0], inv), lift(k, a[1], (-v * inv) % p))
            elif op == "ipow":  # u^k, or (1/u)^-k for k < 0; the slope k u^(k-1) likewise
                kk = params[k]
                base = V[a[0]] % p if kk > 0 else inverse_mod_p(V[a[0]], p)
                v = np.array([pow(int(x), abs(kk), p) for x in base], dtype=object)
                slope = np.array([kk % p * pow(int(x), abs(kk - 1), p) % p for x in base], dtype=object)
                g = None if G[a[0]] is None else G[a[0]] * slope
            elif graph_elementary.rationalizable(graph, k):
                (v, slopes), g = graph_elementary.evaluate(graph, k, V, self.draws), None
                for operand, slope in zip(a, slopes):
                    g = total(g, lift(k, operand, slope))
            else:
                raise ValueError(f"{op} is not a rational operation")
            if d > _UNREDUCED_DEPTH or op not in ("add", "neg"):
                v, d = v % p, 0
                if g is not None:
                    g = g % p
            V[k], G[k], depth[k] = v, g, d


#: Sums and negations in a row a :class:`ModularEvaluator` leaves unreduced (each at most
#: doubles the integers).
_UNREDUCED_DEPTH = 16


def gradients_mod_p(graph, roots, points, p: int = PRIME):
    """Values and gradients of rational graph nodes at points of ``F_p^n`` (one-off
    :class:`ModularEvaluator`): ``values (P, R)``, ``grads (P, R, n)``, residues."""
    return ModularEvaluator(graph, points, p).gradients(roots)


def rank_mod_p(mat, p: int = PRIME) -> int:
    """Rank of an integer matrix ``(r, n)`` over ``F_p`` (Gaussian elimination, Python
    integers)."""
    echelon = Echelon(p)
    for row in np.asarray(mat, dtype=object):
        echelon.add(row)
    return echelon.rank


def rational_reconstruction(a: int, p: int = PRIME):
    """The fraction ``u/v`` with ``u = a v mod p`` and ``|u|, v < sqrt(p / 2)`` (rational
    reconstruction, by the extended Euclidean algorithm), or None when there is none."""
    bound = math.isqrt(p // 2)
    r0, r1, s0, s1 = p, a % p, 0, 1
    while r1 > bound:
        q = r0 // r1
        r0, r1, s0, s1 = r1, r0 - q * r1, s1, s0 - q * s1
    if s1 == 0 or abs(s1) > bound:
        return None
    return Fraction(r1, s1)


class Echelon:
    """Rows of ``F_p^n`` in reduced echelon form, grown one row at a time: the rank of a
    growing list of rows, and whether a row lies in their span.

    Each kept row has a pivot column where it is 1 and every other kept row is 0, so a row
    is reduced by one elimination per pivot column where it is nonzero, without fill-in at
    the other pivots: ``O(n)`` per such column (a unit covector ``e_j``: at most one), and
    keeping a row costs ``O(r n)``.

    Args:
        p: the prime.
    """

    def __init__(self, p: int = PRIME):
        self.p = p
        self.rows: list[list[int]] = []
        self.pivots: list[int] = []
        self.added = 0  # rows offered to :meth:`add`

    @property
    def rank(self) -> int:
        return len(self.rows)

    def reduce(self, row) -> list[int]:
        """The remainder of ``row`` after eliminating the pivot columns (zero iff in the span)."""
        p = self.p
        v = [int(x) % p for x in row]
        for r, c in zip(self.rows, self.pivots):
            f = v[c]
            if f:
                v = [(a - f * b) % p for a, b in zip(v, r)]
        return v

    def add(self, row) -> bool:
        """Append ``row``; whether it raised the rank."""
        self.added += 1
        v = self.reduce(row)
        c = next((i for i, x in enumerate(v) if x), None)
        if c is None:
            return False
        p = self.p
        inv = pow(v[c], -1, p)
        v = [x * inv % p for x in v]
        for i, r in enumerate(self.rows):  # the new pivot column cleared in the other rows
            f = r[c]
            if f:
                self.rows[i] = [(a - f * b) % p for a, b in zip(r, v)]
        self.rows.append(v)
        self.pivots.append(c)
        return True

    def copy(self) -> "Echelon":
        e = Echelon(self.p)
        e.rows, e.pivots, e.added = list(self.rows), list(self.pivots), self.added
        return e


def degrees(graph, roots, memo=None) -> list[tuple[int, int]]:
    """Upper bounds ``(deg numerator, deg denominator)`` of rational graph nodes written as
    quotients of polynomials in the coordinates.

    A denominator is kept as a product of *atoms*, the numerators of the nodes divided by
    (``{atom node: multiplicity}``), so that a sum of terms over the same denominators
    takes their least common multiple instead of their product: ``a/q + b/q`` has
    denominator ``q``, not ``q^2``. The Taylor recurrences of a quotient divide every
    coefficient by the same leading term, so without this the bound doubled at each
    addition of a deep derivative and exceeded the prime (more random points for every
    dependence) where the true degree grows linearly. Bounds only (no cancellation is
    assumed).

    ``memo``: a dict kept by the caller between calls on the same graph (node -> bounds),
    so that each node is visited once over many calls.
    """
    ops, args, params = graph.op, graph.args, graph.param
    D = {} if memo is None else memo  # node -> (num degree, {atom: multiplicity}, den degree)
    empty = {}

    def atoms_deg(atoms):
        return sum(m * D[a][0] for a, m in atoms.items())

    for k in graph.reachable(roots, known=D):
        op, a = ops[k], args[k]
        if op == "x":
            D[k] = (1, empty, 0)
        elif op == "c":
            D[k] = (0, empty, 0)
        elif op == "neg":
            D[k] = D[a[0]]
        elif op == "add":
            (na, qa, da), (nb, qb, db) = D[a[0]], D[a[1]]
            if qa is qb or qa == qb:
                D[k] = (max(na, nb), qa, da)
            else:
                lcm = dict(Counter(qa) | Counter(qb))
                d = atoms_deg(lcm)
                D[k] = (max(na + d - da, nb + d - db), lcm, d)
        elif op == "mul":
            (na, qa, da), (nb, qb, db) = D[a[0]], D[a[1]]
            q = qa if not qb else qb if not qa else dict(Counter(qa) + Counter(qb))
            D[k] = (na + nb, q, da + db)
        elif op == "div":  # (na / qa) / (nb / qb) = na qb / (qa * atom b)
            (na, qa, da), (nb, qb, db) = D[a[0]], D[a[1]]
            q = dict(qa)
            q[a[1]] = q.get(a[1], 0) + 1
            D[k] = (na + db, q, da + nb)
        elif op == "ipow":
            na, qa, da = D[a[0]]
            kk = params[k]
            if kk >= 0:
                D[k] = (kk * na, {atom: kk * m for atom, m in qa.items()} if qa else empty, kk * da)
            else:  # (na / qa)^-m = qa^m / (atom a)^m
                D[k] = (-kk * da, {a[0]: -kk}, -kk * na)
        elif graph_elementary.rationalizable(graph, k):
            # a generator (or an algebraic root) of the rationalised graph: a new variable,
            # its degree bounded by twice one plus its operands' (a circle point is of
            # degree 2 in its parameter; a root's norm doubles the degree)
            D[k] = (2 * (1 + sum(D[b][0] + D[b][2] for b in a)), empty, 0)
        else:
            raise ValueError(f"{op} is not a rational operation")
    return [(D[r][0], D[r][2]) for r in roots]


class ExtendedEvaluator:
    """Values and gradients of graph nodes at one point in ``dps`` decimal digits (mpmath),
    every node kept between requests.

    Args:
        graph: the graph.
        point: ``n`` floats (taken as exact binary numbers).
        dps: decimal digits of the arithmetic.
    """

    def __init__(self, graph, point, dps: int):
        import mpmath

        ctx = self.ctx = mpmath.MPContext()
        ctx.dps = dps
        self.graph, self.point = graph, [float(v) for v in point]
        self.V, self.G = {}, {}
        self.unary = {
            "sin": ctx.sin, "cos": ctx.cos, "tan": ctx.tan, "exp": ctx.exp, "log": ctx.log,
            "sqrt": ctx.sqrt, "tanh": ctx.tanh, "atan": ctx.atan, "asin": ctx.asin,
            "acos": ctx.acos, "sinh": ctx.sinh, "cosh": ctx.cosh, "asinh": ctx.asinh,
            "acosh": ctx.acosh, "atanh": ctx.atanh, "abs": ctx.fabs, "log1p": ctx.log1p,
            "expm1": ctx.expm1, "erf": ctx.erf, "cbrt": ctx.cbrt,
            "logistic": lambda a: 1 / (1 + ctx.exp(-a)), "sign": ctx.sign, "floor": ctx.floor,
            "ceil": ctx.ceil, "round": ctx.nint, "not": lambda a: ctx.mpf(a == 0),
        }
        self.slope = unary_slopes(ctx)

    def gradients(self, roots):
        """``(values, grads)``: lists of mpmath numbers, ``grads[r]`` a list of ``n``."""
        ctx, graph = self.ctx, self.graph
        n = len(self.point)
        zero = ctx.mpf(0)
        zeros = [zero] * n
        compare = {"lt": lambda a, b: a < b, "le": lambda a, b: a <= b, "gt": lambda a, b: a > b,
                   "ge": lambda a, b: a >= b, "eq": lambda a, b: a == b, "ne": lambda a, b: a != b,
                   "and": lambda a, b: bool(a) and bool(b), "or": lambda a, b: bool(a) or bool(b)}
        ops, args, params = graph.op, graph.args, graph.param
        V, G = self.V, self.G
        for k in graph.reachable(roots, known=V):
            op, a = ops[k], args[k]
            if op == "x":
                i = params[k]
                v, g = ctx.mpf(self.point[i]), [zero] * n
                g[i] = ctx.mpf(1)
            elif op == "c":
                exact = graph.exact_value(k)
                v = ctx.mpf(graph.value_of(k)) if exact is None else \
                    ctx.mpf(exact.numerator) / exact.denominator
                g = zeros
            elif op == "add":
                v = V[a[0]] + V[a[1]]
                g = [p + q for p, q in zip(G[a[0]], G[a[1]])]
            elif op == "neg":
                v, g = -V[a[0]], [-q for q in G[a[0]]]
            elif op == "mul":
                va, vb = V[a[0]], V[a[1]]
                v = va * vb
                g = [p * vb + q * va for p, q in zip(G[a[0]], G[a[1]])]
            elif op == "div":
                va, vb = V[a[0]], V[a[1]]
                v = va / vb
                g = [(p - v * q) / vb for p, q in zip(G[a[0]], G[a[1]])]
            elif op == "ipow":
                kk = params[k]
                va = V[a[0]]
                v = va ** kk
                s = kk * va ** (kk - 1)
                g = [q * s for q in G[a[0]]]
            elif op == "pow":
                va, vb = V[a[0]], V[a[1]]
                v = ctx.power(va, vb)
                g = [q * v * ctx.log(va) + p * v * vb / va for p, q in zip(G[a[0]], G[a[1]])]
            elif op == "atan2":
                va, vb = V[a[0]], V[a[1]]
                v = ctx.atan2(va, vb)
                den = va * va + vb * vb
                g = [(vb * p - va * q) / den for p, q in zip(G[a[0]], G[a[1]])]
            elif op == "select":
                pick = a[2] if V[a[0]] != 0 else a[1]
                v, g = V[pick], G[pick]
            elif op in compare:
                v, g = ctx.mpf(compare[op](V[a[0]], V[a[1]])), zeros
            else:
                va = V[a[0]]
                v = self.unary[op](va)
                g = zeros if op not in self.slope else [q * self.slope[op](va, v) for q in G[a[0]]]
            V[k], G[k] = v, g
        return [V[r] for r in roots], [G[r] for r in roots]


__all__ = ["PRIME", "Singular", "const_mod", "ModularEvaluator", "gradients_mod_p", "rank_mod_p", "Echelon",
           "rational_reconstruction",
           "degrees", "ExtendedEvaluator"]
