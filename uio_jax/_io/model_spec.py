"""A model as pure data (:class:`ModelSpec`) and the validation of the file schema.

:func:`spec_from_dict` checks a dict read from a TOML or JSON model file (or built by an
importer) against the schema documented in :mod:`uio_jax._io.model_file`: names are
identifiers and distinct, boxes are ordered pairs of finite numbers, expressions parse
under the whitelist. Every error is one line naming the source and the key.
"""

import keyword
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

from .._errors import ExpressionError, ModelError
from .expressions import ALIASES, CONSTANTS, FUNCTIONS, parse_expression

_TOP_KEYS = ("name", "description", "notes", "states", "angles", "time", "params", "constants", "domain",
             "outputs", "drift", "known", "unknown", "inputs", "dynamics", "initial")


@dataclass(frozen=True)
class ModelSpec:
    """A model as pure data: names, boxes and expression texts (see the module doc for the schema).

    ``dynamics is None`` for the control-affine form (``drift``, ``known``, ``unknown``:
    state -> text, input -> {state -> text}); otherwise the general form with
    ``dynamics`` (state -> text) and the input names ``inputs_known``/``inputs_unknown``.
    ``time`` names the time variable of a time-varying model, ``None`` for a time-invariant
    one. Mappings are read-only and keep their order. Build it with :func:`spec_from_dict`,
    which validates everything.
    """

    states: tuple
    outputs: Mapping
    name: str = ""
    description: str = ""
    notes: tuple = ()
    angles: tuple = ()
    params: Mapping = field(default_factory=dict)
    constants: Mapping = field(default_factory=dict)
    domain: Mapping = field(default_factory=dict)
    drift: Mapping = field(default_factory=dict)
    known: Mapping = field(default_factory=dict)
    unknown: Mapping = field(default_factory=dict)
    dynamics: Mapping | None = None
    inputs_known: tuple = ()
    inputs_unknown: tuple = ()
    time: str | None = None
    initial: Mapping = field(default_factory=dict)

    @property
    def general(self) -> bool:
        """True for the general form ``x' = f(x, p, u, w)``."""
        return self.dynamics is not None

    def to_dict(self) -> dict:
        """The file schema as plain dicts/lists (JSON-ready; :func:`spec_from_dict` reads it back)."""
        if self.general:
            rhs = {"inputs": {"known": list(self.inputs_known), "unknown": list(self.inputs_unknown)},
                   "dynamics": dict(self.dynamics)}
        else:
            rhs = {"drift": dict(self.drift), "known": {k: dict(v) for k, v in self.known.items()},
                   "unknown": {k: dict(v) for k, v in self.unknown.items()}}
        d = {"name": self.name, "description": self.description, "notes": list(self.notes),
             "states": list(self.states), "angles": list(self.angles), "time": self.time,
             "params": {k: list(v) for k, v in self.params.items()}, "constants": dict(self.constants),
             "domain": {k: list(v) for k, v in self.domain.items()}, "outputs": dict(self.outputs),
             **rhs, "initial": dict(self.initial)}
        # the optional keys are written only when they say something (the general form's always)
        return {k: v for k, v in d.items() if v or k in ("states", "outputs", "inputs", "dynamics")}


# ----------------------------------------------------------------------------- validation
class _Where:
    """Prefix of error messages: the file (or source) and the key."""

    def __init__(self, source):
        self.source = source

    def error(self, key, message, cls=ModelError):
        at = f" {key}:" if key else ""
        return cls(f"{self.source}:{at} {message}")


def spec_from_dict(data, source: str = "model") -> ModelSpec:
    """Validate a dict of the file schema and return a :class:`ModelSpec`.

    Args:
        data: the parsed TOML/JSON document (see the module doc).
        source: how errors name the model (a path, ``"from_sympy"``, ...).

    Raises:
        ModelError: one line naming the source, the key and the problem (unknown key,
            missing ``states``/``outputs``, wrong type, duplicate or clashing name, empty
            box, bad expression).
    """
    w = _Where(source)
    if not isinstance(data, Mapping):
        raise w.error("", f"a model must be a table of keys, got {type(data).__name__}")
    extra = [k for k in data if k not in _TOP_KEYS]
    if extra:
        raise w.error("", f"unknown key{'s' if len(extra) > 1 else ''} {', '.join(map(repr, extra))} "
                          f"(allowed: {', '.join(_TOP_KEYS)})")
    for req in ("states", "outputs"):
        if req not in data:
            raise w.error("", f"missing {req!r} (a model needs states and outputs)")
    name = _string(data.get("name", ""), "name", w)
    description = _string(data.get("description", ""), "description", w)
    notes = data.get("notes", [])
    if isinstance(notes, str):
        notes = [notes]
    if not isinstance(notes, list) or not all(isinstance(t, str) for t in notes):
        raise w.error("notes", "must be a list of strings")
    states = _names(data["states"], "states", w)
    if not states:
        raise w.error("states", "must list at least one state")
    taken = {s: "state" for s in states}
    angles = _names(data.get("angles", []), "angles", w)
    for a in angles:
        if a not in states:
            raise w.error("angles", f"{a!r} is not a state (states: {', '.join(states)})")
    params = _params(data.get("params", {}), w, taken)
    constants = _constants(data.get("constants", {}), w, taken)
    time = None
    if "time" in data:
        time = _string(data["time"], "time", w)
        _identifier(time, "time", w)
        _claim(time, "time variable", taken, "time", w)
    general, ik, iu = _general_form_inputs(data, w, taken)
    domain = _boxes(_table(data.get("domain", {}), "domain", w), "domain", w)
    for k in domain:
        if k not in states and k not in ik + iu and k != time:
            what = "a state" + (" or an input" if general else "") + (" or the time" if time else "")
            raise w.error(f"domain.{k}", f"{k!r} is not {what} (states: {', '.join(states)})")
    base_names = states + tuple(params) + tuple(constants) + ((time,) if time else ())
    input_names = ik + iu
    outputs = _exprs(data["outputs"], "outputs", w, base_names + input_names, rows=None)
    if not outputs:
        raise w.error("outputs", "must define at least one output")
    if time in outputs:
        raise w.error(f"outputs.{time}", f"output {time!r} has the name of the time variable (time is "
                                         "measured: the analyses add that output themselves)")
    drift, known, unknown, dynamics = {}, {}, {}, None
    if general:
        dynamics = _exprs(data["dynamics"], "dynamics", w, base_names + input_names, rows=states)
    else:
        drift = _exprs(data.get("drift", {}), "drift", w, base_names, rows=states)
        for kind, out in (("known", known), ("unknown", unknown)):
            for inp, fld in _table(data.get(kind, {}), kind, w).items():
                _identifier(inp, kind, w)
                _claim(inp, "input", taken, kind, w)
                out[inp] = _exprs(fld, f"{kind}.{inp}", w, base_names, rows=states)
    initial = _initial(data.get("initial", {}), w, states, tuple(params) + tuple(constants))
    ro = MappingProxyType
    notes = tuple(notes) + _shadow_notes(taken)
    return ModelSpec(
        states=states, outputs=ro(outputs), name=name, description=description, notes=notes,
        angles=angles, params=ro(params), constants=ro(constants), domain=ro(domain), drift=ro(drift),
        known=ro({k: ro(v) for k, v in known.items()}), unknown=ro({k: ro(v) for k, v in unknown.items()}),
        dynamics=None if dynamics is None else ro(dynamics), inputs_known=ik, inputs_unknown=iu, time=time,
        initial=ro(initial),
    )


def _initial(v, w, states, names) -> dict:
    """The ``[initial]`` table: state -> a finite number or an expression in the parameters and
    constants (kept as text; the analysis reads it, :mod:`uio_jax._io.initial_values`)."""
    out = {}
    for k, val in _table(v, "initial", w).items():
        if k not in states:
            raise w.error(f"initial.{k}", f"{k!r} is not a state (states: {', '.join(states)})")
        if isinstance(val, bool) or not isinstance(val, (int, float, str)):
            raise w.error(f"initial.{k}", f"must be a number or an expression text, got {type(val).__name__}")
        if isinstance(val, str):
            try:
                parse_expression(val, names, what=f"initial.{k}")
            except ExpressionError as exc:
                raise w.error("", str(exc)) from None
        elif not math.isfinite(val):
            raise w.error(f"initial.{k}", f"must be finite, got {val!r}")
        out[k] = val
    return out


def _general_form_inputs(data, w, taken):
    """``(general, known inputs, unknown inputs)``: whether the model is in the general form
    (``[dynamics]``) and the inputs its ``[inputs]`` table names (claimed in ``taken``); the
    control-affine form names its inputs by its tables (empty here)."""
    general = "dynamics" in data
    if general:
        mixed = [k for k in ("drift", "known", "unknown") if k in data]
        if mixed:
            raise w.error(mixed[0], "use either [dynamics] with [inputs] (general form) or "
                                    "[drift]/[known]/[unknown] (control-affine form), not both")
        inputs = _table(data.get("inputs", {}), "inputs", w)
        bad = [k for k in inputs if k not in ("known", "unknown")]
        if bad:
            raise w.error("inputs", f"unknown key {bad[0]!r} (allowed: known, unknown)")
        ik = _names(inputs.get("known", []), "inputs.known", w)
        iu = _names(inputs.get("unknown", []), "inputs.unknown", w)
        for nm in ik + iu:
            _claim(nm, "input", taken, "inputs", w)
    else:
        if "inputs" in data:
            raise w.error("inputs", "only used with [dynamics] (general form); the control-affine "
                                    "form names its inputs by its [known.NAME]/[unknown.NAME] tables")
        ik, iu = (), ()
    return general, ik, iu


def _string(v, key, w):
    if not isinstance(v, str):
        raise w.error(key, f"must be a string, got {type(v).__name__}")
    return v


def _table(v, key, w) -> Mapping:
    if not isinstance(v, Mapping):
        raise w.error(key, f"must be a table (name = value), got {_kind(v)}")
    return v


def _kind(v) -> str:
    return {list: "a list", str: "a string", bool: "a boolean", int: "a number", float: "a number",
            dict: "a table"}.get(type(v), type(v).__name__)


def _shadow_notes(taken) -> tuple:
    """A note per model name that is also a built-in constant or function of expressions
    (``pi``, ``E``, ``sin``): in the model's expressions the name means the model's own
    (a state ``E`` of an SEIR model), said rather than silent."""
    return tuple(f"{what} {nm!r} shadows the built-in {'constant' if nm in CONSTANTS else 'function'} "
                 f"{nm} of expressions: in this model's expressions {nm!r} is the {what}"
                 for nm, what in taken.items() if nm in CONSTANTS or nm in FUNCTIONS or nm in ALIASES)


def _identifier(nm, key, w):
    if not isinstance(nm, str) or not nm.isidentifier() or keyword.iskeyword(nm):
        raise w.error(key, f"{nm!r} is not a valid name (letters, digits and _, not starting with a "
                           "digit, not a Python keyword)")


def _names(v, key, w) -> tuple:
    if isinstance(v, str) or not isinstance(v, (list, tuple)):
        raise w.error(key, f"must be a list of names, got {_kind(v)}")
    seen = set()
    for nm in v:
        _identifier(nm, key, w)
        if nm in seen:
            raise w.error(key, f"{nm!r} is listed twice")
        seen.add(nm)
    return tuple(v)


def _claim(nm, what, taken, key, w):
    if nm in taken:
        other = taken[nm]
        raise w.error(key, f"{what} {nm!r} has the name of {'an' if other[0] in 'aeiou' else 'a'} {other}")
    taken[nm] = what


def _number(v, key, w) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise w.error(key, f"must be a number, got {_kind(v)} {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise w.error(key, f"must be finite, got {v}")
    return v


def _box(v, key, w) -> tuple:
    if isinstance(v, str) or not isinstance(v, (list, tuple)) or len(v) != 2:
        raise w.error(key, f"must be a pair [lo, hi], got {v!r}")
    lo, hi = (_number(x, key, w) for x in v)
    if lo >= hi:
        raise w.error(key, f"empty box: lo={lo} >= hi={hi}")
    if not math.isfinite(hi - lo):  # the samples lo + u (hi - lo) would be inf, and blame the model
        raise w.error(key, f"box [{lo:g}, {hi:g}] too wide: its width overflows float64; give the range "
                           "where the model is meant to be evaluated")
    return (lo, hi)


def _boxes(table, key, w) -> dict:
    out = {}
    for k, v in table.items():
        _identifier(k, key, w)
        out[k] = _box(v, f"{key}.{k}", w)
    return out


def _params(v, w, taken) -> dict:
    from .._model.system import DEFAULT_BOX

    if isinstance(v, (list, tuple)):
        out = {k: DEFAULT_BOX for k in _names(v, "params", w)}
    else:
        out = _boxes(_table(v, "params", w), "params", w)
    for k in out:
        _claim(k, "parameter", taken, "params", w)
    return out


def _constants(v, w, taken) -> dict:
    out = {}
    for k, val in _table(v, "constants", w).items():
        _identifier(k, "constants", w)
        _claim(k, "constant", taken, "constants", w)
        out[k] = _number(val, f"constants.{k}", w)
    return out


def _exprs(table, key, w, names, rows) -> dict:
    """Check a table name -> expression text; ``rows`` (if given) restricts the names to states."""
    table = _table(table, key, w)
    out = {}
    for k, text in table.items():
        if not isinstance(k, str) or not k:
            raise w.error(key, f"names must be non-empty strings, got {k!r}")
        if rows is not None and k not in rows:
            raise w.error(f"{key}.{k}", f"{k!r} is not a state (states: {', '.join(rows)})")
        if rows is None and keyword.iskeyword(k):
            raise w.error(f"{key}.{k}", f"{k!r} is a Python keyword")
        if isinstance(text, bool) or not isinstance(text, (str, int, float)):
            raise w.error(f"{key}.{k}", f"must be an expression string, got {_kind(text)}")
        if not isinstance(text, str):
            text = repr(float(text)) if isinstance(text, float) else str(text)
        try:
            parse_expression(text, names)
        except ExpressionError as exc:
            raise w.error(f"{key}.{k}", str(exc), ExpressionError) from None
        out[k] = text
    return out
