"""Closed forms by ansatz, solved exactly: functions whose differentials lie in a codistribution,
and vector fields that it annihilates, as combinations of monomials with unknown coefficients.

The codistribution is the span of the gradients of kept generators ``k_1..k_r`` on ``N``
coordinates (:class:`~uio_jax._analysis.decisions.space.SpanParts`). At a random point ``z`` of
``F_p^N`` (``p = 2^127 - 1``; :class:`uio_jax._engine.graph_exact.ModularEvaluator`, the
elementary functions on their variety) its rows ``K(z) (r, N)`` and its kernel
``V(z) (N, N - r)`` (the unobservable directions) are computed exactly. Three linear ansatzes
in unknown coefficients ``c`` give equations at each point:

* a function ``f = sum_a c_a m_a`` (monomials ``m_a`` of the first ``m`` coordinates of degree
  at most ``d``) is observable iff ``d f . v = 0`` for every unobservable direction ``v``:
  ``sum_a c_a (d m_a . v_j)(z) = 0``;
* a Laurent monomial ``prod z_i^(a_i)`` is observable iff ``d log`` of it is:
  ``sum_i a_i v_ji(z) / z_i = 0`` (the exponents of the observable ones form a lattice: for a
  scaling symmetry, its invariant monomials);
* a vector field ``X = sum_(i,a) c_ia m_a e_i`` is annihilated by the codistribution iff
  ``d k . X = 0`` for every kept generator: ``sum_(i,a) c_ia (d k / d z_i)(z) m_a(z) = 0``.

Points are added until the solution space stops shrinking (two points in a row leave its
dimension unchanged, or the equations outnumber the unknowns by the rows of two points). A
basis of the solutions, in reduced echelon form with the most complex unknowns first, is read
back as small fractions (rational reconstruction). These are *candidates*: every function
found is verified again by the exact membership test and every field by the exact symmetry
check before it is reported.
"""

import dataclasses
import itertools
import math

import numpy as np

from ..._engine import graph_exact


@dataclasses.dataclass(frozen=True)
class Point:
    """One random point modulo p: the coordinates ``z (N,)``, the kept rows ``K (r, N)``, a
    basis ``V (N - r, N)`` of their kernel, the atoms' values and gradients (``{i: d a / d z_i}``)."""

    z: list
    K: list
    V: list
    values: list
    grads: list

#: The prime of the candidate ansatzes of the named functions: the Mersenne prime ``2^31 - 1``
#: (residues and their products are machine words). A candidate is verified modulo
#: ``2^127 - 1`` before it is named; its coefficients are read back up to ``sqrt(p / 2)``.
CANDIDATE_PRIME = 2**31 - 1

#: Most unknowns an ansatz may have (monomials times coordinates): past it the ansatz is skipped.
MAX_UNKNOWNS = 120
#: Most random points an ansatz draws.
MAX_POINTS = 80


def monomials(m: int, degree: int, low: int = 1) -> list[tuple[int, ...]]:
    """Exponent vectors of the monomials in ``m`` coordinates of total degree ``low..degree``,
    the highest degree first (within a degree, lexicographically descending)."""
    out = []
    for d in range(degree, low - 1, -1):
        for combo in itertools.combinations_with_replacement(range(m), d):
            e = [0] * m
            for i in combo:
                e[i] += 1
            out.append(tuple(e))
    return out


def rational(a: int, p: int = graph_exact.PRIME):
    """The fraction ``u/v`` with ``u = a v mod p`` and ``|u|, v < sqrt(p / 2)``, or None
    (:func:`uio_jax._engine.graph_exact.rational_reconstruction`)."""
    return graph_exact.rational_reconstruction(a, p)


#: Largest numerator or denominator of a coefficient read back from a residue: a solution
#: with larger ones is a spurious one of too few points, or not a readable closed form.
MAX_COEFFICIENT = 10**6


def integer_vector(row, p: int = graph_exact.PRIME):
    """A residue vector as the smallest integer vector proportional to it (its fractions
    reconstructed, scaled by the least common denominator, divided by the gcd, the first
    nonzero entry positive), or None when an entry has no small fraction."""
    fr = []
    for v in row:
        f = rational(int(v), p)
        if f is None or abs(f.numerator) > MAX_COEFFICIENT or f.denominator > MAX_COEFFICIENT:
            return None
        fr.append(f)
    lcm = math.lcm(*(f.denominator for f in fr))
    ints = [int(f * lcm) for f in fr]
    g = math.gcd(*ints)
    if g == 0:
        return None
    ints = [v // g for v in ints]
    first = next(v for v in ints if v)
    return [-v for v in ints] if first < 0 else ints


def kernel(rows, cols: int, p: int = graph_exact.PRIME) -> list[list[int]]:
    """A basis of ``{c : rows c = 0}`` over ``F_p`` (each basis vector: 1 at its own free
    column, zero at the others). ``rows``: a list of rows or a
    :class:`~uio_jax._engine.graph_exact.Echelon` of them."""
    if isinstance(rows, graph_exact.Echelon):
        ech = rows
    else:
        ech = graph_exact.Echelon(p)
        for r in rows:
            ech.add(r)
    pivots = dict(zip(ech.pivots, ech.rows))
    free = [c for c in range(cols) if c not in pivots]
    out = []
    for f in free:
        v = [0] * cols
        v[f] = 1
        for c, r in pivots.items():
            v[c] = (-r[f]) % p
        out.append(v)
    return out


def simplest_basis(vectors, p: int = graph_exact.PRIME) -> list[list[int]]:
    """The reduced echelon form of a basis (columns ordered most complex first by the caller):
    each vector has its leading entry at its most complex unknown and none at the others'."""
    ech = graph_exact.Echelon(p)
    for v in vectors:
        ech.add(v)
    return [row for _, row in sorted(zip(ech.pivots, ech.rows))]


class ModularSpan:
    """The kept generators' rows and the unobservable directions at random points of ``F_p``.

    Args:
        graph: the expression graph.
        kept: graph nodes of the kept generators (independent).
        atoms: graph nodes the polynomial ansatz is written in (the coordinates, and
            elementary functions of one coordinate such as ``cos(theta)``).
        seed: seed of the points.
        fixed: ``{coordinate: value}`` of coordinates held at given values (integers,
            Fractions) at every point: the points are then random points of that section.
    """

    def __init__(self, graph, kept, atoms=(), seed: int = 0, p: int = graph_exact.PRIME, fixed=None):
        self.graph, self.kept, self.atoms = graph, list(kept), list(atoms)
        self.fixed = {int(i): graph_exact.const_mod(v, int(p)) for i, v in (fixed or {}).items()}
        self.rng = np.random.default_rng([int(seed), 0xA25A72])
        self.p = int(p)
        self.points = []  # Point per drawn point

    def point(self, i: int):
        """The ``i``-th :class:`Point` (drawn on first use, in batches: one evaluation of the
        kept generators and the atoms at every point of a batch; a point where the kept rows
        lose rank, or a zero coordinate (not a fixed one) or atom, is dropped), or None when no
        point could be drawn."""
        if len(self.points) <= i:
            self.draw(i + 1 - len(self.points))
        return self.points[i] if i < len(self.points) else None

    def draw(self, count: int) -> None:
        """Draw at least ``count`` more points, evaluated together. A batch with a singular
        point (a vanishing denominator, a square root that does not exist modulo p: half the
        points per root) is drawn again, then in halves, down to single points (at most 8
        draws each)."""
        size = max(int(count), 1)
        while count > 0 and size >= 1:
            got = None
            for _ in range(8 if size == 1 else 2):
                got = self._draw(size)
                if got is not None:
                    break
            if got is None:
                size //= 2
                continue
            self.points.extend(got)
            count -= max(len(got), 1)

    def _draw(self, size):
        """``size`` points evaluated together (the usable ones), or None when one is singular."""
        p, N, r = self.p, self.graph.n, len(self.kept)
        words = self.rng.integers(0, 2**63, size=(size, N, 3))
        zs = [[((int(a) << 126) | (int(b) << 63) | int(c)) % p for a, b, c in pt] for pt in words]
        for z in zs:
            for i, v in self.fixed.items():
                z[i] = v
        ev = graph_exact.ModularEvaluator(self.graph, zs, p)
        try:
            ev.evaluate(self.kept + self.atoms)
        except graph_exact.Singular:
            return None
        kept = [ev.dense(k) for k in self.kept]  # (N, size) each
        grads = [ev.dense(a) for a in self.atoms]
        values = [ev.V[a] % p for a in self.atoms]
        out = []
        for j, z in enumerate(zs):
            K = [[int(v) for v in row[:, j]] for row in kept]
            V = kernel(K, N, p)
            vals = [int(v[j]) for v in values]
            if len(V) == N - r and all(v for i, v in enumerate(z) if i not in self.fixed) and all(vals):
                gr = [{i: int(v) for i, v in enumerate(g[:, j]) if v} for g in grads]
                out.append(Point(z, K, V, vals, gr))
        return out

    def solve(self, equations, unknowns: int, rows_per_point: int):
        """The solutions ``c`` (residues) of ``equations(point) -> rows`` at enough points;
        None when a point could not be drawn or the points ran out."""
        ech, dims, i, count = graph_exact.Echelon(self.p), [], 0, 0
        needed = min(MAX_POINTS, -(-unknowns // max(rows_per_point, 1)) + 3)
        if len(self.points) < needed:
            self.draw(needed - len(self.points))
        while i < MAX_POINTS:
            found = self.point(i)
            if found is None:
                return None
            for row in equations(found):
                ech.add(row)
                count += 1
            i += 1
            if count < unknowns:
                continue
            dims.append(unknowns - ech.rank)
            if dims[-1] == 0 or (len(dims) >= 3 and dims[-1] == dims[-3]
                                 and count >= unknowns + 2 * rows_per_point):
                return kernel(ech, unknowns, self.p)
        return None


def polynomial_functions(span: ModularSpan, degree: int, atoms=None):
    """Integer coefficient vectors of observable polynomials in the span's atoms of degree at
    most ``degree`` (no constant term), with the exponent list: ``(monos, vectors)``; None when
    the ansatz is too large or cannot be solved.

    Args:
        span: the points.
        degree: the highest total degree.
        atoms: indices of the span's atoms the polynomials are written in (default: all); the
            exponent vectors are over these, in this order.
    """
    atoms = list(range(len(span.atoms))) if atoms is None else list(atoms)
    q = len(atoms)
    monos = monomials(q, degree)
    if not q or len(monos) > MAX_UNKNOWNS:
        return None
    p = span.p

    lower = monomials(q, degree - 1, low=0) if degree > 1 else [tuple([0] * q)]
    # d m_a = sum_t e_t m_(a - e_t) d a_t: the monomial one degree lower, per atom
    terms = [[(t, k, _lower(e, t)) for t, k in enumerate(e) if k] for e in monos]

    def equations(pt):
        values = [pt.values[t] for t in atoms]
        low = {e: monomial_value(e, values, p) for e in lower}
        rows = []
        for v in pt.V:
            w = [sum(g * v[i] for i, g in pt.grads[t].items()) % p for t in atoms]  # d a_t . v
            rows.append([sum(k * low[m] * w[t] for t, k, m in terms[a]) % p for a in range(len(monos))])
        return rows

    sol = span.solve(equations, len(monos), max(1, span.graph.n - len(span.kept)))
    if sol is None:
        return None
    return monos, _readable(sol, p)


def laurent_monomials(span: ModularSpan, m: int, among=None):
    """Integer exponent vectors ``a`` (length ``m``) of the observable Laurent monomials
    ``prod z_i^(a_i)`` of the first ``m`` coordinates (a basis of their lattice, read back
    from the reduced echelon form), or None.

    Only the coordinates that the unobservable directions move at the first point are
    unknowns: an exponent of a coordinate that no direction moves appears in no equation
    (``v_i = 0``), so it is free (a monomial with such a factor is that observable coordinate
    times a monomial of the others). ``among``: the coordinates the monomials may use (default:
    the first ``m``)."""
    p = span.p
    first = span.point(0)
    if first is None:
        return None
    moved = [i for i in range(m) if any(v[i] for v in first.V) and (among is None or i in among)]
    if len(moved) > MAX_UNKNOWNS:
        return None
    if not moved:
        return []

    def equations(pt):
        inv = [pow(pt.z[i], -1, p) for i in moved]
        return [[v[i] * w % p for i, w in zip(moved, inv)] for v in pt.V]

    visible = graph_exact.Echelon(p)
    for row in equations(first):
        visible.add(row)
    sol = span.solve(equations, len(moved), max(1, visible.rank))
    if sol is None:
        return None
    return [_placed(vec, moved, m) for vec in _readable(sol, p)]


def atom_monomials(span: ModularSpan, atoms):
    """Integer exponent vectors ``a`` of the observable products ``prod_t A_t^(a_t)`` of the
    span's atoms ``A_t``, ``t`` in ``atoms`` (the model's subexpressions: rational functions
    of the coordinates), a basis of their lattice; or None. A product is observable iff its
    ``d log`` is: ``sum_t a_t (d A_t . v) / A_t = 0`` for every unobservable direction ``v``."""
    atoms = list(atoms)
    if not atoms or len(atoms) > MAX_UNKNOWNS:
        return None
    p = span.p

    def equations(pt):
        inv = [pow(pt.values[t], -1, p) for t in atoms]
        return [[sum(g * v[i] for i, g in pt.grads[t].items()) * w % p for t, w in zip(atoms, inv)] for v in pt.V]

    first = span.point(0)
    if first is None:
        return None
    sol = span.solve(equations, len(atoms), max(1, span.graph.n - len(span.kept)))
    return None if sol is None else _readable(sol, p)


def polynomial_fields(span: ModularSpan, degree: int, n: int | None = None):
    """Integer coefficient vectors of the polynomial vector fields ``X`` of degree at most
    ``degree`` (constant fields included) on the first ``n`` coordinates (default: all ``N``)
    that the span annihilates: ``(monos, vectors)``, exponent vectors of length ``n``,
    unknown ``(i, a)`` at ``i * len(monos) + a``; or None when the ansatz is too large or
    cannot be solved.

    For ``n = N`` every kept gradient annihilates ``X``: ``d k . X = 0``. For ``n < N`` (the
    EORC's ``[x; w; ..]``, an extension) ``X`` lives on ``x`` and is tested against the
    covectors of the span with no component on the other coordinates (``c^T K`` for ``c``
    in the left kernel of ``K``'s last ``N - n`` columns): the covectors the report's ``dim``
    counts. The unobservable directions of ``x`` are their annihilator, which is the
    projection on ``x`` of the span's kernel (:func:`restricted_rows`).

    The unknowns are structured by the directions at the first point: a component ``X_i``
    where every direction has ``v_i = 0`` vanishes, and the monomials are written in the moved
    coordinates only (a field times an observable coordinate is no new direction)."""
    N = span.graph.n
    n = N if n is None else int(n)
    p = span.p
    first = span.point(0)
    if first is None:
        return None
    moved = [i for i in range(n) if any(v[i] for v in first.V)]
    small = monomials(len(moved), degree, low=0)
    if len(small) * len(moved) > MAX_UNKNOWNS:
        return None
    if not moved:
        return [], []

    def equations(pt):
        values = [monomial_value(e, [pt.z[i] for i in moved], p) for e in small]
        return [[k[i] * mv % p for i in moved for mv in values] for k in restricted_rows(pt.K, n, p)]

    rows = len(restricted_rows(first.K, n, p))
    sol = span.solve(equations, len(small) * len(moved), max(1, rows))
    if sol is None:
        return None
    M = len(small)
    monos = [tuple(_placed(e, moved, n)) for e in small]
    out = []
    for vec in _readable(sol, p, order=_field_order(small, len(moved))):
        full = [0] * (n * M)
        for s_, i in enumerate(moved):
            full[i * M:(i + 1) * M] = vec[s_ * M:(s_ + 1) * M]
        out.append(full)
    return monos, out


def restricted_rows(K, n: int, p: int):
    """The covectors of the span of the rows ``K (r, N)`` with no component past ``n``, as
    rows ``(n,)``: ``c^T K[:, :n]`` for ``c`` in a basis of the left kernel of ``K[:, n:]``
    (all of ``K`` when ``n = N``)."""
    N = len(K[0]) if K else n
    if n >= N:
        return K
    r = len(K)
    C = kernel([[K[i][j] for i in range(r)] for j in range(n, N)], r, p)
    return [[sum(c[i] * K[i][j] for i in range(r) if c[i]) % p for j in range(n)] for c in C]


def readable_fields(solutions, monos, n: int, p: int) -> list:
    """Residue vectors of fields (unknown ``(i, a)`` at ``i * len(monos) + a``) as the simplest
    integer basis of their span (most complex monomials first, as :func:`polynomial_fields`)."""
    return _readable(solutions, p, order=_field_order(monos, n))


def _placed(values, at, size) -> list:
    """``size`` zeros with ``values[s]`` at position ``at[s]``."""
    out = [0] * size
    for i, v in zip(at, values):
        out[i] = v
    return out


def _field_order(monos, N):
    """Unknowns of a field ansatz, most complex first: by the degree of their monomial."""
    M = len(monos)
    return sorted(range(M * N), key=lambda u: (-sum(monos[u % M]), u))


def _readable(solutions, p, order=None):
    """The solution space's simplest basis as integer vectors (those without small fractions
    dropped). ``order``: the unknowns from the most complex (default: as given)."""
    if not solutions:
        return []
    n = len(solutions[0])
    order = list(range(n)) if order is None else list(order)
    permuted = [[v[j] for j in order] for v in solutions]
    out = []
    for row in simplest_basis(permuted, p):
        vec = integer_vector(_placed(row, order, n), p)
        if vec is not None:
            out.append(vec)
    return out


def monomial_value(e, z, p: int) -> int:
    """The monomial of exponents ``e`` at the point ``z``, ``prod_i z_i^e_i`` modulo ``p``."""
    return math.prod(pow(z[i], k, p) for i, k in enumerate(e) if k) % p


def _lower(e, t):
    """The exponents ``e`` with one less at ``t``."""
    out = list(e)
    out[t] -= 1
    return tuple(out)


__all__ = ["ModularSpan", "Point", "monomials", "rational", "integer_vector", "kernel", "simplest_basis",
           "polynomial_functions", "laurent_monomials", "atom_monomials", "polynomial_fields", "restricted_rows",
           "readable_fields", "monomial_value",
           "MAX_UNKNOWNS", "MAX_POINTS", "MAX_COEFFICIENT", "CANDIDATE_PRIME"]
