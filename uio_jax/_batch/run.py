"""Batch certification: many models, one table (``uio-jax batch``, :func:`batch_analyze`).

**What is reused between models.** Nothing is compiled for an analysis: every model is
evaluated by numpy over its System's expression graph, nodes and gradients cached per System.

**Parallel runs and time limits.** ``jobs > 1`` analyses models in that many worker
processes (:mod:`uio_jax._batch.workers`), one model at a time each, each worker bound to
one CPU (:mod:`uio_jax._batch.pinning`). With ``timeout``, a model that runs too long has its
worker killed (its row says so) and a fresh worker goes on with the others. Only models given
by path can go to a worker. The workers take the models longest first by their recorded times
(:mod:`uio_jax._batch.timing`).

**On a Dask cluster** (``client``, :mod:`uio_jax._batch.cluster`): the same driver
(:mod:`uio_jax._batch.executor`) hands the models to the cluster's workers instead of the
local pool: same rows, order, time limits and progress; a model whose worker dies is
re-run by Dask on another worker, then is an error row.

**Progress, partial results, Ctrl-C.** The progress display (:class:`uio_jax._progress.CountProgress`)
is a bar on a terminal and one line per finished model elsewhere, with an ETA from the
recorded times. ``on_row`` receives the partial result after every finished model (the
command line rewrites its ``--json/--csv/--markdown`` files there). On Ctrl-C
(KeyboardInterrupt) the workers are stopped and :class:`BatchInterrupted` carries the
rows finished so far (``result.partial`` says "interrupted after 3 of 12 models").
"""

import contextlib
import math
import numbers
import os

from .._analysis.options import check_options
from .._errors import OptionError
from .._progress import CountProgress
from .discovery import discover
from .one_model import run_entry
from .rows import BatchResult
from .timing import longest_first, record_seconds, recorded_seconds, time_key
from .tracker import Tracker
from .workers import run_in_workers


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C during :func:`batch_analyze`: a KeyboardInterrupt that carries the rows
    finished so far in ``result`` (a :class:`BatchResult` whose ``partial`` says
    "interrupted after K of N models"). The worker processes are stopped already."""

    def __init__(self, result):
        super().__init__(result.partial)
        self.result = result


def batch_analyze(models, *, jobs: int = 1, timeout=None, progress=None, keep_reports: bool = True,
                  import_python: bool = False, on_row=None, client=None, sbml=None, **analyze_kwargs) -> BatchResult:
    """Analyse many models; one failing model is one row with its error, the others go on.

    Main arguments:
        models: a path, a :class:`~uio_jax.System`, or a sequence of them. Paths are
            ``FILE.py:NAME``, zoo files ``FILE.py`` (every public no-argument function
            that returns a System; see :mod:`uio_jax._batch.discovery` for how they are
            found), ``.toml``/``.json`` model files, directories and globs. A ``.py``
            file found in a directory or a glob is imported only when it carries the line
            ``# uio-jax: models`` (or is a StrikePy module, parsed without executing it);
            other ``.py`` files are listed in ``skipped``, not executed.

    Other arguments:
        jobs: worker processes (default 1: everything in this process). Workers are
            spawned fresh and pay JAX's start-up; they share the persistent compilation
            cache of this process if one is enabled.
        timeout: seconds one model may run (a positive finite number; None, the default:
            no limit). With a limit, models given by path run in worker processes (``jobs``
            of them, at least one); a model over the limit has its worker killed, its row
            says "timed out", and a fresh worker takes the next model. ``System`` objects
            given directly run in this process, without a limit.
        progress: ``False``: nothing on stderr. ``True`` or ``None`` (default): on a
            terminal a model-count bar with an ETA; elsewhere one line per finished model:
            ``batch 3/12  NAME  dim 4/7  2.3 s  ETA 40 s``.
        keep_reports: keep each model's :class:`~uio_jax.Report` in ``row.report``
            (False frees each model's compiled functions as soon as it is done).
        import_python: also import the ``.py`` files found in directories and globs that
            have no ``# uio-jax: models`` marker (their top-level code runs).
        on_row: None, or a function called with the partial :class:`~uio_jax.BatchResult`
            (the rows finished so far, in the given order; ``partial`` set until the last
            one) after each finished model.
        client: None (default: this machine), or a Dask cluster: a ``distributed.Client``
            or a scheduler address (``"tcp://host:8786"``). The models given by path run
            as tasks on its workers (:mod:`uio_jax._batch.cluster`), with the same rows, time
            limits and progress as ``jobs`` worker processes; the workers must see the model
            files and the cache directory at the same paths. Not with ``jobs > 1``. Needs the
            extra ``uio_jax[cluster]``.
        sbml: one rule of outputs and inputs for every SBML file of the batch: the keyword
            arguments of :func:`uio_jax.load_system` for SBML (``docs/sbml.md``). A file
            without an id the rule names is an error row.
        **analyze_kwargs: passed to :func:`uio_jax.analyze` (``method``, ``samples``,
            ``seed``, ``rtol``, ``max_order``, ``k_max``, ``known_inputs``, ``prob_threshold``).

    Returns:
        :class:`~uio_jax.BatchResult`, a sequence of :class:`~uio_jax.BatchRow` in the
        order the models were given (zoo files in the order their functions are defined).

    Raises:
        OptionError: no model given, a path that matches nothing, impossible options, a
            cluster that cannot be reached or has no worker (checked before any model runs).
        TypeError: ``on_row`` is not callable (before any model runs).
        BatchInterrupted: Ctrl-C (a KeyboardInterrupt carrying the partial result).
    """
    _check_batch_options(jobs, timeout, analyze_kwargs, client)
    if on_row is not None and not callable(on_row):  # not after the first model ran
        raise TypeError(f"on_row must be None or a function of the partial BatchResult, got "
                        f"{type(on_row).__name__}")
    with contextlib.ExitStack() as stack:
        if client is not None:
            from .._filter.cluster import cluster_client, wait_for_workers

            client = stack.enter_context(cluster_client(client))
            slots = wait_for_workers(client)
        return _batch(models, jobs, timeout, progress, keep_reports, import_python, on_row, client,
                      slots if client is not None else jobs, analyze_kwargs, _sbml_rule(sbml))


def _batch(models, jobs, timeout, progress, keep_reports, import_python, on_row, client, slots,
           analyze_kwargs, sbml=None):
    """:func:`batch_analyze` once its options are checked (``slots``: models at once)."""
    # models that may run in worker processes are built there: not here first as well
    # with a time limit, the zoo files are imported only in the workers, under it
    entries, skipped = discover(models, build=jobs == 1 and timeout is None and client is None,
                                import_here=timeout is None,
                                import_python=import_python, sbml=sbml)
    keys = [time_key(e, analyze_kwargs) for e in entries]
    recorded = recorded_seconds(keys)
    remote = sum(e.spec is not None and e.error is None for e in entries)
    parallel = client is not None or (jobs > 1 and remote > 1) or (timeout is not None and remote > 0)
    bar = CountProgress(len(entries), enabled=progress, expected=recorded,
                        workers=min(slots, max(remote, 1)) if parallel else 1)
    options = {k: v for k, v in analyze_kwargs.items() if v is not None}
    tracker = Tracker(entries, skipped, bar, options, on_row)
    try:
        if parallel:
            _run_parallel(entries, jobs, timeout, analyze_kwargs, tracker, recorded, client)
        else:
            _run_here(entries, analyze_kwargs, keep_reports, tracker)
    except KeyboardInterrupt:
        bar.close()
        record_seconds(keys, tracker.rows)
        raise BatchInterrupted(tracker.result(
            f"interrupted after {tracker.done} of {len(tracker.rows)} models")) from None
    finally:
        bar.close()
    record_seconds(keys, tracker.rows)
    return tracker.result()


def _sbml_rule(sbml):
    """The SBML rule checked (a mapping of ``load_system``'s SBML options), its observables
    table made absolute (workers elsewhere read it)."""
    from .._io.sbml_import import SBML_OPTIONS

    if sbml is None:
        return None
    if not isinstance(sbml, dict):
        raise OptionError(f"sbml must be a dict of load_system's SBML options, got {type(sbml).__name__}")
    bad = [k for k in sbml if k not in SBML_OPTIONS]
    if bad:
        raise OptionError(f"sbml: unknown option {bad[0]!r} (options: {', '.join(SBML_OPTIONS)})")
    if sbml.get("observables") is not None:
        sbml = {**sbml, "observables": os.path.abspath(os.fspath(sbml["observables"]))}
    return sbml


def _check_batch_options(jobs, timeout, analyze_kwargs, client=None):
    """Options that would make every model fail: refused before any model runs."""
    if isinstance(jobs, bool) or not isinstance(jobs, numbers.Integral) or jobs < 1:
        raise OptionError(f"jobs must be a positive integer, got {jobs!r}")
    if client is not None and jobs > 1:
        raise OptionError(f"jobs={jobs} and a cluster client exclude each other (the cluster's "
                          "workers run the models; jobs counts processes on this machine)")
    check_options(**analyze_kwargs)
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(timeout, numbers.Real)
                                or not (timeout > 0 and math.isfinite(timeout))):
        raise OptionError(f"timeout must be a positive number of seconds, got {timeout!r}")


def _run_here(entries, analyze_kwargs, keep_reports, tracker):
    """Every entry in this process, in order (``entries`` is emptied as it goes)."""
    for i, e in enumerate(entries):
        tracker.start(i)
        row = run_entry(e, analyze_kwargs, keep_reports)
        entries[i] = e = None  # without its report, the System and its compiled code can go
        tracker.finish(i, row)


def _run_parallel(entries, jobs, timeout, analyze_kwargs, tracker, recorded=(), client=None):
    """Entries with a spec go to worker processes, or to the workers of a Dask ``client``
    (longest recorded time first, see :func:`~uio_jax._batch.timing.longest_first`);
    in-memory Systems and known errors run here."""
    remote = [i for i, e in enumerate(entries) if e.spec is not None and e.error is None]
    for i in sorted(set(range(len(entries))) - set(remote)):
        tracker.start(i)
        tracker.finish(i, run_entry(entries[i], analyze_kwargs, keep_report=False))
    todo = longest_first(remote, recorded)
    if client is not None:
        from .cluster import run_on_cluster

        run_on_cluster(entries, todo, client, timeout, analyze_kwargs, tracker)
    else:
        run_in_workers(entries, todo, jobs, timeout, analyze_kwargs, tracker)
