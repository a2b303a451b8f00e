"""Verified symmetries: proofs of unobservability and an upper bound on the observable space.

A System may declare symmetries (``System(symmetries=...)``, :mod:`uio_jax._model.symmetries`):
fields ``xi`` of the analysed coordinates along which the model is claimed invariant. This
module verifies the claim and turns a verified one into two facts the analyses use.

**The conditions.** With ``x' = f0 + sum_i f_i u_i + sum_j g_j w_j`` and outputs ``h``:

* (S1) ``L_xi h_k = 0`` for every output;
* (S2) ``[xi, f0] = 0`` and ``[xi, f_i] = 0`` for every known field;
* (S3) ``[xi, g_j] = sum_l b_jl g_l`` for every unknown-input field, ``B = (b_jl)`` *constant*.

**Why they bound every order of the EORC.** On the K-th extension (:mod:`.eorc`: state
``[x; w; ..; w^(K-1)]``, drift ``F0 = f0 + sum_j w_j g_j + sum_d w^(d+1) d/dw^(d)``, known
fields ``F_i = f_i``) take the prolongation ::

    Xi = xi + sum_{d < K} c^(d) . d/dw^(d),      c^(d) = -B^T w^(d).

Its bracket with ``F0`` vanishes: the x-part is ``[xi, f0] + sum_j w_j [xi, g_j] + sum_l
c^(0)_l g_l = sum_jl w_j b_jl g_l - sum_jl b_jl w_j g_l = 0``; the ``w^(d)``-part is
``Xi(w^(d+1)) - F0(c^(d)) = c^(d+1) + B^T w^(d+1) = 0`` for ``d < K - 1``, and
``-F0(c^(K-1)) = 0`` for the last (``F0`` does not move ``w^(K-1)``). ``[Xi, F_i] = [xi, f_i]
= 0`` (``f_i`` does not depend on ``w``). With (S1), ``Xi h = 0``, and ``Xi L_v phi =
L_v Xi phi + [Xi, v] phi``: every EORC generator is annihilated by ``Xi``, at every order and
in every extension, and so is every covector of ``Omega-bar_k``. A covector of
``Omega-bar_k`` with no ``w`` part (one that counts in ``dim_k``) therefore annihilates
``xi`` itself: ::

    dim_k  <=  n - rank{xi_1(x), .., xi_s(x)}       (generic rank, every k),

``x_i`` is never observable where some ``xi`` has a nonzero component ``i``, and ``w_l`` is
never observable where column ``l`` of some ``B`` is nonzero (``Xi(w_l) = c^(0)_l``). These
are proofs, not sufficient conditions: the states moved by a symmetry are unobservable for
every method and every order. The argument needs no unknown input for the ORC (``B`` empty)
and holds for smooth known inputs too (their jets enter a drift whose bracket with ``xi``
still vanishes).

**Verification.** The conditions are identities of the model's functions, tested in its
expression graph (:mod:`uio_jax._engine.graph`) at :data:`POINTS` random points: exactly
modulo ``p = 2^127 - 1`` for rational models (a nonzero rational function of degree ``D``
vanishes at a uniform random point with probability at most ``D / p``, Schwartz-Zippel;
``B`` is solved at the first point and checked at the others), in :data:`DIGITS`-digit
mpmath arithmetic otherwise (a value under ``10^(-DIGITS/2)`` of its terms counts as zero).
The rank of the fields is taken at the first point (modulo p never above the generic rank,
so the bound is never too low). A claim that fails any test, a function without an
expression in the graph, or unknown-input fields of lower rank than their number at the
point: the symmetry is reported unverified and not used.
"""

import dataclasses
import random

import numpy as np

from ..._calculus.generators import builder_for
from ..._engine import graph_exact
from ..._errors import ModelError
from ..._model.smooth_inputs import known_coordinates
from ..._model.symmetries import symmetry_fields
from ..results.kinds import Arithmetic
from .settle import new_settler

#: Random points each condition is tested at.
POINTS = 3
#: Decimal digits of the mpmath test (models that are not rational).
DIGITS = 50


@dataclasses.dataclass(frozen=True)
class SymmetryCheck:
    """The verification of one declared symmetry.

    Attributes:
        name: its name in ``System.symmetries``.
        verified: every condition holds at every point.
        how: the arithmetic and points (``"exact mod p = 2^127 - 1 at 3 points"``), or why it
            could not be tested.
        failure: the first condition found false (empty when verified).
        mixing: ``{g_j: {g_l: b_jl}}``, the nonzero constants of (S3), as text.
    """

    name: str
    verified: bool
    how: str
    failure: str = ""
    mixing: dict = dataclasses.field(default_factory=dict)

    def text(self) -> str:
        """One line: the verdict, its arithmetic, and the failure or the input mixing."""
        if not self.verified:
            return f"{self.name}: NOT verified ({self.failure}; {self.how}), not used"
        mix = "; ".join(f"[{self.name}, {j}] = " + _combination(row) for j, row in self.mixing.items())
        return f"{self.name}: verified ({self.how})" + (f"; {mix}" if mix else "")


def _combination(row: dict) -> str:
    """``{"A_3": "1", "A_2": "-1/2"}`` as ``"A_3 - 1/2 A_2"``."""
    out = ""
    for g, b in row.items():
        neg = b.startswith("-")
        mag = b[1:] if neg else b
        term = g if mag == "1" else f"{mag} {g}"
        out += (" - " if neg else " + ") + term if out else ("-" if neg else "") + term
    return out


@dataclasses.dataclass(frozen=True)
class SymmetryBound:
    """What the verified symmetries prove about an analysed System.

    Attributes:
        dim: ``n - rank``, an upper bound of the observable dimension at every order.
        rank: the rank of the verified fields on the ``n`` reported coordinates.
        moved: coordinates some verified symmetry moves: provably unobservable.
        unobservable_inputs: unknown inputs with a nonzero column in some ``B``:
            provably unobservable.
        checks: one :class:`SymmetryCheck` per declared symmetry.
        probability: upper bound on the probability that a verification passed a false
            identity (exact route; None when a check used mpmath).
    """

    dim: int
    rank: int
    moved: tuple
    unobservable_inputs: tuple
    checks: tuple
    probability: float | None

    def to_dict(self) -> dict:
        """The bound as plain data (``Report.details["symmetries"]``)."""
        return {"dim": self.dim, "rank": self.rank, "moved": list(self.moved),
                "unobservable_inputs": list(self.unobservable_inputs),
                "probability": self.probability,
                "checks": [{"name": c.name, "verified": c.verified, "how": c.how,
                            "failure": c.failure, "mixing": c.mixing} for c in self.checks]}


def verify_symmetries(system, seed: int = 0) -> SymmetryBound | None:
    """Verify the declared symmetries of an analysed System and bound its observable space.

    Args:
        system: the System an analysis runs on (:meth:`~uio_jax.System.autonomous`); its
            symmetries are :func:`uio_jax._model.symmetries.symmetry_fields`.
        seed: seed of the random points.

    Returns:
        The :class:`SymmetryBound` (``rank`` 0 and ``dim = n`` when none verified), or
        None when the System declares no symmetry.
    """
    fields = symmetry_fields(system)
    if not fields:
        return None
    builder = builder_for(system)
    graph = builder.graph
    n_rep = system.n - known_coordinates(system)
    outputs = [builder.scalar(k, fn) for k, fn in system.outputs.items()]
    known = [builder.field(k, fn) for k, fn in system.fields().items() if k not in system.unknown]
    unknown = [builder.field(k, fn) for k, fn in system.unknown.items()]
    names = list(system.unknown)
    rng = random.Random(int(seed) * 1_000_003 + 0x5E77)
    chooser = new_settler(system, seed)  # the one place the arithmetic is chosen
    checks, verified_rows, probability = [], [], 0.0
    moved, unobservable = set(), set()
    for name, fn in fields.items():
        try:
            xi = builder.field(f"symmetry {name}", fn)
        except ModelError:
            checks.append(SymmetryCheck(name, False, "no test", "the field has no expression in the "
                                        "graph (a primitive without a rule)"))
            continue
        conditions = ([(f"L_{name} {h.label}", (builder.lie(xi, h).expr,)) for h in outputs]
                      + [(f"[{name}, {f.label}]", builder.bracket(xi, f).expr) for f in known])
        mixing = [builder.bracket(xi, g).expr for g in unknown]
        roots = [e for _, es in conditions for e in es] + [e for es in mixing for e in es] \
            + [e for g in unknown for e in g.expr] + list(xi.expr)
        rational = chooser.arithmetic(roots) is Arithmetic.EXACT
        test = _Modular(graph, roots, rng) if rational else _Extended(system, graph, roots, rng)
        if test.values is None:
            checks.append(SymmetryCheck(name, False, test.how, "every point drawn was singular"))
            continue
        failure = next((f"{what} is not zero" for what, es in conditions if not test.zero(es)), "")
        B = None
        if not failure and unknown:
            G = [g.expr for g in unknown]
            B, failure = test.mixing(mixing, G, names, name)
        if failure:
            checks.append(SymmetryCheck(name, False, test.how, failure))
            continue
        checks.append(SymmetryCheck(name, True, test.how, "", _mixing_text(B, names, test)))
        row = test.row(xi.expr)
        verified_rows.append(xi.expr)
        moved.update(i for i in range(n_rep) if test.nonzero(row[i]))
        if B is not None:
            unobservable.update(names[c] for c in range(len(names)) if any(test.nonzero(B[j][c])
                                                                           for j in range(len(names))))
        if probability is not None:
            probability = None if not rational else max(probability, test.probability(roots))
    rank = _rank(system, graph, verified_rows, n_rep, rng, chooser)
    return SymmetryBound(n_rep - rank, rank, tuple(system.states[i] for i in sorted(moved)),
                         tuple(nm for nm in names if nm in unobservable), tuple(checks),
                         probability if verified_rows else None)


def symmetry_notes(bound: SymmetryBound, observable: dict, where: str, dim: int) -> tuple[list, bool]:
    """A Report's notes on the verified symmetries, and whether its verdicts reached their
    bound (``dim == bound.dim`` with exactly the moved states not observable: then they are
    exact at every order).

    Args:
        bound: the :class:`SymmetryBound` of the analysed System.
        observable: state name -> verdict of the Report.
        where: where the verdicts were read (``"k=10"``, ``"the final span"``).
        dim: the Report's dimension.
    """
    notes = [f"declared symmetry {c.text()}" for c in bound.checks]
    moved = [s for s in bound.moved if s in observable]
    wrong = [s for s in moved if observable[s]]
    if wrong:
        notes.append(f"CONTRADICTION: {', '.join(wrong)} shown observable but moved by a verified "
                     "symmetry: the verdicts are not certain (please report this model)")
        return notes, False
    hidden = [s for s, v in observable.items() if not v]
    at = bound.rank > 0 and dim == bound.dim and set(hidden) == set(moved)
    if at:
        notes.append(f"{where}: the states reach the bound {dim} = n - {bound.rank} of the verified "
                     "symmetries, which holds at every order: the verdicts are exact; "
                     f"{', '.join(hidden)}: not observable (moved by a verified symmetry)")
    elif moved:
        notes.append(f"{', '.join(moved)}: not observable at any order (moved by a verified symmetry: "
                     "a proof, not a missing rank)")
    if bound.unobservable_inputs:
        notes.append(f"unknown input{'s' if len(bound.unobservable_inputs) > 1 else ''} "
                     f"{', '.join(bound.unobservable_inputs)}: never observable (their fields are "
                     "mixed by a verified symmetry)")
    return notes, at


def _rank(system, graph, fields, n_rep, rng, chooser) -> int:
    """Rank of the verified fields (their expressions) at ONE new random point, on the
    reported coordinates: modulo p where they are rational (never above the generic rank),
    else by the SVD of their mpmath values (relative threshold 1e-12, far above the round-off
    of 50 digits)."""
    if not fields:
        return 0
    roots = [e for f in fields for e in f]
    if chooser.arithmetic(roots) is Arithmetic.EXACT:
        test = _Modular(graph, roots, rng)
        if test.values is None:
            return 0  # no point where they are defined: no bound from them
        return graph_exact.rank_mod_p([test.row(f)[:n_rep] for f in fields])
    test = _Extended(system, graph, roots, rng)
    mat = np.array([[float(v) for v in test.row(f)[:n_rep]] for f in fields])
    sv = np.linalg.svd(mat, compute_uv=False)
    return int((sv > 1e-12 * max(sv.max(), 1e-300)).sum())


def _mixing_text(B, names, test) -> dict:
    if B is None:
        return {}
    out = {}
    for j, row in enumerate(B):
        nz = {names[col]: test.show(b) for col, b in enumerate(row) if test.nonzero(b)}
        if nz:
            out[names[j]] = nz
    return out


class _Modular:
    """The conditions' values modulo ``p`` at :data:`POINTS` uniform random points."""

    def __init__(self, graph, roots, rng):
        p = self.p = graph_exact.PRIME
        self.graph, self.values = graph, None
        self.how = f"exact mod p = 2^127 - 1 at {POINTS} points"
        for _ in range(4):
            points = [[rng.randrange(1, p) for _ in range(graph.n)] for _ in range(POINTS)]
            ev = graph_exact.ModularEvaluator(graph, points)
            try:
                ev.evaluate(roots)
            except graph_exact.Singular:
                continue
            self.values = {r: [int(v) % p for v in ev.V[r]] for r in roots}
            return

    def zero(self, exprs) -> bool:
        return all(v == 0 for e in exprs for v in self.values[e])

    def nonzero(self, v) -> bool:
        return int(v) % self.p != 0

    def row(self, exprs) -> list:
        return [self.values[e][0] for e in exprs]

    def mixing(self, brackets, G, names, name):
        """Solve ``[xi, g_j] = sum_l b_jl g_l`` at the first point, test it at the others."""
        p, m = self.p, len(G)
        at = [[[self.values[e][pt] for e in g] for g in G] for pt in range(POINTS)]  # (P, m, N)
        B = []
        for j, br in enumerate(brackets):
            b = graph_exact.solve_mod_p([list(col) for col in zip(*at[0])], [self.values[e][0] for e in br], p)
            if b is None:
                return None, (f"[{name}, {names[j]}] is not a combination of the unknown-input fields"
                              if _rank_full(at[0], p, m) else "the unknown-input fields are dependent at a point")
            for pt in range(1, POINTS):
                for c, e in enumerate(br):
                    if (self.values[e][pt] - sum(b[i] * at[pt][i][c] for i in range(m))) % p:
                        return None, (f"[{name}, {names[j]}] is not a CONSTANT combination of the "
                                      "unknown-input fields")
            B.append(b)
        return B, ""

    def show(self, b) -> str:
        return str(_rational(int(b), self.p))

    def probability(self, roots) -> float:
        """``(D / p)^(POINTS - 1)``, ``D`` the largest sum of the degree bounds of the terms
        of one condition (at most the sum over every root)."""
        D = sum(a + b for a, b in graph_exact.degrees(self.graph, roots))
        return min(1.0, D / self.p) ** (POINTS - 1)


def _rank_full(G0, p, m) -> bool:
    return graph_exact.rank_mod_p(G0, p) == m


def _rational(a: int, p: int):
    """The fraction ``u/v`` with ``u = a v mod p`` and ``|u|, v < sqrt(p / 2)`` (rational
    reconstruction), else the residue."""
    f = graph_exact.rational_reconstruction(a, p)
    if f is None:
        return a
    return f.numerator if f.denominator == 1 else f


class _Extended:
    """The conditions' values in :data:`DIGITS`-digit mpmath at :data:`POINTS` points of
    the sampling box; a value counts as zero under ``10^(-DIGITS/2)`` of the scale."""

    def __init__(self, system, graph, roots, rng):
        lo, hi = system.box()
        self.how = f"mpmath at {DIGITS} digits at {POINTS} points (not exact: the model is not rational)"
        self.tol = 10.0 ** (-DIGITS / 2)
        evs = []
        for _ in range(POINTS):
            pt = lo + np.array([rng.random() for _ in range(graph.n)]) * (hi - lo)
            ev = graph_exact.ExtendedEvaluator(graph, pt, DIGITS)
            evs.append(ev.gradients(roots)[0])
        self.values = {r: [vals[i] for vals in evs] for i, r in enumerate(roots)}
        self.ctx = ev.ctx  # the arithmetic of the solve (same precision)
        self.scale = 1.0 + max(abs(float(v)) for vs in self.values.values() for v in vs)

    def zero(self, exprs) -> bool:
        return all(abs(v) <= self.tol * self.scale for e in exprs for v in self.values[e])

    def nonzero(self, v) -> bool:
        return abs(v) > self.tol * self.scale

    def row(self, exprs) -> list:
        return [self.values[e][0] for e in exprs]

    def mixing(self, brackets, G, names, name):
        ctx, m = self.ctx, len(G)
        at = [[[self.values[e][pt] for e in g] for g in G] for pt in range(POINTS)]
        A0 = ctx.matrix([list(col) for col in zip(*at[0])])
        s = ctx.svd_r(A0, compute_uv=False)
        if min(s) <= self.tol * max(max(s), 1):
            return None, "the unknown-input fields are dependent at a point"
        B = []
        for j, br in enumerate(brackets):
            # least squares by the normal equations (A0 has full column rank, checked above;
            # mpmath's Householder QR divides by zero on a column with zeros under its pivot)
            b = ctx.lu_solve(A0.T * A0, A0.T * ctx.matrix([self.values[e][0] for e in br]))
            b = [b[i] for i in range(m)]
            for pt in range(POINTS):
                for c, e in enumerate(br):
                    if abs(self.values[e][pt] - sum(b[i] * at[pt][i][c] for i in range(m))) > self.tol * self.scale:
                        return None, f"[{name}, {names[j]}] is not a CONSTANT combination of the unknown-input fields"
            B.append(b)
        return B, ""

    def show(self, b) -> str:
        return f"{float(b):.6g}"
