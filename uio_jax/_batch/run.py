"""Batch certification: many models, one table (``uio-jax batch``, :func:`batch_analyze`).

**What is reused between models.** Compiled generator evaluators are cached per System
(:mod:`uio_jax._calculus.generators`): two models are two Systems built from distinct
Python closures, so even models of the same shape trace and compile their own Lie
derivatives in memory. Shared across models of the same sample count and dimensions are
only the rank kernels (module-level ``jax.jit`` functions of :mod:`uio_jax._analysis.rank`).
Across processes, with the caches on (:func:`uio_jax.enable_compile_cache`, the command
line's default), every analysis program is loaded from the program cache
(:mod:`uio_jax._engine.program_cache`, keyed by the model's own jaxprs and the generator
structure, no tracing) and the small shared kernels from JAX's persistent compilation
cache: a second run of the same batch evaluates only.

**Parallel runs and time limits.** ``jobs > 1`` analyses models in that many worker
processes (:mod:`uio_jax._batch.workers`), one model at a time each, each worker bound to
one CPU (worker k to the k-th allowed CPU, cyclically; one worker alone keeps them all):
JAX's thread pools then do not oversubscribe the cores (measured in
``docs/benchmarks/batch.md``). With ``timeout``, a model that runs too long has its worker
killed (its row says so) and a fresh worker goes on with the others. Only models given by
path can go to a worker; ``System`` objects run in the calling process. The workers take
the models longest first by their recorded times (:mod:`uio_jax._batch.timing`).
"""

import numbers
import time

from .._analysis.options import check_options
from .._errors import OptionError
from .._progress import CountProgress
from .discovery import Skipped, discover
from .one_model import run_entry
from .rows import BatchResult
from .timing import longest_first, record_seconds, recorded_seconds, time_key
from .workers import run_in_workers


def batch_analyze(models, *, jobs: int = 1, timeout=None, progress=None, keep_reports: bool = True,
                  **analyze_kwargs) -> BatchResult:
    """Analyse many models; one failing model is one row with its error, the others go on.

    Main arguments:
        models: a path, a :class:`~uio_jax.System`, or a sequence of them. Paths are
            ``FILE.py:NAME``, zoo files ``FILE.py`` (every public no-argument function
            that returns a System; see :mod:`uio_jax._batch.discovery` for how they are
            found), ``.toml``/``.json`` model files, directories and globs.

    Other arguments:
        jobs: worker processes (default 1: everything in this process). Workers are
            spawned fresh and pay JAX's start-up; they share the persistent compilation
            cache of this process if one is enabled.
        timeout: seconds one model may run (None, the default: no limit). With a limit,
            models given by path run in worker processes (``jobs`` of them, at least
            one); a model over the limit has its worker killed, its row says "timed
            out", and a fresh worker takes the next model. ``System`` objects given
            directly run in this process, without a limit.
        progress: ``True`` shows a model-count bar on stderr (off a terminal: one line
            per finished model), ``False`` never, ``None`` (default) only on a terminal
            and once the batch has lasted 2 s.
        keep_reports: keep each model's :class:`~uio_jax.Report` in ``row.report``
            (False frees each model's compiled functions as soon as it is done).
        **analyze_kwargs: passed to :func:`uio_jax.analyze` (``method``, ``samples``,
            ``seed``, ``rtol``, ``max_order``, ``k_max``).

    Returns:
        :class:`~uio_jax.BatchResult`, a sequence of :class:`~uio_jax.BatchRow` in the
        order the models were given (zoo files in the order their functions are defined).

    Raises:
        OptionError: no model given, a path that matches nothing, impossible options
            (checked before any model runs).
    """
    t0 = time.perf_counter()
    _check_batch_options(jobs, timeout, analyze_kwargs)
    # models that may run in worker processes are built there: not here first as well
    entries, skipped = discover(models, build=jobs == 1 and timeout is None)
    keys = [time_key(e, analyze_kwargs) for e in entries]
    bar = CountProgress(len(entries), enabled=progress)
    try:
        remote = sum(e.spec is not None and e.error is None for e in entries)
        if (jobs > 1 and remote > 1) or (timeout is not None and remote):
            rows = _run_parallel(entries, jobs, timeout, analyze_kwargs, bar, recorded_seconds(keys))
        else:
            rows = _run_here(entries, analyze_kwargs, keep_reports, bar)
    finally:
        bar.close()
    record_seconds(keys, rows)
    rows, skipped = _move_skipped(rows, skipped)
    options = {k: v for k, v in analyze_kwargs.items() if v is not None}
    return BatchResult(tuple(rows), tuple(skipped), time.perf_counter() - t0, options)


def _check_batch_options(jobs, timeout, analyze_kwargs):
    """Options that would make every model fail: refused before any model runs."""
    if isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral) or jobs < 1:
        raise OptionError(f"jobs must be a positive integer, got {jobs!r}")
    check_options(**analyze_kwargs)
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, numbers.Real)
                                or not timeout > 0):
        raise OptionError(f"timeout must be a positive number of seconds, got {timeout!r}")


def _run_here(entries, analyze_kwargs, keep_reports, bar):
    """Every entry in this process, in order (``entries`` is emptied as it goes)."""
    rows = []
    for i, e in enumerate(entries):
        label = e.label
        bar.start(label)
        rows.append(run_entry(e, analyze_kwargs, keep_reports))
        entries[i] = e = None  # without its report, the System and its compiled code can go
        bar.finish(label)
    return rows


def _run_parallel(entries, jobs, timeout, analyze_kwargs, bar, recorded=()):
    """Entries with a spec go to worker processes (longest recorded time first, see
    :func:`~uio_jax._batch.timing.longest_first`); in-memory Systems and known errors run here."""
    rows = [None] * len(entries)
    remote = [i for i, e in enumerate(entries) if e.spec is not None and e.error is None]
    local = set(range(len(entries))) - set(remote)
    for i, e in enumerate(entries):
        if i in local:
            bar.start(e.label)
            rows[i] = run_entry(e, analyze_kwargs, keep_report=False)
            bar.finish(e.label)
    run_in_workers(entries, longest_first(remote, recorded), jobs, timeout, analyze_kwargs, bar, rows)
    return rows


def _move_skipped(rows, skipped):
    """Deferred zoo functions that gave no System leave the rows for ``skipped`` (after
    the functions skipped without being called)."""
    late = [(row.spec, row.why) for row in rows if isinstance(row, Skipped)]
    return [r for r in rows if not isinstance(r, Skipped)], list(skipped) + late
