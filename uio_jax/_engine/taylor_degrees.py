"""Degree and height bounds of the Taylor coefficients of :mod:`.taylor` and of their
gradients: the probability that a rank decision taken on them modulo a prime is wrong
(:mod:`.taylor_rank`).

Every coefficient ``v_k`` of an instruction is a rational function of the coordinates and of
the generators' values at ``t = 0`` (each a variable, of degree ``2 (1 + deg u)`` for its
argument ``u``, as :func:`.graph_exact.degrees` counts it). It is bounded in *derivative form*
``v^(k) = k! v_k`` (scaling a row by ``k!`` changes neither the rank nor whether a minor
vanishes modulo ``p > k``), written ``N / Q`` with gradient ``T / Q^2``, ``N`` and ``T``
polynomials with integer coefficients and ``Q`` a product of *atoms*: the numerators of the
order-0 coefficients divided by, and the denominators of the rational constants (the
model's, the known inputs', the exponents'), each with a multiplicity. Kept per coefficient:

* ``e = deg N - deg Q`` (the degree excess), ``eps = log2 |N|_1 - log2 |Q|_1`` and
  ``tau = log2 |T|_1 - 2 log2 |Q|_1`` (``|.|_1`` the sum of the absolute values of the
  coefficients, which is sub-multiplicative), and the atoms' multiplicities.
* A sum of ``n`` terms is written over the least common multiple of their denominators:
  each numerator is multiplied by the atoms it lacks, which leaves its excesses unchanged, so
  the sum has the largest excesses (plus ``log2 n`` bits) over the lcm. A Cauchy sum
  ``sum_j C(k, j) a^(j) b^(k-j)`` takes, per atom, the largest multiplicity of
  ``a^(j) b^(k-j)`` over its terms (multiplicities growing linearly in ``k`` stay linear; a
  bound by the atoms of ``a^(k) b^(k)`` doubled them at every order).
* A product adds excesses (``tau``: ``max(tau_a + eps_b, eps_a + tau_b) + 1``); a quotient by
  ``b_0`` subtracts ``b``'s (``tau``: ``max(tau - eps_b, eps + tau_b - 2 eps_b) + 1``) and adds the
  atom ``b``; a generator's value is a variable over its argument's atoms, its gradient the
  argument's times a slope. Bounds only: no cancellation is assumed.

A decision on rows ``(i_r, k_r)`` has a minor of degree at most ``sum_r deg(i_r, k_r)``
(:meth:`TaylorDegrees.degree`: ``deg N + deg Q``) and a numerator of at most
``log2 r! + sum_r bits(i_r, k_r)`` bits (:meth:`TaylorDegrees.row_bits`: ``log2 |T|_1``).
"""

import math
from collections import Counter
from fractions import Fraction

import numpy as np

#: the degree excess of a zero coefficient
ZERO = -(10**9)
NONE = -math.inf


def _bits(value):
    return math.log2(abs(value)) if value else NONE


class TaylorDegrees:
    """Degree and height bounds of every coefficient of a Taylor program
    (:func:`uio_jax._engine.taylor.program`), order by order, computed on request.

    Args:
        ins: the instructions.
        fields: per field, the instruction of each coordinate's entry (None: zero).
        inputs: the known inputs' coefficients (nonzero ones count as degree 0).
        orders: the highest order.
        lagged: the lagged instructions (computed one order behind, as the engine does).
    """

    def __init__(self, ins, fields, inputs, orders: int, lagged=(), constant=None):
        self.ins, self.fields, self.inputs, self.lagged = ins, fields, inputs, set(lagged)
        #: the instructions constant along the flow (zero beyond order 0: not walked there)
        self.constant = np.zeros(len(ins), dtype=bool) if constant is None else np.asarray(constant, dtype=bool)
        K = int(orders) + 2  # a lagged derivative reads one order ahead
        self.e = np.full((len(ins), K), ZERO, dtype=np.int64)
        self.eps = np.full((len(ins), K), NONE)
        self.tau = np.full((len(ins), K), NONE)
        self.mult = [{} for _ in ins]  # instruction -> {atom: multiplicity per order (K,)}
        self.atom_degree, self.atom_bits = {}, {}
        self.lb = np.array([[math.lgamma(k + 1) - math.lgamma(j + 1) - math.lgamma(k - j + 1) if j <= k else 0.0
                             for j in range(K)] for k in range(K)]) / math.log(2)
        self.K = K
        self.done = -1

    @classmethod
    def of(cls, series, orders: int) -> "TaylorDegrees":
        """The bounds of a :class:`~uio_jax._engine.taylor.TaylorSeries`' program."""
        return cls(series.ins, series.fields, series.inputs, orders, series.lagged, series.plan.constant)

    def degree(self, i: int, k: int) -> int:
        """``deg N + deg Q`` of coefficient ``k`` of instruction ``i`` (the degree a rank
        decision counts per row)."""
        self._upto(k)
        return self._degree(i, k)

    def _degree(self, i, k):
        return max(int(self.e[i, k]) + 2 * self._den(i, k, self.atom_degree), 0)

    def row_bits(self, i: int, k: int) -> float:
        """``log2 |T|_1``: the bits of the numerator of coefficient ``k``'s gradient (0 for a
        zero gradient)."""
        self._upto(k)
        tau = self.tau[i, k]
        return max(float(tau) + 2 * self._den(i, k, self.atom_bits), 0.0) if tau > NONE else 0.0

    def _upto(self, k):
        while self.done < k:
            self._advance()

    def _den(self, i, k, weight):
        return sum(int(m[k]) * weight[a] for a, m in self.mult[i].items() if m[k])

    def _atoms(self, i, k):
        return {a: int(m[k]) for a, m in self.mult[i].items() if m[k]}

    def _advance(self):
        k = self.done + 1
        for i, (op, a, param) in enumerate(self.ins):
            if op == "cos" or (k and self.constant[i]):
                continue  # the sine's bounds (the pair's recurrences are symmetric); zero
            m = k - 1 if i in self.lagged else k
            if m < 0:
                continue
            e, eps, tau, atoms = self._order(i, op, a, param, m)
            for j in (i, param[0]) if op == "sin" else (i,):
                self.e[j, m], self.eps[j, m], self.tau[j, m] = e, eps, tau
                for atom, mult in atoms.items():
                    self.mult[j].setdefault(atom, np.zeros(self.K, dtype=np.int64))[m] = mult
                if m == 0:  # its numerator's bounds, should it become an atom
                    self.atom_degree[j] = max(e + self._den(j, 0, self.atom_degree), 0)
                    self.atom_bits[j] = max(eps + self._den(j, 0, self.atom_bits), 0.0) if eps > NONE else 0.0
        self.done = k

    def _term(self, i, k):
        return int(self.e[i, k]), float(self.eps[i, k]), float(self.tau[i, k]), self._atoms(i, k)

    def _constant_atom(self, key, value: Fraction):
        if value.denominator == 1:
            return {}
        self.atom_degree[key], self.atom_bits[key] = 0, math.log2(value.denominator)
        return {key: 1}

    def _order(self, i, op, a, param, k):
        if op == "x":
            return self._coordinate(param, k)
        if op == "c":
            if k or not param:
                return ZERO, NONE, NONE, {}
            value = Fraction(param)
            return 0, _bits(value.numerator), NONE, self._constant_atom(("c", i), value)
        if op == "neg":
            return self._term(a[0], k)
        if op == "add":
            return _sum([self._term(a[0], k), self._term(a[1], k)])
        if op == "mul":
            return self._product(a[0], a[1], 0, k, k)
        if op == "div":  # b_0 c^(k) = a^(k) - sum_{j<k} C(k, j) c^(j) b^(k-j)
            return self._over(_sum([self._term(a[0], k), self._product(i, a[1], 0, k - 1, k)]), a[1])
        if op == "deriv":  # D^(m) = u^(m+1)
            return self._term(a[0], k + 1)
        if op == "free" and k:  # a^(k) = R^(k-1)
            return self._term(a[0], k - 1)
        if k == 0:
            return self._generator(i, op, a, param)
        if op == "root":  # u_0 w^(k) = sum_j (alpha C(k-1, j-1) - C(k-1, j)) u^(j) w^(k-j)
            alpha = Fraction(param[0])
            e, eps, tau, atoms = self._product(a[0], i, 1, k, k, extra=math.log2(abs(alpha.numerator) +
                                                                                 alpha.denominator))
            return self._over((e, eps, tau, _plus(atoms, self._constant_atom(("alpha", i), alpha))), a[0])
        # sin, cos, exp: v^(k) = sum_{j=1..k} C(k-1, j-1) u^(j) w^(k-j)
        return self._product(a[0], param[0] if op == "sin" else i, 1, k, k, shift=1)

    def _generator(self, i, op, a, param):
        """A generator's value at ``t = 0`` (or a root's): a variable of degree
        ``2 (1 + deg u)`` over its arguments' atoms; its gradient the arguments' times a slope
        (a root's slope ``alpha w / u``: the atom ``u`` too)."""
        operands = param[3] if op == "free" else a
        degree = 2 * (1 + sum(self._degree(u, 0) for u in operands))
        if op == "free":
            key, pairs, kind, values = param
            _, _, tau, atoms = _sum([(0, self.eps[c, 0], self.eps[c, 0] + self.tau[u, 0],
                                      _plus(self._atoms(c, 0), self._atoms(u, 0))) for c, u in pairs])
            return degree, 0.0, tau, atoms
        u = a[0]
        _, eps_u, tau_u, atoms = self._term(u, 0)
        if op != "root":
            return degree, 0.0, tau_u, atoms
        alpha = Fraction(param[0])
        atoms = _plus(_plus(atoms, {u: 1}), self._constant_atom(("alpha", i), alpha))
        return degree, 0.0, _bits(alpha.numerator) + tau_u - eps_u - math.log2(alpha.denominator), atoms

    def _coordinate(self, j, k):
        """``x^(k) = F0^(k-1) + sum_f sum_m C(k-1, m) m! a_fm F_f^(k-1-m)``."""
        if k == 0:
            return 1, 0.0, 0.0, {}
        terms = []
        for f, field in enumerate(self.fields):
            s = field[j]
            if s is None:
                continue
            if f == 0:
                terms.append(self._term(s, k - 1))
                continue
            for m in range(k):
                value = Fraction(self.inputs[f - 1][m])
                if value:
                    w = self.lb[k - 1, m] + math.lgamma(m + 1) / math.log(2) + _bits(value.numerator)
                    e, eps, tau, atoms = self._term(s, k - 1 - m)
                    terms.append((e, eps + w, tau + w, _plus(atoms, self._constant_atom(("in", f, m), value))))
        return _sum(terms)

    def _product(self, a, b, lo, top, k, shift=0, extra=0.0):
        """``sum_{j=lo..top} C(k - shift, j - shift) a^(j) b^(k-j)``."""
        if top < lo:
            return ZERO, NONE, NONE, {}
        j = np.arange(lo, top + 1)
        both = (self.e[a, j] > ZERO) & (self.e[b, k - j] > ZERO)
        if not both.any():
            return ZERO, NONE, NONE, {}
        j = j[both]
        ea, eb, ta, tb = self.eps[a, j], self.eps[b, k - j], self.tau[a, j], self.tau[b, k - j]
        w = self.lb[k - shift, j - shift] + extra
        n = math.log2(len(j))
        with np.errstate(invalid="ignore"):
            eps = float((ea + eb + w).max()) + n
            tau = float((np.maximum(ta + eb, ea + tb) + w).max()) + 1 + n
        atoms = {}
        for atom in self.mult[a].keys() | self.mult[b].keys():
            ma = self.mult[a].get(atom)
            mb = self.mult[b].get(atom)
            m = int(((ma[j] if ma is not None else 0) + (mb[k - j] if mb is not None else 0)).max())
            if m:
                atoms[atom] = m
        return int((self.e[a, j] + self.e[b, k - j]).max()), eps, tau, atoms

    def _over(self, term, b):
        """``(N / Q) / b_0``: ``b_0``'s denominator to the numerator, its numerator a new atom."""
        e, eps, tau, atoms = term
        if e == ZERO:
            return ZERO, NONE, NONE, {}
        eb, tb = float(self.eps[b, 0]), float(self.tau[b, 0])
        return (e - int(self.e[b, 0]), eps - eb, max(tau - eb, eps + tb - 2 * eb) + 1, _plus(atoms, {b: 1}))


def _plus(p, q):
    """The product of two denominators: their atoms' multiplicities added."""
    return p if not q else q if not p else dict(Counter(p) + Counter(q))


def _sum(terms):
    """A sum: the largest excesses (plus ``log2`` of the number of terms) over the lcm."""
    terms = [t for t in terms if t[0] > ZERO]
    if not terms:
        return ZERO, NONE, NONE, {}
    atoms = Counter()
    for *_, t in terms:
        atoms |= Counter(t)
    n = math.log2(len(terms))
    return (max(t[0] for t in terms), max(t[1] for t in terms) + n, max(t[2] for t in terms) + n, dict(atoms))


__all__ = ["TaylorDegrees", "ZERO"]
