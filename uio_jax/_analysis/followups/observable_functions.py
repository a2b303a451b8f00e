"""Observable functions, named (``uj.observable_functions(rep)``): readable functions whose
differentials span the observable codistribution ``Omega``, in place of the generators the
analyses keep (``L_V_x h_u`` of the vehicle of 002 is a page of algebra), each kept only when
the exact checks say so.

**Candidates**, ranked by simplicity (:func:`uio_jax._analysis.followups.expression_text.text_size`:
operators, calls and names of the printed text, then its length):

1. the states and parameters themselves, and, when something is unobservable, the
   observable Laurent monomials (the invariants of a scaling symmetry; an ansatz solved exactly
   modulo p, :mod:`.ansatz`);
2. the model's own subexpressions: every node of the expression graph of its outputs and
   fields (``R(q)^T (p_f - p)`` in the vehicle's camera output, ``theta - phi`` in the
   unicycle's field, ``a + b`` in ``x' = -(a + b) x``) that depends on the report's
   coordinates only and prints as an expression (:mod:`.expression_text`);
3. if these do not reach the dimension: polynomials of degree at most 2 in the coordinates
   and the elementary functions of one coordinate in the model (``cos(theta)``), found by
   ansatz (:mod:`.ansatz`) in tiers, each solved only while short: the coordinates, then with
   one coordinate's elementary functions at a time, then all of them, then with the
   :data:`SUB_ATOMS` simplest subexpressions of several coordinates as atoms
   (``c (b (a + c)) - (a b)(c d)``);
4. if still short: ratios and products of two of the simplest subexpressions, polynomials of
   degree 3, and observable products of powers of the coordinates and those subexpressions
   (rational functions outside the other forms, :func:`~uio_jax._analysis.ansatz.atom_monomials`).

**Identifiable combinations** (:attr:`ObservableFunctions.combinations`): for a model with
parameters, a second run restricted to candidates of the parameters alone names a basis of
every observable function of the parameters (``dim (Omega ∩ span{dp})`` of them, counted
exactly at a random point), so that ``of_only(report.params)`` lists them all whenever they
can be named, and says how many could not.

**Kept** in that order when (a) the candidate's gradient lies in ``Omega`` and (b) it raises
the rank of the functions kept so far, until their number is the observable dimension: the
exact test of :meth:`uio_jax.Report.is_observable` (modulo ``p = 2^127 - 1`` at random points of
the analysis' :class:`~uio_jax._analysis.decisions.settle.Settler`: a raise is certain, a
membership wrong with probability at most ``(D/p)^points``, summed into
:attr:`ObservableFunctions.error_bound`; elsewhere in mpmath). Independent functions in ``Omega``
whose number is ``dim Omega`` span it: **named** means exactly that. When fewer are found the
result says how many, and the kept generators remain a spanning set.

For the EORC (state ``[x; w]``), functions that use ``w`` are named apart, the inputs'
reconstructions (:attr:`ObservableFunctions.input_functions`).
"""

import dataclasses
import enum
import time

import numpy as np

from ..._engine import graph_exact
from ..._engine.graph_numpy import columns
from ..._output import abridged
from ..results.evidence import Settlement
from ..results.kinds import Arithmetic
from . import ansatz
from .expression_text import Printer, text_size

#: Subexpressions tried at most (the simplest ones): bounds the cost on large models.
MAX_SUBEXPRESSIONS = 400
#: Elementary functions of one coordinate that the polynomial ansatz uses as atoms beside the
#: coordinates (``cos(theta)``, ``sin(theta)``, ``exp(k)``, ...).
ATOM_OPS = frozenset({"sin", "cos", "tan", "exp", "log", "sqrt", "atan", "tanh", "sinh", "cosh"})
#: Subexpressions combined pairwise (ratios, products) when the first pass falls short.
PAIR_POOL = 12
#: The simplest subexpressions of several coordinates taken as atoms of a polynomial tier and
#: of products of powers (rational functions) when the other forms fall short.
SUB_ATOMS = 6


class Source(enum.Enum):
    """Where a named function comes from."""

    VARIABLE = "variable"
    SUBEXPRESSION = "subexpression"
    POLYNOMIAL = "polynomial ansatz"
    MONOMIAL = "monomial ansatz"
    COMBINATION = "ratio or product of subexpressions"


@dataclasses.dataclass(frozen=True)
class NamedFunction:
    """One observable function.

    Attributes:
        text: the function as an expression in the model's names (``sympy.sympify`` reads
            it, with the names as symbols).
        source: a :class:`Source`.
        variables: the names it depends on.
        node: its node in the analysed System's expression graph (not serialised).
        globally: with ``scope="global"``, how many values it takes as a function of the
            unknowns (a :class:`~uio_jax.GlobalVerdict` value: ``"global"`` where one).
    """

    text: str
    source: Source
    variables: tuple
    node: int | None = dataclasses.field(default=None, compare=False, repr=False)
    globally: str | None = None

    def to_dict(self) -> dict:
        return {"text": self.text, "source": self.source.value, "variables": list(self.variables),
                **({"globally": self.globally} if self.globally else {})}


@dataclasses.dataclass(frozen=True)
class ObservableFunctions:
    """The named observable functions of a report.

    Attributes:
        functions: independent observable functions of the report's states and parameters,
            at most ``dim`` of them, simplest first.
        input_functions: (EORC) observable functions that use the unknown inputs.
        dim: the observable dimension they are counted against.
        generators: labels of the kept generators: a spanning set of ``Omega`` in any case.
        arithmetic: how the checks were decided: ``"exact mod p"`` or ``"mpmath"``.
        error_bound: probability bound that one of the memberships is wrong (exact route).
        seconds: time spent naming them (not in :meth:`to_dict`: the JSON is the same at every run).
        combinations: independent observable functions of the parameters alone (the
            identifiable combinations), named apart: ``combinations_dim`` of them when all
            could be named.
        combinations_dim: ``dim (Omega ∩ span{dp})``, the number of independent observable
            functions of the parameters alone (at a random point modulo p).
    """

    functions: tuple
    input_functions: tuple
    dim: int
    generators: tuple
    arithmetic: str
    error_bound: float
    seconds: float
    combinations: tuple = ()
    combinations_dim: int = 0

    @property
    def complete(self) -> bool:
        """Whether the named functions span the observable codistribution (count = dim)."""
        return len(self.functions) == self.dim

    @property
    def texts(self) -> tuple:
        """The functions' texts."""
        return tuple(f.text for f in self.functions)

    def of_only(self, names) -> tuple:
        """The named functions (the identifiable combinations first) that use nothing but
        ``names``: for the report's parameters a basis of every identifiable combination
        (:attr:`combinations`), all ``combinations_dim`` of them when all could be named."""
        names = set(names)
        out, seen = [], set()
        for f in self.combinations + self.functions + self.input_functions:
            if set(f.variables) <= names and f.text not in seen:
                seen.add(f.text)
                out.append(f)
        return tuple(out)

    def summary(self) -> str:
        """One line: how many were named, against what, how decided."""
        named = len(self.functions)
        if self.complete:
            head = f"{named} of {self.dim} named (they span the observable codistribution)"
        else:
            head = (f"{named} of {self.dim} named; the other {self.dim - named} given only as generators "
                    f"(the kept generators span it: {abridged(self.generators)})")
        how = ("exact mod p, P(wrong) <= " f"{self.error_bound:.1e}" if self.arithmetic == "exact mod p"
               else f"decided in {self.arithmetic}, not exact")
        combos = ""
        if self.combinations_dim:
            combos = (f"; identifiable combinations: {len(self.combinations)} of {self.combinations_dim} named"
                      + ("" if len(self.combinations) == self.combinations_dim else
                         " (the others are no function of the candidate forms)"))
        return f"{head}{combos}; {how}"

    def to_dict(self) -> dict:
        return {"functions": [f.to_dict() for f in self.functions],
                "input_functions": [f.to_dict() for f in self.input_functions],
                "dim": self.dim, "named": len(self.functions), "complete": self.complete,
                "generators": list(self.generators), "arithmetic": self.arithmetic,
                "error_bound": self.error_bound,
                "combinations": [f.to_dict() for f in self.combinations],
                "combinations_dim": self.combinations_dim}


def make_candidate(graph, printer, names, node, source, only=None):
    """``(NamedFunction, node)`` of a node that prints as an expression and depends on some
    coordinate (all of them in ``only`` when given), else None."""
    text = printer.text(node)
    if text is None:
        return None
    cols = columns(graph, graph.reachable([node]))[0][node]
    if not cols or (only is not None and not set(cols) <= only):
        return None
    return NamedFunction(text, source, tuple(names[i] for i in cols), node), node


def name_functions(parts, inputs: int = 0, seed: int = 0) -> ObservableFunctions:
    """Name observable functions of a finished analysis.

    Args:
        parts: the final codistribution (:class:`~uio_jax._analysis.decisions.space.SpanParts`).
        inputs: how many coordinates after the report's ``n`` are unknown inputs whose
            reconstructions are named too (the EORC's ``w``; 0 otherwise).
        seed: seed of the ansatz points.

    Returns:
        :class:`ObservableFunctions`.
    """
    start = time.perf_counter()
    run = _Run(parts, parts.n + inputs, seed)
    run.first_pass()
    if run.short():
        run.second_pass()
    state = tuple(f for f, _ in run.chosen)
    given = tuple(f for f, _ in run.given)
    combinations, combinations_dim, bound = _combinations(parts, run, inputs, seed)
    return ObservableFunctions(state, given, parts.dim, tuple(nd.label for nd in parts.nodes),
                               run.arithmetic, run.error_bound() + bound, time.perf_counter() - start,
                               combinations, combinations_dim)


def _combinations(parts, run, inputs, seed):
    """``(functions, count, bound)``: a basis of the observable functions of the parameters
    alone (named by a run restricted to them, as many as ``dim (Omega ∩ span{dp})``), and the
    probability bound of its checks. Parameters that are all identifiable are their own basis."""
    params = parts.original.joint_param_names if parts.original is not None else ()
    idx = [i for i, nm in enumerate(parts.names[:parts.n]) if nm in params]
    if not idx:
        return (), 0, 0.0
    own = [f for f, _ in run.chosen if f.source is Source.VARIABLE and f.text in params]
    if len(own) == len(idx):
        return tuple(own), len(idx), 0.0
    if not run.exact:
        return (), 0, 0.0
    count = _restricted_dim(parts, idx, seed)
    if not count:
        return (), 0, 0.0
    restricted = _Run(parts, parts.n + inputs, seed, only=set(idx), target=count)
    restricted.first_pass()
    if restricted.short():
        restricted.second_pass()
    return tuple(f for f, _ in restricted.chosen), count, restricted.error_bound()


def _restricted_dim(parts, idx, seed) -> int:
    """``dim (Omega ∩ span{e_i : i in idx})`` at a random point modulo ``p = 2^127 - 1``: the
    rank ``r`` of the kept rows minus the rank of their columns off ``idx``."""
    point = ansatz.ModularSpan(parts.builder.graph, [nd.expr for nd in parts.nodes], seed=seed + 7).point(0)
    if point is None:
        return 0
    off = [j for j in range(parts.builder.graph.n) if j not in set(idx)]
    return len(point.K) - graph_exact.rank_mod_p([[row[j] for j in off] for row in point.K])


class _Run:
    """One naming: the candidates, the checks, the kept functions."""

    def __init__(self, parts, m, seed, only=None, target=None):
        self.parts, self.m, self.seed = parts, m, seed
        #: coordinates the candidates may use (None: any of the first m), and how many
        #: functions are wanted (default: the dimension)
        self.only, self.target = only, parts.dim if target is None else target
        self.graph = parts.builder.graph
        self.printer = Printer(self.graph, parts.names[:m])
        self.settler = parts.settler
        self.start_bound = self.settler.error_bound
        self.exact = self.settler.arithmetic([nd.expr for nd in parts.nodes]) is Arithmetic.EXACT
        self.arithmetic = "exact mod p" if self.exact else "mpmath"
        self.tried = set()
        self.chosen, self.given = [], []  # (NamedFunction, Node)
        self.subexpressions = []
        # the screen: every candidate's gradient at one random point modulo the candidate
        # prime, reduced against the functions kept so far (an independence there is certain)
        self.screen, self.kept_rows = None, graph_exact.Echelon(ansatz.CANDIDATE_PRIME)
        if self.exact:
            rng = np.random.default_rng([int(seed), 0x5C4EE2])
            z = [int(v) for v in rng.integers(1, ansatz.CANDIDATE_PRIME, size=self.graph.n)]
            self.screen = graph_exact.ModularEvaluator(self.graph, [z], ansatz.CANDIDATE_PRIME)

    def error_bound(self) -> float:
        return self.settler.error_bound - self.start_bound

    # ---------------------------------------------------------------- candidates
    def first_pass(self):
        """The variables, the model's subexpressions and the Laurent monomials; then, if short,
        the polynomial ansatz of degree 2 (over the atoms)."""
        g = self.graph
        self.variables = [c for c in (self._candidate(g.coords[i], Source.VARIABLE) for i in range(self.m)) if c]
        order = g.reachable(self.parts.roots)
        cols = columns(g, order)[0]
        reach = [k for k in order if g.op[k] not in ("x", "c") and cols[k] and max(cols[k]) < self.m]
        subs = [c for c in (self._candidate(k, Source.SUBEXPRESSION) for k in reach) if c is not None]
        subs.sort(key=simplicity)
        self.subexpressions = subs[:MAX_SUBEXPRESSIONS]
        elementary = [k for k in reach if g.op[k] in ATOM_OPS and len(cols[k]) == 1]
        # the simplest subexpressions of several coordinates, as atoms of the last tier and
        # of the products of their powers (rational functions outside the other forms)
        compound = [node for fn, node in self.subexpressions
                    if len(fn.variables) > 1 and self.settler.arithmetic([node]) is Arithmetic.EXACT][:SUB_ATOMS]
        self.atoms = list(g.coords[:self.m]) + elementary + compound
        self.atom_cols = [None] * self.m + [next(iter(cols[k])) for k in elementary] + ["sub"] * len(compound)
        self.span = ansatz.ModularSpan(g, [nd.expr for nd in self.parts.nodes], self.atoms, self.seed,
                                        ansatz.CANDIDATE_PRIME)
        hidden = self.exact and self.parts.dim < self.parts.n  # a scaling may hide something
        self._select(self.variables + self.subexpressions + (self._laurent() if hidden else []))
        if self.exact:
            self._tiers(2)

    def second_pass(self):
        """Ratios and products of two of the simplest subexpressions (or variables); the
        ansatz of degree 3."""
        # a ratio or product with a variable named already is no new function: d(a/b) is in
        # span{da, db}, so with da named it adds db only, which b itself would have added
        named = {fn.text for fn, _ in self.chosen + self.given if fn.source is Source.VARIABLE}
        pool = [c for c in self.variables if c[0].text not in named]
        pool += [c for c in self.subexpressions if c[0].source is Source.SUBEXPRESSION][:PAIR_POOL]
        g, cands = self.graph, []
        for i, a in enumerate(pool):
            for b in pool[i + 1:]:
                for node in (g.div(a[1], b[1]), g.div(b[1], a[1]), g.mul(a[1], b[1])):
                    cands.append(self._candidate(node, Source.COMBINATION))
        self._select([c for c in cands if c is not None])
        if self.exact:
            self._tiers(3)
        if self.exact and self.short():
            self._select(self._atom_products())

    def short(self) -> bool:
        """Whether fewer functions than wanted are named so far."""
        inputs = 0 if self.only is not None else self.m - self.parts.n
        return len(self.chosen) < self.target or len(self.given) < inputs

    def _candidate(self, node, source):
        """``(NamedFunction, graph node)`` of a printable node not tried yet, else None."""
        if node in self.tried:
            return None
        self.tried.add(node)
        return make_candidate(self.graph, self.printer, self.parts.names, node, source, self.only)

    def _tiers(self, degree):
        """The polynomial ansatz of ``degree`` in growing sets of atoms, each solved only while
        the functions named are short (the cost of an ansatz grows as the cube of its
        unknowns): the coordinates; the coordinates and the elementary functions of one
        coordinate (``cos(theta)``, ``sin(theta)``), one coordinate at a time; all atoms."""
        m = self.m
        coords = [i for i in range(m) if self.only is None or i in self.only]
        groups, compound = {}, []
        for t in range(m, len(self.atoms)):
            if self.atom_cols[t] == "sub":
                if self._allowed(self.atoms[t]):
                    compound.append(t)
            elif self.only is None or self.atom_cols[t] in self.only:
                groups.setdefault(self.atom_cols[t], []).append(t)
        tiers = [coords] + [coords + ts for ts in groups.values()]
        if len(groups) > 1:
            tiers.append(coords + [t for ts in groups.values() for t in ts])
        if compound:
            tiers.append(coords + compound)
        for tier in tiers:
            if not self.short():
                return
            self._select(self._polynomials(degree, tier))

    def _polynomials(self, degree, tier):
        found = ansatz.polynomial_functions(self.span, degree, tier)
        if found is None:
            return []
        monos, vectors = found
        g, out = self.graph, []
        atoms = [self.atoms[t] for t in tier]
        for vec in vectors:
            node = g.zero
            for c, e in zip(vec, monos):
                if c:
                    node = g.add(node, g.mul(g.const(c), _monomial(g, e, atoms)))
            out.append(self._candidate(node, Source.POLYNOMIAL))
        return out

    def _allowed(self, node) -> bool:
        """Whether a node uses only the coordinates this run may use."""
        cols = columns(self.graph, self.graph.reachable([node]))[0][node]
        return bool(cols) and max(cols) < self.m and (self.only is None or set(cols) <= self.only)

    def _atom_products(self):
        """Products of powers of the coordinates and the subexpression atoms that are
        observable (:func:`~uio_jax._analysis.ansatz.atom_monomials`): rational functions."""
        atoms = [t for t in range(len(self.atoms)) if (t < self.m or self.atom_cols[t] == "sub")
                 and self._allowed(self.atoms[t])]
        return self._products(ansatz.atom_monomials(self.span, atoms), [self.atoms[t] for t in atoms],
                              Source.COMBINATION)

    def _laurent(self):
        return self._products(ansatz.laurent_monomials(self.span, self.m, among=self.only), self.graph.coords,
                              Source.MONOMIAL)

    def _products(self, vectors, bases, source):
        """The candidates ``prod_t bases[t]**a_t`` of the exponent vectors ``a`` with two factors
        or more (a single base's power: the base itself is tried)."""
        g, out = self.graph, []
        for vec in vectors or ():
            if sum(1 for a in vec if a) < 2:
                continue
            num, den = g.one, g.one
            for base, a in zip(bases, vec):
                if a > 0:
                    num = g.mul(num, g.ipow(base, a))
                elif a < 0:
                    den = g.mul(den, g.ipow(base, -a))
            out.append(self._candidate(g.div(num, den), source))
        return out

    # ---------------------------------------------------------------- the checks
    def _select(self, cands):
        """Keep the candidates, simplest first, that lie in ``Omega`` and raise the rank of the
        functions kept so far. Independence is tested first, on the screen (all candidates
        evaluated in one walk of the graph; a candidate dependent there is passed over, which
        never names a wrong function), then membership by the Settler, exactly."""
        dim, n = self.target, self.parts.n
        inputs = 0 if self.only is not None else self.m - n
        cands = sorted((c for c in cands if c is not None), key=simplicity)
        rows = self._screen_rows([node for _, node in cands])
        for fn, node in cands:
            uses_inputs = any(self.parts.names.index(v) >= n for v in fn.variables)
            if uses_inputs and len(self.given) >= inputs:
                continue
            if not uses_inputs and len(self.chosen) >= dim:
                continue
            row = None if rows is None else rows.get(node)
            if row is not None and not any(self.kept_rows.reduce(row)):
                continue
            nd = self.parts.builder.make(fn.text, "scalar", 0, node)
            if not self._holds(list(self.parts.nodes), nd, "dependent"):
                continue
            if row is None and not self._holds([k for _, k in self.chosen + self.given], nd, "independent"):
                continue
            if row is None:  # the screen no longer reflects every kept function
                self.screen, self.kept_rows = None, None
            else:
                self.kept_rows.add(row)
            (self.given if uses_inputs else self.chosen).append((fn, nd))
            if len(self.chosen) >= dim and len(self.given) >= inputs:
                return

    def _screen_rows(self, nodes):
        """``{node: gradient row}`` at the screen point of the candidates made rational, or
        None (no screen, or a candidate singular there). A candidate without a row takes the
        exact independence test of the Settler, and the screen is dropped once it keeps one."""
        if self.screen is None:
            return None
        rational = [k for k in nodes if self.settler.arithmetic([k]) is Arithmetic.EXACT]
        try:
            self.screen.evaluate(rational)
        except graph_exact.Singular:
            self.screen, self.kept_rows = None, None
            return None
        except ValueError:  # a node without a value modulo p (a constant known in float64)
            rational = [k for k in rational if self._evaluates(k)]
        return {k: self.screen.row(k, 0) for k in rational}

    def _evaluates(self, node) -> bool:
        try:
            self.screen.evaluate([node])
        except (ValueError, graph_exact.Singular):
            return False
        return True

    def _holds(self, kept, nd, outcome) -> bool:
        esc = self.settler.settle(kept, nd, "not voted: a named function checked directly")
        if esc is None:
            return False
        if esc.how is Settlement.EXTENDED:
            self.arithmetic = "mpmath"
        return esc.result == outcome


def simplicity(candidate):
    fn = candidate[0]
    return (text_size(fn.text), len(fn.text), fn.text)


def _monomial(g, e, atoms):
    node = g.one
    for i, k in enumerate(e):
        if k:
            node = g.mul(node, g.ipow(atoms[i], k))
    return node


__all__ = ["make_candidate", "simplicity", "Source", "NamedFunction", "ObservableFunctions", "name_functions",
           "MAX_SUBEXPRESSIONS", "PAIR_POOL", "SUB_ATOMS"]
