"""The follow-up questions asked of a finished analysis, as functions of its report
(StructuralIdentifiability.jl keeps ``find_identifiable_functions`` apart from
``assess_identifiability``): which readable functions are observable, which closed-form
symmetries move what is not, and a model whose parameters are all identifiable.

Each reads the report's final codistribution (``Report.space``): the symbolic route keeps its
generators as nodes of the model's expression graph, which the candidates are tested against;
the Taylor route keeps only the output's Taylor coefficients at a point (each answer says
what that leaves out). An answer is computed once per report and kept in ``Report.followups``.
"""

from ..._errors import ModelError
from ..results.kinds import FollowUp, Method, Route
from ..results.report import Report
from .found_symmetries import FoundSymmetries
from .found_symmetries import find_symmetries as _search_symmetries
from .observable_functions import ObservableFunctions, name_functions
from .point_naming import name_at_point
from .reparametrise import reparametrised_model


def _report(rep, what: str) -> Report:
    if not isinstance(rep, Report):
        kind = type(rep).__name__
        hint = (" (the identifiability report at t = 0 answers is_observable; it has no span to name "
                "functions on)" if kind == "IdentifiabilityReport" else "")
        raise ModelError(f"{what} needs the Report of uj.analyze on a System, got {kind}{hint}")
    return rep


def observable_functions(rep: Report) -> ObservableFunctions:
    """Readable observable functions that span the observable codistribution of ``rep``,
    each checked exactly (:mod:`uio_jax._analysis.followups.observable_functions`); on the
    Taylor route, the candidates that need no ansatz, tested at the route's random point
    (:mod:`uio_jax._analysis.followups.point_naming`). Computed once per report (about the
    cost of a small analysis) and kept in ``rep.followups``.

    Args:
        rep: a :class:`~uio_jax.Report` of :func:`uio_jax.analyze`.

    Returns:
        :class:`~uio_jax._analysis.followups.observable_functions.ObservableFunctions`
        (``.texts``: the functions as sympy-readable strings; ``.complete``: ``dim`` of
        them were named).

    Raises:
        ModelError: not a Report of a generic-state analysis.
    """
    rep = _report(rep, "observable_functions")
    known = rep.followups.get(FollowUp.OBSERVABLE_FUNCTIONS)
    if known is not None:
        return known
    if rep.route is Route.TAYLOR:
        named = name_at_point(rep.space, rep.dim, rep.generators)
    else:
        inputs = len(rep.details.get("extended_state", ())) - rep.n if rep.method is Method.EORC else 0
        named = name_functions(rep.space.parts(), inputs=max(inputs, 0))
    return rep.followups.keep(FollowUp.OBSERVABLE_FUNCTIONS, named)


def find_symmetries(rep: Report) -> FoundSymmetries:
    """The unobservable distribution of ``rep`` as verified closed-form symmetries:
    polynomial vector fields of degree at most 1 (translations, rotations, scalings) found
    by an exact ansatz and verified by the symmetry check of declared symmetries
    (:mod:`uio_jax._analysis.followups.found_symmetries`). Not searched on the Taylor route
    (said in the answer). Computed once per report and kept in ``rep.followups``.

    Raises:
        ModelError: not a Report of a generic-state analysis.
    """
    rep = _report(rep, "find_symmetries")
    known = rep.followups.get(FollowUp.SYMMETRIES)
    if known is not None:
        return known
    if rep.route is Route.TAYLOR:
        found = FoundSymmetries((), rep.n - rep.dim, "" if rep.n == rep.dim else
                                "the Taylor route keeps no symbolic generators to search against")
    else:
        parts = rep.space.parts()
        found = _search_symmetries(parts, parts.original)
    return rep.followups.keep(FollowUp.SYMMETRIES, found)


def reparametrise(rep: Report) -> dict | None:
    """A model whose parameters are all identifiable, in the model-file schema
    (:func:`uio_jax.save_model` writes it as TOML), or None when every parameter of ``rep``
    is identifiable already: the parameters of a cross-section of the unobservable
    directions fixed, the others standing for identifiable combinations
    (:mod:`uio_jax._analysis.followups.reparametrise`; it uses :func:`find_symmetries`).

    Raises:
        ModelError: not a Report of a generic-state analysis; the analysis ran on more
            coordinates than the report's (EORC, a time-varying model) or on the Taylor
            route (no symbolic generators); a function of the model has no expression text.
    """
    rep = _report(rep, "reparametrise")
    if all(rep.identifiable.values()):
        return None
    if rep.route is Route.TAYLOR:
        raise ModelError("reparametrise: the Taylor route keeps no symbolic generators to choose a "
                         "cross-section with (method='orc' takes the symbolic route)")
    parts = rep.space.parts()
    if parts.builder.graph.n != rep.n:
        raise ModelError("reparametrised_model: the analysis ran on more coordinates than the "
                         "states and parameters (EORC, general_ui extension or time)")
    try:
        return reparametrised_model(parts, rep, find_symmetries(rep))
    except ValueError as exc:
        raise ModelError(f"reparametrised_model: {exc}") from None


__all__ = ["observable_functions", "find_symmetries", "reparametrise"]
