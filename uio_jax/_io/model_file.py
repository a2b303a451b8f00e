"""Declarative model files (TOML or JSON, same schema): read them into Systems, write them back.

A model file holds data only; its expressions go through the whitelisted parser of
:mod:`uio_jax._expressions` (never ``eval``). Schema (every key but ``states`` and
``outputs`` is optional; tables keep their order)::

    name = "unicycle, range output, v unknown"     # shown in reports
    description = "004 section 11.1.1"             # free text, kept, not used
    notes = ["..."]                                # copied into every report
    states = ["r", "phi", "theta"]                 # order of the state vector
    angles = ["phi", "theta"]                      # sampled in [-pi, pi), wrapped by the EKF

    [params]          # unknown constant parameters -> sampling box [lo, hi]
    k = [0.5, 1.5]    # (or: params = ["k", "c"], each in the default box [0.5, 1.5])

    [constants]       # known constants -> value
    g = 9.81

    [domain]          # sampling box of a state (or of an input of the general form)
    r = [0.5, 2.0]

    [outputs]         # output name -> expression
    y_r = "r"

    # EITHER the control-affine form x' = f0 + sum_i f_i u_i + sum_j g_j w_j
    [drift]           # state -> component of f0; missing states: 0
    [known.omega]     # one table per known input: state -> component of f_i
    theta = "1"
    [unknown.v]       # one table per unknown input: state -> component of g_j
    r = "cos(theta - phi)"
    phi = "sin(theta - phi)/r"

    # OR the general form x' = f(x, p, u, w), split by uio_jax._affine
    [inputs]
    known = ["omega"]
    unknown = ["v"]
    [dynamics]        # state -> component of f; missing states: 0
    r = "v*cos(theta - phi)"
    phi = "v*sin(theta - phi)/r"
    theta = "omega"

Expressions may use the states, params, constants (and, in the general form, the inputs),
numbers, ``pi``, ``E``, ``+ - * / **`` and the functions of
:data:`uio_jax._expressions.FUNCTIONS`. Names (states, params, constants, inputs) must be
Python identifiers, distinct from each other. Numbers may also be given for expressions.

In the general form an input that enters non-affinely is promoted to a state (see
:mod:`uio_jax._affine`); the System's notes say so.

Reading: :func:`read_model_file` (-> :class:`ModelSpec`), :func:`build_system`
(spec -> System), :func:`load_model_file` (both). Writing: :func:`save_model` for any
System that carries its spec in ``System.source`` (model files, ``System.from_sympy``,
StrikePy imports); Systems made of Python functions cannot be written.
"""

import json
import keyword
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import jax.numpy as jnp
import numpy as np

from .._errors import ExpressionError, LoadError, ModelError
from .expressions import Num, parse_expression

_TOP_KEYS = ("name", "description", "notes", "states", "angles", "params", "constants", "domain",
             "outputs", "drift", "known", "unknown", "inputs", "dynamics")
_SUFFIXES = (".toml", ".json")


@dataclass(frozen=True)
class ModelSpec:
    """A model as pure data: names, boxes and expression texts (see the module doc for the schema).

    ``dynamics is None`` for the control-affine form (``drift``, ``known``, ``unknown``:
    state -> text, input -> {state -> text}); otherwise the general form with
    ``dynamics`` (state -> text) and the input names ``inputs_known``/``inputs_unknown``.
    Mappings are read-only and keep their order. Build it with :func:`spec_from_dict`,
    which validates everything (names, boxes, expressions).
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

    @property
    def general(self) -> bool:
        """True for the general form ``x' = f(x, p, u, w)``."""
        return self.dynamics is not None

    def to_dict(self) -> dict:
        """The file schema as plain dicts/lists (JSON-ready; :func:`spec_from_dict` reads it back)."""
        d = {}
        if self.name:
            d["name"] = self.name
        if self.description:
            d["description"] = self.description
        if self.notes:
            d["notes"] = list(self.notes)
        d["states"] = list(self.states)
        if self.angles:
            d["angles"] = list(self.angles)
        if self.params:
            d["params"] = {k: list(v) for k, v in self.params.items()}
        if self.constants:
            d["constants"] = dict(self.constants)
        if self.domain:
            d["domain"] = {k: list(v) for k, v in self.domain.items()}
        d["outputs"] = dict(self.outputs)
        if self.general:
            d["inputs"] = {"known": list(self.inputs_known), "unknown": list(self.inputs_unknown)}
            d["dynamics"] = dict(self.dynamics)
        else:
            if self.drift:
                d["drift"] = dict(self.drift)
            if self.known:
                d["known"] = {k: dict(v) for k, v in self.known.items()}
            if self.unknown:
                d["unknown"] = {k: dict(v) for k, v in self.unknown.items()}
        return d


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
    domain = _boxes(_table(data.get("domain", {}), "domain", w), "domain", w)
    for k in domain:
        if k not in states and k not in ik + iu:
            raise w.error(f"domain.{k}", f"{k!r} is not a state{' or an input' if general else ''} "
                                        f"(states: {', '.join(states)})")
    base_names = states + tuple(params) + tuple(constants)
    input_names = ik + iu
    outputs = _exprs(data["outputs"], "outputs", w, base_names + input_names, rows=None)
    if not outputs:
        raise w.error("outputs", "must define at least one output")
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
    ro = MappingProxyType
    return ModelSpec(
        states=states, outputs=ro(outputs), name=name, description=description, notes=tuple(notes),
        angles=angles, params=ro(params), constants=ro(constants), domain=ro(domain), drift=ro(drift),
        known=ro({k: ro(v) for k, v in known.items()}), unknown=ro({k: ro(v) for k, v in unknown.items()}),
        dynamics=None if dynamics is None else ro(dynamics), inputs_known=ik, inputs_unknown=iu,
    )


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


# ----------------------------------------------------------------------------- building
def build_system(spec: ModelSpec):
    """The :class:`uio_jax.System` of a spec (expressions compiled to JAX, general form split).

    Callables take ``x`` (shape ``(n,)``), or ``(x, p)`` when the spec has params; the
    spec is kept in ``System.source`` so that :func:`save_model` can write it back.
    """
    from .._model.system import System
    from .affine import Parts, split_general, vector_function
    from .expressions import to_function

    names = spec.inputs_known + spec.inputs_unknown
    base = tuple(spec.states) + tuple(spec.params)
    consts = dict(spec.constants)
    allowed = base + tuple(consts) + names

    def trees(table):
        return {k: parse_expression(t, allowed) for k, t in table.items()}

    drift = {k: e for k, e in trees(spec.drift).items() if e != Num(0.0)}  # "0" entries: no drift

    if spec.general:
        parts = split_general(spec.states, trees(spec.dynamics), trees(spec.outputs), spec.inputs_known,
                              spec.inputs_unknown, dict(spec.params), consts, dict(spec.domain), spec.angles)
    else:
        parts = Parts(
            states=tuple(spec.states),
            outputs={k: to_function(e, base, consts) for k, e in trees(spec.outputs).items()},
            known={k: vector_function(trees(f), spec.states, base, consts) for k, f in spec.known.items()},
            unknown={k: vector_function(trees(f), spec.states, base, consts) for k, f in spec.unknown.items()},
            drift=vector_function(drift, spec.states, base, consts) if drift else None,
            domain=dict(spec.domain), angles=tuple(spec.angles),
        )
    wrap = _with_params if spec.params else _no_params
    return System(
        parts.states,
        {k: wrap(f) for k, f in parts.outputs.items()},
        known={k: wrap(f) for k, f in parts.known.items()},
        unknown={k: wrap(f) for k, f in parts.unknown.items()},
        drift=None if parts.drift is None else wrap(parts.drift),
        domain=parts.domain, angles=parts.angles, name=spec.name,
        params=dict(spec.params), source=spec, notes=tuple(spec.notes) + tuple(parts.notes),
    )


def _no_params(fn):
    """``fn(z)`` with ``z = x``: the System's callable as is."""
    return fn


def _with_params(fn):
    """``fn(z)`` on ``z = [x; p]`` -> the System's callable ``(x, p)``."""

    def f(x, p):
        if isinstance(x, np.ndarray) and isinstance(p, np.ndarray):  # one-off numpy evaluation
            return fn(np.concatenate([x, p]).astype(np.float64))
        return fn(jnp.concatenate([jnp.asarray(x), jnp.asarray(p)]))

    return f


# ----------------------------------------------------------------------------- files
def read_model_file(path) -> ModelSpec:
    """Read and validate a ``.toml`` or ``.json`` model file (schema in the module doc).

    Raises:
        LoadError: missing or unreadable file, unsupported suffix, TOML/JSON syntax error
            (with its line).
        ModelError: schema or expression problem (naming the file and key).
    """
    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in _SUFFIXES:
        raise LoadError(f"{path}: a model file must end in .toml or .json")
    if not os.path.isfile(path):
        raise LoadError(f"model file not found: {path}")
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        text = raw.decode("utf-8")
    except OSError as exc:
        raise LoadError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise LoadError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    if suffix == ".toml":
        tomllib = _tomllib()
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise LoadError(f"{path}: TOML syntax error: {exc}") from None
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise LoadError(f"{path}: JSON syntax error: {exc.msg} (at line {exc.lineno}, "
                            f"column {exc.colno})") from None
    return spec_from_dict(data, path)


def _tomllib():
    try:
        import tomllib
    except ImportError:  # Python < 3.11
        try:
            import tomli as tomllib
        except ImportError:
            raise LoadError("reading TOML needs Python 3.11 or the tomli package (pip install tomli)") from None
    return tomllib


def load_model_file(path):
    """Load a System from a declarative ``.toml``/``.json`` model file.

    The System's name is the file's ``name`` key or the file name; its ``source`` is the
    :class:`ModelSpec` (so :func:`save_model` can write it back).

    Raises:
        LoadError, ModelError: one line naming the file (and key) and the problem.
    """
    from .._errors import UioJaxError

    spec = read_model_file(path)
    try:
        system = build_system(spec)
    except UioJaxError as exc:
        msg = str(exc)
        if not msg.startswith(os.fspath(path)):
            msg = f"{os.fspath(path)}: {msg}"
        raise type(exc)(msg) from None
    if not system.name:
        object.__setattr__(system, "name", os.path.basename(os.fspath(path)))
    return system


def save_model(system, path) -> None:
    """Write a System's declarative model to ``path`` (``.toml`` or ``.json``, from the suffix).

    Works for Systems built from model files, :meth:`System.from_sympy` or StrikePy
    modules (they keep their :class:`ModelSpec` in ``System.source``); reading the file
    back with :func:`load_model_file` gives the same model.

    Raises:
        ModelError: the System is made of Python functions (no spec), or the suffix is
            neither ``.toml`` nor ``.json``.
    """
    spec = getattr(system, "source", None)
    if not isinstance(spec, ModelSpec):
        label = f" {system.name!r}" if getattr(system, "name", "") else ""
        raise ModelError(f"System{label} is made of Python functions and cannot be written as a model file "
                         "(only Systems loaded from model files, from_sympy or StrikePy keep their equations)")
    path = os.fspath(path)
    suffix = os.path.splitext(path)[1].lower()
    if suffix not in _SUFFIXES:
        raise ModelError(f"{path}: a model file must end in .toml or .json")
    data = spec.to_dict()
    if "name" not in data and system.name:
        data = {"name": system.name, **data}
    text = to_toml(data) if suffix == ".toml" else json.dumps(data, indent=2, ensure_ascii=False) + "\n"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)


# ----------------------------------------------------------------------------- TOML writer
_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _toml_key(k: str) -> str:
    return k if _BARE.match(k) else _toml_string(k)


def _toml_string(s: str) -> str:
    out = json.dumps(s, ensure_ascii=True)  # JSON escapes are valid TOML basic-string escapes
    return out.replace("\x7f", "\\u007f")


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return _toml_string(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def to_toml(data: Mapping) -> str:
    """Write the model schema (plain values first, then tables, then tables of tables) as TOML."""
    lines = []
    for k, v in data.items():
        if not isinstance(v, Mapping):
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for k, v in data.items():
        if not isinstance(v, Mapping):
            continue
        flat = {kk: vv for kk, vv in v.items() if not isinstance(vv, Mapping)}
        nested = {kk: vv for kk, vv in v.items() if isinstance(vv, Mapping)}
        if flat or not nested:
            lines += ["", f"[{_toml_key(k)}]"]
            lines += [f"{_toml_key(kk)} = {_toml_value(vv)}" for kk, vv in flat.items()]
        for kk, vv in nested.items():
            lines += ["", f"[{_toml_key(k)}.{_toml_key(kk)}]"]
            lines += [f"{_toml_key(k3)} = {_toml_value(v3)}" for k3, v3 in vv.items()]
    return "\n".join(lines) + "\n"
