"""SBML models with declared outputs and inputs: :func:`load_sbml` (reached through
:func:`uio_jax.load_system` for a ``.xml`` or ``.sbml`` file).

SBML has no outputs and no inputs: the user declares them. The equations come from
:func:`uio_jax._io.sbml_read.read_sbml` (exact sympy); the roles of the other identifiers
follow the defaults of ``docs/sbml.md``:

* a global or local parameter is an **unknown constant parameter** (identified with the
  states), unless ``fixed`` gives its value (or ``fixed`` names it: its value in the file);
* a compartment's size, and a species without an equation (boundary or constant), is a
  **known constant** at its value in the file, unless ``estimate`` names it (then it is a
  parameter to identify; without a value in the file it is one by default);
* ``known`` / ``unknown`` name parameters or species without an equation that are
  **inputs** instead: functions of time, measured (known) or not (unknown). They must enter
  the right-hand side affinely, with no product of two inputs and in no output (checked
  exactly with sympy; otherwise refused in one line).

The System is built by :func:`uio_jax.system_from_sympy` in its general form
(``x' = f(x, p, u, w)``), so it keeps its spec: :func:`uio_jax.save_model` writes the
converted model as TOML. Outputs are expressions in the model's identifiers, read by the
whitelisted parser of :mod:`uio_jax._io.expressions` (never evaluated), or the rows of a PEtab
observables table (``observableId``, ``observableFormula``).
"""

import ast
import csv
import os
from collections.abc import Mapping

from .._errors import ExpressionError, LoadError, ModelError, OptionError
from .expressions import CONSTANTS, Binary, Call, Name, Num, Unary, parse_expression
from .sbml_read import read_sbml

#: Suffixes of SBML files (``load_system`` and the batch route them here).
SBML_SUFFIXES = (".xml", ".sbml")
#: The keyword arguments of :func:`load_sbml` (``load_system`` checks them first).
SBML_OPTIONS = ("outputs", "observables", "known", "unknown", "fixed", "estimate")
#: The columns of a PEtab observables table this reader uses (others are ignored).
PETAB_COLUMNS = ("observableId", "observableFormula")

_FUNCS = {"abs": "Abs", "min": "Min", "max": "Max", "pow": "Pow"}


def is_sbml_path(spec) -> bool:
    """Whether ``spec`` names an SBML file by its suffix (``.xml`` or ``.sbml``)."""
    return isinstance(spec, (str, os.PathLike)) and os.path.splitext(os.fspath(spec))[1].lower() in SBML_SUFFIXES


def load_sbml(path, outputs=None, *, observables=None, known=(), unknown=(), fixed=None, estimate=()):
    """A System from an SBML file with declared outputs and inputs (rules: module doc).

    Main arguments:
        path: the SBML file (``.xml`` or ``.sbml``).
        outputs: output name -> expression in the model's identifiers
            (``{"y1": "S1 + S2"}``), or a sequence of expressions (named ``y1, y2, ...``,
            or after the identifier when an expression is one).

    Other arguments:
        observables: instead of ``outputs``, a PEtab observables table (TSV with columns
            ``observableId`` and ``observableFormula``); a name in a formula that is no
            identifier of the model is a parameter to identify (PEtab's observable
            parameters), with a note.
        known, unknown: identifiers (parameters, species without an equation) that are
            known / unknown inputs ``u(t)``, ``w(t)``.
        fixed: identifier -> value (a number), or a sequence of identifiers fixed at their
            value in the file: known constants instead of parameters to identify.
        estimate: compartments or species without an equation to identify instead of
            fixing them at their value in the file.

    Returns:
        A :class:`uio_jax.System` on the states (species changed by reactions or rate
        rules, parameters with a rate rule) and the parameters to identify; time-varying
        (``t``) when a formula uses SBML's time. Its notes list the roles chosen.

    Raises:
        LoadError: python-libsbml or sbmlmath missing (the extra ``uio_jax[sbml]``), a
            missing, unreadable or invalid file or observables table.
        ModelError: an SBML feature that is not supported (events, delays, algebraic
            rules, piecewise, non-constant compartments, fast reactions), an input that
            does not enter affinely.
        OptionError: no outputs declared, an unknown identifier in ``outputs``, ``known``,
            ``unknown``, ``fixed`` or ``estimate``, an identifier in two roles.
    """
    where = os.fspath(path)
    if outputs is None and observables is None:
        raise OptionError(f"{where}: an SBML model declares no outputs: give outputs= (name -> expression "
                          "in the model's ids; CLI --outputs NAME=EXPR) or observables= (a PEtab table)")
    if outputs is not None and observables is not None:
        raise OptionError(f"{where}: give outputs= or observables=, not both")
    model = read_sbml(path)
    sp = _sympy()
    roles = _Roles(model, where, known, unknown, fixed, estimate)
    if observables is not None:
        texts, extra = _observables(observables, model)
    else:
        texts, extra = _output_texts(outputs, where), ()
    outs = {k: _to_sympy(sp, _parse(t, model.ids() + extra, f"{where}: output {k!r}"), model)
            for k, t in texts.items()}
    notes = list(model.notes) + [f"PEtab observable parameter {nm!r} is not in the model: a parameter "
                                 "to identify" for nm in extra]
    used = set().union(*(e.free_symbols for e in (*model.odes.values(), *outs.values())))
    used = {s.name for s in used}
    params, constants = roles.split(used, extra)
    constants, odes, outs = _exact_constants(sp, constants, model.odes, outs)
    inputs = [v for v in (*roles.known, *roles.unknown) if v in used]
    _check_affine(sp, odes, outs, [sp.Symbol(v) for v in inputs], where)
    notes += roles.notes(used)
    from .sympy_import import system_from_sympy

    return system_from_sympy(
        list(model.states), outs, dynamics=[odes[s] for s in model.states],
        known=list(roles.known), unknown=list(roles.unknown), params=params or None,
        constants=constants or None, name=model.name, notes=notes,
        time=model.time if model.time_used else None)


def _exact_constants(sp, constants, odes, outs):
    """``(constants, odes, outs)`` with every constant a float whose decimal is its exact
    value; a value of the file that no float's decimal equals (a species' initial amount
    over its compartment's size, ``1/3``) is substituted into the equations as a rational
    instead (a constant of a model file is the decimal of its float)."""
    exact = {}
    out = {}
    for nm, v in constants.items():
        if isinstance(v, sp.Rational) and sp.Rational(repr(float(v))) != v:
            exact[sp.Symbol(nm)] = v
        else:
            out[nm] = float(v)
    if exact:
        odes = {k: e.xreplace(exact) for k, e in odes.items()}
        outs = {k: e.xreplace(exact) for k, e in outs.items()}
    return out, odes, outs


def _sympy():
    from .sbml_read import libraries

    return libraries()[2]


class _Roles:
    """Which identifier is an input, a known constant or a parameter (module doc)."""

    def __init__(self, model, where, known, unknown, fixed, estimate):
        self.model, self.where = model, where
        self.known = _names(known, "known", where)
        self.unknown = _names(unknown, "unknown", where)
        self.estimate = _names(estimate, "estimate", where)
        if fixed is None:
            fixed = {}
        elif not isinstance(fixed, Mapping):
            fixed = {k: None for k in _names(fixed, "fixed", where)}
        self.fixed = {self._check(k, "fixed"): _value(v, k, where) for k, v in fixed.items()}
        seen = {}
        for role, names in (("known", self.known), ("unknown", self.unknown), ("fixed", tuple(self.fixed)),
                            ("estimate", self.estimate)):
            for nm in names:
                self._check(nm, role)
                if nm in seen:
                    raise OptionError(f"{where}: {nm!r} is named in {seen[nm]} and in {role}: give it one role")
                seen[nm] = role

    def _check(self, nm, role) -> str:
        m = self.model
        if nm in m.states:
            raise OptionError(f"{self.where}: {nm!r} in {role} is a state of the model (changed by "
                              "reactions or a rate rule)")
        if nm in m.assigned:
            raise OptionError(f"{self.where}: {nm!r} in {role} is defined by a formula of the model "
                              "(an assignment rule or a reaction rate)")
        ent = m.entities.get(nm)
        if ent is None:
            raise OptionError(f"{self.where}: {nm!r} in {role} is no id of the model "
                              f"({_listing(m.entities)})")
        if role in ("known", "unknown") and ent.kind == "compartment":
            raise OptionError(f"{self.where}: {nm!r} in {role} is a compartment: a compartment's size "
                              "cannot be an input")
        return nm

    def split(self, used, extra):
        """``(params, constants)`` of the identifiers ``used``: name -> sampling box, name ->
        value (a sympy Rational from the file, or the user's number; ``extra``: PEtab's
        observable parameters, identified)."""
        params, constants = {}, {}
        for nm, ent in self.model.entities.items():
            if nm not in used or nm in self.known or nm in self.unknown:
                continue
            if nm in self.fixed:
                value = self.fixed[nm] if self.fixed[nm] is not None else ent.value
                if value is None:
                    raise OptionError(f"{self.where}: {nm!r} in fixed has no value in the file: "
                                      "give one (NAME=VALUE)")
                if ent.kind == "compartment" and not value > 0:
                    given = "fixed" if self.fixed[nm] is not None else "its size in the file, fixed"
                    raise OptionError(f"{self.where}: compartment {nm!r} of size {value} ({given}): a compartment's "
                                      "size must be positive (the rates of its species are divided by it)")
                constants[nm] = value
            elif ent.kind in ("parameter", "local") or nm in self.estimate or ent.value is None:
                params[nm] = _box(ent.value)
            else:
                if ent.kind == "compartment" and not ent.value > 0:
                    raise ModelError(f"{self.where}: compartment {nm!r} has size {ent.value} in the file: a "
                                     "compartment's size must be positive (fix it with fixed={name: size})")
                constants[nm] = ent.value
        for nm in extra:
            params[nm] = _box(None)
        return params, constants

    def notes(self, used) -> list:
        """The report's lines about the roles chosen (those a default decided)."""
        out = []
        for nm, ent in self.model.entities.items():
            if nm in used and ent.value is None and ent.kind in ("compartment", "species") \
                    and nm not in self.fixed and nm not in self.known and nm not in self.unknown:
                out.append(f"{ent.what} {nm!r} has no value in the file: a parameter to identify")
        fixed_default = [nm for nm, ent in self.model.entities.items()
                         if nm in used and ent.kind in ("compartment", "species") and ent.value is not None
                         and nm not in self.estimate and nm not in self.known and nm not in self.unknown
                         and nm not in self.fixed]
        given = [f"{nm} = {v:g}" if v is not None else f"{nm} (its value in the file)"
                 for nm, v in self.fixed.items() if nm in used]
        if given:
            out.append(f"fixed by the user, known constants: {', '.join(given)}")
        if fixed_default:
            out.append("known constants at their values in the file (compartment sizes, species without an "
                       f"equation): {', '.join(fixed_default)}")
        return out


def _names(v, role, where) -> tuple:
    if v is None:
        return ()
    if isinstance(v, str):
        v = [v]
    try:
        out = tuple(v)
    except TypeError:
        raise OptionError(f"{where}: {role} must be a sequence of ids, got {type(v).__name__}") from None
    for nm in out:
        if not isinstance(nm, str):
            raise OptionError(f"{where}: {role} must name ids (strings), got {nm!r}")
    return out


def _value(v, nm, where):
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or v != v or v in (float("inf"), float("-inf")):
        raise OptionError(f"{where}: fixed value of {nm!r} must be a finite number, got {v!r}")
    return v


def _box(value) -> tuple:
    """Sampling box of a parameter: around its positive value in the file, else the default."""
    from .._model.system import DEFAULT_BOX

    if value is not None and value > 0:
        return (float(value / 2), float(value * 3 / 2))  # value: a sympy Rational, exact halves
    return DEFAULT_BOX


def _listing(entities, limit=12) -> str:
    names = list(entities)
    more = f", ... ({len(names)} in all)" if len(names) > limit else ""
    return "ids: " + (", ".join(names[:limit]) + more if names else "none")


# ----------------------------------------------------------------------------- outputs
def _output_texts(outputs, where) -> dict:
    """name -> expression text of ``outputs`` (a mapping, or a sequence named y1, y2, ...)."""
    if isinstance(outputs, str):
        outputs = [outputs]
    if isinstance(outputs, Mapping):
        items = list(outputs.items())
    else:
        try:
            seq = list(outputs)
        except TypeError:
            raise OptionError(f"{where}: outputs must be a mapping name -> expression or a sequence of "
                              f"expressions, got {type(outputs).__name__}") from None
        items = [(t if isinstance(t, str) and t.strip().isidentifier() else f"y{i}", t)
                 for i, t in enumerate(seq, start=1)]
    if not items:
        raise OptionError(f"{where}: outputs is empty: declare at least one output")
    out = {}
    for k, t in items:
        k = k.strip() if isinstance(k, str) else k
        if not isinstance(k, str) or not k.isidentifier():
            raise OptionError(f"{where}: output name {k!r} is not a valid name (letters, digits and _)")
        if k in out:
            raise OptionError(f"{where}: output {k!r} is declared twice")
        if isinstance(t, bool) or not isinstance(t, (str, int, float)):
            raise OptionError(f"{where}: output {k!r} must be an expression (text), got {type(t).__name__}")
        out[k] = t if isinstance(t, str) else repr(t)
    return out


def _observables(path, model):
    """``(texts, extra)`` of a PEtab observables table: observableId -> formula, and the
    names its formulas use that are no identifier of the model (parameters to identify)."""
    path = os.fspath(path)
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
            header = rows[0].keys() if rows else []
    except OSError as exc:
        raise LoadError(f"observables table {path}: cannot read: {exc.strerror or exc}") from None
    except (UnicodeDecodeError, csv.Error) as exc:
        raise LoadError(f"observables table {path}: not a UTF-8 TSV table ({exc})") from None
    missing = [c for c in PETAB_COLUMNS if c not in header]
    if not rows or missing:
        raise LoadError(f"observables table {path}: needs a header with {', '.join(PETAB_COLUMNS)} and one row "
                        f"per observable (missing: {', '.join(missing) or 'rows'})")
    texts, ids = {}, set(model.ids())
    extra = []
    for i, row in enumerate(rows, start=2):
        oid = (row["observableId"] or "").strip()
        if not oid.isidentifier() or oid in texts:
            raise LoadError(f"observables table {path} line {i}: observableId {oid!r} is not a new valid id")
        text = (row["observableFormula"] or "").replace("^", "**")  # PEtab writes powers as ^
        texts[oid] = text
        for nm in _names_in(text, f"observables table {path} line {i}"):
            if nm not in ids and nm not in extra and nm not in CONSTANTS:
                extra.append(nm)
    return texts, tuple(extra)


def _names_in(text, what) -> list:
    """The variable names of an expression text, read with ``ast`` (never evaluated)."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        parse_expression(text, ())  # raises its one-line syntax error
        return []
    calls = {id(n.func) for n in ast.walk(tree) if isinstance(n, ast.Call)}
    return [n.id for n in ast.walk(tree) if isinstance(n, ast.Name) and id(n) not in calls]


def _parse(text, names, what):
    try:
        return parse_expression(text, names, what=what)
    except ExpressionError as exc:
        raise OptionError(str(exc)) from None


def _to_sympy(sp, e, model):
    """An expression tree as sympy, numbers exact (their decimals), formulas substituted."""
    if isinstance(e, Num):
        return sp.Rational(repr(e.value))
    if isinstance(e, Name):
        if e.id in model.assigned:
            return model.assigned[e.id]
        if e.id in CONSTANTS and e.id not in model.ids():
            return {"pi": sp.pi, "E": sp.E}[e.id]
        return sp.Symbol(e.id)
    if isinstance(e, Unary):
        inner = _to_sympy(sp, e.operand, model)
        return -inner if e.op == "-" else inner
    if isinstance(e, Binary):
        a, b = _to_sympy(sp, e.left, model), _to_sympy(sp, e.right, model)
        return {"+": sp.Add, "-": lambda x, y: x - y, "*": sp.Mul, "/": lambda x, y: x / y,
                "**": sp.Pow}[e.op](a, b)
    if isinstance(e, Call):
        args = [_to_sympy(sp, a, model) for a in e.args]
        name = _FUNCS.get(e.func, e.func)
        if name in ("sec", "csc", "cot"):
            return 1 / {"sec": sp.cos, "csc": sp.sin, "cot": sp.tan}[name](*args)
        return getattr(sp, name)(*args)
    raise TypeError(f"not an expression tree: {e!r}")


# ----------------------------------------------------------------------------- affinity
def _check_affine(sp, odes, outputs, inputs, where):
    """Refuse, in one line, an input that enters a right-hand side non-affinely (in a
    denominator, through a function, squared, times another input) or an output at all:
    exact, on the sympy expressions (numerator of degree <= 1 in the inputs)."""
    if not inputs:
        return
    names = {s.name for s in inputs}
    for k, h in outputs.items():
        bad = sorted(names & {s.name for s in h.free_symbols})
        if bad:
            raise ModelError(f"{where}: output {k!r} uses the input {bad[0]!r}: an output may not depend on "
                             "an input")
    for state, f in odes.items():
        if not (f.free_symbols & set(inputs)):
            continue
        num, den = sp.fraction(sp.together(f))
        why = _nonaffine(sp, num, den, [v for v in inputs if v in f.free_symbols])
        if why:
            raise ModelError(f"{where}: the equation of {state!r} is not affine in the inputs ({why}: "
                             f"{sp.sstr(f)[:120]}); declare it as neither known nor unknown, or reformulate "
                             "the model")


def _nonaffine(sp, num, den, inputs) -> str:
    """Why ``num / den`` is not affine in ``inputs`` ('' when it is)."""
    for v in inputs:
        if v in den.free_symbols:
            return f"{v.name!r} is in a denominator"
        try:
            if sp.Poly(num, v).degree() > 1:
                return f"{v.name!r} enters with a power above 1"
        except sp.PolynomialError:
            return f"{v.name!r} enters through a function"
    if sp.Poly(num, *inputs).total_degree() > 1:
        return f"a product of inputs ({', '.join(v.name for v in inputs)})"
    return ""

