"""One model of a batch: load it, analyse it, and turn every error into its row."""

import time

from .._analysis.analyze import analyze
from .._errors import UioJaxError, exit_message
from .._io.initial_values import file_initial
from .._io.loading import load_system, one_line
from .._model.system import System
from .discovery import Entry, Skipped, build_deferred
from .rows import BatchRow, row_from_report


def load_entry(entry: Entry) -> System:
    """The System of an entry (built already, or loaded from its spec by ``load_system``).

    Raises:
        LoadError, ModelError: a spec that does not load.
    """
    if entry.system is not None:
        return entry.system
    return load_system(entry.spec, **(entry.options or {}))


def run_entry(entry: Entry, analyze_kwargs, keep_report=True, on_system=None):
    """Load and analyse one model with ``analyze(system, **analyze_kwargs)``
    (``on_system(system)``, when given, is called with the loaded System first).

    Returns:
        its :class:`BatchRow` (every error becomes the row's one-line error; ``seconds``
        counts building, loading and analysing; the Report kept when ``keep_report``), or
        a :class:`Skipped` for a deferred zoo function that gave no System.
    """
    if entry.deferred:
        entry = build_deferred(entry)
        if isinstance(entry, Skipped):
            return entry
    t0 = time.perf_counter() - entry.build_s
    if entry.error is not None:
        return BatchRow(entry.label, error=entry.error, seconds=entry.build_s)
    try:
        system = load_entry(entry)
        if on_system is not None:
            on_system(system)
        rep = analyze(system, **analyze_kwargs)
    except UioJaxError as exc:
        return BatchRow(entry.label, error=one_line(exc, with_type=False), seconds=time.perf_counter() - t0)
    except Exception as exc:  # a bug or a model that breaks JAX: one row, the batch goes on
        return BatchRow(entry.label, error=one_line(exc), seconds=time.perf_counter() - t0)
    except SystemExit as exc:  # a model function that calls sys.exit: its row, not the batch's end
        return BatchRow(entry.label, error=f"{entry.label} {exit_message(exc)}",
                        seconds=time.perf_counter() - t0)
    return row_from_report(entry.label, rep, time.perf_counter() - t0, rep if keep_report else None,
                           notes=initial_table_note(system))


def initial_table_note(system) -> tuple[str, ...]:
    """The note of a model loaded with a known initial state (a model file's ``[initial]``
    table), which a batch does not use: it answers the generic question."""
    table = file_initial(system)
    if not table:
        return ()
    values = ", ".join(f"{k} = {v}" for k, v in table.items())
    return (f"its [initial] table ({values}) is not used: batch answers the question at generic states; "
            "'uio-jax analyze' on the file answers at that initial state",)
