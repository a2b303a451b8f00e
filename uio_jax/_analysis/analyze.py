"""``analyze``: choice of the analysis and its context (the options are checked by
:mod:`uio_jax._analysis.options`).

How ``method="auto"`` chooses, in order: no unknown input -> ``"orc"`` (Hermann-Krener;
``"general_ui"``'s closure along the drift when the known inputs are smooth; with switchable
known inputs on a model of :data:`~uio_jax._analysis.taylor_route.TAYLOR_MIN_VARIABLES`
coordinates or more that the Taylor route evaluates, ``"series"``: the ORC's final span,
decided on the output's Taylor series without symbolic brackets); one unknown
input, no drift, and no known input or switchable ones -> ``"single_ui"`` (Martinelli's
analytic solution); known inputs that are switchable with a drift or several unknown inputs
-> ``"eorc"`` (extended observability rank criterion, sufficient only: no exact solution is
known for that meaning); otherwise ``"general_ui"`` (Martinelli's general solution: any
number of unknown inputs, drift, smooth known inputs; exact). ``"series"`` (every input
known): rank of the output Taylor coefficients along a generic known input (STRIKE-GOLDD's
test, :mod:`uio_jax._analysis.series`): the ORC's final verdict without nested brackets,
much faster on large models, but per-order dims that are not the ORC's steps. ``"fast"``:
like ``"auto"`` with ``"series"`` in place of ``"orc"``.
"""

import dataclasses

import jax

from .._errors import OptionError
from .._model.experiments import Experiments
from .._model.symmetries import symmetry_fields
from .._model.system import System
from .context import Context
from .eorc import eorc_report
from .general_ui import check_applicable as general_ui_applicable
from .general_ui import general_ui_report
from .identifiability import analyze_experiments, analyze_initial
from .initial import unused_note, unused_parameters
from .memory import check_memory
from .options import DEFAULTS, check_options
from .orc import run_orc
from .series import check_applicable as series_applicable
from .series import series_report
from .single_ui import check_applicable, single_ui_report
from .symmetry import symmetry_notes, verify_symmetries
from .taylor_route import NotTaken, taylor_applicable, taylor_report


def analyze(
    system: System,
    *,
    method: str = DEFAULTS["method"],
    samples: int = DEFAULTS["samples"],
    seed: int = DEFAULTS["seed"],
    rtol: float | None = DEFAULTS["rtol"],
    max_order: int | None = DEFAULTS["max_order"],
    k_max: int | None = DEFAULTS["k_max"],
    known_inputs: str = DEFAULTS["known_inputs"],
    prob_threshold: float = DEFAULTS["prob_threshold"],
    initial=None,
    shared=None,
):
    """Which states of ``system`` are observable: the observable codistribution.

    Main arguments:
        system: a :class:`~uio_jax.System`; or several experiments (a sequence of Systems, or
            :class:`~uio_jax.Experiments`): then, as with ``initial=``, see below.

    Other arguments:
        method: ``"auto"`` (default), ``"orc"``, ``"single_ui"``, ``"general_ui"``,
            ``"eorc"``, ``"series"`` or ``"fast"``: how ``"auto"`` and ``"fast"`` choose is in
            the module docstring; ``Report.method`` records the choice.
        samples: number S of random states drawn for the float64 screen (votes at the first
            decision samples, :func:`~uio_jax._analysis.memory.decision_count`; margins and the
            figure at as many as fit in memory, ``Certificate.capped``). The verdicts do not rest
            on these votes: every decision is settled again modulo p (or in extended precision).
        prob_threshold: the probability of correctness the exact decisions must reach
            (StructuralIdentifiability.jl's ``prob_threshold``; default 0.999999): each
            decision modulo ``p = 2^127 - 1`` is wrong with probability at most
            ``D / p`` per point (Schwartz-Zippel, ``D`` a degree bound), points are added
            until the sum over the analysis, ``Certificate.error_bound``, is under
            ``1 - prob_threshold``.
        seed: seed of the sampled states, an integer in ``[0, 2**64)`` (same seed, same
            report).
        rtol: relative tolerance on ``s_i / s_1`` after scaling (default
            :func:`uio_jax.default_rtol`, 1e-8).
        max_order: optional cap on the number of steps m of the ORC / single_ui recursion.
        k_max: highest order k of the EORC (default n + 2; it stops earlier once every unknown
            input is observable and the states reach their rank with every input known); given,
            every order up to it is run. Other methods do not use it (their report notes it).
        known_inputs: ``"switchable"`` (default; a known input may be chosen freely and may
            jump: Martinelli's papers, the classical ORC/EORC) or ``"smooth"`` (a generic smooth
            function of time, known with its derivatives: TUIO6's); the answers can differ (004
            11.1.1: dim 2 switchable, 1 smooth). ``Report.known_inputs`` records it.
        initial, shared: a known initial state ``state -> value`` (a number, a parameter's name,
            a function of ``p``; one per experiment for several) and the shared parameters (default:
            those common to all): local identifiability at ``t = 0`` (an :class:`~uio_jax.IdentifiabilityReport`).

    Returns:
        :class:`~uio_jax.Report`. For a System with ``params``, the analysis runs on
        ``z = [x; p]`` with ``p' = 0`` (:meth:`System.joint`) and the Report lists the
        parameters apart (``params``, ``identifiable``).

    Raises:
        OptionError: unknown method, an option out of its range (samples < 8, a seed
            outside ``[0, 2**64)``, rtol not in (0, 1), ...), a method that does not apply
            (``"series"`` on a model the Taylor engines cannot expand), or a request whose
            arrays cannot fit in memory: samples x n x n x 8 bytes and more, or, for the
            EORC, samples x N x N with N = n + k_max m_w (:mod:`uio_jax._analysis.memory`;
            the limit is ``$UIO_JAX_MEMORY_LIMIT``, default half the physical memory).
        ModelError: a model that fails at the sampled states.

    References:
        Martinelli, IROS 2017 (002): Algorithms 1-3; INRIA RR-8608 (004): sections 4-10.
    """
    if initial is not None or shared is not None or not isinstance(system, System):
        report = _identifiability(system, initial, shared, method, seed, max_order, prob_threshold)
        return _with_unused_options_note(report, samples=samples, rtol=rtol, k_max=k_max, known_inputs=known_inputs)
    opts = check_options(method=method, samples=samples, seed=seed, rtol=rtol,
                         max_order=max_order, k_max=k_max, known_inputs=known_inputs,
                         prob_threshold=prob_threshold)
    samples, seed, rtol = opts["samples"], opts["seed"], opts["rtol"]
    max_order, k_max, known_inputs = opts["max_order"], opts["k_max"], opts["known_inputs"]

    # parameters -> states with zero derivative; time -> a known coordinate with t' = 1
    system = system.autonomous()
    report = _run(system, method, samples, seed, rtol, max_order, k_max, known_inputs, opts["prob_threshold"])
    return _with_notes(report, system, k_max, seed)


def _identifiability(system, initial, shared, method, seed, max_order, prob_threshold):
    """The known-initial-state or several-experiment analysis (:mod:`.identifiability`,
    ``docs/initial_conditions.md``): local identifiability of the parameters and observability
    of the unknown initial states at ``t = 0`` from the output's Taylor coefficients, decided
    exactly. ``max_order`` caps the order of the coefficients (default ``2 u + 2``, ``u`` the
    number of unknowns); ``method`` must be ``"auto"``; ``samples``, ``rtol``, ``k_max`` and
    ``known_inputs`` do not apply (known inputs are generic, there is no float64 screen)."""
    opts = check_options(method=method, seed=seed, max_order=max_order, prob_threshold=prob_threshold)
    if opts["method"] != "auto":
        raise OptionError(f"method {method!r} does not apply with initial= or several experiments (use 'auto')")
    kw = {"seed": opts["seed"], "prob_threshold": opts["prob_threshold"], "max_order": opts["max_order"]}
    if isinstance(system, Experiments):
        if initial is not None or shared is not None:
            raise OptionError("give initial= and shared= inside uj.Experiments, not to analyze")
        return analyze_experiments(system.systems, system.initial, shared=system.shared, **kw)
    if isinstance(system, System):
        if shared is not None:
            raise OptionError("shared= applies to several experiments (a sequence of Systems)")
        return analyze_initial(system, initial, **kw)
    if isinstance(system, (list, tuple)):
        return analyze_experiments(system, initial, shared=shared, **kw)
    raise OptionError(f"analyze needs a uio_jax.System, got {type(system).__name__}")


def _with_unused_options_note(report, **given):
    """``report`` (at t = 0) with a note naming the options given that it does not use."""
    ignored = [f"{k}={v!r}" for k, v in given.items() if v != DEFAULTS[k]]
    if not ignored:
        return report
    return dataclasses.replace(report, notes=tuple(report.notes) + (
        f"{', '.join(ignored)} not used: at t = 0 there is no float64 screen (samples, rtol), no EORC "
        "(k_max), and known inputs are generic (known_inputs)",))


def _with_notes(report, system, k_max, seed):
    """``report`` with what the run alone does not say: outputs that add nothing, a
    ``k_max`` given to a method that does not use it, the declared symmetries (verified;
    the EORC uses them itself), the meaning of switchable known inputs."""
    report = _with_idle_outputs_note(report, system)
    unused = unused_parameters(system)
    if unused:
        report = dataclasses.replace(report, notes=tuple(report.notes) + (unused_note(unused),))
    if k_max is not None and report.method != "eorc":  # given, but not used: said, not silent
        report = dataclasses.replace(report, notes=tuple(report.notes) + (
            f"k_max={k_max} applies to the EORC only: the {report.method} analysis that ran does "
            "not use it (max_order caps its steps)",))
    if report.method != "eorc" and symmetry_fields(system):
        report = _with_symmetries(report, system, seed)
    if report.known_inputs == "switchable":
        report = dataclasses.replace(report, notes=tuple(report.notes) + (SWITCHABLE_NOTE,))
    return report


#: The note of every answer for switchable known inputs: the other meaning can give less.
SWITCHABLE_NOTE = ("this answer holds for known inputs that may be chosen freely and may jump "
                   "(known_inputs='switchable'); generic smooth known inputs can hide more (a boat's "
                   "heading from GPS with smooth thrust and yaw rate): known_inputs='smooth', "
                   "--known-inputs smooth")


def _with_idle_outputs_note(report, system):
    """``report`` with a note naming the outputs that add no direction at step 0 (a
    constant such as ``"0"``, ``"x - x"`` or a boolean, or a function of the outputs kept
    before them), when the first step lists outputs by name."""
    first = report.history[0] if report.history else None
    names = list(system.outputs)
    if first is None or first.m != 0 or not set(first.added) <= set(names):
        return report
    known = set(system.known_outputs)  # time as an output of its own coordinate: not the user's
    idle = [y for y in names if y not in first.added and y not in known]
    if not idle:
        return report
    many = len(idle) > 1
    note = (f"output{'s' if many else ''} {', '.join(idle)} add{'' if many else 's'} no direction at "
            "m=0: constant on the domain (a number, a boolean, x - x), or a function of the "
            "outputs kept before")
    return dataclasses.replace(report, notes=tuple(report.notes) + (note,))


def _with_symmetries(report, system, seed):
    """``report`` with the notes and ``details["symmetries"]`` of the System's verified
    symmetries (:mod:`uio_jax._analysis.symmetry`): the coordinates they move are proved
    unobservable, and a verdict that contradicts one is flagged."""
    cert = report.certificate
    bound = verify_symmetries(system, seed=seed, prob_threshold=cert.prob_threshold)
    verdicts = {**report.observable, **report.identifiable}
    notes, _ = symmetry_notes(bound, verdicts, "the final span", report.dim)
    details = {**report.details, "symmetries": bound.to_dict()}
    if bound.probability:  # the verification's bound, charged to the report's certificate
        cert = dataclasses.replace(cert, error_bound=cert.error_bound + bound.probability)
    return dataclasses.replace(report, notes=tuple(report.notes) + tuple(notes), details=details, certificate=cert)


def _run(system, method, samples, seed, rtol, max_order, k_max, known_inputs, prob_threshold):
    """The report of the analysis ``method`` chooses on the autonomous ``system``."""
    chosen, why = _choose(system, method, known_inputs)
    notes = [why] if why else []
    if chosen == "eorc":  # its size depends on k_max: checked by the EORC itself
        return eorc_report(system, samples=samples, seed=seed, rtol=rtol, k_max=k_max, prob_threshold=prob_threshold,
                           notes=notes, known_inputs=known_inputs)
    if chosen == "general_ui":
        check_memory(samples, system.n, what=f"samples={samples} x {system.n} states",
                     advice="lower samples")
        return general_ui_report(system, samples=samples, seed=seed, rtol=rtol, prob_threshold=prob_threshold,
                                 known_inputs=known_inputs, notes=notes)
    check_memory(samples, system.n, what=f"samples={samples} x {system.n} states",
                 advice="lower samples")
    with jax.enable_x64(True):
        if chosen == "series":
            series_applicable(system)
        elif chosen == "single_ui":
            check_applicable(system)
        ctx = Context(system, samples, seed, rtol, prob_threshold)
        report = _taylor_report(ctx, method, chosen, why, seed, max_order)
        if report is not None:
            return report
        if chosen == "orc":
            return _orc_report(ctx, why, max_order)
        if chosen == "series":
            return series_report(ctx, seed=seed, why=why, max_order=max_order)
        return single_ui_report(ctx, why=why, max_order=max_order)


def _taylor_report(ctx, method, chosen, why, seed, max_order):
    """The report of the Taylor route where the engine takes it (:mod:`.taylor_route`), else
    None: ``"orc"`` and ``"series"`` on large models; for ``"auto"`` on a large model with
    switchable known inputs, the series test in place of the ORC (its final span)."""
    system = ctx.system
    if method == "auto" and chosen == "orc" and system.known and taylor_applicable(ctx, "series"):
        chosen, why = "series", (f"{why}; {system.n} variables with known inputs -> the series test on the "
                                 "Taylor route (the ORC's final span; its orders are not the ORC's steps)")
    elif chosen not in ("orc", "series") or not taylor_applicable(ctx, chosen):
        return None
    try:
        return taylor_report(ctx, chosen, seed=seed, why=why, max_order=max_order)
    except NotTaken:
        return None  # the symbolic route decides it (the ORC where auto chose it)


def _choose(system, method, known_inputs="switchable"):
    """The analysis to run on ``system`` (autonomous) and, for ``auto``, why."""
    n_unknown = len(system.unknown)
    smooth = known_inputs == "smooth" and bool(system.known)
    if method == "fast":
        if n_unknown == 0 and not smooth:
            return "series", "fast: no unknown input -> series (generic-input output series; ORC's verdict)"
        chosen, why = _choose(system, "auto", known_inputs)
        return chosen, why.replace("auto:", "fast:", 1)
    if method == "auto":
        if n_unknown == 0:
            if smooth:
                return "general_ui", "auto: no unknown input, smooth known inputs -> general_ui"
            return "orc", "auto: no unknown input -> ORC"
        if n_unknown == 1 and system.drift is None and not smooth:
            return "single_ui", "auto: one unknown input, no drift -> single_ui"
        inputs = f"{n_unknown} unknown input{'s' if n_unknown != 1 else ''}" + (
            " and a drift" if system.drift else "")
        if system.known and not smooth:
            return "eorc", (f"auto: {inputs} with switchable known inputs -> EORC (no exact "
                            "solution is known for that meaning; known_inputs='smooth' gives "
                            "the exact general solution for smooth ones)")
        return "general_ui", f"auto: {inputs} -> general_ui"
    if method == "single_ui" and smooth:
        raise OptionError("method 'single_ui' answers for switchable known inputs; for "
                          "known_inputs='smooth' use method='general_ui' (or 'auto')")
    if method == "general_ui":
        general_ui_applicable(system, known_inputs)
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
