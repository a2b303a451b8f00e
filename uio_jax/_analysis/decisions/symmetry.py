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
expression graph by the zero test of the analyses' :class:`~uio_jax._analysis.settle.Settler`
(:meth:`~uio_jax._analysis.settle.Settler.vanishes`): modulo ``p = 2^127 - 1`` where the graph
is made rational (a nonzero value proves "not zero"; zeros are "zero" with the Schwartz-Zippel
bound ``D / p`` per point, summed into :attr:`SymmetryBound.probability` and charged to the
caller's certificate), elsewhere in mpmath at two precisions, labelled not exact. For (S3) the
unknown-input fields are solved on ``m`` coordinates where they are independent
(``B = G_I^-1 [xi, g]_I``, by the adjugate in the graph): ``B`` is constant when its gradient
vanishes, and (S3) holds when ``[xi, g] - G B`` vanishes on every coordinate. The rank of the
fields is taken at the Settler's first point (modulo p never above the generic rank, so the
bound is never too low). A claim that fails any test, a function without an expression in the
graph, a test that cannot be decided, or unknown-input fields dependent at the point: the
symmetry is reported unverified and not used.
"""

import dataclasses

import numpy as np

from ..._calculus.generators import builder_for
from ..._engine import graph_exact
from ..._errors import ModelError
from ..._model.smooth_inputs import known_coordinates
from ..._model.symmetries import symmetry_fields
from ..results.kinds import Arithmetic
from .settle import DEFAULT_PROB_THRESHOLD, Settler


@dataclasses.dataclass(frozen=True)
class SymmetryCheck:
    """The verification of one declared symmetry.

    Attributes:
        name: its name in ``System.symmetries``.
        verified: every condition holds at every point.
        how: the arithmetic (``"exact mod p = 2^127 - 1 (zero tests of the Settler, P(wrong)
            <= 1.2e-36)"``), or why it could not be tested.
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
            identity (exact route: the sum of the zero tests' bounds, charged to the caller;
            None when a check used mpmath).
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


def verify_symmetries(system, seed: int = 0, prob_threshold: float = DEFAULT_PROB_THRESHOLD,
                      charge=None) -> SymmetryBound | None:
    """Verify the declared symmetries of an analysed System and bound its observable space.

    Args:
        system: the System an analysis runs on (:meth:`~uio_jax.System.autonomous`); its
            symmetries are :func:`uio_jax._model.symmetries.symmetry_fields`.
        seed: seed of the random points.
        prob_threshold: the caller's probability of correctness: each zero test is certified
            under its share of ``1 - prob_threshold`` (:class:`~uio_jax._analysis.settle.Settler`).
        charge: the caller's Settler, whose ``error_bound`` receives the bound of these tests
            (so that the caller's certificate counts them), or None.

    Returns:
        The :class:`SymmetryBound` (``rank`` 0 and ``dim = n`` when none verified), or
        None when the System declares no symmetry.
    """
    fields = symmetry_fields(system)
    if not fields:
        return None
    builder = builder_for(system)
    graph = builder.graph
    lo, hi = system.box()
    settler = Settler(graph, lo, hi, int(seed) + 0x5E77, prob_threshold)
    n_rep = system.n - known_coordinates(system)
    outputs = [builder.scalar(k, fn) for k, fn in system.outputs.items()]
    known = [builder.field(k, fn) for k, fn in system.fields().items() if k not in system.unknown]
    unknown = [builder.field(k, fn) for k, fn in system.unknown.items()]
    names = list(system.unknown)
    checks, verified_rows, exact = [], [], True
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
        test = _Test(settler, graph)
        failure = next((f for f in (test.zero(what, es) for what, es in conditions) if f), "")
        B = None
        if not failure and unknown:
            B, failure = test.mixing(builder, xi, unknown, names, name)
        exact = exact and test.exact
        if failure:
            checks.append(SymmetryCheck(name, False, test.how(), failure))
            continue
        checks.append(SymmetryCheck(name, True, test.how(), "", _mixing_text(B, names, test)))
        verified_rows.append(xi.expr)
        moved.update(i for i in range(n_rep) if test.nonzero(xi.expr[i]))
        if B is not None:
            unobservable.update(names[c] for c in range(len(names)) if any(test.nonzero(B[j][c])
                                                                           for j in range(len(names))))
    rank = _rank(settler, verified_rows, n_rep)
    if charge is not None:
        charge.add_bound(settler.error_bound)
    return SymmetryBound(n_rep - rank, rank, tuple(system.states[i] for i in sorted(moved)),
                         tuple(nm for nm in names if nm in unobservable), tuple(checks),
                         settler.error_bound if verified_rows and exact else None)


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


def _rank(settler, fields, n_rep) -> int:
    """Rank of the verified fields (their expressions) at the Settler's first point, on the
    reported coordinates: modulo p where they are made rational (never above the generic
    rank), else by the SVD of their values in mpmath (relative threshold 1e-12, far above the
    round-off of 60 digits)."""
    if not fields:
        return 0
    roots = [e for f in fields for e in f]
    values = settler.values_mod_p(roots)
    if values is not None:
        rows = [values[i * len(f):i * len(f) + n_rep] for i, f in enumerate(fields)]
        return graph_exact.rank_mod_p(rows)
    if settler.arithmetic(roots) is Arithmetic.EXACT:
        return 0  # no point where they are defined: no bound from them
    mat = np.array([[float(v) for v in settler.values_extended(f)[:n_rep]] for f in fields])
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


class _Test:
    """The zero tests of one symmetry, by the Settler; records the arithmetic used."""

    def __init__(self, settler, graph):
        self.settler, self.graph = settler, graph
        self.hows = set()
        self.exact = True

    def how(self) -> str:
        if not self.hows:
            return "no test"
        if self.hows == {"exact mod p"}:
            return f"exact mod p = 2^127 - 1 (zero tests of the Settler, P(wrong) <= {self.settler.error_bound:.1e})"
        return ("mpmath at 30 and 60 digits (not exact: the model is not rational)" if "mpmath" in self.hows
                else "undecided")

    def vanishes(self, exprs):
        """``(zero, decided)`` of the nodes ``exprs``."""
        zero, how = self.settler.vanishes(list(exprs))
        if how:
            self.hows.add(how)
            self.exact = self.exact and how == "exact mod p"
        return zero, bool(how)

    def zero(self, what, exprs) -> str:
        """The failure text of the condition ``exprs == 0`` (empty when it holds)."""
        zero, decided = self.vanishes(exprs)
        if not decided:
            return (f"{what} could not be decided (every point drawn was singular, or the two "
                    "precisions disagree)")
        return "" if zero else f"{what} is not zero"

    def nonzero(self, node) -> bool:
        """Whether the node is not identically zero (decided; an undecided test counts as
        zero: a coordinate is only called moved when proved)."""
        zero, decided = self.vanishes([node])
        return decided and not zero

    def mixing(self, builder, xi, unknown, names, name):
        """(S3): ``B`` (graph nodes, ``m x m``) with ``[xi, g_j] = sum_l b_jl g_l`` and ``B``
        constant, or ``(None, failure)``."""
        g = self.graph
        G = [u.expr for u in unknown]
        m = len(G)
        rows = self._independent_rows(G)
        if rows is None:
            return None, "the unknown-input fields are dependent at a point"
        brackets = [builder.bracket(xi, u).expr for u in unknown]
        GI = [[G[l_][i] for l_ in range(m)] for i in rows]  # m x m: row i, column l
        B = g.solve(GI, [[br[i] for i in rows] for br in brackets])  # B[j][l]
        for j, br in enumerate(brackets):
            residual = [g.sub(br[c], g.dot([G[l_][c] for l_ in range(m)], B[j])) for c in range(g.n)]
            failure = self.zero(f"[{name}, {names[j]}] minus its combination of the unknown-input fields", residual)
            if failure:
                return None, (f"[{name}, {names[j]}] is not a combination of the unknown-input fields ({failure})"
                              if "not zero" in failure else failure)
            units = [tuple(g.one if c == i else g.zero for c in range(g.n)) for i in range(g.n)]
            slopes = [d for t in units for d in g.jvp(B[j], t)]
            failure = self.zero(f"the gradient of the mixing of [{name}, {names[j]}]", slopes)
            if failure:
                return None, (f"[{name}, {names[j]}] is not a CONSTANT combination of the unknown-input fields"
                              if "not zero" in failure else failure)
        return B, ""

    def _independent_rows(self, G):
        """``m`` coordinates where the unknown-input fields ``G`` (``m`` fields of ``n``
        nodes) are independent at the Settler's first point, or None."""
        m = len(G)
        flat = [e for col in G for e in col]
        values = self.settler.values_mod_p(flat)
        n = self.graph.n
        if values is not None:
            ech, rows = graph_exact.Echelon(), []
            for i in range(n):
                if ech.add([values[l_ * n + i] for l_ in range(m)]):
                    rows.append(i)
            return rows if len(rows) == m else None
        if self.settler.arithmetic(flat) is Arithmetic.EXACT:
            return None
        vals = self.settler.values_extended(flat)
        mat = np.array([[float(vals[l_ * n + i]) for l_ in range(m)] for i in range(n)])
        rows, basis = [], np.zeros((0, m))
        for i in range(n):
            trial = np.vstack([basis, mat[i]])
            if np.linalg.matrix_rank(trial, tol=1e-10 * max(np.abs(mat).max(), 1e-300)) > len(rows):
                rows.append(i)
                basis = trial
        return rows if len(rows) == m else None

    def show(self, node) -> str:
        """The constant ``node`` as text: a small fraction (modulo p, reconstructed) or its
        value to 6 digits (mpmath)."""
        values = self.settler.values_mod_p([node])
        if values is not None:  # the fraction u/v = value mod p with |u|, v < sqrt(p / 2), else the residue
            fraction = graph_exact.rational_reconstruction(values[0], graph_exact.PRIME)
            return str(values[0] if fraction is None else fraction)
        return f"{float(self.settler.values_extended([node])[0]):.6g}"
