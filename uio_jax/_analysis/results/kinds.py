"""The closed sets a result is made of: which analysis ran, on which route, what its answer
proves, and the plan that chose them (:func:`uio_jax._analysis.plan.plan` fills it).

Every member is a ``str`` whose value is its text (:class:`TextEnum`): it compares equal to
that text (``report.method == "eorc"``), is written as it in JSON, and prints as it in an
f-string, so that results keep the member and text is derived from it, never parsed back
(optimistix's ``RESULTS``, diffrax's ``RESULTS``).
"""

import dataclasses
import enum


class TextEnum(str, enum.Enum):
    """A ``str``-valued enumeration that formats as its value (``f"{Method.ORC}"`` is
    ``"orc"`` on every Python version; ``enum.StrEnum`` is 3.11+)."""

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


class Method(TextEnum):
    """The analysis that ran (``Report.method``; the papers' algorithms).

    ``ORC``: the observability rank condition, no unknown input (Hermann-Krener; 002
    Algorithm 1). ``SERIES``: the rank of the output's Taylor coefficients along a generic
    known input, the ORC's final codistribution (STRIKE-GOLDD's test). ``SINGLE_UI``:
    Martinelli's observable codistribution for one unknown input without drift (002
    Algorithms 2-3). ``GENERAL_UI``: Martinelli's general solution (any number of unknown
    inputs, drift, smooth known inputs). ``EORC``: the extended observability rank criterion
    (sufficient only below its bounds).
    """

    ORC = "orc"
    SERIES = "series"
    SINGLE_UI = "single_ui"
    GENERAL_UI = "general_ui"
    EORC = "eorc"

    @property
    def step_name(self) -> str:
        """How its steps are numbered: ``"k"`` (orders: the EORC, the series test), else ``"m"``."""
        return "k" if self in (Method.EORC, Method.SERIES) else "m"


class Route(TextEnum):
    """How the codistribution was computed (``Report.route``).

    ``SYMBOLIC``: Lie derivatives, brackets and rescaled fields built as nodes of the model's
    expression graph, their gradients evaluated at sampled states and settled modulo p.
    ``TAYLOR``: the output's Taylor coefficients and their gradients computed numerically,
    order by order, at a random point modulo p (Sedoglavic's route): no symbolic Lie
    derivative, no graph node per generator.
    """

    SYMBOLIC = "symbolic"
    TAYLOR = "taylor"


class Answer(TextEnum):
    """What a report's verdicts prove (``Report.answer``; decided by the analysis that ran,
    :func:`uio_jax._analysis.decisions.answer.decide_answer`).

    ``EXACT``: the necessary and sufficient question, every decision in exact arithmetic
    modulo p with the certificate's probability bound. ``NOT_CERTIFIED``: the necessary and
    sufficient question, but some decision was made in extended precision or on float64
    votes. ``SUFFICIENT_ONLY``: "observable" is proven, "not observable" means "not shown"
    (the EORC below its bounds, a recursion stopped by a cap, a general solution whose known
    inputs' jets may have been truncated).
    """

    EXACT = "exact"
    NOT_CERTIFIED = "not_certified"
    SUFFICIENT_ONLY = "sufficient_only"


class FollowUp(TextEnum):
    """A follow-up question asked of a report (the value is its key in ``to_dict()``)."""

    OBSERVABLE_FUNCTIONS = "observable_functions"
    SYMMETRIES = "found_symmetries"


class Verdict(TextEnum):
    """The verdict on one unknown (a ``str``: written as its value in JSON).

    ``DETERMINED``: locally identifiable (a parameter) or observable at ``t = 0`` (an unknown
    initial state): ``e_j`` lies in the row space of the Jacobian of the output coefficients,
    decided exactly. ``NOT_DETERMINED``: proved not (the span closed without it, or a verified
    symmetry moves it). ``UNDECIDED``: not determined up to the order reached, and not
    proved undeterminable.
    """

    DETERMINED = "determined"
    NOT_DETERMINED = "not_determined"
    UNDECIDED = "undecided"


class Arithmetic(enum.Enum):
    """How the rank decisions of an analysis were made (the weakest one decides).

    ``EXACT``: every decision modulo a prime at random points of the (rationalised) model,
    each wrong with a probability bounded a priori (``Certificate.error_bound``).
    ``EXTENDED``: some decision was settled in extended precision (mpmath at two
    precisions: the model has a function that is not made rational), none rests on float64.
    ``FLOAT64``: some decision rests on the float64 vote of the sampled states alone, or
    could not be settled.
    """

    EXACT = "exact arithmetic modulo p"
    EXTENDED = "extended precision (mpmath), not exact arithmetic"
    FLOAT64 = "float64 votes of the sampled states, not exact arithmetic"


@dataclasses.dataclass(frozen=True)
class Plan:
    """What :func:`uio_jax._analysis.plan.plan` chose, before any sample was drawn.

    Attributes:
        method: the analysis (:class:`Method`).
        route: the route it runs on (:class:`Route`).
        arithmetic: the arithmetic of its decisions: :attr:`Arithmetic.EXACT` where the
            model's outputs and fields are made rational (every derivative of them is),
            :attr:`Arithmetic.EXTENDED` where they are not (mpmath at two precisions).
        why: the choice in words (the method, the route, the arithmetic).
        note: the sentence the report's notes carry for the choice ("" for a method the
            caller named).
        fallback: the plan run where :attr:`route` cannot decide at its random points
            (the Taylor route: every point drawn singular, a degree bound too large): the
            symbolic route of the method the options chose; None where there is none.
    """

    method: Method
    route: Route
    arithmetic: Arithmetic
    why: str
    note: str = ""
    fallback: "Plan | None" = None

    def to_dict(self) -> dict:
        """JSON-ready: members as their values (the arithmetic as its name, lower case)."""
        return {"method": self.method.value, "route": self.route.value,
                "arithmetic": self.arithmetic.name.lower(), "why": self.why,
                "fallback": None if self.fallback is None else self.fallback.to_dict()}


__all__ = ["TextEnum", "Method", "Route", "Answer", "FollowUp", "Verdict", "Arithmetic", "Plan"]
