"""``analyze``: option checks, choice of the analysis, and the float64 context."""

import numbers

import jax

from .._errors import OptionError
from .._model.system import System
from .context import Context
from .orc import run_orc
from .rank import default_rtol
from .single_ui import check_applicable, single_ui_report

METHODS = ("auto", "orc", "single_ui", "eorc", "series", "fast")


def analyze(
    system: System,
    *,
    method: str = "auto",
    samples: int = 4096,
    seed: int = 0,
    rtol: float | None = None,
    max_order: int | None = None,
    k_max: int | None = None,
):
    """Which states of ``system`` are observable: the observable codistribution.

    Main arguments:
        system: a :class:`~uio_jax.System`.

    Other arguments:
        method: ``"auto"`` (default), ``"orc"``, ``"single_ui"``, ``"eorc"``,
            ``"series"`` or ``"fast"``.
            ``"auto"`` picks, in order: no unknown input -> ``"orc"`` (Hermann-Krener);
            one unknown input and no drift -> ``"single_ui"`` (Martinelli's analytic
            solution); otherwise ``"eorc"`` (extended observability rank criterion,
            sufficient only). ``"series"`` (every input known): rank of the output Taylor
            coefficients along a generic known input (STRIKE-GOLDD's test, see
            :mod:`uio_jax._series`): the ORC's final verdict without nested brackets, much
            faster on large models, but per-order dims that are not the ORC's steps.
            ``"fast"``: like ``"auto"`` with ``"series"`` in place of ``"orc"``.
            ``Report.method`` records the choice.
        samples: number S of random states of the domain at which every rank is
            evaluated (the certificate). More samples, surer verdict; cost is linear.
        seed: seed of the sampled states (same seed, same report).
        rtol: relative tolerance on ``s_i / s_1`` after scaling (default
            :func:`uio_jax.default_rtol`, 1e-8).
        max_order: optional cap on the number of steps m of the ORC / single_ui recursion.
        k_max: highest order k of the EORC (default n + 2); ignored by the other methods.

    Returns:
        :class:`~uio_jax.Report`. For a System with ``params``, the analysis runs on
        ``z = [x; p]`` with ``p' = 0`` (:meth:`System.joint`) and the Report lists the
        parameters apart (``params``, ``identifiable``).

    Raises:
        OptionError: unknown method, impossible sample count, a method that does not apply.
        ModelError: a model that fails at the sampled states.

    References:
        Martinelli, IROS 2017 (002): Algorithms 1-3 and the 7-step procedure;
        Martinelli, INRIA RR-8608 (004): sections 4-10.
    """
    if not isinstance(system, System):
        raise OptionError(f"analyze needs a uio_jax.System, got {type(system).__name__}")
    if method not in METHODS:
        raise OptionError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if isinstance(samples, bool) or not isinstance(samples, numbers.Integral) or samples < 8:
        raise OptionError(f"samples must be an integer >= 8, got {samples!r}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise OptionError(f"seed must be a non-negative integer, got {seed!r}")
    if rtol is None:
        rtol = default_rtol()
    if not (isinstance(rtol, numbers.Real) and 0 < rtol < 1):
        raise OptionError(f"rtol must be a number in (0, 1), got {rtol!r}")
    if max_order is not None and (
        isinstance(max_order, bool) or not isinstance(max_order, numbers.Integral) or max_order < 0
    ):
        raise OptionError(f"max_order must be a non-negative integer, got {max_order!r}")
    if k_max is not None and (
        isinstance(k_max, bool) or not isinstance(k_max, numbers.Integral) or k_max < 1
    ):
        raise OptionError(f"k_max must be a positive integer, got {k_max!r}")

    chosen, why = _choose(system, method)
    system = system.joint()  # parameters -> states with zero derivative
    with jax.enable_x64(True):
        if chosen == "orc":
            ctx = Context(system, int(samples), int(seed), float(rtol))
            return _orc_report(ctx, why, max_order)
        if chosen == "series":
            from .series import check_applicable as series_applicable
            from .series import series_report

            series_applicable(system)
            ctx = Context(system, int(samples), int(seed), float(rtol))
            return series_report(ctx, seed=int(seed), why=why, max_order=max_order)
        if chosen == "single_ui":
            check_applicable(system)
            ctx = Context(system, int(samples), int(seed), float(rtol))
            return single_ui_report(ctx, why=why, max_order=max_order)
    if chosen == "eorc":
        try:
            from .eorc import eorc_report
        except ImportError:
            eorc_report = None
        if eorc_report is not None:
            return eorc_report(system, samples=int(samples), seed=int(seed), rtol=float(rtol),
                               k_max=k_max, notes=[why] if why else [])
    raise OptionError(
            f"method {chosen!r} is not available yet in this version of uio_jax"
            + (f" ({why})" if why else "")
        )


def _choose(system, method):
    """The analysis to run and, for ``auto``, why."""
    n_unknown = len(system.unknown)
    if method == "fast":
        if n_unknown == 0:
            return "series", "fast: no unknown input -> series (generic-input output series; ORC's verdict)"
        chosen, why = _choose(system, "auto")
        return chosen, why.replace("auto:", "fast:", 1)
    if method == "auto":
        if n_unknown == 0:
            return "orc", "auto: no unknown input -> ORC"
        if n_unknown == 1 and system.drift is None:
            return "single_ui", "auto: one unknown input, no drift -> single_ui"
        return "eorc", (
            f"auto: {n_unknown} unknown input{'s' if n_unknown != 1 else ''}"
            + (" and a drift" if system.drift else "")
            + " -> EORC"
        )
    if method in ("orc", "series") and n_unknown:
        raise OptionError(
            f"method {method!r} needs every input known, but {', '.join(system.unknown)} "
            "is unknown; use method='auto' (or treat it as known with "
            "System.with_known([...]))"
        )
    return method, ""


def _orc_report(ctx, why, max_order):
    labels = [lbl for lbl in ctx.system.fields() if lbl not in ctx.system.unknown]
    history, reason = run_orc(ctx, labels, max_steps=max_order)
    notes = [why] if why else []
    return ctx.report("orc", history, reason, notes=notes)
