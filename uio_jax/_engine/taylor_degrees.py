"""Degree bounds of the Taylor coefficients of :mod:`.taylor`: the Schwartz-Zippel bound of
a rank decision taken on them modulo p.

Every coefficient ``v_k`` of an instruction is a rational function of the coordinates (and
of the generators of the elementary functions, counted as :func:`.graph_exact.degrees`
counts them). Its bound is kept as an *excess* ``e_k = deg num - deg den`` and a denominator
written as a product of *atoms* (the numerators of the order-0 coefficients divided by,
with multiplicities), as :func:`.graph_exact.degrees` keeps it, so that a sum over the same
denominators takes their least common multiple instead of their product. The atoms of an
instruction are kept non-decreasing in ``k`` (each order's denominator is taken as a
multiple of the previous one's), so the Cauchy product ``sum_j a_j b_{k-j}`` is bounded by
the excess ``max_j (e^a_j + e^b_{k-j})`` over the denominator ``A^a_k A^b_k``. Bounds only:
no cancellation is assumed.
"""

import numpy as np

#: the excess of a zero coefficient
ZERO = -(10**9)


class TaylorDegrees:
    """Degree bounds ``(numerator, denominator)`` of every coefficient of a Taylor program
    (:func:`uio_jax._engine.taylor.program`), order by order.

    Args:
        ins: the instructions.
        fields: per field, the instruction of each coordinate's entry (None: zero).
        inputs: the known inputs' coefficients (nonzero ones count as degree 0).
        orders: the highest order.
        lagged: the lagged instructions (computed one order behind, as the engine does).
    """

    def __init__(self, ins, fields, inputs, orders: int, lagged=()):
        self.ins, self.fields, self.inputs, self.lagged = ins, fields, inputs, set(lagged)
        K = int(orders) + 2  # a lagged derivative reads one order ahead
        self.e = np.full((len(ins), K), ZERO, dtype=np.int64)  # excess per order
        self.atoms = [[{} for _ in range(K)] for _ in ins]  # instruction -> order -> {atom: mult}
        self.atom_degree = {}  # atom (an instruction) -> degree of its order-0 numerator
        self.done = -1

    @classmethod
    def of(cls, series, orders: int) -> "TaylorDegrees":
        """The bounds of a :class:`~uio_jax._engine.taylor.TaylorSeries`' program."""
        return cls(series.ins, series.fields, series.inputs, orders, series.lagged)

    def degree(self, i: int, k: int) -> int:
        """``deg num + deg den`` of coefficient ``k`` of instruction ``i`` (the degree the
        rank decisions count per row, as :meth:`uio_jax._analysis.settle.Settler.count_bound`)."""
        while self.done < k:
            self._advance()
        d = self._den(self.atoms[i][k])
        return max(int(self.e[i, k]) + 2 * d, 0)

    def _den(self, atoms) -> int:
        return sum(m * self.atom_degree[a] for a, m in atoms.items())

    def _advance(self):
        k = self.done + 1
        for i, (op, a, param) in enumerate(self.ins):
            if op == "cos":
                continue  # the sine's bounds (the pair's recurrences are symmetric)
            m = k - 1 if i in self.lagged else k
            if m < 0:
                continue
            e, atoms = self._order(i, op, a, param, m)
            if m and self.atoms[i][m - 1]:  # non-decreasing denominators
                atoms = _lcm(atoms, self.atoms[i][m - 1])
            for j in (i, param[0]) if op == "sin" else (i,):
                self.e[j, m], self.atoms[j][m] = e, atoms
                if m == 0:  # the degree of its numerator, should it become an atom
                    self.atom_degree[j] = max(e + self._den(atoms), 0)
        self.done = k

    def _order(self, i, op, a, param, k):
        E = self.e
        if op == "x":
            return self._coordinate(param, k)
        if op == "c":
            return (0, {}) if k == 0 else (ZERO, {})
        if op == "neg":
            return int(E[a[0], k]), self.atoms[a[0]][k]
        if op == "add":
            return max(int(E[a[0], k]), int(E[a[1], k])), _lcm(self.atoms[a[0]][k], self.atoms[a[1]][k])
        if op == "mul":
            return self._product(a[0], a[1], 0, k)
        if op == "div":
            return self._quotient(i, a, k)
        if op == "deriv":  # D_m = (m + 1) u_{m+1}
            return int(E[a[0], k + 1]), self.atoms[a[0]][k + 1]
        if op == "free" and k:  # a_k = R_{k-1} / k
            return int(E[a[0], k - 1]), self.atoms[a[0]][k - 1]
        if k == 0:  # a generator or a root: a new variable of degree 2 (1 + its operands'
            # deg num + deg den), as graph_exact.degrees counts it
            operands = param[3] if op == "free" else a
            return 2 * (1 + sum(max(int(E[u, 0]) + 2 * self._den(self.atoms[u][0]), 0) for u in operands)), {}
        if op == "root":  # k u_0 w_k = sum_{j=1..k} ((alpha + 1) j - k) u_j w_{k-j}
            return self._over([self._product(a[0], i, 1, k)], a[0])
        # s_k = (1/k) sum_{j>=1} j u_j c_{k-j} (and c_k alike); E_k = (1/k) sum j u_j E_{k-j}
        return self._product(a[0], param[0] if op == "sin" else i, 1, k)

    def _over(self, terms, b):
        """The bound of ``(sum of terms) / b_0``: the denominator of ``b_0`` to the numerator,
        its numerator a new atom."""
        e, atoms = _sum(terms)
        if e == ZERO:
            return ZERO, {}
        atoms = dict(atoms)
        atoms[b] = atoms.get(b, 0) + 1
        return e - int(self.e[b, 0]), atoms

    def _coordinate(self, j, k):
        """``x_{j,k} = F_{j,k-1} / k`` with ``F = f0 + sum_i u_i(t) f_i``."""
        if k == 0:
            return 1, {}
        terms = []
        for f, field in enumerate(self.fields):
            s = field[j]
            if s is None:
                continue
            if f == 0:
                terms.append((int(self.e[s, k - 1]), self.atoms[s][k - 1]))
            else:
                terms += [(int(self.e[s, k - 1 - m]), self.atoms[s][k - 1 - m])
                          for m in range(k) if self.inputs[f - 1][m]]
        return _sum(terms)

    def _product(self, a, b, lo, k):
        """``sum_{j=lo..k} a_j b_{k-j}``: the largest excess of a term over ``A^a_k A^b_{k-lo}``."""
        ea, eb = self.e[a, lo:k + 1], self.e[b, k - lo::-1]
        both = (ea > ZERO) & (eb > ZERO)
        if not both.any():
            return ZERO, {}
        return int((ea + eb)[both].max()), _plus(self.atoms[a][k], self.atoms[b][k - lo])

    def _quotient(self, i, a, k):
        """``c_k = (a_k - sum_{j<k} c_j b_{k-j}) / b_0``: the bound of the sum, over ``b_0``
        (its denominator to the numerator, its numerator a new atom)."""
        terms = [(int(self.e[a[0], k]), self.atoms[a[0]][k])]
        if k:
            terms.append(self._tail(i, a[1], k))
        return self._over(terms, a[1])

    def _tail(self, c, b, k):
        """``sum_{j<k} c_j b_{k-j}``."""
        ec, eb = self.e[c, :k], self.e[b, k:0:-1]
        both = (ec > ZERO) & (eb > ZERO)
        if not both.any():
            return ZERO, {}
        return int((ec + eb)[both].max()), _plus(self.atoms[c][k - 1], self.atoms[b][k])


def _lcm(p, q):
    if not q:
        return p
    if not p:
        return q
    out = dict(p)
    for atom, m in q.items():
        if m > out.get(atom, 0):
            out[atom] = m
    return out


def _plus(p, q):
    if not q:
        return p
    if not p:
        return q
    out = dict(p)
    for atom, m in q.items():
        out[atom] = out.get(atom, 0) + m
    return out


def _sum(terms):
    """The bound of a sum: the largest excess over the lcm of the denominators."""
    terms = [t for t in terms if t[0] > ZERO]
    if not terms:
        return ZERO, {}
    atoms = {}
    for _, t in terms:
        atoms = _lcm(atoms, t)
    return max(e for e, _ in terms), atoms


__all__ = ["TaylorDegrees", "ZERO"]
