"""Batch certification: many models, one table (``uio-jax batch``, :func:`batch_analyze`).

**Where models are found.** A path may be

* ``FILE.py:NAME``: one model, loaded as by :func:`uio_jax.load_system`;
* ``FILE.py``: a zoo file. Every public module-level function *defined in that file* (its
  ``__module__`` is the file's; respects ``__all__`` when the file sets it) that takes no
  required argument is **called** and kept when it returns a :class:`~uio_jax.System`
  (public module-level ``System`` objects count too). Calling is the only way to know
  what a zoo function builds, so a zoo file must keep its public no-argument functions
  free of side effects. Functions are skipped without being called when their name ends
  in ``_experiment`` (the zoo's convention for Monte Carlo experiments, see
  :func:`uio_jax.load_experiment`) or their return annotation names another type.
  A function that returns something else is skipped (listed in ``skipped``); one that
  raises is a failed model. With ``jobs > 1`` or a ``timeout`` the functions are called
  in the worker process that analyses their model, not in the caller first. A StrikePy
  model module (recognised by ``uio_jax._strikepy_import.is_strikepy_module``, when that
  importer is installed) is one model;
* ``FILE.toml`` / ``FILE.json``: one model file, loaded by ``load_system(FILE)``;
* a directory: every ``.py``, ``.toml`` and ``.json`` file below it (recursively, sorted;
  names starting with ``_`` or ``.`` are ignored);
* a glob (``systems/*.py``, ``models/**/*.toml``): every match, as above.

**What is reused between models.** Compiled generator evaluators are cached per System
(:mod:`uio_jax._generators`): two models are two Systems built from distinct Python
closures, so even models of the same shape trace and compile their own Lie derivatives in
memory. Shared across models of the same sample count and dimensions are only the rank
kernels (module-level ``jax.jit`` functions of :mod:`uio_jax._rank`). Across processes,
with the caches on (:func:`uio_jax.enable_compile_cache`, the command line's default), every
analysis program is loaded from the program cache (:mod:`uio_jax._program_cache`, keyed by
the model's own jaxprs and the generator structure, no tracing) and the small shared
kernels from JAX's persistent compilation cache: a second run of the same batch evaluates
only.

**Parallel runs and time limits.** ``jobs > 1`` analyses models in that many worker
processes (spawned, each with its own JAX; they use the persistent cache directory of the
caller), one model at a time each, each worker bound to one CPU (worker k to the k-th
allowed CPU, cyclically; one worker alone keeps them all): JAX's thread pools then do not
oversubscribe the cores (on 2 cores, 2 jobs: 66-68 s -> 53-55 s for the warm batch of 67
models). With ``timeout``, a model that runs too long has its
worker killed (its row says so) and a fresh worker goes on with the others. Only models
given by path can go to a worker; ``System`` objects run in the calling process.

**Longest first.** With a cache directory, every batch records each model's time in
``batch_seconds.json`` there (keyed by the model's spec and the analysis options); the
workers of a later batch take the models in decreasing order of their recorded time
(models without one first, in the order given): one long model started last would leave
the other workers idle at the end. The rows keep the order the models were given.
"""

import csv
import inspect
import io
import json
import math
import numbers
import os
import sys
import time
from dataclasses import dataclass, field, replace

from .._errors import LoadError, OptionError, UioJaxError
from .._model.system import System
from .._progress import is_terminal

#: Suffixes of model files collected from directories and globs.
MODEL_SUFFIXES = (".py", ".toml", ".json")
_GLOB_CHARS = "*?["


@dataclass(frozen=True)
class BatchRow:
    """One model of a batch: its verdict, certificate and time, or its error.

    Attributes:
        model: the model's name (``FILE.py:NAME``, the model file, or the System's name).
        method: analysis that ran (None when the model failed before it).
        n: dimension of the analysed vector (states, plus parameters when there are any).
        dim: generic dimension of the observable codistribution.
        observable: names of the observable state components.
        params: names of the unknown constant parameters (empty when none).
        identifiable: names of the identifiable parameters.
        fraction: fraction of the samples at the generic rank (``certificate.fraction``).
        gap_decades: margin of the weakest rank decision, ``log10(sigma_r_min /
            sigma_next_max)`` (``certificate.gap_decades``; inf when nothing was rejected).
        seconds: wall time of building/loading plus analysing the model, in seconds.
        error: the one-line error of a failed model, None when it passed.
        report: the :class:`~uio_jax.Report` (None for a failed model, with
            ``keep_reports=False``, or when the model ran in a worker process).
    """

    model: str
    method: str | None = None
    n: int | None = None
    dim: int | None = None
    observable: tuple[str, ...] = ()
    params: tuple[str, ...] = ()
    identifiable: tuple[str, ...] = ()
    fraction: float | None = None
    gap_decades: float | None = None
    seconds: float = 0.0
    error: str | None = None
    report: object = field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        """True when the model was analysed."""
        return self.error is None

    @property
    def unobservable(self) -> int | None:
        """Number of unobservable directions, ``n - dim`` (None for a failed model)."""
        return None if self.n is None or self.dim is None else self.n - self.dim

    def to_dict(self) -> dict:
        """JSON-ready dictionary (no report; inf/NaN as strings)."""
        d = {
            "model": self.model, "ok": self.ok, "method": self.method, "n": self.n,
            "dim": self.dim, "unobservable": self.unobservable,
            "observable": list(self.observable), "params": list(self.params),
            "identifiable": list(self.identifiable), "fraction": _num(self.fraction),
            "gap_decades": _num(self.gap_decades), "seconds": round(self.seconds, 4),
            "error": self.error,
        }
        return d


@dataclass(frozen=True)
class BatchResult:
    """Result of :func:`batch_analyze`: a sequence of :class:`BatchRow` (iterate, index, len).

    Attributes:
        rows: one row per model, in the order the models were given/found.
        skipped: ``(name, reason)`` of the public functions of zoo files that gave no System.
        seconds: wall time of the whole batch (s).
        options: the analysis options used (method, samples, seed, ...).
    """

    rows: tuple[BatchRow, ...]
    skipped: tuple[tuple[str, str], ...] = ()
    seconds: float = 0.0
    options: dict = field(default_factory=dict)

    def __iter__(self):
        return iter(self.rows)

    def __len__(self):
        return len(self.rows)

    def __getitem__(self, i):
        return self.rows[i]

    @property
    def failed(self) -> tuple[BatchRow, ...]:
        """Rows of the models that failed."""
        return tuple(r for r in self.rows if not r.ok)

    @property
    def ok(self) -> bool:
        """True when every model was analysed."""
        return not self.failed

    def to_dict(self) -> dict:
        """JSON-ready dictionary: ``models`` (rows), ``skipped``, ``options``, ``seconds``."""
        return {
            "models": [r.to_dict() for r in self.rows],
            "failed": len(self.failed),
            "skipped": [{"name": n, "reason": why} for n, why in self.skipped],
            "options": dict(self.options),
            "seconds": round(self.seconds, 3),
        }

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)

    def to_csv(self) -> str:
        """CSV text, one line per model (lists joined by ``;``)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        cols = ["model", "ok", "method", "n", "dim", "unobservable", "observable", "params",
                "identifiable", "fraction", "gap_decades", "seconds", "error"]
        writer.writerow(cols)
        for r in self.rows:
            d = r.to_dict()
            writer.writerow(["" if d[c] is None else ";".join(d[c]) if isinstance(d[c], list) else d[c]
                             for c in cols])
        return buf.getvalue()

    def to_markdown(self) -> str:
        """A Markdown table (failed models carry their error in the last column)."""
        headers, body = self._cells(markdown=True)
        lines = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
        lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in body]
        return "\n".join(lines) + "\n"

    def table(self) -> str:
        """The table for a terminal: aligned columns, then one line per failed model's error."""
        headers, body = self._cells(markdown=False)
        widths = [max(len(h), *(len(row[i]) for row in body)) if body else len(h)
                  for i, h in enumerate(headers)]
        right = {"dim / n", "unobs.", "fraction", "gap (dec.)", "time (s)"}

        def fmt(cells):
            out = [c.rjust(w) if h in right else c.ljust(w) for c, w, h in zip(cells, widths, headers)]
            return "  ".join(out).rstrip()

        lines = [fmt(headers), fmt(["-" * w for w in widths])]
        lines += [fmt(row) for row in body]
        return "\n".join(lines)

    def summary(self) -> str:
        """One line: models passed / failed, total time, functions skipped."""
        n_fail = len(self.failed)
        text = (f"{len(self.rows) - n_fail} of {len(self.rows)} models analysed"
                + (f", {n_fail} failed" if n_fail else "") + f" in {self.seconds:.1f} s")
        if self.skipped:
            text += (f"; {len(self.skipped)} function{'s' if len(self.skipped) != 1 else ''} "
                     "giving no System skipped")
        return text

    def _cells(self, markdown):
        has_params = any(r.params for r in self.rows)
        headers = ["model", "method", "dim / n", "observable states"]
        if has_params:
            headers.append("identifiable params")
        headers += ["unobs.", "fraction", "gap (dec.)", "time (s)", "error" if markdown else "status"]
        body = []
        for r in self.rows:
            if not r.ok:
                cells = [r.model, r.method or "-", "-", "-"] + (["-"] if has_params else [])
                cells += ["-", "-", "-", f"{r.seconds:.2f}", f"FAILED: {r.error}"]
            else:
                cells = [r.model, r.method, f"{r.dim} / {r.n}", _names(r.observable, r.n - len(r.params))]
                if has_params:
                    cells.append(_names(r.identifiable, len(r.params)) if r.params else "-")
                cells += [str(r.unobservable), _pct(r.fraction), _gap(r.gap_decades), f"{r.seconds:.2f}",
                          "" if markdown else "ok"]
            body.append(cells)
        return headers, body


def batch_analyze(models, *, jobs: int = 1, timeout=None, progress=None, keep_reports: bool = True,
                  **analyze_kwargs) -> BatchResult:
    """Analyse many models; one failing model is one row with its error, the others go on.

    Main arguments:
        models: a path, a :class:`~uio_jax.System`, or a sequence of them. Paths are
            ``FILE.py:NAME``, zoo files ``FILE.py`` (every public no-argument function
            that returns a System; see the module docstring for how they are found),
            ``.toml``/``.json`` model files, directories and globs.

    Other arguments:
        jobs: worker processes (default 1: everything in this process). Workers are
            spawned fresh and pay JAX's start-up; they share the persistent compilation
            cache of this process if one is enabled.
        timeout: seconds one model may run (None, the default: no limit). With a limit,
            models given by path run in worker processes (``jobs`` of them, at least
            one); a model over the limit has its worker killed, its row says "timed
            out", and a fresh worker takes the next model. ``System`` objects given
            directly run in this process, without a limit.
        progress: ``True`` shows a model-count bar on stderr, ``False`` never, ``None``
            (default) only on a terminal and once the batch has lasted 2 s.
        keep_reports: keep each model's :class:`~uio_jax.Report` in ``row.report``
            (False frees each model's compiled functions as soon as it is done).
        **analyze_kwargs: passed to :func:`uio_jax.analyze` (``method``, ``samples``,
            ``seed``, ``rtol``, ``max_order``, ``k_max``).

    Returns:
        :class:`BatchResult`, a sequence of :class:`BatchRow` in the order the models
        were given (zoo files in the order their functions are defined).

    Raises:
        OptionError: no model given, a path that matches nothing, impossible options.
    """
    t0 = time.perf_counter()
    _check_options(jobs, analyze_kwargs)
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, numbers.Real)
                                or not timeout > 0):
        raise OptionError(f"timeout must be a positive number of seconds, got {timeout!r}")
    # models that may run in worker processes are built there: not here first as well
    entries, skipped = discover(models, build=jobs == 1 and timeout is None)
    keys = [_time_key(e, analyze_kwargs) for e in entries]
    bar = _BatchProgress(len(entries), enabled=progress)
    try:
        remote = sum(e.spec is not None and e.error is None for e in entries)
        if (jobs > 1 and remote > 1) or (timeout is not None and remote):
            rows = _run_parallel(entries, jobs, timeout, analyze_kwargs, bar, _recorded_seconds(keys))
        else:
            rows = []
            for i, e in enumerate(entries):
                bar.start(e.label)
                rows.append(_run_entry(e, analyze_kwargs, keep_reports))
                entries[i] = e = None  # without its report, the System and its compiled code can go
                bar.finish()
    finally:
        bar.close()
    _record_seconds(keys, rows)
    rows, skipped = _move_skipped(rows, skipped)
    options = {k: v for k, v in analyze_kwargs.items() if v is not None}
    return BatchResult(tuple(rows), tuple(skipped), time.perf_counter() - t0, options)


def _move_skipped(rows, skipped):
    """Deferred zoo functions that gave no System leave the rows for ``skipped`` (after
    the functions skipped without being called)."""
    late = [(row.spec, row.why) for row in rows if isinstance(row, _Skipped)]
    return [r for r in rows if not isinstance(r, _Skipped)], list(skipped) + late


# ---------------------------------------------------------------------------- discovery
@dataclass(frozen=True)
class _Entry:
    """A model to run: its row label, how a process loads it, or why it cannot be."""

    label: str
    spec: str | None = None  # what a (worker) process loads; None: in-memory System only
    kind: str = "spec"  # "spec" (FILE.py:NAME), "file" (.toml/.json), "strikepy"
    system: System | None = field(default=None, repr=False)
    error: str | None = None
    build_s: float = 0.0  # time spent building ``system`` during discovery (added to the row)
    deferred: bool = False  # a zoo function not called yet: called where the model runs


@dataclass(frozen=True)
class _Skipped:
    """In place of a row: a deferred zoo function that gave no System."""

    spec: str
    why: str


def discover(models, *, build: bool = True):
    """Expand paths, globs, directories and zoo files into models.

    Args:
        models: a path, a System, or a sequence of them (see :func:`batch_analyze`).
        build: call the zoo files' functions now (their Systems are then reused). False:
            a function that must be called to know what it builds is an entry marked
            ``deferred``, called where the model runs (a worker process); one that gives
            no System then turns into a skipped function. A parallel batch of the zoo and
            StrikePy's models spent 19 s here, before its workers started, building
            Systems the workers built again.

    Returns:
        ``(entries, skipped)``: the models in order, and ``(name, reason)`` of zoo
        functions that gave no System.

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
            entries.append(_Entry(item.name or f"system {i + 1}", None, "system", item))
        elif isinstance(item, (str, os.PathLike)):
            for path in _expand(os.fspath(item)):
                e, s = _entries_of(path, build)
                entries += e
                skipped += s
        else:
            raise OptionError(f"a model must be a path or a uio_jax.System, got {type(item).__name__}")
    return entries, skipped


def _expand(item: str) -> list[str]:
    """Files (or one ``FILE.py:NAME`` spec) named by a path, directory or glob."""
    if _is_spec(item):
        path = item.rpartition(":")[0]
        if not os.path.isfile(path):
            raise OptionError(f"model file not found: {path}")
        return [item]
    if any(c in item for c in _GLOB_CHARS) and not os.path.exists(item):
        import glob

        matches = sorted(glob.glob(item, recursive=True))
        files = []
        for m in matches:
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


def _entries_of(path: str, build: bool = True):
    """Entries (and skipped functions) of one file or ``FILE.py:NAME`` spec."""
    if _is_spec(path):
        return [_Entry(path, path, "spec")], []
    if path.endswith((".toml", ".json")):
        return [_Entry(path, path, "file")], []
    if not path.endswith(".py"):
        return [_Entry(path, error=f"not a model file (expected {', '.join(MODEL_SUFFIXES)}): {path}")], []
    strikepy = _strikepy()
    if strikepy is not None:
        try:
            if strikepy.is_strikepy_module(path):
                return [_Entry(path, path, "strikepy")], []
        except Exception as exc:  # a broken file: report it as the zoo loader would
            return [_Entry(path, error=_one_line(exc))], []
    return _zoo_entries(path, build)


def _zoo_entries(path: str, build: bool = True):
    """Every System a zoo file's public no-argument functions build (calls them, or with
    ``build`` False marks them deferred)."""
    from .._io.loading import load_module

    try:
        module = load_module(path)
    except UioJaxError as exc:
        return [_Entry(path, error=str(exc))], []
    names = getattr(module, "__all__", None)
    items = [(k, getattr(module, k, None)) for k in names] if names is not None else list(vars(module).items())
    entries, skipped = [], []
    for name, obj in items:
        if name.startswith("_"):
            continue
        spec = f"{path}:{name}"
        if isinstance(obj, System):
            entries.append(_Entry(spec, spec, "spec", _named(obj, path, name)))
            continue
        if not inspect.isfunction(obj) or obj.__module__ != module.__name__ or not _no_required_args(obj):
            continue
        why = _skip_without_calling(name, obj)
        if why:
            skipped.append((spec, why))
            continue
        if not build:
            entries.append(_Entry(spec, spec, "spec", deferred=True))
            continue
        built, error, seconds = _call_zoo_function(spec, obj)
        if error is not None:
            entries.append(_Entry(spec, spec, "spec", error=error, build_s=seconds))
        elif isinstance(built, System):
            entries.append(_Entry(spec, spec, "spec", _named(built, path, name), build_s=seconds))
        else:
            skipped.append((spec, _no_system(built)))
    if not entries and not skipped:
        return [_Entry(path, error=f"{path} defines no public function that returns a uio_jax.System")], []
    return entries, skipped


def _call_zoo_function(spec, fn):
    """``(result, error, seconds)`` of calling a zoo function: its return value, or the
    one-line error of what it raised (then the result is None)."""
    t0 = time.perf_counter()
    try:
        return fn(), None, time.perf_counter() - t0
    except UioJaxError as exc:
        return None, f"{spec}: {exc}", time.perf_counter() - t0
    except Exception as exc:
        return None, f"{spec} raised {_one_line(exc)}", time.perf_counter() - t0


def _no_system(value) -> str:
    return f"returns {type(value).__name__}"


def _build_deferred(entry: _Entry):
    """Call a deferred zoo function: ``(entry with its System, or with the error)``, or a
    :class:`_Skipped` when it gives no System."""
    from .._io.loading import load_module, split_spec

    path, name = split_spec(entry.spec)
    try:
        fn = getattr(load_module(path), name)
    except (UioJaxError, AttributeError) as exc:
        return replace(entry, error=_one_line(exc, with_type=False), deferred=False)
    built, error, seconds = _call_zoo_function(entry.spec, fn)
    if error is not None:
        return replace(entry, error=error, build_s=seconds, deferred=False)
    if not isinstance(built, System):
        return _Skipped(entry.spec, _no_system(built))
    return replace(entry, system=_named(built, path, name), build_s=seconds, deferred=False)


def _no_required_args(fn) -> bool:
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return False
    return all(p.default is not p.empty or p.kind in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
               for p in sig.parameters.values())


def _skip_without_calling(name, fn) -> str:
    """Why a zoo function is known not to build a System without calling it ('' if unknown)."""
    if name.endswith("_experiment"):
        return "a Monte Carlo experiment (name ends in _experiment)"
    ann = inspect.signature(fn).return_annotation
    if ann is inspect.Signature.empty or ann is None:
        return ""
    text = ann if isinstance(ann, str) else getattr(ann, "__name__", "")
    if text and "System" not in text:
        return f"annotated to return {text}"
    return ""


def _named(system, path, name):
    if not system.name:
        object.__setattr__(system, "name", f"{os.path.basename(path)}:{name}")
    return system


def _strikepy():
    """The StrikePy importer module, or None while it is not part of this uio_jax."""
    if not _has_module("_strikepy_import"):
        return None
    from .._io import strikepy_import as _strikepy_import

    return _strikepy_import if hasattr(_strikepy_import, "is_strikepy_module") else None


# ---------------------------------------------------------------------------- running
def _load(entry: _Entry) -> System:
    """The System of an entry (built already, or loaded from its spec by ``load_system``)."""
    if entry.system is not None:
        return entry.system
    from .._io.loading import load_system

    if entry.kind == "strikepy" and _strikepy() is None:
        raise LoadError(f"{entry.spec}: StrikePy models are not supported by this version of uio_jax")
    if entry.kind == "file" and not _has_module("_model_file"):
        raise LoadError(f"{entry.spec}: .toml/.json model files are not supported by this version of uio_jax")
    return load_system(entry.spec)


def _has_module(name) -> bool:
    import importlib.util

    return importlib.util.find_spec(f"{__package__}.{name}") is not None


def _run_entry(entry: _Entry, analyze_kwargs, keep_report=True) -> BatchRow:
    """Load and analyse one model; every error becomes the row's one-line error."""
    from .._analysis.analyze import analyze

    if entry.deferred:
        entry = _build_deferred(entry)
        if isinstance(entry, _Skipped):
            return entry
    t0 = time.perf_counter() - entry.build_s
    if entry.error is not None:
        return BatchRow(entry.label, error=entry.error, seconds=entry.build_s)
    try:
        rep = analyze(_load(entry), **analyze_kwargs)
    except UioJaxError as exc:
        return BatchRow(entry.label, error=_one_line(exc, with_type=False), seconds=time.perf_counter() - t0)
    except Exception as exc:  # a bug or a model that breaks JAX: one row, the batch goes on
        return BatchRow(entry.label, error=_one_line(exc), seconds=time.perf_counter() - t0)
    return _row(entry.label, rep, time.perf_counter() - t0, rep if keep_report else None)


def _row(label, rep, seconds, report=None) -> BatchRow:
    """A row from a Report."""
    params = tuple(getattr(rep, "params", ()) or ())
    ident = getattr(rep, "identifiable", {}) or {}
    cert = rep.certificate
    fraction, gap = float(cert.fraction), float(cert.gap_decades)
    error = None
    if math.isnan(fraction) or math.isnan(gap):
        error = "the certificate is NaN (no usable sample?)"
    return BatchRow(
        model=label, method=rep.method, n=rep.n, dim=rep.dim,
        observable=tuple(s for s, ok in rep.observable.items() if ok),
        params=params, identifiable=tuple(p for p in params if ident.get(p)),
        fraction=fraction, gap_decades=gap, seconds=seconds, error=error, report=report,
    )


def _run_parallel(entries, jobs, timeout, analyze_kwargs, bar, recorded=()):
    """Entries with a spec go to worker processes (longest recorded time first, see
    :func:`_longest_first`); in-memory Systems and known errors run here."""
    rows = [None] * len(entries)
    remote = [i for i, e in enumerate(entries) if e.spec is not None and e.error is None]
    local = set(range(len(entries))) - set(remote)
    for i, e in enumerate(entries):
        if i in local:
            bar.start(e.label)
            rows[i] = _run_entry(e, analyze_kwargs, keep_report=False)
            bar.finish()
    _run_in_workers(entries, _longest_first(remote, recorded), jobs, timeout, analyze_kwargs, bar, rows)
    return rows


#: File in the cache directory with each model's last batch time in seconds.
_SECONDS_FILE = "batch_seconds.json"


def _time_key(entry, analyze_kwargs):
    """Key of a model's recorded time: its spec and the analysis options (None: in-memory)."""
    if entry.spec is None or entry.error is not None:
        return None
    opts = ",".join(f"{k}={v!r}" for k, v in sorted(analyze_kwargs.items()) if v is not None)
    return f"{entry.kind}|{entry.spec}|{opts}"


def _seconds_path():
    from .._engine.compile_cache import cache_dir_in_use

    d = cache_dir_in_use()
    return None if d is None else os.path.join(d, _SECONDS_FILE)


def _read_seconds(path):
    """The recorded times (a dict); empty without a cache directory, a file, or a valid one."""
    try:
        with open(path, encoding="utf-8") as f:
            known = json.load(f)
    except (TypeError, OSError, ValueError):
        return {}
    return known if isinstance(known, dict) else {}


def _recorded_seconds(keys):
    """Recorded time of each key (None: unknown)."""
    known = _read_seconds(_seconds_path())
    out = []
    for k in keys:
        v = known.get(k) if k is not None else None
        out.append(float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None)
    return out


def _record_seconds(keys, rows):
    """Add this batch's times to the file in the cache directory (atomic replace; a cache
    directory that cannot be written only loses the ordering of the next batch)."""
    path = _seconds_path()
    if path is None:
        return
    known = _read_seconds(path)
    for k, row in zip(keys, rows):
        if k is not None and isinstance(row, BatchRow):
            known[k] = round(float(row.seconds), 3)
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(known, f, indent=0, sort_keys=True)
        os.replace(tmp, path)
    except OSError:
        try:
            os.remove(tmp)
        except OSError:
            pass


def _longest_first(todo, recorded):
    """``todo`` (entry indices) reordered: unknown times first in the given order, then
    decreasing recorded time (a stable sort)."""
    if not recorded:
        return list(todo)
    return sorted(todo, key=lambda i: -math.inf if recorded[i] is None else -recorded[i])


def _run_in_workers(entries, todo, jobs, timeout, analyze_kwargs, bar, rows):
    """Run ``entries[i]`` for ``i in todo`` in ``jobs`` spawned worker processes.

    Each worker takes one model at a time through a pipe (its clock starts when the model is
    sent, after the worker has imported JAX and said it is ready). A model that runs longer
    than ``timeout`` seconds (None: no limit) has its worker killed and gets a row saying
    so; a worker that dies (memory, signal) gives its model a row with the exit code. A
    fresh worker replaces a killed or dead one, so the other models go on.
    """
    import multiprocessing
    from multiprocessing.connection import wait

    from .._engine.compile_cache import cache_dir_in_use

    ctx = multiprocessing.get_context("spawn")
    cache_dir = cache_dir_in_use()
    pending = list(todo)[::-1]  # popped from the end: in order
    slots = [None] * min(jobs, len(pending))

    def finish(i, row):
        rows[i] = row
        bar.finish(entries[i].label)

    try:
        while True:
            for k, w in enumerate(slots):
                if w is None and pending:
                    slots[k] = w = _Worker(ctx, cache_dir, k if len(slots) > 1 else None)
                if w is not None and w.task is None and w.ready and pending:
                    i = pending.pop()
                    e = entries[i]
                    w.send(i, (e.label, e.spec, e.kind, analyze_kwargs, e.deferred))
                    bar.start(e.label)
            live = [w for w in slots if w is not None and (w.task is not None or not w.ready)]
            if not live:
                break
            deadlines = [w.since + timeout - time.monotonic() for w in live
                         if timeout is not None and w.task is not None]
            ready = wait([w.conn for w in live], max(0.0, min(deadlines)) if deadlines else None)
            for k, w in enumerate(slots):
                if w not in live:
                    continue
                if w.conn in ready:
                    msg = w.receive()
                    if msg is _Worker.DIED:
                        code = w.stop()
                        slots[k] = None
                        if w.task is None:  # died while starting: the others would too
                            while pending:
                                i = pending.pop()
                                finish(i, BatchRow(entries[i].label,
                                                   error=f"batch worker process failed to start (exit code {code})"))
                        else:
                            finish(w.task, BatchRow(entries[w.task].label, seconds=w.elapsed(),
                                                    error=f"worker process died (exit code {code})"))
                    elif msg == "ready":
                        w.ready = True
                    else:
                        skip = msg.get("skipped")
                        finish(w.task, _Skipped(entries[w.task].spec, skip) if skip else BatchRow(**msg))
                        w.task = None
                elif w.task is not None and timeout is not None and w.elapsed() >= timeout:
                    w.stop()
                    slots[k] = None
                    finish(w.task, BatchRow(entries[w.task].label, seconds=w.elapsed(),
                                            error=f"timed out after {timeout:g} s (worker stopped)"))
    finally:
        for w in slots:
            if w is not None:
                w.close()


class _Worker:
    """One spawned analysis process and the parent's end of its pipe."""

    DIED = object()

    def __init__(self, ctx, cache_dir, slot=None):
        self.conn, there = ctx.Pipe()
        self.proc = ctx.Process(target=_worker_main, args=(there, cache_dir, slot), daemon=True)
        self.proc.start()
        there.close()
        self.ready = False
        self.task = None  # index of the entry being analysed
        self.since = time.monotonic()

    def send(self, i, task):
        self.conn.send(task)
        self.task, self.since = i, time.monotonic()

    def elapsed(self) -> float:
        return time.monotonic() - self.since

    def receive(self):
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            return self.DIED

    def stop(self):
        """Kill the process; returns its exit code."""
        if self.proc.is_alive():
            self.proc.kill()
        self.proc.join()
        self.conn.close()
        return self.proc.exitcode

    def close(self):
        """Ask the process to finish (it is idle), else kill it."""
        try:
            if self.task is None and self.ready:
                self.conn.send(None)
                self.proc.join(timeout=5)
        except (OSError, ValueError):
            pass
        self.stop()


def _worker_main(conn, cache_dir, slot=None):
    """A worker process: set up the caches, say ready, then analyse models until told to stop."""
    _pin_to_one_cpu(slot)
    _worker_init(cache_dir)
    conn.send("ready")
    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send(_worker_run(*task))


def _pin_to_one_cpu(slot):
    """Bind this worker to one CPU of those allowed (slot ``k`` -> the k-th, cyclically),
    before JAX starts its thread pool, so that it sizes the pool to that one CPU.

    Unpinned, every worker's XLA runs its large operations on a pool as wide as the machine
    and ``jobs`` workers oversubscribe the cores: on 2 cores the warm batch of the 67 zoo
    and StrikePy models took 66-68 s with 2 jobs, 110-115 CPU-s; pinned 53-55 s, 90-93 CPU-s.
    A single worker (``slot`` None) keeps every CPU. Where the platform cannot pin (no
    ``os.sched_setaffinity``), nothing happens.
    """
    if slot is None or not hasattr(os, "sched_setaffinity"):
        return
    try:
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {cpus[slot % len(cpus)]})
    except OSError:  # pragma: no cover - a container that forbids it: run unpinned
        pass


def _worker_init(cache_dir):
    """Set up a worker: the caller's persistent cache directory, if any."""
    if cache_dir:
        from .._engine.compile_cache import enable_compile_cache

        enable_compile_cache(cache_dir)


def _worker_run(label, spec, kind, analyze_kwargs, deferred=False) -> dict:
    """Analyse one model in a worker; returns the row's fields (no Report), or
    ``{"skipped": reason}`` for a deferred zoo function that gave no System."""
    row = _run_entry(_Entry(label, spec, kind, deferred=deferred), analyze_kwargs, keep_report=False)
    if isinstance(row, _Skipped):
        return {"skipped": row.why}
    return {k: getattr(row, k) for k in BatchRow.__dataclass_fields__ if k != "report"}


def _check_options(jobs, kw):
    """Options that would make every model fail: refused before any model runs."""
    if isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral) or jobs < 1:
        raise OptionError(f"jobs must be a positive integer, got {jobs!r}")
    from .._analysis.analyze import METHODS

    unknown = set(kw) - {"method", "samples", "seed", "rtol", "max_order", "k_max"}
    if unknown:
        raise OptionError(f"unknown analysis option {sorted(unknown)[0]!r}")
    if kw.get("method", "auto") not in METHODS:
        raise OptionError(f"unknown method {kw['method']!r}; choose one of {', '.join(METHODS)}")
    samples, seed = kw.get("samples", 8), kw.get("seed", 0)
    if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) or samples < 8:
        raise OptionError(f"samples must be an integer >= 8, got {samples!r}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise OptionError(f"seed must be a non-negative integer, got {seed!r}")
    rtol = kw.get("rtol")
    if rtol is not None and not (isinstance(rtol, numbers.Real) and 0 < rtol < 1):
        raise OptionError(f"rtol must be a number in (0, 1), got {rtol!r}")


# ---------------------------------------------------------------------------- progress
class _BatchProgress:
    """Model-count progress bar on stderr: ``batch [###---] 3/12  running NAME  ETA 40 s``.

    ``enabled=None`` shows it only when the stream is a terminal and the batch has lasted
    ``delay`` seconds; the line is redrawn when a model starts and when it ends.
    """

    def __init__(self, total, *, enabled=None, delay=2.0, stream=None):
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            enabled = is_terminal(self.stream)
        self.enabled = bool(enabled) and total > 0
        self.total, self.delay, self.done = total, delay, 0
        self.t0 = time.perf_counter()
        self.shown = False
        self.width = 0

    def start(self, label):
        """A model starts (drawn only once the bar is due)."""
        self._draw(f"running {label}")

    def finish(self, label=None):
        """A model is done."""
        self.done += 1
        self._draw(f"done {label}" if label else "")

    def _draw(self, what):
        elapsed = time.perf_counter() - self.t0
        if not self.enabled or (not self.shown and elapsed < self.delay):
            return
        self.shown = True
        frac = self.done / self.total
        fill = int(round(20 * frac))
        eta = f"  ETA {elapsed / self.done * (self.total - self.done):4.0f} s" if self.done else ""
        line = f"batch [{'#' * fill}{'-' * (20 - fill)}] {self.done}/{self.total}{eta}  {what}"
        line = line[:110]
        self.stream.write("\r" + line.ljust(self.width))
        self.width = len(line)
        self.stream.flush()

    def close(self):
        """Clear the bar's line (if it was shown)."""
        if self.shown:
            self.stream.write("\r" + " " * self.width + "\r")
            self.stream.flush()


# ---------------------------------------------------------------------------- formatting
def _one_line(exc, with_type=True) -> str:
    text = str(exc).strip()
    first = text.splitlines()[0] if text else ""
    return f"{type(exc).__name__}: {first}" if with_type else (first or type(exc).__name__)


def _names(names, total) -> str:
    if total and len(names) == total:
        return "all"
    return ", ".join(names) if names else "none"


def _pct(x) -> str:
    return "-" if x is None else f"{100 * x:.1f}%"


def _gap(x) -> str:
    if x is None:
        return "-"
    return "inf" if math.isinf(x) else f"{x:.1f}"


def _num(x):
    if x is None:
        return None
    return x if math.isfinite(x) else str(x)
