"""The one chooser: which analysis runs on a System, on which route, in which arithmetic,
decided before any sample is drawn (sympy's ``_dm_rref_choose_method``: one function with its
rules explained, then one dispatch in :mod:`uio_jax._analysis.analyze`).

The method, for ``method="auto"``, in order (the papers' theorems decide what is exact):

1. no unknown input -> ``"orc"`` (Hermann-Krener), or ``"general_ui"``'s closure along the
   drift when the known inputs are generic smooth functions of time;
2. one unknown input, no drift, known inputs switchable or absent -> ``"single_ui"``
   (Martinelli's analytic solution);
3. unknown inputs with switchable known inputs and a drift or several unknown inputs ->
   ``"eorc"`` (sufficient only: no exact solution is known for that meaning);
4. otherwise ``"general_ui"`` (Martinelli's general solution: exact).

``"fast"`` is ``"auto"`` with ``"series"`` in place of ``"orc"`` (the ORC's final span without
nested brackets). A named method is checked to apply (``"series"``/``"orc"`` need every input
known, ``"single_ui"`` one unknown input and switchable known inputs, ``"general_ui"`` smooth
known inputs).

The route: the Taylor route (the output's Taylor series at a random point modulo p,
Sedoglavic's test; :mod:`uio_jax._analysis.recursions.taylor_route`) for the ORC and the series
test on models of :data:`~uio_jax._analysis.recursions.taylor_route.TAYLOR_MIN_VARIABLES`
coordinates or more, without unknown or smooth known inputs and with a Taylor rule for every
node; below that size the symbolic route costs as little, and its generators are what the
follow-up questions test candidates against. With switchable known inputs ``"auto"`` takes
the series test on the Taylor route (the ORC's final span; the report says so). Where the
Taylor route cannot decide at its random points, the plan's ``fallback`` runs: the symbolic
route of the method the caller's options chose. A smaller model whose roots have no common
point modulo ``2^127 - 1`` (the symbolic route's prime) takes the Taylor route too, where that
route applies: it takes roots in ``F_p[i]`` and stays exact.
The arithmetic: exact modulo p where the model's outputs and fields are made rational (every
derivative of them is: :meth:`uio_jax._analysis.decisions.settle.Settler.arithmetic`, the one
place it is decided), extended precision otherwise. The symbolic route also needs a point
modulo p where the model's roots exist; the Taylor route takes roots in ``F_p[i]``, where
they always do.
"""

from .._calculus.generators import builder_for
from .._errors import OptionError
from .decisions.settle import model_roots, new_settler
from .recursions.general_ui import check_applicable as general_ui_applicable
from .recursions.series import check_applicable as series_applicable
from .recursions.single_ui import check_applicable as single_ui_applicable
from .recursions.taylor_route import TAYLOR_MIN_VARIABLES, taylor_applicable
from .results.kinds import Arithmetic, Method, Plan, Route

#: Why each arithmetic, in words (:attr:`Plan.why`; ``{primes}``: the route's, :data:`PRIMES_WHY`).
ARITHMETIC_WHY = {
    Arithmetic.EXACT: "every decision modulo {primes} at random points (the model's outputs and fields are "
                      "rational, or made rational by independent generators)",
    Arithmetic.EXTENDED: "decisions in extended precision (mpmath at two precisions): the model has a function "
                         "that is not made rational, or roots with no common point modulo p",
}

#: The primes of each route, in words (:attr:`Plan.why`, exact arithmetic).
PRIMES_WHY = {Route.SYMBOLIC: "p = 2^127 - 1", Route.TAYLOR: "random primes p below 2^26, roots in F_p[i]"}


def choose_method(system, method: str, known_inputs: str = "switchable") -> tuple[Method, str]:
    """The analysis to run on ``system`` (autonomous) and, for ``"auto"``/``"fast"``, the
    note that says why (the module docstring's rules).

    Raises:
        OptionError: a named method that does not apply to ``system``.
    """
    n_unknown = len(system.unknown)
    smooth = known_inputs == "smooth" and bool(system.known)
    if method == "fast":
        if n_unknown == 0 and not smooth:
            return Method.SERIES, "fast: no unknown input -> series (generic-input output series; ORC's verdict)"
        chosen, why = choose_method(system, "auto", known_inputs)
        return chosen, why.replace("auto:", "fast:", 1)
    if method == "auto":
        if n_unknown == 0:
            if smooth:
                return Method.GENERAL_UI, "auto: no unknown input, smooth known inputs -> general_ui"
            return Method.ORC, "auto: no unknown input -> ORC"
        if n_unknown == 1 and system.drift is None and not smooth:
            return Method.SINGLE_UI, "auto: one unknown input, no drift -> single_ui"
        inputs = f"{n_unknown} unknown input{'s' if n_unknown != 1 else ''}" + (
            " and a drift" if system.drift else "")
        if system.known and not smooth:
            return Method.EORC, (f"auto: {inputs} with switchable known inputs -> EORC (no exact "
                                 "solution is known for that meaning; known_inputs='smooth' gives "
                                 "the exact general solution for smooth ones)")
        return Method.GENERAL_UI, f"auto: {inputs} -> general_ui"
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
    if method == "series":
        series_applicable(system)
    if method == "single_ui":
        single_ui_applicable(system)
    return Method(method), ""


def plan(system, method: str = "auto", known_inputs: str = "switchable", *, seed: int = 0,
         prob_threshold: float | None = None, settler=None) -> Plan:
    """Choose the method, the route and the arithmetic of one analysis of ``system``
    (autonomous: :meth:`System.autonomous`), before any sample is drawn (module docstring).

    Args:
        system: the System the analysis runs on.
        method: the caller's ``method`` option (``"auto"``, ``"fast"`` or a method's name).
        known_inputs: ``"switchable"`` or ``"smooth"``.
        seed, prob_threshold: those of the analysis (its Settler's).
        settler: the analysis' :class:`~uio_jax._analysis.decisions.settle.Settler`, when the
            caller made it already (it keeps what it decided about the graph).

    Returns:
        :class:`~uio_jax._analysis.results.kinds.Plan`.

    Raises:
        OptionError: a named method that does not apply to ``system``.
    """
    chosen, note = choose_method(system, method, known_inputs)
    builder = builder_for(system)
    if settler is None:
        settler = new_settler(system, seed) if prob_threshold is None else new_settler(system, seed, prob_threshold)
    roots = model_roots(system, builder)
    arithmetic = settler.arithmetic(roots, roots_in_extension=True)  # the Taylor route's
    symbolic = arithmetic  # the symbolic route's: roots modulo p (asked where it matters)
    if arithmetic is Arithmetic.EXACT and system.n < TAYLOR_MIN_VARIABLES:
        symbolic = settler.arithmetic(roots)
    route, fallback = Route.SYMBOLIC, None
    route_why = ("the symbolic route: Lie derivatives and brackets as nodes of the model's expression graph, "
                 "decided at sampled states and settled at random points")
    taylor = chosen
    if method == "auto" and chosen is Method.ORC and system.known:
        taylor = Method.SERIES  # the ORC's steps are not the Taylor orders with inputs
    rootless = symbolic is not arithmetic  # exact only with roots in F_p[i]: the Taylor route at any size
    if taylor in (Method.ORC, Method.SERIES) and taylor_applicable(system, builder.graph, roots, arithmetic, taylor,
                                                                   any_size=rootless):
        fallback = Plan(chosen, Route.SYMBOLIC, symbolic, "the symbolic route, where the Taylor route "
                        "cannot decide at its random points", note)
        if taylor is not chosen:
            note = (f"{note}; {system.n} variables with known inputs -> the series test on the Taylor route "
                    "(the ORC's final span; its orders are not the ORC's steps)")
        chosen, route = taylor, Route.TAYLOR
        size = ("the model's roots have no common point modulo 2^127 - 1; roots in F_p[i] here" if rootless
                else f"{system.n} coordinates, at least {TAYLOR_MIN_VARIABLES}")
        route_why = (f"the Taylor route ({size}, no unknown input): "
                     "the output's Taylor coefficients at a random point modulo p, no symbolic Lie derivative")
    else:
        arithmetic = symbolic if system.n < TAYLOR_MIN_VARIABLES else settler.arithmetic(roots)
    method_why = note or f"method {chosen.value!r} as asked"
    why = f"{method_why}; {route_why}; {ARITHMETIC_WHY[arithmetic].format(primes=PRIMES_WHY[route])}"
    return Plan(chosen, route, arithmetic, why, note, fallback)


__all__ = ["plan", "choose_method"]
