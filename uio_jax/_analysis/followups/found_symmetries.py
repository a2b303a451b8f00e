"""Symmetries, found: the unobservable distribution as closed-form vector fields (``Report.symmetries``).

The unobservable directions of a report are the kernel of its codistribution at each point;
:meth:`uio_jax.Report.unobservable_directions` gives them as numbers. Here they are found as
**vector fields in closed form**: polynomial fields of degree at most 1 in the coordinates
(translations, rotations, scalings and every other linear field), by the ansatz of
:func:`uio_jax._analysis.followups.ansatz.polynomial_fields` (every kept gradient annihilates the field:
a linear system in its coefficients, solved modulo ``p = 2^127 - 1`` at random points, its
solutions read back as small integers). A solution is only a candidate: each is checked by
the symmetry check of declared symmetries (:func:`uio_jax._analysis.decisions.symmetry.verify_symmetries`,
exactly modulo p) and kept only when verified and independent of the fields kept before (rank
modulo p at a random point). A verified field moves the coordinates it has a component on at
every order of every analysis (the proof is in :mod:`.symmetry`).

The fields found need not span the whole unobservable distribution (a direction may be a
symmetry of no polynomial form, or a field that annihilates the codistribution without
commuting with the dynamics); the result says how many of ``n - dim`` directions they span.
Where the analysis runs on more coordinates than the report's (the EORC's ``[x; w; w'; ..]``,
the general solution's extension), the fields live on ``x`` and the ansatz tests them against
the covectors of the span with no component on the other coordinates (those the report's
``dim`` counts; :func:`uio_jax._analysis.followups.ansatz.polynomial_fields`); the check runs on the
System before the extension, its unknown inputs as unknown inputs, and its condition (S3)
is the prolongation to the inputs: the proof in :mod:`.symmetry` covers every order of every
extension. Not searched for a time-varying model (the report's states are not a System's)
or one not made rational.
"""

import dataclasses

import numpy as np

from ..._calculus.generators import builder_for
from ..._engine import graph_exact
from ..._errors import ModelError
from ..._model.system import System, derived_system
from ..decisions.settle import DEFAULT_PROB_THRESHOLD
from ..decisions.symmetry import verify_symmetries
from ..results.kinds import Arithmetic
from . import ansatz

#: Highest degree of the field ansatz (1: translations, rotations, scalings, linear fields).
DEGREE = 1


@dataclasses.dataclass(frozen=True)
class FoundSymmetry:
    """One verified symmetry.

    Attributes:
        kind: ``"translation"``, ``"rotation"``, ``"scaling"`` or ``"linear field"``.
        components: ``{name: text}`` of its nonzero components (expressions in the names).
        how: how the symmetry check decided (``"exact mod p = 2^127 - 1 at 3 points"``).
    """

    kind: str
    components: dict
    how: str

    def text(self) -> str:
        """``rotation: x -> -y, y -> x, theta -> 1``."""
        return f"{self.kind}: " + ", ".join(f"{k} -> {v}" for k, v in self.components.items())

    def to_dict(self) -> dict:
        return {"kind": self.kind, "components": dict(self.components), "how": self.how}


@dataclasses.dataclass(frozen=True)
class FoundSymmetries:
    """The symmetries found for a report.

    Attributes:
        fields: the verified, independent :class:`FoundSymmetry` fields.
        hidden: ``n - dim``, the number of unobservable directions.
        searched: why the search ran or did not (``""`` when it ran).
    """

    fields: tuple
    hidden: int
    searched: str = ""

    @property
    def complete(self) -> bool:
        """Whether the fields span the unobservable distribution."""
        return len(self.fields) == self.hidden

    def summary(self) -> str:
        if self.searched:
            return f"not searched ({self.searched})"
        return (f"{len(self.fields)} of {self.hidden} unobservable direction{'s' if self.hidden != 1 else ''} "
                "given by verified symmetries (polynomial fields of degree <= 1)")

    def to_dict(self) -> dict:
        return {"fields": [f.to_dict() for f in self.fields], "hidden": self.hidden,
                "complete": self.complete, "searched": self.searched or None}


def find_symmetries(parts, system, seed: int = 0, prob_threshold: float = DEFAULT_PROB_THRESHOLD) -> FoundSymmetries:
    """Verified symmetries of the System a report is about.

    Args:
        parts: the final codistribution (:class:`~uio_jax._analysis.decisions.space.SpanParts`).
        system: the System whose states are the report's (for the EORC and an extended
            general solution: the System before the extension, its unknown inputs as unknown
            inputs; the codistribution may live on more coordinates).
        seed: seed of the ansatz points.
        prob_threshold: the probability of correctness of the symmetry check's zero tests.
    """
    n = parts.n
    hidden = n - parts.dim
    if hidden == 0:
        return FoundSymmetries((), 0)
    if system is None or system.n != n:
        return FoundSymmetries((), hidden, "the report's states are not those of a System to verify "
                                           "fields on (a time-varying model)")
    if parts.settler.arithmetic([nd.expr for nd in parts.nodes]) is not Arithmetic.EXACT:
        return FoundSymmetries((), hidden, "the model is not made rational")
    span = ansatz.ModularSpan(parts.builder.graph, [nd.expr for nd in parts.nodes], seed=seed,
                              p=ansatz.CANDIDATE_PRIME)
    found = None
    for degree in range(DEGREE, -1, -1):  # the largest ansatz that fits
        found = ansatz.polynomial_fields(span, degree, n)
        if found is not None:
            break
    if found is None:
        return FoundSymmetries((), hidden, "the field ansatz could not be solved")
    monos, vectors = found
    vectors = _symmetric(monos, vectors, system, n, seed)
    fields = sorted((PolynomialField(monos, v, n) for v in vectors), key=lambda f: f.size)
    return FoundSymmetries(_verified(fields, system, span, hidden, seed, prob_threshold), hidden)


def _symmetric(monos, vectors, system, n, seed) -> list:
    """The combinations of the annihilating fields ``vectors`` that satisfy the symmetry
    conditions (S1)-(S3) of :mod:`.symmetry` at random points modulo the candidate prime.

    The fields that annihilate the span include every function multiple of a symmetry
    (``ry d/drx`` beside the translation ``d/drx``). (S1)-(S3) are linear in ``X`` and ``b``:
    with ``X = sum_k a_k X_k`` they are linear equations in ``(a, b)`` at each point, whose
    solutions are the candidate symmetries (checked exactly afterwards). Returns integer
    vectors (the simplest basis of the combinations), or ``vectors`` unchanged where the
    conditions cannot be evaluated."""
    if not vectors:
        return vectors
    p = ansatz.CANDIDATE_PRIME
    builder = builder_for(system)
    outputs = [builder.scalar(k, fn) for k, fn in system.outputs.items()]
    known = [builder.field(k, fn) for k, fn in system.fields().items() if k not in system.unknown]
    unknown = [builder.field(k, fn) for k, fn in system.unknown.items()]
    try:
        xis = [builder.field(f"candidate field {i}", PolynomialField(monos, v, n).callable())
               for i, v in enumerate(vectors)]
    except ModelError:
        return vectors
    conds = [[(builder.lie(xi, h).expr,) for h in outputs] + [builder.bracket(xi, f).expr for f in known]
             for xi in xis]
    mixes = [[builder.bracket(xi, g).expr for g in unknown] for xi in xis]
    G = [g.expr for g in unknown]
    roots = [e for c in conds for es in c for e in es] + [e for c in mixes for es in c for e in es] \
        + [e for g in G for e in g]
    rng = np.random.default_rng([int(seed), 0x5A7E])
    for _ in range(4):
        points = [[int(v) for v in rng.integers(1, p, size=builder.graph.n)] for _ in range(3)]
        ev = graph_exact.ModularEvaluator(builder.graph, points, p)
        try:
            ev.evaluate(roots)
            break
        except graph_exact.Singular:
            ev = None
        except ValueError:  # not made rational (a constant known in float64 only)
            return vectors
    if ev is None:
        return vectors
    K, m = len(xis), len(G)
    rows = []
    for t in range(len(points)):
        def at(e):
            return int(ev.V[e][t]) % p
        for c in range(len(conds[0])):
            for e in range(len(conds[0][c])):
                rows.append([at(conds[k][c][e]) for k in range(K)] + [0] * (m * m))
        for j in range(m):
            for e in range(len(G[j])):
                row = [at(mixes[k][j][e]) for k in range(K)] + [0] * (m * m)
                for l_ in range(m):
                    row[K + j * m + l_] = (-at(G[l_][e])) % p
                rows.append(row)
    combos = ansatz.kernel(rows, K + m * m, p)
    fields = [[sum(a[k] * vectors[k][u] for k in range(K)) % p for u in range(len(vectors[0]))]
              for a in combos if any(a[:K])]
    return ansatz.readable_fields(fields, monos, n, p)


def _verified(fields, system, span, hidden, seed, prob_threshold) -> tuple:
    """The candidate fields that pass the symmetry check of declared symmetries on
    ``system`` (:func:`uio_jax._analysis.decisions.symmetry.verify_symmetries`), independent of those
    kept before (rank modulo p at the span's first point), at most ``hidden``."""
    if not fields:
        return ()
    names = tuple(system.states)
    declared = {f"found_{i}": f.callable() for i, f in enumerate(fields)}
    with derived_system():
        probe = System(system.states, dict(system.outputs), dict(system.known), dict(system.unknown),
                       system.drift, dict(system.domain), system.angles, system.name, symmetries=declared)
    bound = verify_symmetries(probe, seed=seed, prob_threshold=prob_threshold)
    kept, echelon, point = [], graph_exact.Echelon(), span.point(0)
    for f, check in zip(fields, bound.checks if bound else ()):
        if check.verified and point is not None and echelon.add(f.at(point.z)):
            kept.append(FoundSymmetry(f.kind(), f.components(names), check.how))
        if len(kept) == hidden:
            break
    return tuple(kept)


class PolynomialField:
    """A polynomial vector field from the ansatz' integer coefficients (unknown ``(i, a)``
    of component ``i`` and monomial ``monos[a]`` at ``i * len(monos) + a``): its values modulo
    p, a JAX callable, its components as text and its kind."""

    def __init__(self, monos, vector, N):
        M = len(monos)
        self.terms = [[(vector[i * M + a], monos[a]) for a in range(M) if vector[i * M + a]] for i in range(N)]
        degree = max((sum(e) for t in self.terms for _, e in t), default=0)
        self.size = (degree, sum(len(t) for t in self.terms))

    def at(self, z):
        p = graph_exact.PRIME
        return [sum(c * ansatz.monomial_value(e, z, p) for c, e in terms) % p for terms in self.terms]

    def callable(self):
        terms = self.terms

        def body(z):  # Python's operators only: runs on numpy, JAX and graph values alike
            comps = []
            for tt in terms:
                acc = 0.0 * z[0]
                for c, e in tt:
                    m = float(c)
                    for j, k in enumerate(e):
                        if k:
                            m = m * z[j] ** k
                    acc = acc + m
                comps.append(acc)
            return comps

        def xi(z):
            if isinstance(z, np.ndarray):
                return np.stack(body(z))
            import jax.numpy as jnp

            return jnp.stack(body(z))

        xi.emit, xi.graph_native = body, True  # its expression without JAX (graph_trace)
        return xi

    def components(self, names) -> dict:
        return {name: _poly_text(terms, names) for name, terms in zip(names, self.terms) if terms}

    def kind(self) -> str:
        degrees = {sum(e) for terms in self.terms for _, e in terms}
        if degrees == {0}:
            return "translation"
        linear = {}  # (i, j) -> c of the component i's term c z_j
        for i, terms in enumerate(self.terms):
            for c, e in terms:
                if sum(e) == 1:
                    linear[(i, e.index(1))] = c
        if linear and all(i == j for i, j in linear):
            return "scaling"
        if any(linear.get((j, i)) == -c for (i, j), c in linear.items() if i != j):
            return "rotation"
        return "linear field"


def _poly_text(terms, names) -> str:
    parts = []
    for c, e in terms:
        factors = [n if k == 1 else f"{n}**{k}" for n, k in zip(names, e) if k]
        body = "*".join(factors)
        if not body:
            term = str(abs(c))
        elif abs(c) == 1:
            term = body
        else:
            term = f"{abs(c)}*{body}"
        parts.append(("-" if c < 0 else "+", term))
    return ("-" if parts[0][0] == "-" else "") + parts[0][1] + "".join(f" {sign} {term}" for sign, term in parts[1:])


__all__ = ["FoundSymmetry", "FoundSymmetries", "PolynomialField", "find_symmetries", "DEGREE"]
