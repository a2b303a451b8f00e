"""An SBML file read into exact sympy equations: :func:`read_sbml` (the first half of
:func:`uio_jax._io.sbml_import.load_sbml`; the rules are stated in ``docs/sbml.md``).

python-libsbml reads and checks the file (function definitions are expanded in each formula by
libsbml's ``SBMLTransforms.replaceFD``); sbmlmath turns each MathML formula into sympy, with every number an exact
rational (``<cn> 0.1 </cn>`` is ``1/10``; a double of the file, such as a parameter's
``value``, is the decimal it prints as). The result, :class:`SbmlModel`, holds

* the **states**: species changed by reactions or by a rate rule, and parameters with a
  rate rule, with their right-hand sides; a species in concentration
  (``hasOnlySubstanceUnits="false"``) divides the reaction rates by its compartment's size
  (``d[S]/dt = sum_r stoichiometry_r * rate_r * conversion factor / V``), a species in amount
  does not;
* every other identifier with its kind (:class:`Entity`): parameters, local parameters
  renamed ``<reaction>_<parameter>``, compartments, species without an equation; assignment
  rules and reaction identifiers are substituted (recursively) everywhere;
* the time symbol when a formula uses SBML's time.

Refused in one line (:class:`~uio_jax.ModelError`): events, algebraic rules, delays,
piecewise and logical expressions, non-constant compartments, fast reactions, variable
stoichiometries, reactions without kinetic law, functions outside the expression whitelist.
A file that does not read (missing, not SBML, invalid) is a :class:`~uio_jax.LoadError`.

python-libsbml and sbmlmath are the optional extra ``uio_jax[sbml]``, imported here only.
"""

import keyword
import os
from dataclasses import dataclass, field

from .._errors import LoadError, ModelError
from .expressions import FUNCTIONS

#: The extra that installs this reader's dependencies.
EXTRA = 'pip install "uio_jax[sbml]" (python-libsbml and sbmlmath)'
#: Names tried, in order, for SBML's time symbol (the first that is no identifier of the model).
TIME_NAMES = ("t", "time", "t_sbml")


@dataclass(frozen=True)
class Entity:
    """An SBML identifier that is not a state: ``kind`` is ``"parameter"`` (a global
    parameter), ``"local"`` (a kinetic law's parameter, renamed), ``"compartment"`` or
    ``"species"`` (a species without an equation: boundary or constant); ``value`` is its
    exact value in the file (a sympy Rational; None when the file gives none); ``what``
    says where it comes from, for messages."""

    kind: str
    value: object
    what: str


@dataclass
class SbmlModel:
    """The equations of an SBML model (see the module doc).

    Attributes:
        name: the model's name or id (the file name when it has neither).
        states: state ids, in file order (species, then parameters with a rate rule).
        odes: state id -> sympy right-hand side (in the model's symbols, time as ``time``).
        entities: every other identifier usable in outputs -> :class:`Entity`.
        assigned: identifiers that are formulas (assignment rules, reaction rates) ->
            their sympy expression, already substituted.
        time: the name of the time symbol (``"t"`` unless an id takes it).
        time_used: whether a formula uses time (the model is then time-varying).
        notes: remarks for the report.
    """

    name: str
    states: tuple
    odes: dict
    entities: dict
    assigned: dict
    time: str
    time_used: bool = False
    notes: list = field(default_factory=list)

    def ids(self) -> tuple:
        """Every identifier an output may use: states, entities and assigned formulas."""
        return tuple(self.states) + tuple(self.entities) + tuple(self.assigned)


def libraries():
    """``(libsbml, sbmlmath, sympy)``, or a one-line LoadError naming the extra."""
    try:
        import libsbml
        import sbmlmath
        import sympy
    except ImportError as exc:
        raise LoadError(f"reading SBML needs {exc.name}: {EXTRA}") from None
    return libsbml, sbmlmath, sympy


def read_document(path):
    """``(document, model)`` of ``path`` read by libsbml (the document keeps the model
    alive), or a one-line LoadError."""
    libsbml, _, _ = libraries()
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise LoadError(f"SBML file not found: {path}")
    doc = libsbml.readSBMLFromFile(path)
    for i in range(doc.getNumErrors()):
        err = doc.getError(i)
        if err.getSeverity() >= libsbml.LIBSBML_SEV_ERROR:
            text = " ".join(err.getMessage().split())
            raise LoadError(f"{path}: not a valid SBML file (line {err.getLine()}): {text}")
    model = doc.getModel()
    if model is None:
        raise LoadError(f"{path}: the SBML document has no model")
    return doc, model


def read_sbml(path) -> SbmlModel:
    """Read an SBML file into an :class:`SbmlModel` (exact sympy equations).

    Raises:
        LoadError: python-libsbml or sbmlmath missing (naming the extra), a missing,
            unreadable or invalid file.
        ModelError: one line naming the SBML element that uses an unsupported feature.
    """
    doc, model = read_document(path)
    where = os.fspath(path)
    _refuse_structure(model, where)
    reader = _Reader(model, where)
    out = reader.build(model.getName() or model.getId() or os.path.basename(where))
    del doc  # the model's objects were read: the document may go
    return out


def _refuse_structure(model, where):
    """Events, algebraic rules and non-constant compartments: one line each."""
    if model.getNumEvents():
        ids = ", ".join(e.getId() or "?" for e in model.getListOfEvents())
        raise ModelError(f"{where}: SBML events are not supported (the model has {model.getNumEvents()}: "
                         f"{ids}); an event changes the state by jumps")
    for rule in model.getListOfRules():
        if rule.isAlgebraic():
            raise ModelError(f"{where}: algebraic rules are not supported (a differential-algebraic model)")
    for comp in model.getListOfCompartments():
        if not comp.getConstant():
            raise ModelError(f"{where}: compartment {comp.getId()!r} is not constant (a varying volume "
                             "is not supported)")
    for reaction in model.getListOfReactions():
        if reaction.isSetFast() and reaction.getFast():
            raise ModelError(f"{where}: reaction {reaction.getId()!r} is fast (a quasi-steady-state "
                             "reaction is not supported)")
        if reaction.getKineticLaw() is None or not reaction.getKineticLaw().isSetMath():
            raise ModelError(f"{where}: reaction {reaction.getId()!r} has no kinetic law")


class _Reader:
    """One model's formulas to sympy (see the module doc)."""

    def __init__(self, model, where):
        self.libsbml, self.sbmlmath, self.sp = libraries()
        self.model, self.where = model, where
        ids = [o.getId() for lst in (model.getListOfSpecies(), model.getListOfParameters(),
                                     model.getListOfCompartments(), model.getListOfReactions())
               for o in lst]
        self.time = next((t for t in TIME_NAMES if t not in ids), None)
        self.time_used = False
        self.notes = []

    # ------------------------------------------------------------------ formulas
    def math(self, obj, what, local=None):
        """The exact sympy expression of ``obj``'s math (``local``: renamings of its ids)."""
        sp = self.sp
        ast = obj.getMath().deepCopy()  # function definitions expanded by libsbml, in the copy
        self.libsbml.SBMLTransforms.replaceFD(ast, self.model.getListOfFunctionDefinitions())
        try:
            expr = self.sbmlmath.sbml_math_to_sympy(ast, ignore_units=True, evaluate=True)
        except (NotImplementedError, ValueError, AssertionError, TypeError) as exc:
            text = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"{self.where}: {what}: formula not supported ({text})") from None
        swap = {}
        for node in sp.preorder_traversal(expr):
            swap.update(self._atom(node, what))
        expr = expr.xreplace(swap) if swap else expr
        if local:
            expr = expr.xreplace({sp.Symbol(k): sp.Symbol(v) for k, v in local.items()})
        return expr

    def _atom(self, node, what) -> dict:
        """The replacement of one node of a formula (empty: kept), or its one-line refusal."""
        sp, sm = self.sp, self.sbmlmath
        bad = None
        if isinstance(node, sp.Piecewise):
            bad = "piecewise (a switch: the model is not smooth)"
        elif isinstance(node, (sm.Delay, sm.RateOf)):
            bad = f"{type(node).__name__.lower()} (a delay differential equation)" \
                if isinstance(node, sm.Delay) else "rateOf"
        elif isinstance(node, (sp.core.relational.Relational, sp.logic.boolalg.BooleanFunction,
                               sp.logic.boolalg.BooleanAtom)):
            bad = "a comparison or logical operator"
        elif node.is_Atom and node.is_number and node.is_finite is False:
            bad = f"the number {node}"
        elif isinstance(node, sm.TimeSymbol):
            if self.time is None:
                raise ModelError(f"{self.where}: {what}: uses time, and every name for it "
                                 f"({', '.join(TIME_NAMES)}) is an id of the model")
            self.time_used = True
            return {node: sp.Symbol(self.time)}
        elif isinstance(node, sm.CSymbol):
            if "avogadro" in str(node.definition_url):
                return {node: sp.Rational(repr(float(node)))}
            bad = f"the symbol {node.name!r}"
        elif isinstance(node, sp.Float):
            value = float(node)
            if value != value or value in (float("inf"), float("-inf")):
                bad = f"the number {value}"
            else:
                return {node: sp.Rational(repr(value))}
        elif isinstance(node, sp.Function) and type(node).__name__ not in FUNCTIONS:
            bad = f"the function {type(node).__name__!r} (allowed: {', '.join(FUNCTIONS)})"
        if bad:
            raise ModelError(f"{self.where}: {what} uses {bad}: not supported")
        return {}

    def value(self, number, is_set=True):
        """An attribute's double as the exact decimal it prints as (None when unset)."""
        if not is_set or number != number:
            return None
        return self.sp.Rational(repr(float(number)))

    # ------------------------------------------------------------------ the model
    def build(self, name) -> SbmlModel:
        """The :class:`SbmlModel`: entities, rules, reactions, then the substitutions."""
        sp = self.sp
        entities = self._entities()
        assigned, rated = {}, {}
        for rule in self.model.getListOfRules():
            var = rule.getVariable()
            expr = self.math(rule, f"rule for {var!r}")
            if rule.isAssignment():
                assigned[var] = expr
            else:
                rated[var] = expr
        self._check_rule_targets(assigned, rated, entities)
        for ia in self.model.getListOfInitialAssignments():
            sym = ia.getSymbol()  # a constant's value for all time; species' initial values are ignored
            ent = entities.get(sym)
            if ent is not None and ent.what in ("parameter", "compartment") and sym not in assigned | rated:
                assigned[sym] = self.math(ia, f"initial assignment of {sym!r}")
                del entities[sym]
        rates, locals_ = self._reactions(entities)
        assigned.update(rates)
        for k in assigned:
            entities.pop(k, None)
        assigned = _resolve(sp, assigned, self.where)
        states, odes = self._odes(rated, entities)
        subs = {sp.Symbol(k): v for k, v in assigned.items()}
        odes = {s: sp.sympify(e).xreplace(subs) for s, e in odes.items()}
        entities.update(locals_)
        for s in states:
            entities.pop(s, None)
        bad = next((k for k in (*states, *entities, *assigned) if keyword.iskeyword(k)), None)
        if bad is not None:
            raise ModelError(f"{self.where}: the id {bad!r} is a Python keyword: not supported as a name")
        return SbmlModel(name=name, states=tuple(states), odes=odes, entities=entities, assigned=assigned,
                         time=self.time, time_used=self.time_used, notes=self.notes)

    def _entities(self) -> dict:
        m, out = self.model, {}
        for p in m.getListOfParameters():
            out[p.getId()] = Entity("parameter", self.value(p.getValue(), p.isSetValue()),
                                    "parameter" if p.getConstant() else "non-constant parameter")
        for c in m.getListOfCompartments():
            out[c.getId()] = Entity("compartment", self.value(c.getSize(), c.isSetSize()), "compartment")
        for s in m.getListOfSpecies():
            out[s.getId()] = Entity("species", self._initial(s), "species")
        return out

    def _initial(self, s):
        """A species' initial value in its own units (amount or concentration), or None."""
        size = self.model.getCompartment(s.getCompartment())
        size = self.value(size.getSize(), size.isSetSize()) if size is not None else None
        amount = self.value(s.getInitialAmount(), s.isSetInitialAmount())
        conc = self.value(s.getInitialConcentration(), s.isSetInitialConcentration())
        if s.getHasOnlySubstanceUnits():
            return amount if amount is not None else (conc * size if conc is not None and size else None)
        return conc if conc is not None else (amount / size if amount is not None and size else None)

    def _check_rule_targets(self, assigned, rated, entities):
        refs = {r.getId() for rx in self.model.getListOfReactions()
                for r in (*rx.getListOfReactants(), *rx.getListOfProducts()) if r.isSetId()}
        for var in (*assigned, *rated):
            if var in refs:
                raise ModelError(f"{self.where}: a rule sets the stoichiometry {var!r}: a variable "
                                 "stoichiometry is not supported")
            ent = entities.get(var)
            if ent is None:
                raise ModelError(f"{self.where}: a rule sets {var!r}, which is no species, parameter "
                                 "or compartment of the model")
            if ent.kind == "compartment":
                raise ModelError(f"{self.where}: a rule sets compartment {var!r} (a varying volume is "
                                 "not supported)")

    def _reactions(self, entities):
        """``(rates, locals)``: reaction id -> its rate (local parameters renamed), and the
        renamed local parameters -> Entity."""
        rates, locals_ = {}, {}
        taken = set(entities) | {r.getId() for r in self.model.getListOfReactions()}
        for rx in self.model.getListOfReactions():
            rid, law = rx.getId(), rx.getKineticLaw()
            params = law.getListOfLocalParameters() if law.getLevel() >= 3 else law.getListOfParameters()
            renamed = {}
            for lp in params:
                new = f"{rid}_{lp.getId()}"
                while new in taken:
                    new += "_"
                taken.add(new)
                renamed[lp.getId()] = new
                locals_[new] = Entity("local", self.value(lp.getValue(), lp.isSetValue()),
                                      f"local parameter {lp.getId()!r} of reaction {rid!r}")
            rates[rid] = self.math(law, f"kinetic law of reaction {rid!r}", renamed)
        return rates, locals_

    def _odes(self, rated, entities):
        """``(states, odes)``: species changed by reactions or rate rules, then parameters
        with a rate rule; reaction fluxes by the stoichiometries (see the module doc)."""
        sp, m = self.sp, self.model
        flux = {}
        for rx in m.getListOfReactions():
            for sign, refs in ((-1, rx.getListOfReactants()), (1, rx.getListOfProducts())):
                for ref in refs:
                    flux.setdefault(ref.getSpecies(), []).append(sign * self._stoich(ref, rx) * sp.Symbol(rx.getId()))
        states, odes = [], {}
        for s in m.getListOfSpecies():
            sid = s.getId()
            if sid in rated:
                states.append(sid)
                odes[sid] = rated[sid]
            elif sid in flux and sid in entities and not s.getBoundaryCondition() and not s.getConstant():
                states.append(sid)
                odes[sid] = self._species_rate(s, flux[sid])
        for p in m.getListOfParameters():
            if p.getId() in rated:
                states.append(p.getId())
                odes[p.getId()] = rated[p.getId()]
        return states, odes

    def _stoich(self, ref, rx):
        if ref.isSetStoichiometryMath():
            raise ModelError(f"{self.where}: reaction {rx.getId()!r} gives {ref.getSpecies()!r} a "
                             "stoichiometryMath: a variable stoichiometry is not supported")
        if ref.getLevel() >= 3 and not ref.getConstant():
            raise ModelError(f"{self.where}: reaction {rx.getId()!r}: the stoichiometry of "
                             f"{ref.getSpecies()!r} is not constant: not supported")
        if ref.getLevel() >= 3 and not ref.isSetStoichiometry():
            self.notes.append(f"reaction {rx.getId()!r}: no stoichiometry for {ref.getSpecies()!r}, taken as 1")
            return 1
        return self.value(ref.getStoichiometry())

    def _species_rate(self, s, terms):
        """``sum(terms) * conversion factor``, divided by the compartment's size for a species
        in concentration."""
        sp = self.sp
        rate = sp.Add(*terms)
        factor = s.getConversionFactor() or self.model.getConversionFactor()
        if factor:
            rate = rate * sp.Symbol(factor)
        if not s.getHasOnlySubstanceUnits():
            rate = rate / sp.Symbol(s.getCompartment())
        return rate


def _resolve(sp, assigned, where) -> dict:
    """Assignment formulas substituted into each other until none refers to another
    (a cycle is refused: SBML forbids it)."""
    symbols = {sp.Symbol(k): k for k in assigned}
    out = dict(assigned)
    for _ in range(len(out) + 1):
        pending = {k: e for k, e in out.items() if e.free_symbols & symbols.keys()}
        if not pending:
            return out
        subs = {sp.Symbol(k): e for k, e in out.items()}
        out = {k: (e.xreplace(subs) if k in pending else e) for k, e in out.items()}
    cycle = sorted(k for k, e in out.items() if e.free_symbols & symbols.keys())
    raise ModelError(f"{where}: assignment rules refer to each other in a cycle ({', '.join(cycle)})")
