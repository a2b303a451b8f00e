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

Cost: ``O(|graph| K^2 N P)`` for ``K`` orders, ``N`` coordinates and ``P`` points, where the
symbolic route builds ``L_F^k h`` as graph nodes whose number grows with every order (a
single-output chain of 60 variables: 500 000 nodes). Modulo ``p`` the generators of the
elementary functions take random values at ``t = 0`` (:mod:`.graph_elementary`: a point of
the circle for ``sin``/``cos`` of one argument, a random ``exp u``), which is the rank of the
model made rational; in float64 and mpmath they are the real values.

The arithmetic is an object (:class:`Modular`, :class:`Float`, :class:`Extended`) with the
few operations the recurrences need, so that one program serves the exact decision, the
float64 margins and the extended-precision directions.
"""

from fractions import Fraction

import numpy as np

from . import graph_elementary
from .graph_elementary import Singular
from .graph_exact import PRIME, const_mod


class Unsupported(ValueError):
    """A node the Taylor route does not evaluate (the symbolic route serves the model)."""


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


def program(graph, roots):
    """The instructions that evaluate the graph nodes behind ``roots`` in Taylor mode:
    ``(instructions, slot)`` with ``slot[node]`` the instruction of each node.

    An instruction is ``(op, operands, param)`` on earlier instructions: ``x`` (coordinate
    ``param``), ``c`` (exact constant ``param``), ``add``, ``neg``, ``mul``, ``div``,
    ``sin``/``cos`` (the circle point of operand ``u``: the sine's ``param`` is ``(cosine
    instruction, graph node of u)``, the cosine's the sine instruction), ``exp`` (``param``:
    the graph node of ``u``; the generators are keyed by graph nodes, as in
    :class:`~uio_jax._engine.graph_elementary.Draws`). Integer powers become products, ``tan``, ``sinh``, ``tanh``, ...
    rational functions of the circle point or of ``exp``.

    Raises:
        Unsupported: a node outside these (the symbolic route serves such a model).
    """
    ins, slot, consts, generators = [], {}, {}, {}

    def emit(op, operands=(), param=None):
        ins.append((op, tuple(operands), param))
        return len(ins) - 1

    def const(value):
        value = Fraction(value)
        if value not in consts:
            consts[value] = emit("c", (), value)
        return consts[value]

    def power(a, m):
        out, base = None, a
        while m:
            if m & 1:
                out = base if out is None else emit("mul", (out, base))
            m >>= 1
            if m:
                base = emit("mul", (base, base))
        return out

    for k in graph.reachable(roots):
        op, a = graph.op[k], [slot.get(b) for b in graph.args[k]]
        if op == "x":
            slot[k] = emit("x", (), graph.param[k])
        elif op == "c":
            value = graph.exact_value(k)
            if value is None:
                raise Unsupported("a constant known in float64 only")
            slot[k] = const(value)
        elif op in ("add", "mul", "div", "neg"):
            slot[k] = emit(op, a)
        elif op == "ipow":
            m = graph.param[k]
            pos = const(1) if m == 0 else power(a[0], abs(m))
            slot[k] = pos if m >= 0 else emit("div", (const(1), pos))
        elif op in graph_elementary.CIRCLE:
            if ("circle", a[0]) not in generators:
                s = emit("sin", (a[0],), None)
                c = emit("cos", (a[0],), s)
                ins[s] = ("sin", (a[0],), (c, graph.args[k][0]))
                generators["circle", a[0]] = (s, c)
            s, c = generators["circle", a[0]]
            slot[k] = s if op == "sin" else c if op == "cos" else emit("div", (s, c))
        elif op in graph_elementary.EXPONENTIAL:
            if ("exp", a[0]) not in generators:
                generators["exp", a[0]] = emit("exp", (a[0],), graph.args[k][0])
            slot[k] = _exponential_kind(op, generators["exp", a[0]], emit, const)
        else:
            raise Unsupported(f"{op} has no Taylor rule here")
    return ins, slot


def _exponential_kind(op, E, emit, const):
    """``op(u)`` as a rational function of ``E = exp u`` (instructions emitted)."""
    if op == "exp":
        return E
    if op == "expm1":
        return emit("add", (E, const(-1)))
    if op == "logistic":
        return emit("div", (E, emit("add", (E, const(1)))))
    E2 = emit("mul", (E, E))
    if op == "tanh":
        return emit("div", (emit("add", (E2, const(-1))), emit("add", (E2, const(1)))))
    sign = 1 if op == "cosh" else -1  # (E^2 +- 1) / (2 E)
    return emit("div", (emit("add", (E2, const(sign))), emit("mul", (const(2), E))))


class TaylorSeries:
    """The Taylor coefficients of graph nodes along the flow of ``F``, order by order, with
    their gradients with respect to the ``N`` coordinates at ``t = 0``.

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
        N = graph.n
        wanted = list(roots) + [v for f in fields for v in f if v is not None]
        self.ins, self.slot = program(graph, wanted)
        self.fields = [[None if v is None else self.slot[v] for v in f] for f in fields]
        self.inputs = inputs
        P = len(arithmetic.points)
        self.C = np.zeros((len(self.ins), self.K + 1, P, N + 1), dtype=arithmetic.dtype)
        if arithmetic.dtype is object:
            self.C[...] = 0
        self.done = -1  # the highest order computed
        self._inverse = {}  # instruction -> inverse of its order-0 value (P,)

    def coefficient(self, node, k: int):
        """``(P, N + 1)``: the value (column 0) and the gradient of coefficient ``k`` of a
        root node, computing the orders up to ``k`` on first request."""
        while self.done < k:
            self._advance()
        return self.C[self.slot[node], k]

    def _advance(self):
        k = self.done + 1
        if k > self.K:
            raise ValueError(f"order {k} beyond the {self.K} orders prepared")
        for i, (op, a, param) in enumerate(self.ins):
            if op == "cos":
                continue  # computed with its sine
            self._order(i, op, a, param, k)
        self.done = k

    def _order(self, i, op, a, param, k):
        ar, C = self.ar, self.C
        if op == "x":
            C[i, k] = self._coordinate(param, k)
        elif op == "c":
            if k == 0:
                C[i, 0, :, 0] = ar.constant(param)
        elif op == "add":
            C[i, k] = ar.reduce(C[a[0], k] + C[a[1], k])
        elif op == "neg":
            C[i, k] = ar.reduce(-C[a[0], k])
        elif op == "mul":
            C[i, k] = ar.reduce(_cauchy(C[a[0], :k + 1], C[a[1], k::-1]))
        elif op == "div":
            self._quotient(i, a, k)
        elif op == "sin":
            self._circle(i, param, a[0], k)
        elif op == "exp":
            self._exponential(i, param, a[0], k)

    def _coordinate(self, j, k):
        ar = self.ar
        P, N1 = self.C.shape[2:]
        if k == 0:
            out = np.zeros((P, N1), dtype=ar.dtype)
            out[:, 0] = ar.points[:, j]
            out[:, 1 + j] = 1
            return out
        total = np.zeros((P, N1), dtype=ar.dtype)
        for f, field in enumerate(self.fields):
            s = field[j]
            if s is None:
                continue
            if f == 0:
                total = total + self.C[s, k - 1]
            else:  # u_f(t) f_f: the Cauchy product with the input's coefficients
                for m in range(k):
                    a = self.inputs[f - 1][m]
                    if a:
                        total = total + ar.constant(a) * self.C[s, k - 1 - m]
        return ar.reduce(total * ar.constant(Fraction(1, k)))

    def _quotient(self, i, a, k):
        ar, C = self.ar, self.C
        rest = C[a[0], k]
        if k:
            rest = rest - _cauchy(C[i, :k], C[a[1], k:0:-1])
        if a[1] not in self._inverse:
            self._inverse[a[1]] = ar.inverse(ar.reduce(C[a[1], 0, :, 0]))
        inv = self._inverse[a[1]]
        value = ar.reduce(rest[:, 0] * inv)
        out = rest * inv[:, None]
        out[:, 1:] = out[:, 1:] - (value * inv)[:, None] * C[a[1], 0, :, 1:]
        out[:, 0] = value
        C[i, k] = ar.reduce(out)

    def _weighted(self, u, k):
        """``j u_j`` for ``j = 1..k`` (the derivative's coefficients times their order)."""
        w = np.arange(1, k + 1).reshape(-1, 1, 1)
        return self.C[u, 1:k + 1] * (w.astype(object) if self.ar.dtype is object else w)

    def _circle(self, s, param, u, k):
        ar, C = self.ar, self.C
        c, node = param
        if k == 0:
            sv, cv = ar.circle(("circle", node), C[u, 0, :, 0])
            C[s, 0, :, 0], C[c, 0, :, 0] = sv, cv
            C[s, 0, :, 1:] = ar.reduce(cv[:, None] * C[u, 0, :, 1:])
            C[c, 0, :, 1:] = ar.reduce(-sv[:, None] * C[u, 0, :, 1:])
            return
        du, inv_k = self._weighted(u, k), ar.constant(Fraction(1, k))
        C[s, k] = ar.reduce(_cauchy(du, C[c, k - 1::-1]) * inv_k)
        C[c, k] = ar.reduce(-_cauchy(du, C[s, k - 1::-1]) * inv_k)

    def _exponential(self, e, node, u, k):
        ar, C = self.ar, self.C
        if k == 0:
            E = ar.exponential(("exp", node), C[u, 0, :, 0])
            C[e, 0, :, 0] = E
            C[e, 0, :, 1:] = ar.reduce(E[:, None] * C[u, 0, :, 1:])
            return
        C[e, k] = ar.reduce(_cauchy(self._weighted(u, k), C[e, k - 1::-1]) * ar.constant(Fraction(1, k)))


def _cauchy(A, B):
    """``sum_j A_j B_j`` of dual numbers (value in column 0, gradient after it): ``A, B``
    ``(J, P, N + 1)`` with ``B`` already reversed; ``(P, N + 1)``."""
    out = (A * B[..., :1]).sum(axis=0)
    out[:, 1:] = out[:, 1:] + (A[..., :1] * B[..., 1:]).sum(axis=0)
    return out


__all__ = ["Unsupported", "Modular", "Float", "Extended", "program", "TaylorSeries", "Singular"]
