"""The exact sympy route of the first-call benchmark (``scripts/bench_first_call.py``).

What a user who knows sympy writes for a fast exact answer: Lie derivatives and brackets are
symbolic (``sympy.diff``, unsimplified); each candidate is kept when its gradient at ONE random
point raises the rank; the gradient at the point is evaluated exactly, in rational arithmetic,
by forward-mode differentiation over the expression (one walk of its tree, shared
subexpressions once: no symbolic gradient of a large expression is formed); ranks are exact
(``DomainMatrix`` over ``QQ``).

The point is exact: states get random rationals in their boxes; a state that appears in
``sin``, ``cos`` or ``tan`` (an angle; the model's expressions are expanded with
``expand_trig`` first, so ``sin(theta - phi)`` reads the states' sines and cosines) gets a
point of the unit circle with rational coordinates, ``sin = 2t/(1+t^2)``,
``cos = (1-t^2)/(1+t^2)`` at a random rational ``t``. A value that is not rational there (a
bare angle, a square root, a constant such as ``cos(7 pi / 10)``) makes the route refuse the
model (:class:`NotExact`).

:func:`orc` is Algorithm 1 of Martinelli (002) and :func:`single_ui` Algorithms 2-3 with the
project's stopping rule: the algorithms of ``scripts/sympy_oracle.py`` (which evaluates in 50
digits) in exact arithmetic. One random point decides every rank: the generic rank with
probability one.
"""

from __future__ import annotations

import random
from fractions import Fraction

import sympy as sp
from sympy.polys.matrices import DomainMatrix


class NotExact(ValueError):
    """A value at the point that is not rational: the route does not apply to the model."""


class ExactPoint:
    """One random exact point of a model's box, and exact values and gradients there."""

    def __init__(self, model, seed=0):
        rng = random.Random(seed)
        self.states = list(model.states)
        self.n = len(self.states)
        self.index = {s: k for k, s in enumerate(self.states)}
        self.values, self.circle = {}, {}
        for s in self.states:
            lo, hi = (Fraction(repr(float(b))) for b in model.box(s))
            if hi - lo > 6:  # an angle box [-pi, pi): a rational point of the unit circle
                t = Fraction(rng.randint(-999, 999), 1000)
                self.circle[s] = (2 * t / (1 + t * t), (1 - t * t) / (1 + t * t))
            self.values[s] = lo + (hi - lo) * Fraction(rng.randint(1, 999), 1000)
        self.memo = {}

    def prepare(self, expr):
        """A model's expression with the sines and cosines of sums expanded."""
        expr = sp.sympify(expr)
        return sp.expand_trig(expr) if expr.atoms(sp.sin, sp.cos, sp.tan) else expr

    def jet(self, e):
        """``(value, gradient)`` of ``e`` at the point (Fractions; the gradient a tuple of n)."""
        got = self.memo.get(e)
        if got is None:
            got = self.memo[e] = self._jet(e)
        return got

    def _jet(self, e):
        n = self.n
        zero = (Fraction(0),) * n
        if e.is_Rational:
            return Fraction(int(e.p), int(e.q)), zero
        if e.is_Symbol:
            if e not in self.index:
                raise NotExact(f"a symbol that is not a state: {e}")
            g = [Fraction(0)] * n
            g[self.index[e]] = Fraction(1)
            return (None if e in self.circle else self.values[e]), tuple(g)  # an angle: not rational
        if e.is_Add or e.is_Mul:
            v, g = self.jet(e.args[0])
            for a in e.args[1:]:
                va, ga = self.jet(a)
                if e.is_Add:
                    v, g = (None if v is None or va is None else v + va), tuple(x + y for x, y in zip(g, ga))
                else:
                    v, g = _product(v, g, va, ga)
            return v, g
        if e.is_Pow and e.exp.is_Integer:
            k = int(e.exp)
            v, g = self.jet(e.base)
            if v is None:
                raise NotExact(f"a power of an angle: {e}")
            if v == 0 and k < 0:
                raise ZeroDivisionError("the point is a pole")
            d = k * v ** (k - 1)
            return v**k, tuple(d * x for x in g)
        if isinstance(e, (sp.sin, sp.cos, sp.tan)) and e.args[0] in self.circle:
            s = e.args[0]
            sin, cos = self.circle[s]
            g = [Fraction(0)] * n
            k = self.index[s]
            if isinstance(e, sp.sin):
                g[k] = cos
                return sin, tuple(g)
            if isinstance(e, sp.cos):
                g[k] = -sin
                return cos, tuple(g)
            g[k] = 1 + (sin / cos) ** 2
            return sin / cos, tuple(g)
        raise NotExact(f"no exact value at the point: {e}")

    def value(self, e):
        v = self.jet(e)[0]
        if v is None:
            raise NotExact(f"an angle's value is needed: {e}")
        return v

    def gradient(self, e):
        return [sp.QQ(x.numerator, x.denominator) for x in self.jet(e)[1]]



def _product(v, g, va, ga):
    """``(value, gradient)`` of a product from those of its factors; a value None (an angle,
    not rational) is allowed where it multiplies a zero gradient only."""
    if v is None or va is None:
        if (v is None and any(ga)) or (va is None and any(g)) or (v is None and va is None):
            raise NotExact("an angle times a function of the state")
        if v is None:
            return None, tuple(x * va for x in g)
        return None, tuple(v * y for y in ga)
    return v * va, tuple(x * va + v * y for x, y in zip(g, ga))


def _rank(rows) -> int:
    return DomainMatrix([list(r) for r in rows], (len(rows), len(rows[0])), sp.QQ).rank() if rows else 0


class _Span:
    def __init__(self):
        self.rows, self.dim = [], 0

    def contains(self, row) -> bool:
        return _rank(self.rows + [row]) == self.dim

    def add(self, row) -> bool:
        if self.contains(row):
            return False
        self.rows.append(row)
        self.dim += 1
        return True


def lie(e, v, states):
    """``L_v e`` (symbolic, unsimplified)."""
    return sp.Add(*[sp.diff(e, s) * c for s, c in zip(states, v) if c != 0])


def _absorb(pt, candidates, span):
    return [c for c in candidates if c != 0 and span.add(pt.gradient(c))]


def orc(model, seed=0) -> dict:
    """The ORC's dims (Algorithm 1), exact."""
    pt = ExactPoint(model, seed)
    X = pt.states
    fields = [[pt.prepare(e) for e in f]
              for f in ([model.drift] if model.drift is not None else []) + list(model.known.values())]
    span = _Span()
    frontier = _absorb(pt, [pt.prepare(h) for h in model.outputs.values()], span)
    dims = [span.dim]
    while frontier and span.dim < pt.n:
        frontier = _absorb(pt, [lie(k, v, X) for k in frontier for v in fields], span)
        dims.append(span.dim)
    return {"dims": dims, "dim": dims[-1]}


def _lemma1(pt, phi, count, lg1) -> bool:
    """Lemma 1 of 002 at the point (``sympy_oracle._lemma1``, exact): for each of the ``count``
    known inputs, ``L_{phi^i_j} L_g^1 = 0`` up to where ``span{phi^i_0..phi^i_j}`` stops growing."""
    for i in range(count):
        vecs = []
        for j in range(pt.n):
            if pt.value(lie(lg1, phi(i, j), pt.states)) != 0:
                return False
            vecs.append([sp.QQ(*_pq(pt.value(e))) for e in phi(i, j)])
            if _rank(vecs + [[sp.QQ(*_pq(pt.value(e))) for e in phi(i, j + 1)]]) == _rank(vecs):
                break
    return True


def _pq(x: Fraction):
    return x.numerator, x.denominator


def single_ui(model, seed=0) -> dict:
    """The dims of Algorithm 2 of 002 (one unknown input, no drift; the project's stopping rule,
    ``sympy_oracle.single_ui``), exact. When ``L_g h`` vanishes for every output, 004 section 7
    (``sympy_oracle.single_ui``'s ``offset``) is not taken: the route refuses (:class:`NotExact`)."""
    pt = ExactPoint(model, seed)
    X, n = pt.states, pt.n
    (g,) = [[pt.prepare(e) for e in v] for v in model.unknown.values()]
    fields = [[pt.prepare(e) for e in f] for f in model.known.values()]
    span = _Span()
    outputs = [pt.prepare(h) for h in model.outputs.values()]
    frontier = _absorb(pt, outputs, span)
    dims = [span.dim]
    h = lg1 = None
    for out in outputs:
        cand = lie(out, g, X)
        if cand != 0 and pt.value(cand) != 0:
            h, lg1 = out, cand
            break
    if h is None:
        raise NotExact("L_g h vanishes for every output (004 section 7)")
    g_scaled = [e / lg1 for e in g]
    G = sp.Matrix(g)
    cache = {}

    def phi(i, j):
        if (i, j) not in cache:
            if j == 0:
                cache[i, j] = fields[i]
            else:
                a = sp.Matrix(phi(i, j - 1))
                cache[i, j] = list((G.jacobian(X) * a - a.jacobian(X) * G) / lg1)
        return cache[i, j]

    phi1_zero = all(all(pt.value(e) == 0 for e in phi(i, 1)) for i in range(len(fields)))
    lemma = phi1_zero or _lemma1(pt, phi, len(fields), lg1)
    tau = None if lemma else pt.gradient(lie(lg1, g, X) / lg1**2)
    m_prime = 0 if lemma or span.contains(tau) else None
    m, min_star = 0, 0 if phi1_zero else 1
    while span.dim < n and m < n + 2:
        m += 1
        cands = [lie(k, v, X) for k in frontier for v in fields + [g_scaled]]
        cands += [lie(h, phi(i, m - 1), X) for i in range(len(fields))]
        frontier = _absorb(pt, cands, span)
        dims.append(span.dim)
        if m_prime is None and span.contains(tau):
            m_prime = m
        if dims[-1] == dims[-2] and m_prime is not None and m - 1 >= max(m_prime, min_star):
            break
    return {"dims": dims, "dim": span.dim}


__all__ = ["ExactPoint", "NotExact", "orc", "single_ui"]
