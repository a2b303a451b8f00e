"""Proofs of "not determined" at a known initial state: symmetries that keep the known values.

At a specific initial state no order bound is known (:mod:`.initial`), so an unknown that the
output coefficients have not determined by the cap is *undecided*. A symmetry can prove it is
not determinable. Let ``xi`` be a vector field on ``z = [x; p]`` with

* (S1)-(S3) of :mod:`.symmetry`: ``L_xi h = 0``, ``[xi, f] = 0`` for the drift and every
  known field, ``[xi, g_j] = sum_l b_jl g_l`` with ``B`` constant for the unknown-input
  fields (then the flow of ``xi`` maps every solution to a solution with the same output, for
  every known input, the unknown inputs transformed by ``B``);
* (T) tangent to the set of initial states ``M = {x_k = v_k(p) for the known components}``:
  ``xi(x_k - v_k(p)) = xi_k - L_xi v_k`` vanishes on ``M`` (``v_k`` a number, a parameter or
  a function of the parameters), so that its flow maps ``M`` into ``M``.

Then for ``theta`` on ``M`` the curve ``s -> Phi_s(theta)`` stays in ``M`` and keeps the whole
output: an unknown ``theta_j`` with ``xi_j`` not identically zero on ``M`` is not locally
identifiable at generic points of ``M`` ("not determined", proved).

**The search.** Fields of degree at most 1 in ``z`` (translations, rotations, scalings and
every other affine field; the class :mod:`.found_symmetries` searches at generic states). On
``M`` the field must not move what is known or determined: a known or determined coordinate's
component may depend only on the known states and the parameters their values name (a
component that depends on a free coordinate is nonzero on ``M``), the undetermined ones on
every coordinate. (S1)-(S3) and (T) are linear in the field's coefficients and ``B``: their
equations are collected at random points modulo ``q = 2^31 - 1`` (for (T): at random points of
``M``) until the solution space stops shrinking, and its simplest integer basis is read back
(:func:`uio_jax._analysis.ansatz.readable_fields`). These are candidates. Each one is then
**verified exactly**: (S1)-(S3) by the symmetry check of declared symmetries
(:func:`uio_jax._analysis.symmetry.verify_symmetries`), and (T) and "moves ``theta_j``" by the
zero test of the analysis' own :class:`~uio_jax._analysis.settle.Settler` on the graph of the
unknowns (the known values substituted), all modulo ``p = 2^127 - 1`` with their bounds
charged to the report. A nonzero value at a point proves "moves"; an identity holds with the
Schwartz-Zippel bound.

Not searched: several experiments (a symmetry must act on every experiment at once), a known
value known in float64 only, models whose ansatz would exceed :data:`MAX_UNKNOWNS`.
"""

import dataclasses
from fractions import Fraction

import numpy as np

from ..._calculus.generators import builder_for
from ..._engine import graph_exact
from ..._engine.graph_elementary import Singular
from ..._errors import ModelError
from ..._model.system import System, derived_system
from ..decisions.symmetry import verify_symmetries
from ..followups import ansatz
from ..followups.found_symmetries import PolynomialField

#: Most unknowns of the field ansatz (coefficients and mixing constants): past it no search.
MAX_UNKNOWNS = 240
#: Most random points the ansatz draws.
MAX_POINTS = 60


@dataclasses.dataclass(frozen=True)
class Proof:
    """A verified symmetry keeping the known initial values, and what it moves.

    Attributes:
        field: its nonzero components, ``{name: text}``.
        moved: the unknowns (target coordinate indices) it moves on the set of initial states.
        how: how the symmetry conditions were verified.
    """

    field: dict
    moved: tuple
    how: str

    def text(self, names) -> str:
        comps = ", ".join(f"{k} -> {v}" for k, v in self.field.items())
        return f"{', '.join(names[i] for i in self.moved)} (moved by the verified symmetry {comps})"


@dataclasses.dataclass(frozen=True)
class Search:
    """The outcome of a search: the proofs found and, in words, what was tried."""

    proofs: tuple
    tried: str


def prove_not_determined(ex, settler, undecided, seed: int, prob_threshold: float) -> Search:
    """Symmetries of experiment ``ex`` that keep its known initial values and move some of
    the ``undecided`` unknowns (module docstring).

    Args:
        ex: the :class:`~uio_jax._analysis.initial.Experiment` (attached to its target graph).
        settler: the Settler of the target graph (the tangency and "moves" tests; every bound
            is charged to it, and the symmetry check's too).
        undecided: target coordinate indices of the unknowns not determined.
        seed: seed of the points.
        prob_threshold: the caller's probability of correctness.
    """
    ansatz_ = _Ansatz(ex, undecided, seed)
    if ansatz_.refusal:
        return Search((), f"no symmetry search ({ansatz_.refusal})")
    try:
        vectors = ansatz_.solve()
    except ValueError:  # a node without a value modulo p (erf, a constant known in float64 only)
        return Search((), "no symmetry search (the model is not made rational: no exact check applies)")
    tried = ("a search for symmetries keeping the known initial values (vector fields of degree <= 1 in the "
             "states and parameters, each checked exactly)")
    if vectors is None:
        return Search((), f"{tried} could not be solved (the points ran out or were singular)")
    if not vectors:
        return Search((), f"{tried} found none")
    fields = [PolynomialField(ansatz_.monos, v, ansatz_.N) for v in vectors]
    try:
        proofs = _verified(ex, fields, settler, undecided, seed, prob_threshold)
    except ModelError as exc:  # a candidate the symmetry check cannot take: no proof from it
        return Search((), f"{tried} found candidates the check could not take ({exc})")
    if not proofs:
        return Search((), f"{tried} found {len(fields)} candidate field{'s' if len(fields) > 1 else ''}, none "
                          "verified that moves them")
    return Search(tuple(proofs), tried)


class _Ansatz:
    """The linear equations of (S1)-(S3) and (T) in the coefficients of a field of degree <= 1."""

    def __init__(self, ex, undecided, seed):
        self.refusal = ""
        joint = ex.joint
        self.builder = builder_for(joint)
        self.graph = self.builder.graph
        N = self.N = joint.n
        self.q = ansatz.CANDIDATE_PRIME
        self.rng = np.random.default_rng([int(seed), 0x1A17])
        self.monos = [tuple(0 for _ in range(N))] + [tuple(int(i == a) for i in range(N)) for a in range(N)]
        self.outputs = [self.builder.scalar(k, fn).expr for k, fn in joint.outputs.items()]
        fields = joint.fields()
        self.known = [self.builder.field(k, fn).expr for k, fn in fields.items() if k not in joint.unknown]
        self.unknown = [self.builder.field(k, fn).expr for k, fn in joint.unknown.items()]
        # the known states: joint index -> value node (a constant, a parameter, a function of p)
        ns = len(ex.system.states)
        self.values, anchors = {}, set()
        for k, name in enumerate(ex.system.states):
            v = ex.initial.get(name)
            if v is None:
                continue
            anchors.add(k)
            node = _joint_value(self.builder, v, ns, tuple(ex.system.params))
            if node is None:
                self.refusal = f"the known value {name} = {v.text} is known in float64 only"
                return
            self.values[k] = node
            anchors.update(i for i in range(ns, N) if self._depends(node, i))
        free = {i for i, t in enumerate(ex.z_index) if t is not None and t in set(undecided)}
        # allowed monomials per component: all of them for an undetermined unknown; the
        # constant and the anchors (known states, parameters their values name) otherwise
        self.allowed = [list(range(N + 1)) if i in free else [0] + [a + 1 for a in sorted(anchors)]
                        for i in range(N)]
        self.index = {(i, a): u for u, (i, a) in enumerate((i, a) for i in range(N) for a in self.allowed[i])}
        m = len(self.unknown)
        self.n_c = len(self.index)
        self.count = self.n_c + m * m
        if self.count > MAX_UNKNOWNS:
            self.refusal = f"the field ansatz would have {self.count} unknowns, more than {MAX_UNKNOWNS}"

    def _depends(self, node, i) -> bool:
        return any(self.graph.op[k] == "x" and self.graph.param[k] == i for k in self.graph.reachable([node]))

    # ------------------------------------------------------------------ points and rows
    def _random_point(self, roots, on_initial_states=False):
        """``(z, evaluator of roots at z)`` at a random point (``on_initial_states``: its known
        states then set to their values), or None where 64 draws were singular."""
        for _ in range(64):
            z = [int(v) for v in self.rng.integers(1, self.q, size=self.N)]
            try:
                if on_initial_states:
                    first = self._evaluator(z, roots)
                    for k, node in self.values.items():
                        z[k] = int(first.V[node][0]) % self.q
                return z, self._evaluator(z, roots)
            except Singular:
                continue
        return None

    def _evaluator(self, z, roots):
        ev = graph_exact.ModularEvaluator(self.graph, [z], self.q)
        ev.evaluate(roots)
        return ev

    def _symmetry_rows(self):
        """The rows of (S1)-(S3) at a random point (None where it is singular)."""
        q, N = self.q, self.N
        roots = self.outputs + [e for f in self.known + self.unknown for e in f]
        drawn = self._random_point(roots)
        if drawn is None:
            return None
        z, ev = drawn
        mono = [1] + z
        rows = []
        for h in self.outputs:
            gh = ev.row(h, 0)
            row = [0] * self.count
            for (i, a), u in self.index.items():
                row[u] = mono[a] * int(gh[i]) % q
            rows.append(row)
        m = len(self.unknown)
        for j, field in enumerate(self.known + self.unknown):
            values = [int(ev.V[e][0]) % q for e in field]
            grads = [ev.row(e, 0) for e in field]
            for k in range(N):
                row = [0] * self.count
                for (i, a), u in self.index.items():  # xi_i d_i F_k
                    row[u] = (row[u] + mono[a] * int(grads[k][i])) % q
                for a in self.allowed[k]:  # - F . d xi_k: the linear monomial z_(a-1)
                    if a:
                        u = self.index[(k, a)]
                        row[u] = (row[u] - values[a - 1]) % q
                if j >= len(self.known):  # - sum_l b_jl g_l,k
                    jj = j - len(self.known)
                    for l_, g_l in enumerate(self.unknown):
                        row[self.n_c + jj * m + l_] = (-int(ev.V[g_l[k]][0])) % q
                rows.append(row)
        return rows

    def _tangency_rows(self):
        """The rows of (T) at a random point of the set of initial states."""
        if not self.values:
            return []
        q = self.q
        drawn = self._random_point(list(self.values.values()), on_initial_states=True)
        if drawn is None:
            return None
        z, ev = drawn
        mono = [1] + z
        rows = []
        for k, node in self.values.items():
            grad = ev.row(node, 0)
            row = [0] * self.count
            for a in self.allowed[k]:
                u = self.index[(k, a)]
                row[u] = (row[u] + mono[a]) % q
            for (i, a), u in self.index.items():
                if int(grad[i]):
                    row[u] = (row[u] - int(grad[i]) * mono[a]) % q
            rows.append(row)
        return rows

    def solve(self):
        """Integer coefficient vectors (layout ``i * (N + 1) + a``) of the simplest basis of the
        fields that satisfy the equations at every point drawn, or None."""
        q = self.q
        ech, ranks = graph_exact.Echelon(q), []
        for _ in range(MAX_POINTS):
            rows, tangent = self._symmetry_rows(), self._tangency_rows()
            if rows is None or tangent is None:
                return None
            for row in rows + tangent:
                ech.add(row)
            ranks.append(ech.rank)
            if ech.rank == self.count or (len(ranks) >= 3 and ranks[-1] == ranks[-3]):
                break
        else:
            return None
        M = self.N + 1
        full = []
        for vec in ansatz.kernel(ech, self.count, q):
            out = [0] * (self.N * M)
            for (i, a), u in self.index.items():
                out[i * M + a] = vec[u]
            if any(out):
                full.append(out)
        return ansatz.readable_fields(full, self.monos, self.N, q)


def _verified(ex, fields, settler, undecided, seed, prob_threshold) -> list:
    """The candidate fields that are symmetries (exact symmetry check), tangent to the set of
    initial states and moving some undecided unknown there (the Settler's zero tests)."""
    joint = ex.joint
    declared = {f"keeps_initial_{i}": f.callable() for i, f in enumerate(fields)}
    with derived_system():
        probe = System(joint.states, dict(joint.outputs), dict(joint.known), dict(joint.unknown), joint.drift,
                       dict(joint.domain), joint.angles, joint.name, symmetries=declared)
    bound = verify_symmetries(probe, seed=seed, prob_threshold=prob_threshold, charge=settler)
    builder = builder_for(joint)
    graph, target = builder.graph, ex.target
    ns = len(ex.system.states)
    coord_map = ex.coord_map[:joint.n]
    proofs = []
    for i, (f, check) in enumerate(zip(fields, bound.checks if bound else ())):
        if not check.verified:
            continue
        xi = builder.field(f"keeps_initial_{i}", f.callable()).expr
        tangency = []
        for k, name in enumerate(ex.system.states):
            v = ex.initial.get(name)
            if v is None:
                continue
            value = _joint_value(builder, v, ns, tuple(ex.system.params))
            tangency.append(graph.sub(xi[k], graph.jvp([value], xi)[0]))
        if tangency:
            zero, how = settler.vanishes(target.import_nodes(graph, tangency, coord_map))
            if not (zero and how):
                continue
        moved = []
        for k, t in enumerate(ex.z_index):
            if t is None or t not in undecided:
                continue
            (node,) = target.import_nodes(graph, [xi[k]], coord_map)
            is_zero, decided = settler.vanishes([node])
            if decided and not is_zero:
                moved.append(t)
        if moved:
            proofs.append(Proof(f.components(joint.states), tuple(moved), check.how))
    return proofs


def _joint_value(builder, v, ns, params):
    """The node of the joint graph that the known value ``v`` equals (None for a value known
    in float64 only)."""
    g = builder.graph
    if isinstance(v.value, Fraction):
        return g.const(v.value)
    if isinstance(v.value, float):
        return None
    if isinstance(v.value, str):
        return g.x(ns + params.index(v.value))
    fn = v.value
    return builder.function(f"initial value of {v.state}", lambda z: fn(z[ns:])).expr


__all__ = ["Proof", "Search", "prove_not_determined", "MAX_UNKNOWNS", "MAX_POINTS"]
