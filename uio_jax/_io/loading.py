"""``load_system(...)``: models loaded by path, not installed (a zoo file's ``NAME``, a
declarative model file, a StrikePy module, an SBML model: :func:`load_system` says how)."""

import ast
import importlib.util
import os
import sys
import traceback

from .._errors import LoadError, OptionError, UioJaxError, exit_message
from .._model.system import System


def load_system(spec, *args, **kwargs) -> System:
    """Load a System from ``"file.py:name"``, ``"model.toml"``/``"model.json"`` or a StrikePy module.

    * ``"path/to/file.py:name"``: ``name`` is a function returning a System (called with
      ``*args, **kwargs``) or a System object; the file is executed as a module named
      after it.
    * ``"path/to/model.toml"`` or ``.json``: a declarative model file
      (:func:`uio_jax.load_model_file`).
    * ``"path/to/model.py"`` (no ``:name``) that is a StrikePy model module
      (:func:`uio_jax.load_strikepy`; read, never executed).
    * ``"path/to/model.xml"`` or ``.sbml``: an SBML model; SBML declares no outputs or
      inputs, so the keyword arguments do: ``outputs={"y": "S1 + S2"}`` (or
      ``observables="observables.tsv"``, a PEtab table), ``known=``/``unknown=`` (ids that
      are inputs), ``fixed=`` (parameters fixed at a value), ``estimate=`` (compartments or
      boundary species to identify). Rules and defaults: ``docs/sbml.md``.

    Raises:
        LoadError: bad spec, missing file, file that fails to import, missing name,
            or a name that does not give a System.
        ModelError: a declarative model or StrikePy module with a bad entry, an SBML
            feature that is not supported.
        OptionError: an SBML model without outputs, or with an unknown id in its options.
    """
    if isinstance(spec, os.PathLike):
        spec = os.fspath(spec)
    if isinstance(spec, str):
        suffix = os.path.splitext(spec)[1].lower()
        if suffix in (".xml", ".sbml"):
            return _sbml(spec, args, kwargs)
        if suffix in (".toml", ".json"):
            if args or kwargs:
                raise LoadError(f"{spec}: a model file takes no arguments")
            from .model_file import load_model_file

            return load_model_file(spec)
        if suffix == ".py":
            from .strikepy_import import is_strikepy_module, load_strikepy

            if not os.path.isfile(spec):
                raise LoadError(f"model file not found: {spec} (give a Python model as FILE.py:NAME, "
                                "or the path of a StrikePy model module)")
            if is_strikepy_module(spec):
                if args or kwargs:
                    raise LoadError(f"{spec}: a StrikePy model takes no arguments")
                return load_strikepy(spec)
            offered = model_functions(spec)
            if offered and _is_zoo_file(spec):
                raise LoadError(f"{spec} is a zoo file, not a StrikePy model module; name one model as "
                                "FILE.py:NAME: "
                                + ", ".join(f"{spec}:{nm}" for nm in offered))
            defines = f" (it defines: {', '.join(offered)})" if offered else ""
            raise LoadError(f"{spec} is not a StrikePy model module (no sympy import or no top-level x, f, h): "
                            f"name the entry as FILE.py:NAME{defines}")
    path, name = split_spec(spec)
    module = load_module(path)
    if not hasattr(module, name):
        public = sorted(k for k in vars(module) if not k.startswith("_") and callable(vars(module)[k]))
        raise LoadError(f"{path} has no {name!r} (it defines: {', '.join(public) or 'nothing'})")
    obj = getattr(module, name)
    if callable(obj) and not isinstance(obj, System):
        obj = call_loaded(spec, obj, *args, **kwargs)
    if not isinstance(obj, System):
        raise LoadError(f"{spec} did not give a uio_jax.System (got {type(obj).__name__})")
    return obj if obj.name else obj.with_name(f"{os.path.basename(path)}:{name}")


def call_loaded(spec, fn, *args, **kwargs):
    """``fn(*args, **kwargs)``, a function of the model file named by ``spec``; what it raises
    becomes one line naming ``spec`` (a UioJaxError keeps its type, anything else, exit
    included, is a LoadError)."""
    try:
        return fn(*args, **kwargs)
    except UioJaxError as exc:
        raise type(exc)(f"{spec}: {exc}") from None
    except Exception as exc:
        raise LoadError(f"{spec} raised {one_line(exc)}") from None
    except SystemExit as exc:
        raise LoadError(f"{spec} {exit_message(exc)}") from None


def _sbml(spec, args, kwargs) -> System:
    """An SBML model with its declarations (keyword arguments only, checked by name)."""
    if args:
        raise LoadError(f"{spec}: an SBML model takes keyword arguments only (outputs=, known=, ...)")
    from .sbml_import import SBML_OPTIONS, load_sbml

    bad = [k for k in kwargs if k not in SBML_OPTIONS]
    if bad:
        raise OptionError(f"{spec}: unknown option {bad[0]!r} for an SBML model (options: "
                          f"{', '.join(SBML_OPTIONS)})")
    return load_sbml(spec, **kwargs)


def model_functions(path) -> list[str]:
    """Public top-level functions of a Python file, in file order, read without running it.

    The entries ``FILE.py:NAME`` a zoo file offers (``ast``: ``def`` statements at top level
    whose name does not start with ``_``); empty when the file cannot be read or parsed.
    """
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            tree = ast.parse(fh.read())
    except (OSError, SyntaxError, ValueError, RecursionError, MemoryError):
        return []
    return [node.name for node in tree.body
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and not node.name.startswith("_")]


def _is_zoo_file(path) -> bool:
    """Whether the file's first line is the zoo marker ``# uio-jax: models``."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            return fh.readline().strip().replace(" ", "") == "#uio-jax:models"
    except OSError:
        return False


def split_spec(spec: str) -> tuple[str, str]:
    """``"a/b.py:fn"`` -> ``("a/b.py", "fn")``, with a LoadError for a malformed spec."""
    if not isinstance(spec, str) or ":" not in spec:
        raise LoadError(f"model must be given as FILE.py:NAME, MODEL.toml, MODEL.json or a StrikePy "
                        f"MODEL.py, got {spec!r}")
    path, name = spec.rsplit(":", 1)
    if not path or not name.isidentifier():
        raise LoadError(f"model must be given as FILE.py:NAME, MODEL.toml, MODEL.json or a StrikePy "
                        f"MODEL.py, got {spec!r}")
    return path, name


def load_module(path: str):
    """Execute a Python file as a module (cached in ``sys.modules`` by absolute path)."""
    if not os.path.isfile(path):
        raise LoadError(f"model file not found: {path}")
    abspath = os.path.abspath(path)
    modname = "uio_jax_model_" + "".join(c if c.isalnum() else "_" for c in abspath)
    if modname in sys.modules:
        return sys.modules[modname]
    spec = importlib.util.spec_from_file_location(modname, abspath)
    if spec is None or spec.loader is None:
        raise LoadError(f"cannot load {path} as a Python module")
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except (Exception, SystemExit) as exc:  # a model file that calls sys.exit: an error too
        tb = traceback.extract_tb(exc.__traceback__)
        where = next((f" (line {f.lineno})" for f in reversed(tb) if f.filename == abspath), "")
        raise LoadError(
            f"model file {path} fails to load{where}: {one_line(exc)}"
        ) from None
    sys.modules[modname] = module
    return module


def one_line(exc, with_type=True) -> str:
    """The first line of an exception's message, after its type name unless ``with_type`` is
    False (then the type name only when the message is empty)."""
    text = str(exc).strip()
    first = text.splitlines()[0] if text else ""
    return f"{type(exc).__name__}: {first}" if with_type else (first or type(exc).__name__)
