"""Declarative model files (TOML or JSON, same schema): read them into Systems, write them back.

A model file holds data only; its expressions go through the whitelisted parser of
:mod:`uio_jax._io.expressions` (never ``eval``). Schema (every key but ``states`` and
``outputs`` is optional; tables keep their order)::

    name = "unicycle, range output, v unknown"     # shown in reports
    description = "004 section 11.1.1"             # free text, kept, not used
    notes = ["..."]                                # copied into every report
    states = ["r", "phi", "theta"]                 # order of the state vector
    angles = ["phi", "theta"]                      # sampled in [-pi, pi), wrapped by the EKF
    time = "t"        # a time-varying model: expressions may use t (box: domain.t, default [0, 1])

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

    # OR the general form x' = f(x, p, u, w), split by uio_jax._io.affine
    [inputs]
    known = ["omega"]
    unknown = ["v"]
    [dynamics]        # state -> component of f; missing states: 0
    r = "v*cos(theta - phi)"
    phi = "v*sin(theta - phi)/r"
    theta = "omega"

Expressions may use the states, params, constants, the time variable when ``time`` names
one (and, in the general form, the inputs), numbers, ``pi``, ``E``, ``+ - * / **`` and the
functions of :data:`uio_jax._io.expressions.FUNCTIONS`. Names (states, params, constants,
inputs, time) must be Python identifiers, distinct from each other; no name is reserved for
time: a ``t`` that is not declared (by ``time = "t"`` or otherwise) is an unknown name. An
output may not be named like the time variable (time is measured: the analyses add that
output, see :meth:`uio_jax.System.autonomous`). Numbers may also be given for expressions.

In the general form an input that enters non-affinely is promoted to a state (see
:mod:`uio_jax._io.affine`); the System's notes say so.

Reading: :func:`read_model_file` (-> :class:`ModelSpec`), :func:`build_system`
(spec -> System), :func:`load_model_file` (both). Writing: :func:`save_model` for any
System that carries its spec in ``System.source`` (model files, ``System.from_sympy``,
StrikePy imports); Systems made of Python functions cannot be written.
"""

import json
import os

from .._errors import LoadError, ModelError, UioJaxError
from .expressions import Num, parse_expression
from .model_spec import ModelSpec, spec_from_dict
from .toml_writer import to_toml

_SUFFIXES = (".toml", ".json")


# ----------------------------------------------------------------------------- building
def build_system(spec: ModelSpec):
    """The :class:`uio_jax.System` of a spec (expressions compiled to JAX, general form split).

    Callables take ``x`` (shape ``(n,)``), or ``(x, p)`` when the spec has params, with a
    trailing scalar ``t`` when it has a time variable (``(x, t)``, ``(x, p, t)``); the spec is
    kept in ``System.source`` so that :func:`save_model` can write it back.
    """
    from .._model.system import DEFAULT_TIME_BOX
    from .affine import Parts, split_general, system_callables, vector_function
    from .expression_functions import to_function

    names = spec.inputs_known + spec.inputs_unknown
    time, time_box = spec.time, None
    extra = {}  # the coordinates after the parameters in z: the time, sampled in its box
    if time is not None:
        time_box = tuple(spec.domain.get(time, DEFAULT_TIME_BOX))
        extra = {time: time_box}
    base = tuple(spec.states) + tuple(spec.params) + tuple(extra)
    consts = dict(spec.constants)
    allowed = base + tuple(consts) + names

    def trees(table):
        return {k: parse_expression(t, allowed) for k, t in table.items()}

    drift = {k: e for k, e in trees(spec.drift).items() if e != Num(0.0)}  # "0" entries: no drift

    if spec.general:
        parts = split_general(spec.states, trees(spec.dynamics), trees(spec.outputs), spec.inputs_known,
                              spec.inputs_unknown, {**spec.params, **extra}, consts, dict(spec.domain),
                              spec.angles)
    else:
        parts = Parts(
            states=tuple(spec.states),
            outputs={k: to_function(e, base, consts) for k, e in trees(spec.outputs).items()},
            known={k: vector_function(trees(f), spec.states, base, consts) for k, f in spec.known.items()},
            unknown={k: vector_function(trees(f), spec.states, base, consts) for k, f in spec.unknown.items()},
            drift=vector_function(drift, spec.states, base, consts) if drift else None,
            domain={k: b for k, b in spec.domain.items() if k != time}, angles=tuple(spec.angles),
        )
    wrap = system_callables(bool(spec.params), time is not None)
    return parts.to_system(wrap, name=spec.name, params=dict(spec.params), source=spec, notes=spec.notes,
                           time=time, time_box=time_box)


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
        what = "a directory" if os.path.isdir(path) else "not a regular file" if os.path.exists(path) else ""
        raise LoadError(f"model file {path} is {what}" if what else f"model file not found: {path}")
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        text = raw.decode("utf-8-sig")  # a byte-order mark (some editors write one) is not text
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
        except RecursionError:
            raise LoadError(f"{path}: TOML nested too deeply (arrays or tables in one another)") from None
    else:
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise LoadError(f"{path}: JSON syntax error: {exc.msg} (at line {exc.lineno}, "
                            f"column {exc.colno})") from None
        except RecursionError:
            raise LoadError(f"{path}: JSON nested too deeply (arrays or objects in one another)") from None
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
    spec = read_model_file(path)
    try:
        system = build_system(spec)
    except UioJaxError as exc:
        msg = str(exc)
        if not msg.startswith(os.fspath(path)):
            msg = f"{os.fspath(path)}: {msg}"
        raise type(exc)(msg) from None
    return system if system.name else system.with_name(os.path.basename(os.fspath(path)))


def save_model(system, path) -> None:
    """Write a System's declarative model to ``path`` (``.toml`` or ``.json``, from the suffix).

    Works for Systems built from model files, :meth:`System.from_sympy` or StrikePy
    modules (they keep their :class:`ModelSpec` in ``System.source``); reading the file
    back with :func:`load_model_file` gives the same model. ``system`` may also be a
    dictionary in the model-file schema (``Report.reparametrised_model()``): it is checked
    as a model file is, then written.

    Raises:
        ModelError: the System is made of Python functions (no spec), or the suffix is
            neither ``.toml`` nor ``.json``.
    """
    if isinstance(system, dict):
        spec = spec_from_dict(system, "model dictionary")
        system = build_system(spec)
    from .._model.system import System

    if not isinstance(system, System):
        raise ModelError(f"save_model needs a uio_jax.System or a model dictionary, got {type(system).__name__}")
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
