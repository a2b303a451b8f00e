"""Truncated Taylor series along the flow, with their gradients: Sedoglavic's route to the
observability rank, without symbolic Lie derivatives.

For ``z' = F(z, t)`` on ``z = [x; p]`` (``p' = 0``), ``F = f0 + sum_i u_i(t) f_i`` with known
inputs ``u_i(t) = sum_j a_ij t^j``, the solution from ``z(0) = z0`` and any node ``v`` of the
expression graph have Taylor series ``v(t) = sum_k v_k t^k``; the output coefficients
``y_k = L_F^k h / k!`` (at ``t = 0``) are the rows of the observability matrix. They are
computed here *numerically*, order by order, in one of three arithmetics, with their
gradients ``d v_k / d z0`` (forward mode: a dual number of ``N + 1`` entries per
coefficient):

    x_{i,k}   = F_{i,k-1} / k                                 (the ODE)
    (a b)_k   = sum_{j<=k} a_j b_{k-j}                         (Cauchy product)
    (a / b)_k = (a_k - sum_{j<k} c_j b_{k-j}) / b_0
    s = sin u, c = cos u:  s_k =  (1/k) sum_{j=1..k} j u_j c_{k-j},  c_k = -(1/k) sum j u_j s_{k-j}
    E = exp u:             E_k =  (1/k) sum_{j=1..k} j u_j E_{k-j}
    r = sqrt u:            2 r_0 r_k = u_k - sum_{0<j<k} r_j r_{k-j}
    a = log u, atan2(u, v), ...:  a_k = R_{k-1} / k,  R = a' = sum_i c_i(u) u_i'

(the instructions, and which of them run one order behind: :mod:`.taylor_program`).

Cost: ``O(|graph| K^2 N P)`` for ``K`` orders, ``N`` coordinates and ``P`` points, where the
symbolic route builds ``L_F^k h`` as graph nodes whose number grows with every order (a
single-output chain of 60 variables: 500 000 nodes). Modulo ``p`` the generators of the
elementary functions take random values at ``t = 0`` (:mod:`.graph_elementary`: a point of
the circle for ``sin``/``cos`` of one argument, a random ``exp u``, a random value of a
logarithmic kind, a square root of the argument's value), which is the rank of the model
made rational; in float64 and mpmath they are the real values.

The arithmetic is an object (:class:`Modular`, :class:`Float`, :class:`Extended`) with the
few operations the recurrences need, so that one program serves the exact decision, the
float64 margins and the extended-precision directions.
"""

from fractions import Fraction

import numpy as np

from . import graph_elementary
from .graph_elementary import Singular
from .graph_exact import PRIME, const_mod
from .taylor_program import Unsupported, program


class Modular:
    """Residues modulo the prime ``p`` (Python integers in numpy object arrays).

    Args:
        points: ``(P, N)`` residues, the coordinates at ``t = 0``.
        draws: the :class:`~uio_jax._engine.graph_elementary.Draws` of the generators.
    """

    dtype = object

    def __init__(self, points, draws, p: int = PRIME):
        self.p = p
        self.points = np.array([[int(v) % p for v in row] for row in points], dtype=object)
        self.draws = draws

    def reduce(self, a):
        return a % self.p

    def constant(self, value: Fraction):
        return const_mod(value, self.p)

    def inverse(self, a):
        """Elementwise inverse of ``(P,)`` residues.

        Raises:
            Singular: a residue is zero (a denominator vanishes at the point).
        """
        out = np.empty(len(a), dtype=object)
        for i, v in enumerate(a):
            v = int(v) % self.p
            if v == 0:
                raise Singular("division by zero modulo p")
            out[i] = pow(v, -1, self.p)
        return out

    def circle(self, key, u0):
        s, c = self.draws.get(key)
        return s, c

    def exponential(self, key, u0):
        return self.draws.get(key)

    def sqrt(self, u0):
        """Square roots of ``(P,)`` residues (:class:`~uio_jax._engine.graph_elementary.NotSquare`
        where there is none: the point is drawn again)."""
        return graph_elementary.sqrt_mod_p(u0, self.p)

    def free(self, key, kind, values):
        """The random value of a logarithmic kind's generator at the points."""
        return self.draws.get(key)


class Float:
    """float64 at real points ``(P, N)`` (the elementary functions at their real values)."""

    dtype = np.float64

    def __init__(self, points):
        self.points = np.asarray(points, dtype=np.float64)

    def reduce(self, a):
        return a

    def constant(self, value: Fraction):
        return float(value)

    def inverse(self, a):
        return 1.0 / a

    def circle(self, key, u0):
        return np.sin(u0), np.cos(u0)

    def exponential(self, key, u0):
        return np.exp(u0)

    def sqrt(self, u0):
        return np.sqrt(u0)

    def free(self, key, kind, values):
        if kind == "atan2":
            return np.arctan2(values[0], values[1])
        return _NUMPY[kind](values[0])


class Extended:
    """mpmath numbers at ``dps`` decimal digits, at real points ``(P, N)`` (floats taken as
    exact binary numbers)."""

    dtype = object

    def __init__(self, points, dps: int):
        import mpmath

        self.ctx = mpmath.MPContext()
        self.ctx.dps = dps
        self.points = np.array([[self.ctx.mpf(float(v)) for v in row] for row in np.asarray(points, float)],
                               dtype=object)

    def reduce(self, a):
        return a

    def constant(self, value: Fraction):
        return self.ctx.mpf(value.numerator) / value.denominator

    def inverse(self, a):
        return np.array([1 / v for v in a], dtype=object)

    def circle(self, key, u0):
        return (np.array([self.ctx.sin(v) for v in u0], dtype=object),
                np.array([self.ctx.cos(v) for v in u0], dtype=object))

    def exponential(self, key, u0):
        return np.array([self.ctx.exp(v) for v in u0], dtype=object)

    def sqrt(self, u0):
        return np.array([self.ctx.sqrt(v) for v in u0], dtype=object)

    def free(self, key, kind, values):
        if kind == "atan2":
            return np.array([self.ctx.atan2(a, b) for a, b in zip(*values)], dtype=object)
        fn = getattr(self.ctx, kind)
        return np.array([fn(v) for v in values[0]], dtype=object)


#: numpy's functions of the logarithmic kinds (float64 values at real points)
_NUMPY = {"log": np.log, "log1p": np.log1p, "atan": np.arctan, "atanh": np.arctanh, "asin": np.arcsin,
          "acos": np.arccos, "asinh": np.arcsinh, "acosh": np.arccosh}


class TaylorSeries:
    """The Taylor coefficients of graph nodes along the flow of ``F``, order by order, with
    their gradients with respect to the ``N`` coordinates at ``t = 0``.

    Coefficients are kept per order, ``C[k]`` of shape ``(instructions, P, N + 1)`` (the value
    in column 0, the gradient after it), allocated when the order is computed: a model whose
    span closes after two orders never holds more.

    Args:
        graph: the expression graph on ``N`` coordinates.
        fields: ``[f0, f_1, ..]``: per field, ``N`` graph nodes (None for a zero entry).
        inputs: ``(len(fields) - 1, orders + 1)`` exact coefficients ``a_ij`` of the known
            inputs (Fractions), empty for a drift-only model.
        roots: the graph nodes whose series are asked (outputs, test functions).
        arithmetic: :class:`Modular`, :class:`Float` or :class:`Extended` (its ``points``
            ``(P, N)`` are the coordinates at ``t = 0``).
        orders: the highest order ``K`` that will be asked.

    Raises:
        Unsupported: a node without a Taylor rule here.
    """

    def __init__(self, graph, fields, inputs, roots, arithmetic, orders: int):
        self.ar, self.K = arithmetic, int(orders)
        self.N = graph.n
        wanted = list(roots) + [v for f in fields for v in f if v is not None]
        self.ins, self.slot, self.lagged = program(graph, wanted)
        self.fields = [[None if v is None else self.slot[v] for v in f] for f in fields]
        self.inputs = inputs
        self.P = len(arithmetic.points)
        self.C = []  # per order: (instructions, P, N + 1)
        self._inverse = {}  # instruction -> inverse of its order-0 value (P,)

    def coefficient(self, node, k: int):
        """``(P, N + 1)``: the value (column 0) and the gradient of coefficient ``k`` of a
        root node, computing the orders up to ``k`` on first request."""
        while len(self.C) <= k:
            self._advance()
        return self.C[k][self.slot[node]]

    def _zeros(self, *shape):
        out = np.zeros(shape, dtype=self.ar.dtype)
        if self.ar.dtype is object:
            out[...] = 0
        return out

    def _orders(self, i, lo, hi, reverse=False):
        """``(hi - lo + 1, P, N + 1)``: coefficients ``lo..hi`` of instruction ``i`` (reversed)."""
        ks = range(hi, lo - 1, -1) if reverse else range(lo, hi + 1)
        return np.stack([self.C[j][i] for j in ks])

    def _advance(self):
        k = len(self.C)
        if k > self.K:
            raise ValueError(f"order {k} beyond the {self.K} orders prepared")
        self.C.append(self._zeros(len(self.ins), self.P, self.N + 1))
        for i, (op, a, param) in enumerate(self.ins):
            if op == "cos":
                continue  # computed with its sine
            if i in self.lagged:
                if k:  # one order behind: coefficient k - 1, which needs u_k
                    self.C[k - 1][i] = self._order(i, op, a, param, k - 1)
                continue
            self.C[k][i] = self._order(i, op, a, param, k)

    def _order(self, i, op, a, param, k):
        ar = self.ar
        if op == "x":
            return self._coordinate(param, k)
        if op == "c":
            out = self._zeros(self.P, self.N + 1)
            if k == 0:
                out[:, 0] = ar.constant(param)
            return out
        if op == "add":
            return ar.reduce(self.C[k][a[0]] + self.C[k][a[1]])
        if op == "neg":
            return ar.reduce(-self.C[k][a[0]])
        if op == "mul":
            return ar.reduce(_cauchy(self._orders(a[0], 0, k), self._orders(a[1], 0, k, reverse=True)))
        if op == "div":
            rest = self.C[k][a[0]]
            if k:
                rest = rest - _cauchy(self._orders(i, 0, k - 1), self._orders(a[1], 1, k, reverse=True))
            return self._over(rest, a[1])
        if op == "deriv":
            return ar.reduce(self.C[k + 1][a[0]] * ar.constant(Fraction(k + 1)))
        if op == "sin":
            return self._circle(i, param, a[0], k)
        if op == "exp":
            return self._exponential(i, param, a[0], k)
        if op == "sqrt":
            return self._root(i, a[0], k)
        return self._free(param, a[0], k)

    def _over(self, rest, b, factor=1):
        """``c = rest / (factor b_0)`` of dual numbers: ``dc = (d rest - c factor d b_0) / (factor b_0)``."""
        ar = self.ar
        if b not in self._inverse:
            self._inverse[b] = ar.inverse(ar.reduce(self.C[0][b][:, 0]))
        inv = self._inverse[b]
        if factor != 1:
            inv = ar.reduce(inv * ar.constant(Fraction(1, factor)))
        value = ar.reduce(rest[:, 0] * inv)
        out = rest * inv[:, None]
        out[:, 1:] = out[:, 1:] - (value * inv * factor)[:, None] * self.C[0][b][:, 1:]
        out[:, 0] = value
        return ar.reduce(out)

    def _coordinate(self, j, k):
        ar = self.ar
        out = self._zeros(self.P, self.N + 1)
        if k == 0:
            out[:, 0] = ar.points[:, j]
            out[:, 1 + j] = 1
            return out
        for f, field in enumerate(self.fields):
            s = field[j]
            if s is None:
                continue
            if f == 0:
                out = out + self.C[k - 1][s]
            else:  # u_f(t) f_f: the Cauchy product with the input's coefficients
                for m in range(k):
                    if self.inputs[f - 1][m]:
                        out = out + ar.constant(self.inputs[f - 1][m]) * self.C[k - 1 - m][s]
        return ar.reduce(out * ar.constant(Fraction(1, k)))

    def _weighted(self, u, k):
        """``j u_j`` for ``j = 1..k`` (the derivative's coefficients times their order)."""
        w = np.arange(1, k + 1).reshape(-1, 1, 1)
        return self._orders(u, 1, k) * (w.astype(object) if self.ar.dtype is object else w)

    def _circle(self, s, param, u, k):
        ar, (c, node) = self.ar, param
        if k == 0:
            sv, cv = ar.circle(("circle", node), self.C[0][u][:, 0])
            out_c = self._zeros(self.P, self.N + 1)
            out_c[:, 0] = cv
            out_c[:, 1:] = ar.reduce(-sv[:, None] * self.C[0][u][:, 1:])
            self.C[0][c] = out_c
            out = self._zeros(self.P, self.N + 1)
            out[:, 0] = sv
            out[:, 1:] = ar.reduce(cv[:, None] * self.C[0][u][:, 1:])
            return out
        du, inv_k = self._weighted(u, k), ar.constant(Fraction(1, k))
        self.C[k][c] = ar.reduce(-_cauchy(du, self._orders(s, 0, k - 1, reverse=True)) * inv_k)
        return ar.reduce(_cauchy(du, self._orders(c, 0, k - 1, reverse=True)) * inv_k)

    def _exponential(self, e, node, u, k):
        ar = self.ar
        if k == 0:
            E = ar.exponential(("exp", node), self.C[0][u][:, 0])
            out = self._zeros(self.P, self.N + 1)
            out[:, 0] = E
            out[:, 1:] = ar.reduce(E[:, None] * self.C[0][u][:, 1:])
            return out
        prod = _cauchy(self._weighted(u, k), self._orders(e, 0, k - 1, reverse=True))
        return ar.reduce(prod * ar.constant(Fraction(1, k)))

    def _root(self, r, u, k):
        """``r = sqrt u``: ``r_0`` a root of ``u_0``, ``2 r_0 r_k = u_k - sum_{0<j<k} r_j r_{k-j}``."""
        ar = self.ar
        if k == 0:
            value = ar.sqrt(self.C[0][u][:, 0])
            out = self._zeros(self.P, self.N + 1)
            out[:, 0] = value
            inv = ar.inverse(ar.reduce(2 * value))
            out[:, 1:] = ar.reduce(self.C[0][u][:, 1:] * inv[:, None])
            return out
        rest = self.C[k][u]
        if k > 1:
            rest = rest - _cauchy(self._orders(r, 1, k - 1), self._orders(r, 1, k - 1, reverse=True))
        return self._over(rest, r, factor=2)

    def _free(self, param, R, k):
        """A logarithmic kind: a free value at ``t = 0``, then ``a_k = R_{k-1} / k``."""
        ar = self.ar
        key, pairs, kind, operands = param
        if k:
            return ar.reduce(self.C[k - 1][R] * ar.constant(Fraction(1, k)))
        out = self._zeros(self.P, self.N + 1)
        out[:, 0] = ar.free(key, kind, [self.C[0][v][:, 0] for v in operands])
        for c, u in pairs:  # d a_0 = sum c_i(u_0) d u_i
            out[:, 1:] = out[:, 1:] + self.C[0][c][:, :1] * self.C[0][u][:, 1:]
        return ar.reduce(out)


def _cauchy(A, B):
    """``sum_j A_j B_j`` of dual numbers (value in column 0, gradient after it): ``A, B``
    ``(J, P, N + 1)`` with ``B`` already reversed; ``(P, N + 1)``."""
    out = (A * B[..., :1]).sum(axis=0)
    out[:, 1:] = out[:, 1:] + (A[..., :1] * B[..., 1:]).sum(axis=0)
    return out


__all__ = ["Unsupported", "Modular", "Float", "Extended", "program", "TaylorSeries", "Singular"]
