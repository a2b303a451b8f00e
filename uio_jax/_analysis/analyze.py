"""``analyze``: check the options (:mod:`uio_jax._analysis.options`), plan
(:func:`uio_jax._analysis.plan.plan`, before any sample is drawn; its module docstring states
the rules of ``method="auto"``), dispatch (:func:`dispatch`), add the notes.
"""

import dataclasses

from .._calculus.generators import builder_for
from .._engine.graph_trace import GraphFunction
from .._errors import OptionError
from .._model.experiments import Experiments
from .._model.symmetries import symmetry_fields
from .._model.system import System
from .at_t0.identifiability import analyze_experiments, analyze_initial
from .at_t0.initial import unused_note, unused_parameters
from .decisions.context import Context
from .decisions.memory import check_memory
from .decisions.settle import new_settler
from .decisions.symmetry import symmetry_notes, verify_symmetries
from .followups.questions import observable_functions
from .globally.run import DEFAULT_TIMEOUT, check_global, global_identifiability
from .options import DEFAULTS, check_options
from .plan import plan
from .recursions.eorc import eorc_report
from .recursions.general_ui import general_ui_report
from .recursions.orc import run_orc
from .recursions.series import series_report
from .recursions.single_ui import single_ui_report
from .recursions.taylor_route import NotTaken, taylor_report
from .results.kinds import FollowUp, Method, Route
from .results.report import Report


def analyze(system: System, *, method: str = DEFAULTS["method"], samples: int = DEFAULTS["samples"],
            seed: int = DEFAULTS["seed"], rtol: float | None = DEFAULTS["rtol"],
            max_order: int | None = DEFAULTS["max_order"], k_max: int | None = DEFAULTS["k_max"],
            known_inputs: str = DEFAULTS["known_inputs"], prob_threshold: float = DEFAULTS["prob_threshold"],
            initial=None, shared=None, scope: str = DEFAULTS["scope"], global_timeout: float | None = None):
    """Which states of ``system`` are observable: the observable codistribution.

    Main arguments:
        system: a :class:`~uio_jax.System`; or several experiments (a sequence of Systems, or
            :class:`~uio_jax.Experiments`): then, as with ``initial=``, see below.

    Other arguments:
        method: ``"auto"`` (default), ``"orc"``, ``"single_ui"``, ``"general_ui"``,
            ``"eorc"``, ``"series"`` or ``"fast"``: how ``"auto"`` and ``"fast"`` choose is in
            :mod:`uio_jax._analysis.plan`; ``Report.method`` records the choice and
            ``Report.plan`` the whole plan (method, route, arithmetic, why).
        samples: number S of random states drawn for the float64 screen (votes at the first
            decision samples; margins and the figure at as many as fit in memory,
            ``Certificate.capped``). The verdicts do not rest on these votes: every decision
            is settled again modulo p (or in extended precision).
        prob_threshold: the probability of correctness the exact decisions must reach
            (default 0.999999): each decision modulo ``p = 2^127 - 1`` is wrong with
            probability at most ``D / p`` per point (Schwartz-Zippel), points are added until
            the sum, ``Certificate.error_bound``, is under ``1 - prob_threshold``.
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
        scope: ``"local"`` (default) or ``"global"``: also how many values each parameter and
            unknown initial state takes (``rep.global_identifiability``, ``rep.value_counts``;
            SIAN's route solved by msolve, the ``global`` extra: :mod:`uio_jax._analysis.globally`,
            ``docs/global.md``), within ``global_timeout`` seconds (default 600; past it the
            answer is "undecided" with the reason).

    Returns:
        :class:`~uio_jax.Report`. For a System with ``params``, the analysis runs on
        ``z = [x; p]`` with ``p' = 0`` (:meth:`System.joint`) and the Report lists the
        parameters apart (``params``, ``identifiable``).

    Raises:
        OptionError: unknown method, an option out of its range (samples < 8, a seed
            outside ``[0, 2**64)``, rtol not in (0, 1), ...), a method that does not apply
            (``"series"`` on a model the Taylor engines cannot expand), or a request whose
            arrays cannot fit in memory: samples x n x n x 8 bytes and more, or, for the
            EORC, samples x N x N with N = n + k_max m_w (:mod:`uio_jax._analysis.decisions.memory`;
            the limit is ``$UIO_JAX_MEMORY_LIMIT``, default half the physical memory).
        ModelError: a model that fails at the sampled states.

    References:
        Martinelli, IROS 2017 (002): Algorithms 1-3; INRIA RR-8608 (004): sections 4-10.
    """
    scope = check_options(scope=scope)["scope"]
    timeout = DEFAULT_TIMEOUT if global_timeout is None else global_timeout
    if scope == "global":  # what the global question refuses, refused before any work
        if not isinstance(system, System) or shared is not None:
            raise OptionError("scope='global' answers one System (with or without initial=), not several experiments")
        check_global(system, initial, seed=seed, prob_threshold=prob_threshold, timeout=timeout)
    report = _local(system, method=method, samples=samples, seed=seed, rtol=rtol, max_order=max_order, k_max=k_max,
                    known_inputs=known_inputs, prob_threshold=prob_threshold, initial=initial, shared=shared)
    if scope == "global":
        report = _with_global(report, system, initial, seed, prob_threshold, max_order, timeout)
    return report


def _with_global(report, system, initial, seed, prob_threshold, max_order, timeout):
    """``report`` with the global answer (``report.global_answer``); on a generic-state report
    whose functions are named on the model's own graph, the named observable functions are
    asked too, and each gets its ``globally`` mark."""
    graph, named = builder_for(system.joint()).graph, None
    if isinstance(report, Report) and report.route is Route.SYMBOLIC and report.space.parts().builder.graph is graph:
        named = observable_functions(report)
    asked = {f"f{i}": GraphFunction(graph, f.node) for i, f in enumerate(named.functions if named else ())
             if f.node is not None}
    answer = global_identifiability(system, initial=initial, seed=seed, prob_threshold=prob_threshold,
                                    max_order=max_order, timeout=timeout, functions=asked or None)
    if asked:  # the marks go on the named functions; the answer keeps the unknowns
        marks = answer.global_identifiability
        marked = [dataclasses.replace(f, globally=marks[f"f{i}"].value) if f"f{i}" in marks else f
                  for i, f in enumerate(named.functions)]
        report.followups.keep(FollowUp.OBSERVABLE_FUNCTIONS, dataclasses.replace(named, functions=tuple(marked)))
        answer = dataclasses.replace(answer, functions=(), global_identifiability={
            k: v for k, v in marks.items() if k not in asked}, value_counts={
            k: v for k, v in answer.value_counts.items() if k not in asked})
    return dataclasses.replace(report, global_answer=answer)


def _local(system, *, method, samples, seed, rtol, max_order, k_max, known_inputs, prob_threshold, initial, shared):
    """The local question: the observable codistribution at generic states, or identifiability
    at t = 0 with ``initial=`` or several experiments."""
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
    settler = new_settler(system, seed, opts["prob_threshold"])
    chosen = plan(system, method, known_inputs, settler=settler)
    report = dispatch(system, chosen, settler, samples=samples, seed=seed, rtol=rtol, max_order=max_order,
                      k_max=k_max, known_inputs=known_inputs, prob_threshold=opts["prob_threshold"])
    return _with_notes(dataclasses.replace(report, plan=chosen), system, k_max, seed)


def _identifiability(system, initial, shared, method, seed, max_order, prob_threshold):
    """The known-initial-state or several-experiment analysis (:mod:`.identifiability`):
    ``max_order`` caps the order of the coefficients (default ``2 u + 2``, ``u`` the number of
    unknowns); ``method`` must be ``"auto"``; the other options do not apply."""
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
    return _noted(report, f"{', '.join(ignored)} not used: at t = 0 there is no float64 screen (samples, rtol), "
                  "no EORC (k_max), and known inputs are generic (known_inputs)")


def _with_notes(report, system, k_max, seed):
    """``report`` with what the run alone does not say: outputs that add nothing, a
    ``k_max`` given to a method that does not use it, the declared symmetries (verified;
    the EORC uses them itself), the meaning of switchable known inputs."""
    report = _with_idle_outputs_note(report, system)
    unused = unused_parameters(system)
    if unused:
        report = _noted(report, unused_note(unused))
    if k_max is not None and report.method is not Method.EORC:  # given, but not used: said, not silent
        report = _noted(report, f"k_max={k_max} applies to the EORC only: the {report.method} analysis that "
                                "ran does not use it (max_order caps its steps)")
    if report.method is not Method.EORC and symmetry_fields(system):
        report = _with_symmetries(report, system, seed)
    if report.known_inputs == "switchable":
        report = _noted(report, SWITCHABLE_NOTE)
    return report


def _noted(report, *notes):
    """``report`` with ``notes`` added after its own."""
    return dataclasses.replace(report, notes=tuple(report.notes) + notes)


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
    return _noted(report, note)


def _with_symmetries(report, system, seed):
    """``report`` with the notes and ``details["symmetries"]`` of the System's verified
    symmetries (:mod:`uio_jax._analysis.decisions.symmetry`): the coordinates they move are proved
    unobservable, and a verdict that contradicts one is flagged."""
    cert = report.certificate
    bound = verify_symmetries(system, seed=seed, prob_threshold=cert.prob_threshold)
    verdicts = {**report.observable, **report.identifiable}
    notes, _ = symmetry_notes(bound, verdicts, "the final span", report.dim)
    details = {**report.details, "symmetries": bound.to_dict()}
    if bound.probability:  # the verification's bound, charged to the report's certificate
        cert = dataclasses.replace(cert, error_bound=cert.error_bound + bound.probability)
    return dataclasses.replace(report, notes=tuple(report.notes) + tuple(notes), details=details, certificate=cert)


def dispatch(system, chosen, settler, *, samples, seed, rtol, max_order, k_max, known_inputs, prob_threshold):
    """Run the :class:`~uio_jax._analysis.results.kinds.Plan` ``chosen`` on the autonomous
    ``system`` (``settler``: the plan's, shared by the analysis) and return its Report.

    Where the Taylor route cannot decide at its random points (``NotTaken``), the plan's
    fallback runs and the report says so."""
    notes = [chosen.note] if chosen.note else []
    if chosen.method is Method.EORC:  # its size depends on k_max: checked by the EORC itself
        return eorc_report(system, samples=samples, seed=seed, rtol=rtol, k_max=k_max, prob_threshold=prob_threshold,
                           notes=notes, known_inputs=known_inputs)
    check_memory(samples, system.n, what=f"samples={samples} x {system.n} states", advice="lower samples")
    if chosen.method is Method.GENERAL_UI:
        return general_ui_report(system, samples=samples, seed=seed, rtol=rtol, prob_threshold=prob_threshold,
                                 known_inputs=known_inputs, notes=notes)
    ctx = Context(system, samples, seed, rtol, prob_threshold, settler=settler)
    if chosen.route is Route.TAYLOR:
        try:
            return taylor_report(ctx, chosen.method, seed=seed, why=chosen.note, max_order=max_order)
        except NotTaken as exc:
            chosen = chosen.fallback
            notes = ([chosen.note] if chosen.note else []) + [
                f"the Taylor route could not decide ({exc}): the symbolic route ran"]
    if chosen.method is Method.ORC:
        labels = [lbl for lbl in system.fields() if lbl not in system.unknown]
        history, reason = run_orc(ctx, labels, max_steps=max_order)
        return ctx.report("orc", history, reason, notes=notes)
    if chosen.method is Method.SERIES:
        return series_report(ctx, seed=seed, notes=notes, max_order=max_order)
    return single_ui_report(ctx, notes=notes, max_order=max_order)
