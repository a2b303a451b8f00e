"""Truncated Taylor series along the flow, with their gradients: Sedoglavic's route to the
observability rank, without symbolic Lie derivatives.

For ``z' = F(z, t)`` on ``z = [x; p]`` (``p' = 0``), ``F = f0 + sum_i u_i(t) f_i`` with known
inputs ``u_i(t) = sum_j a_ij t^j``, the solution from ``z(0) = z0`` and any node ``v`` of the
expression graph have Taylor series ``v(t) = sum_k v_k t^k``; the output coefficients
``y_k = L_F^k h / k!`` (at ``t = 0``) are the rows of the observability matrix. They are
computed here *numerically*, order by order, with their gradients ``d v_k / d z0`` (forward
mode: a dual number of ``N + 1`` entries per coefficient, the value first):

    x_{i,k}   = F_{i,k-1} / k                                 (the ODE)
    (a b)_k   = sum_{j<=k} a_j b_{k-j}                         (Cauchy product)
    (a / b)_k = (a_k - sum_{j<k} c_j b_{k-j}) / b_0
    s = sin u, c = cos u:  s_k =  (1/k) sum_{j=1..k} j u_j c_{k-j},  c_k = -(1/k) sum j u_j s_{k-j}
    E = exp u:             E_k =  (1/k) sum_{j=1..k} j u_j E_{k-j}
    w = u^alpha:           k u_0 w_k = sum_{j=1..k} ((alpha + 1) j - k) u_j w_{k-j}
    a = log u, atan2(u, v), ...:  a_k = R_{k-1} / k,  R = a' = sum_i c_i(u) u_i'

(the instructions, and which of them run one order behind: :mod:`.taylor_program`; their
schedule: :mod:`.taylor_plan`). Every Cauchy sum of one instruction at one order is one
matrix product of its past orders (``(J,) x (J, N + 1)`` per row), and the sums, negations
and scalings of one level of the program are one numpy operation.

Cost: ``O(|products| K^2 N)`` multiply-adds for ``K`` orders and ``N`` coordinates (a product
with a parameter or a constant is a scaling, ``O(K N)``), where the symbolic route builds
``L_F^k h`` as graph nodes whose number grows with every order. Modulo ``p`` the generators
of the elementary functions take random values at ``t = 0`` (:mod:`.graph_elementary`), which
is the rank of the model made rational; in float64 and mpmath they are the real values.

The arithmetic is an object (:mod:`.taylor_arithmetic`: float64, mpmath, Python integers
modulo one prime; :mod:`.taylor_word`: int64 modulo several machine-word primes, and their
quadratic extensions for roots) with the few operations the recurrences need, so that one
program serves the exact decision, the float64 margins and the extended-precision
directions.
"""

from fractions import Fraction

import numpy as np

from .graph_elementary import Singular
from .taylor_arithmetic import Extended, Float, Modular
from .taylor_columns import bits, colouring
from .taylor_plan import VECTOR, Plan
from .taylor_program import Unsupported, program

#: histories up to this many bytes are allocated for every order at once (no copies as they grow)
WHOLE_HISTORY = 256 * 2**20


class TaylorSeries:
    """The Taylor coefficients of graph nodes along the flow of ``F``, order by order, with
    their gradients with respect to the ``N`` coordinates at ``t = 0``.

    Args:
        graph: the expression graph on ``N`` coordinates.
        fields: ``[f0, f_1, ..]``: per field, ``N`` graph nodes (None for a zero entry).
        inputs: ``(len(fields) - 1, orders + 1)`` exact coefficients ``a_ij`` of the known
            inputs (Fractions), empty for a drift-only model.
        roots: the graph nodes whose series are asked (outputs, test functions).
        arithmetic: an arithmetic of :mod:`.taylor_arithmetic` or :mod:`.taylor_word` (its
            ``points`` ``(rows, N)`` are the coordinates at ``t = 0``).
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
        moving = any(any(row) for row in inputs)
        self.plan = Plan(self.ins, self.fields, self.lagged, [self.slot[r] for r in roots], moving)
        self.P = arithmetic.rows
        self.colour, count, self.support = colouring(self.ins, self.fields, [self.slot[v] for v in wanted], self.N)
        self._columns = {}  # instruction -> the coordinates of its support (expanded rows)
        W = count + 1
        self.W = W
        self.now = np.zeros((self.P, len(self.ins), W), dtype=arithmetic.dtype)
        self.H = np.zeros((self.P, len(self.plan.hist), 0, W), dtype=arithmetic.dtype)
        self.base = None  # order 0 of the instructions constant along the flow
        self.done = -1
        self._inverse = {}  # instruction -> inverse of its order-0 value (rows,)

    def coefficient(self, node, k: int):
        """``(rows, N + 1)``: the value (column 0) and the gradient of coefficient ``k`` of a
        root node, computing the orders up to ``k`` on first request."""
        while self.done < k:
            self._pass()
        i = self.slot[node]
        if self.plan.constant[i]:
            packed = self.base[:, self.plan.base[i]] if k == 0 else np.zeros_like(self.base[:, 0])
        else:
            packed = self.H[:, self.plan.hist[i], k]
        return self._expand(i, packed)

    def _expand(self, i, packed):
        """The gradient of instruction ``i`` over the ``N`` coordinates from its compressed
        columns (:mod:`.taylor_columns`)."""
        if self.support is None:
            return packed
        cols = self._columns.get(i)
        if cols is None:
            cols = self._columns[i] = np.array(bits(self.support[i]), dtype=np.int64)
        out = np.zeros((self.P, self.N + 1), dtype=packed.dtype)
        out[:, 0] = packed[:, 0]
        out[:, 1 + cols] = packed[:, 1 + self.colour[cols]]
        return out

    # ------------------------------------------------------------------ passes
    def _pass(self):
        k = self.done + 1
        if k > self.K:
            raise ValueError(f"order {k} beyond the {self.K} orders prepared")
        self._grow(k)
        if k == 0:
            self._first()
        else:
            self._coordinates(k)
            if k == 1:
                self.now[:, self.plan.const_rows] = 0
            for step in self.plan.steps:
                self._step(step, k)
        self.done = k

    def _grow(self, k):
        """Room for order ``k`` in the history: a capacity that doubles from 4 orders (a run
        that stops early holds few), and from 16 on every order at once where that is at most
        :data:`WHOLE_HISTORY` bytes (a long run copies its history once more, not at every
        doubling)."""
        cap = self.H.shape[2]
        if k < cap:
            return
        whole = self.H.shape[0] * self.H.shape[1] * (self.K + 1) * self.W * self.H.itemsize
        size = min(max(2 * cap, 4), self.K + 1)
        if cap >= 16 and whole <= WHOLE_HISTORY:
            size = self.K + 1
        new = np.zeros(self.H.shape[:2] + (size, self.W), dtype=self.ar.dtype)
        new[:, :, :cap] = self.H
        self.H = new

    def _first(self):
        """Order 0: the point, the constants, then every instruction at ``k = 0``."""
        ar, plan = self.ar, self.plan
        xs = [(i, p) for i, (op, _, p) in enumerate(self.ins) if op == "x"]
        if xs:
            rows, cols = np.array([i for i, _ in xs]), np.array([p for _, p in xs])
            self.now[:, rows, 0] = ar.points[:, cols]
            self.now[:, rows, 1 + self.colour[cols]] = self._per_row(ar.element(Fraction(1)))[:, None]
        for i, (op, _, value) in enumerate(self.ins):
            if op == "c":
                self.now[:, i, 0] = ar.element(value)
        self._keep(np.array(sorted(i for i, _ in xs if i in plan.hist), dtype=np.int64), 0)
        for step in plan.first:
            self._step(step, 0)
        self.base = self.now[:, plan.const_rows].copy()

    def _coordinates(self, k):
        """``x_k = (F0_{k-1} + sum_f sum_m a_fm F^f_{k-1-m}) / k`` for the moving coordinates."""
        ar, plan = self.ar, self.plan
        rows, _ = plan.coords
        if not len(rows):
            return
        src = plan.sources
        out = np.zeros((self.P, len(rows), self.W), dtype=ar.dtype)
        has = src >= 0
        out[:, has] = self.now[:, src[has]]
        for pos, f, s in plan.input_terms:
            coefs = [self.inputs[f - 1][m] for m in range(k)]
            if not any(coefs):
                continue
            if plan.constant[s]:
                a = self._per_row(ar.scalar(coefs[k - 1]))[:, None]
                out[:, pos] = ar.reduce(out[:, pos] + a * self._first_of(s))
                continue
            v = np.stack([self._per_row(ar.scalar(c)) for c in coefs[::-1]], axis=1)
            out[:, pos] = out[:, pos] + ar.scalar_dot(v, self.H[:, plan.hist[s], :k])
        scale = _column(ar.scalar(Fraction(1, k)), 3)
        self.now[:, rows] = ar.reduce(out * scale)
        self._keep(np.array([i for i in rows if i in plan.hist], dtype=np.int64), k)

    def _keep(self, kept, order):
        if len(kept):
            self.H[:, [self.plan.hist[int(i)] for i in kept], order] = self.now[:, kept]

    def _step(self, step, k):
        kind, lag, members, kept = step
        m = k - lag
        if kind in VECTOR:
            self._vector(kind, members, m)
        else:
            rule = getattr(self, "_" + kind)
            for i in members:
                self.now[:, i] = rule(i, m)
        self._keep(kept, m)

    def _vector(self, kind, members, m):
        ar, now = self.ar, self.now
        out = members[0]
        if kind == "add":
            now[:, out] = ar.reduce(now[:, members[1]] + now[:, members[2]])
        elif kind == "neg":
            now[:, out] = ar.reduce(-now[:, members[1]])
        elif kind == "scale":
            factors = np.stack([self._per_row(ar.scalar(c)) for c in members[2]], axis=1)
            now[:, out] = ar.reduce(now[:, members[1]] * factors[:, :, None])
        elif kind == "mul":  # sum_j a_j (x) b_{m-j}, one einsum for the group
            now[:, out] = self._cauchy(self.H[:, members[1], :m + 1], self.H[:, members[2], :m + 1])
        else:  # cmul: c_0 (x) x_m for a factor constant along the flow
            c0, x = self._first_of(members[1]), now[:, members[2]]
            res = ar.mul(c0[..., :1], x)
            res[..., 1:] = res[..., 1:] + ar.mul(x[..., :1], c0[..., 1:])
            now[:, out] = ar.reduce(res)

    # ------------------------------------------------------------------ helpers
    def _per_row(self, c):
        """A scalar or a per-row array as an array ``(rows,)``."""
        if np.ndim(c):
            return c
        out = np.empty(self.P, dtype=self.ar.dtype)
        out[:] = c
        return out

    def _first_of(self, i):
        """Order 0 of instruction(s) ``i`` constant along the flow (during the first pass: the
        pass buffer)."""
        if self.done < 0:
            return self.now[:, i]
        idx = [self.plan.base[int(j)] for j in np.atleast_1d(i)]
        return self.base[:, idx] if np.ndim(i) else self.base[:, idx[0]]

    def _zero(self, i):
        """Order 0 (rows, N + 1) of any instruction."""
        if self.plan.constant[i]:
            return self._first_of(i)
        return self.H[:, self.plan.hist[i], 0]

    def _past(self, i, lo, hi):
        """``(rows, hi - lo + 1, N + 1)``: orders ``lo..hi`` of an instruction with history."""
        return self.H[:, self.plan.hist[i], lo:hi + 1]

    def _cauchy(self, A, B):
        """``sum_j A_j (x) B_{J-1-j}`` of dual numbers: ``A, B (rows, .., J, N + 1)``."""
        ar = self.ar
        other = ar.dot(A[..., ::-1, 0], B)
        other[..., 0] = 0
        return ar.reduce(ar.dot(B[..., ::-1, 0], A) + other)

    def _weighted(self, U, V, q):
        """``sum_{j=1..m} q_j u_j (x) v_{m-j}``: ``U`` orders ``1..m``, ``V`` orders ``0..m-1``,
        ``q (m,)`` or ``(rows, m)`` weights."""
        ar = self.ar
        other = ar.dot(ar.reduce(q * U[:, :, 0])[:, ::-1], V)
        other[:, 0] = 0
        return ar.reduce(ar.dot(ar.reduce(q * V[:, ::-1, 0]), U) + other)

    def _inverse_of(self, b):
        if b not in self._inverse:
            self._inverse[b] = self.ar.inverse(self.ar.reduce(self._zero(b)[:, 0]))
        return self._inverse[b]

    def _over(self, rest, b, factor=1):
        """``c = rest / (factor b_0)`` of dual numbers: ``dc = (d rest - c factor d b_0) / (factor b_0)``."""
        ar = self.ar
        inv = self._inverse_of(b)
        inv_f = inv if factor == 1 else ar.reduce(inv * ar.scalar(Fraction(1, factor)))
        value = ar.mul(rest[:, 0], inv_f)
        out = ar.mul(rest, inv_f[:, None])
        out[:, 1:] = out[:, 1:] - ar.mul(ar.mul(value, inv)[:, None], self._zero(b)[:, 1:])
        out[:, 0] = value
        return ar.reduce(out)

    def _dual(self, value, slope, du):
        """The dual number of ``value`` whose gradient is ``slope du`` (``(rows,)``, ``(rows, N)``)."""
        out = np.zeros((self.P, self.W), dtype=self.ar.dtype)
        out[:, 0] = value
        out[:, 1:] = self.ar.mul(slope[:, None], du)
        return out

    # ------------------------------------------------------------------ rules
    def _div(self, i, m):
        a, b = self.ins[i][1]
        rest = self.now[:, a]
        if m and not self.plan.constant[b]:
            C, B = self._past(i, 0, m - 1), self._past(b, 1, m)
            rest = self.ar.reduce(rest - self._cauchy(C, B))
        return self._over(rest, b)

    def _deriv(self, i, m):
        """``D_m = (m + 1) u_{m+1}`` (lagged: ``u_{m+1}`` is the pass's order)."""
        return self.ar.reduce(self.now[:, self.ins[i][1][0]] * _column(self.ar.scalar(Fraction(m + 1)), 2))

    def _sin(self, s, m):
        ar, (u,), (c, node) = self.ar, self.ins[s][1], self.ins[s][2]
        if m == 0:
            u0 = self.now[:, u]
            sv, cv = ar.circle(("circle", node), u0[:, 0])
            self.now[:, c] = self._dual(cv, ar.reduce(-sv), u0[:, 1:])
            return self._dual(sv, cv, u0[:, 1:])
        U, w = self._past(u, 1, m), np.arange(1, m + 1)
        inv = _column(ar.scalar(Fraction(1, m)), 2)
        self.now[:, c] = ar.reduce(-self._weighted(U, self._past(s, 0, m - 1), w) * inv)
        return ar.reduce(self._weighted(U, self._past(c, 0, m - 1), w) * inv)

    def _exp(self, e, m):
        ar, (u,), node = self.ar, self.ins[e][1], self.ins[e][2]
        if m == 0:
            u0 = self.now[:, u]
            E = ar.exponential(("exp", node), u0[:, 0])
            return self._dual(E, E, u0[:, 1:])
        prod = self._weighted(self._past(u, 1, m), self._past(e, 0, m - 1), np.arange(1, m + 1))
        return ar.reduce(prod * _column(ar.scalar(Fraction(1, m)), 2))

    def _root(self, r, m):
        """``w = u^alpha``: ``w_0`` a root of ``u_0^a`` (``alpha = a/b``), then
        ``m u_0 w_m = sum_{j=1..m} ((alpha + 1) j - m) u_j w_{m-j}``."""
        ar, (u,), (alpha, key) = self.ar, self.ins[r][1], self.ins[r][2]
        if m == 0:
            u0 = self.now[:, u]
            w0 = self._int_power(ar.root(ar.reduce(u0[:, 0]), alpha.denominator, key), alpha.numerator)
            slope = ar.reduce(ar.mul(w0, self._inverse_of(u)) * self._per_row(ar.scalar(alpha)))
            return self._dual(w0, slope, u0[:, 1:])
        j = np.arange(1, m + 1)
        q = ar.reduce(np.multiply.outer(self._per_row(ar.scalar(alpha + 1)), j)
                      - self._per_row(ar.scalar(Fraction(m)))[:, None])
        rest = self._weighted(self._past(u, 1, m), self._past(r, 0, m - 1), q)
        return self._over(rest, u, factor=m)

    def _int_power(self, r, a):
        ar = self.ar
        out, base, e = None, r, abs(a)
        while e:
            if e & 1:
                out = base if out is None else ar.mul(out, base)
            e >>= 1
            if e:
                base = ar.mul(base, base)
        return out if a > 0 else ar.inverse(out)

    def _free(self, i, m):
        """A logarithmic kind: a free value at ``t = 0``, then ``a_m = R_{m-1} / m``."""
        ar = self.ar
        R, (key, pairs, kind, operands) = self.ins[i][1][0], self.ins[i][2]
        if m:
            return ar.reduce(self.now[:, R] * _column(ar.scalar(Fraction(1, m)), 2))
        out = np.zeros((self.P, self.W), dtype=ar.dtype)
        out[:, 0] = ar.free(key, kind, [self.now[:, v, 0] for v in operands])
        for c, u in pairs:  # d a_0 = sum c_i(u_0) d u_i
            out[:, 1:] = out[:, 1:] + ar.mul(self.now[:, c, :1], self.now[:, u, 1:])
        return ar.reduce(out)


def _column(a, ndim):
    """A per-row factor ``(rows,)`` (or a scalar) shaped to broadcast over ``ndim`` axes."""
    if np.ndim(a) == 0:
        return a
    return np.asarray(a).reshape((-1,) + (1,) * (ndim - 1))


__all__ = ["Unsupported", "Modular", "Float", "Extended", "program", "TaylorSeries", "Singular"]
