"""Where the models of a batch are found: paths, globs, directories and zoo files expanded
into :class:`Entry` objects, one per model.

A path may be

* ``FILE.py:NAME``: one model, loaded as by :func:`uio_jax.load_system`;
* ``FILE.py``: a zoo file. Every public module-level function *defined in that file* (its
  ``__module__`` is the file's; respects ``__all__`` when the file sets it) that takes no
  required argument is **called** and kept when it returns a :class:`~uio_jax.System`
  (public module-level ``System`` objects count too), so a zoo file must keep its public
  no-argument functions free of side effects. Functions are skipped without being called
  when their name ends in ``_experiment`` (the zoo's Monte Carlo experiments) or their return
  annotation names another type; one that returns something else is listed in ``skipped``,
  one that raises is a failed model. With ``jobs > 1`` or a ``timeout`` the functions are
  called in the worker process that analyses their model; with a ``timeout`` the file is not
  even imported in the caller (:func:`listed_entries` reads it), so that top-level code that
  hangs or ends the process costs the rows of that file's models only. A StrikePy model
  module (:func:`uio_jax._io.strikepy_import.is_strikepy_module`) is one model;
* ``FILE.toml`` / ``FILE.json``: one model file, loaded by ``load_system(FILE)``;
* ``FILE.xml`` / ``FILE.sbml``: one SBML model, loaded by ``load_system(FILE, **sbml)`` with
  the batch's one rule of outputs and inputs (``sbml``, see :func:`discover`);
* a directory: every ``.py``, ``.toml``, ``.json``, ``.xml`` and ``.sbml`` file below it (recursively, sorted;
  names starting with ``_`` or ``.`` are ignored);
* a glob (``systems/*.py``, ``models/**/*.toml``): every match, as above.

**Which Python files are executed.** Importing a ``.py`` file runs its top-level code, so
discovery decides from the file's text alone (read, never imported) what to do with it:

1. a file with the marker line ``# uio-jax: models`` (:data:`ZOO_MARKER`; alone on one of
   its first :data:`MARKER_LINES` lines, spaces and case free) is a zoo file: imported;
2. otherwise a StrikePy model module is one model, *parsed* by
   :func:`uio_jax.load_strikepy` (never executed: a statement it does not interpret is
   the row's error);
3. otherwise a file the user named itself (``FILE.py`` given as a path, not found through
   a directory or a glob), or any file when ``import_python`` is True
   (``--import-python``), is a zoo file: imported;
4. any other ``.py`` file is not imported: it is listed in ``skipped`` with the reason.

``.toml`` and ``.json`` files are parsed, never executed; ``FILE.py:NAME`` is always a
file the user named.
"""

import ast
import glob
import inspect
import os
import re
import time
from dataclasses import dataclass, field, replace

from .._errors import OptionError, UioJaxError, exit_message
from .._io.loading import load_module, one_line, split_spec
from .._io.strikepy_import import is_strikepy_module
from .._model.system import System

#: Suffixes of model files collected from directories and globs.
MODEL_SUFFIXES = (".py", ".toml", ".json", ".xml", ".sbml")
#: The line that makes a ``.py`` file found in a directory or a glob a zoo file to import.
ZOO_MARKER = "# uio-jax: models"
#: The marker counts on one of a file's first lines (after a shebang, an encoding line...).
MARKER_LINES = 10
_MARKER_RE = re.compile(r"#\s*uio-jax\s*:\s*models\s*", re.I)
#: Why a ``.py`` file found in a directory or a glob was not imported.
NOT_IMPORTED = f"not imported: no {ZOO_MARKER!r} marker; name the file or pass --import-python"
_GLOB_CHARS = "*?["


@dataclass(frozen=True)
class Entry:
    """A model to run: its row label, how a process loads it, or why it cannot be.

    Attributes:
        label: the row's model name.
        spec: what a (worker) process loads; None: an in-memory System only.
        kind: ``"spec"`` (``FILE.py:NAME``), ``"file"`` (.toml/.json), ``"strikepy"`` or
            ``"system"`` (given as a System).
        system: the System, when built already.
        error: why the model cannot be run (then it is a failed row).
        build_s: seconds spent building ``system`` during discovery (added to the row).
        deferred: a zoo function not called yet: called where the model runs.
        options: keyword arguments of ``load_system`` (an SBML model's outputs and inputs).
    """

    label: str
    spec: str | None = None
    kind: str = "spec"
    system: System | None = field(default=None, repr=False)
    error: str | None = None
    build_s: float = 0.0
    deferred: bool = False
    options: dict | None = None


@dataclass(frozen=True)
class Skipped:
    """In place of a row: a deferred zoo function ``spec`` that gave no System (``why``)."""

    spec: str
    why: str


def discover(models, *, build: bool = True, import_python: bool = False, import_here: bool = True, sbml=None):
    """Expand paths, globs, directories and zoo files into models.

    Args:
        models: a path, a System, or a sequence of them (see :func:`uio_jax.batch_analyze`).
        import_python: import every ``.py`` file found in a directory or a glob that is not
            a StrikePy module, marked or not (see the module doc for the rule otherwise).
        build: call the zoo files' functions now (their Systems are then reused). False: a
            function that must be called to know what it builds is an entry marked
            ``deferred``, called where the model runs (a worker process), so that a parallel
            batch does not build every System twice.
        import_here: import the zoo files here to find their models (default). False (with
            ``build`` False; a batch with a time limit): a zoo file is *read* here
            (:func:`listed_entries`) and imported only in the worker that runs one of its
            models, under the limit.
        sbml: the keyword arguments of :func:`uio_jax.load_system` for every SBML file (one
            rule for all; None: each SBML model's row then says it declares no outputs).

    Returns:
        ``(entries, skipped)``: the :class:`Entry` of every model in order, and
        ``(name, reason)`` of zoo functions that gave no System and of the ``.py`` files
        not imported (reason :data:`NOT_IMPORTED`).

    Raises:
        OptionError: nothing given, or a path that matches nothing.
    """
    if isinstance(models, (str, os.PathLike, System)):
        models = [models]
    models = list(models)
    if not models:
        raise OptionError("no model given: pass files, directories, globs or FILE.py:NAME")
    entries, skipped = [], []
    for i, item in enumerate(models):
        if isinstance(item, System):
            entries.append(Entry(item.name or f"system {i + 1}", None, "system", item))
        elif isinstance(item, (str, os.PathLike)):
            item = os.fspath(item)
            named = _is_spec(item) or os.path.isfile(item)  # the user named this very file
            for path in expand(item):
                e, s = _entries_of(path, build, named or import_python, import_here, sbml)
                entries += e
                skipped += s
        else:
            raise OptionError(f"a model must be a path or a uio_jax.System, got {type(item).__name__}")
    return entries, skipped


def expand(item: str) -> list[str]:
    """The files (or the one ``FILE.py:NAME`` spec) named by a path, directory or glob.

    Raises:
        OptionError: a missing file, an empty directory, a glob that matches no model file.
    """
    if _is_spec(item):
        path = item.rpartition(":")[0]
        if not os.path.isfile(path):
            raise OptionError(f"model file not found: {path}")
        return [item]
    if any(c in item for c in _GLOB_CHARS) and not os.path.exists(item):
        files = []
        for m in sorted(glob.glob(item, recursive=True)):
            files += _dir_files(m) if os.path.isdir(m) else [m] if _is_model_file(m) else []
        if not files:
            raise OptionError(f"no model file matches {item!r}")
        return files
    if os.path.isdir(item):
        files = _dir_files(item)
        if not files:
            raise OptionError(f"no model file ({', '.join(MODEL_SUFFIXES)}) in directory {item}")
        return files
    if os.path.isfile(item):
        return [item]
    raise OptionError(f"no such file, directory or model: {item}")


def _is_spec(item: str) -> bool:
    """``FILE.py:NAME`` (an existing or missing file; NAME an identifier)."""
    path, sep, name = item.rpartition(":")
    return bool(sep) and bool(path) and name.isidentifier() and not os.path.exists(item)


def _is_model_file(path: str) -> bool:
    base = os.path.basename(path)
    return os.path.isfile(path) and base.endswith(MODEL_SUFFIXES) and not base.startswith(("_", "."))


def _dir_files(top: str) -> list[str]:
    out = []
    for root, dirs, files in os.walk(top):
        dirs[:] = sorted(d for d in dirs if not d.startswith(("_", ".")))
        out += [os.path.join(root, f) for f in sorted(files) if _is_model_file(os.path.join(root, f))]
    return out


def has_zoo_marker(path) -> bool:
    """Whether the file ``path`` declares itself a zoo file: a line ``# uio-jax: models``
    (:data:`ZOO_MARKER`, spaces and case free) among its first :data:`MARKER_LINES` lines.
    The file is read, never imported; an unreadable file has no marker."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for _, line in zip(range(MARKER_LINES), fh):
                if _MARKER_RE.fullmatch(line.strip()):
                    return True
    except OSError:
        return False
    return False


def _entries_of(path: str, build: bool = True, may_import: bool = True, import_here: bool = True, sbml=None):
    """Entries (and skipped functions or files) of one file or ``FILE.py:NAME`` spec;
    ``may_import``: an unmarked ``.py`` file that is no StrikePy module is imported (the
    user named it, or asked for every Python file) instead of skipped."""
    if _is_spec(path):
        return [Entry(path, path, "spec")], []
    if path.endswith((".toml", ".json")):
        return [Entry(path, path, "file")], []
    if path.lower().endswith((".xml", ".sbml")):
        return [Entry(path, path, "sbml", options=dict(sbml or {}))], []
    if not path.endswith(".py"):
        return [Entry(path, error=f"not a model file (expected {', '.join(MODEL_SUFFIXES)}): {path}")], []
    zoo_entries = _zoo_entries if import_here or build else listed_entries
    if has_zoo_marker(path):
        return zoo_entries(path, build)
    try:
        if is_strikepy_module(path):  # read as text: parsed later, never executed
            return [Entry(path, path, "strikepy")], []
    except Exception as exc:  # a broken file: report it as the zoo loader would
        return [Entry(path, error=one_line(exc))], []
    if not may_import:
        return [], [(path, NOT_IMPORTED)]
    return zoo_entries(path, build)


def _zoo_entries(path: str, build: bool = True):
    """Every System a zoo file's public no-argument functions build (calls them, or with
    ``build`` False marks them deferred)."""
    try:
        module = load_module(path)
    except UioJaxError as exc:
        return [Entry(path, error=str(exc))], []
    entries, skipped = [], []
    for name, obj in _public_items(module):
        spec = f"{path}:{name}"
        if isinstance(obj, System):
            entries.append(Entry(spec, spec, "spec", _named(obj, path, name)))
        elif _is_zoo_function(obj, module):
            why = _skip_without_calling(name, obj)
            if why:
                skipped.append((spec, why))
            elif not build:
                entries.append(Entry(spec, spec, "spec", deferred=True))
            else:
                _add_built(entries, skipped, spec, obj, path, name)
    if not entries and not skipped:
        return [Entry(path, error=f"{path} defines no public function that returns a uio_jax.System")], []
    return entries, skipped


def _public_items(module):
    """``(name, object)`` of a module's public names (its ``__all__`` when it sets one)."""
    names = getattr(module, "__all__", None)
    items = [(k, getattr(module, k, None)) for k in names] if names is not None else list(vars(module).items())
    return [(k, v) for k, v in items if not k.startswith("_")]


def _is_zoo_function(obj, module) -> bool:
    """A function defined in ``module`` that takes no required argument."""
    return inspect.isfunction(obj) and obj.__module__ == module.__name__ and _no_required_args(obj)


def _add_built(entries, skipped, spec, fn, path, name):
    """Call a zoo function: its System (or its error) is an entry, anything else skipped."""
    built, error, seconds = _call_zoo_function(spec, fn)
    if error is not None:
        entries.append(Entry(spec, spec, "spec", error=error, build_s=seconds))
    elif isinstance(built, System):
        entries.append(Entry(spec, spec, "spec", _named(built, path, name), build_s=seconds))
    else:
        skipped.append((spec, _no_system(built)))


def _call_zoo_function(spec, fn):
    """``(result, error, seconds)`` of calling a zoo function: its return value, or the
    one-line error of what it raised (then the result is None)."""
    t0 = time.perf_counter()
    try:
        return fn(), None, time.perf_counter() - t0
    except UioJaxError as exc:
        return None, f"{spec}: {exc}", time.perf_counter() - t0
    except Exception as exc:
        return None, f"{spec} raised {one_line(exc)}", time.perf_counter() - t0
    except SystemExit as exc:  # the batch goes on: an error row
        return None, f"{spec} {exit_message(exc)}", time.perf_counter() - t0


def _no_system(value) -> str:
    return f"returns {type(value).__name__}"


def build_deferred(entry: Entry):
    """Call the zoo function of a deferred entry: the entry with its System (or with the
    error), or a :class:`Skipped` when the function gives no System."""
    path, name = split_spec(entry.spec)
    try:
        module = load_module(path)
        fn = getattr(module, name)
    except (UioJaxError, AttributeError) as exc:
        return replace(entry, error=one_line(exc, with_type=False), deferred=False)
    if isinstance(fn, System):  # a module-level System named by listed_entries
        return replace(entry, system=_named(fn, path, name), deferred=False)
    if not _is_zoo_function(fn, module):
        return Skipped(entry.spec, f"not a function without required arguments ({type(fn).__name__})")
    built, error, seconds = _call_zoo_function(entry.spec, fn)
    if error is not None:
        return replace(entry, error=error, build_s=seconds, deferred=False)
    if not isinstance(built, System):
        return Skipped(entry.spec, _no_system(built))
    return replace(entry, system=_named(built, path, name), build_s=seconds, deferred=False)


def _no_required_args(fn) -> bool:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return False
    return all(p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
               for p in sig.parameters.values())


def _skip_without_calling(name, fn, annotation=None) -> str:
    """Why a zoo function is known not to build a System without calling it ('' if unknown);
    ``annotation``: its return annotation as text, when ``fn`` is not at hand (read from
    the file)."""
    if name.endswith("_experiment"):
        return "a Monte Carlo experiment (name ends in _experiment)"
    if annotation is None:
        ann = inspect.signature(fn).return_annotation
        if ann is inspect.Signature.empty or ann is None:
            return ""
        annotation = ann if isinstance(ann, str) else getattr(ann, "__name__", "")
    if annotation and annotation != "None" and "System" not in annotation:
        return f"annotated to return {annotation}"
    return ""


def _named(system, path, name):
    return system if system.name else system.with_name(f"{os.path.basename(path)}:{name}")


def listed_entries(path: str, build: bool = False):
    """The models of a zoo file found by reading it, not importing it: a deferred entry per
    public top-level ``def`` that takes no required argument, per public top-level
    ``NAME = ...System(...)`` and per ``NAME = factory(...)`` of a function defined in the file
    (``__all__`` respected when it is a literal list), in file order; names ending in
    ``_experiment`` and functions annotated to return another type
    are skipped as :func:`_zoo_entries` skips them. The worker that runs an entry imports
    the file (:func:`build_deferred`). ``build`` is unused (always deferred)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            tree = ast.parse(fh.read(), filename=path)
    except SyntaxError as exc:
        return [Entry(path, error=f"model file {path} fails to load (line {exc.lineno}): SyntaxError: "
                                  f"{exc.msg}")], []
    except (OSError, ValueError, RecursionError, MemoryError) as exc:
        return [Entry(path, error=f"model file {path} fails to load: {one_line(exc)}")], []
    public = _literal_all(tree)
    defined = {node.name for node in tree.body if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))}
    found = {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            args = node.args
            required = len(args.posonlyargs) + len(args.args) - len(args.defaults) + sum(
                d is None for d in args.kw_defaults)
            if required == 0:
                returns = ast.unparse(node.returns) if node.returns is not None else ""
                found[node.name] = _skip_without_calling(node.name, None, returns)
        elif isinstance(node, ast.Assign) and isinstance(node.value, ast.Call) and (
                "system" in ast.unparse(node.value.func).lower() or _local_call(node.value, defined)):
            found.update((t.id, "") for t in node.targets if isinstance(t, ast.Name))
    entries, skipped = [], []
    for name, why in found.items():
        if name.startswith("_") or (public is not None and name not in public):
            continue
        spec = f"{path}:{name}"
        if why:
            skipped.append((spec, why))
        else:
            entries.append(Entry(spec, spec, "spec", deferred=True))
    if not entries and not skipped:
        return [Entry(path, error=f"{path} defines no public top-level function without required "
                                  "arguments (read, not imported: with a time limit the workers "
                                  "import zoo files)")], []
    return entries, skipped


def _local_call(call, defined) -> bool:
    """Whether ``call`` calls a function defined at the top of the same file (a factory such
    as ``name = _alias("target", "doc")``, whose result a worker inspects: a function without
    required arguments or a System is a model, anything else is skipped)."""
    return isinstance(call.func, ast.Name) and call.func.id in defined


def _literal_all(tree):
    """The names of a literal ``__all__ = [...]`` at the top of a module, else None."""
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "__all__"
                                                for t in node.targets):
            try:
                return set(ast.literal_eval(node.value))
            except (ValueError, TypeError, SyntaxError, RecursionError):
                return None
    return None
