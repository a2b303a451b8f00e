"""The result of an analysis: dimensions per step, verdicts, evidence, the plan that chose it,
and the follow-up answers computed on it so far.

:class:`Report` holds the answer (it imports nothing above ``results/``); its unobservable
directions are computed by :mod:`uio_jax._analysis.results.directions` with the report's
``space`` (the final codistribution), its text written by
:mod:`uio_jax._analysis.results.report_text`. The follow-up questions
(:mod:`uio_jax._analysis.followups.questions`) keep what they computed in
:attr:`Report.followups`, which :meth:`Report.to_dict` serialises (it runs no search).
"""

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from ..._errors import ModelError
from . import directions
from .evidence import Certificate, Finding, Step, jsonable
from .functions_of_z import function_of_z
from .kinds import Answer, FollowUp, Method, Plan, Route, TextEnum, Verdict
from .report_text import answer_text, report_text
from .stop import Stop

#: What every analysis answers, as in the papers (Martinelli 2015/2017).
SEMANTICS = (
    "Unknown inputs are smooth (analytic) functions of time and known inputs may be chosen "
    "freely (they may jump), as in Martinelli's papers: a direction that could only be "
    "hidden by an unknown input that jumps together with a known input counts as "
    "observable. Tools such as STRIKE-GOLDD/StrikePy by default model an unknown input as "
    "a polynomial in time of fixed degree, which answers a different question."
)

#: The same, for known inputs that are generic smooth functions of time (``known_inputs="smooth"``).
SEMANTICS_SMOOTH = (
    "Unknown inputs are smooth (analytic) functions of time and known inputs are generic "
    "smooth functions of time, known with their derivatives (TUIO6's meaning): a direction "
    "that a smooth unknown input can hide for a generic smooth known input counts as "
    "unobservable, even if a jump of the known input would reveal it. Tools such as "
    "STRIKE-GOLDD/StrikePy by default model an unknown input as a polynomial in time of "
    "fixed degree, which answers a different question."
)


class Question(TextEnum):
    """Which question a report answers (a ``str``: written as its value in JSON).

    ``GENERIC_STATES``: the observable codistribution at generic states (every
    :class:`Report`); the others: :func:`uio_jax.analyze` with ``initial=`` or several
    experiments (:attr:`description` says each).
    """

    GENERIC_STATES = "generic_states"
    KNOWN_INITIAL_STATE = "known_initial_state"
    KNOWN_INITIAL_STATE_FREE_INPUT_JETS = "known_initial_state_free_input_jets"
    EXPERIMENTS = "experiments"
    EXPERIMENTS_FREE_INPUT_JETS = "experiments_free_input_jets"

    @property
    def sufficient_only(self) -> bool:
        """Whether only "determined" verdicts are proofs (unknown inputs with free jets)."""
        return self in (Question.KNOWN_INITIAL_STATE_FREE_INPUT_JETS, Question.EXPERIMENTS_FREE_INPUT_JETS)

    @property
    def description(self) -> str:
        """The question in words."""
        return _QUESTIONS[self]


_QUESTIONS = {
    Question.GENERIC_STATES: "the observable functions at generic states (the observable codistribution)",
    Question.KNOWN_INITIAL_STATE: (
        "local identifiability of the parameters and observability of the unknown initial states "
        "at the given initial state (its known components at the given values, not generic ones), "
        "from the output's Taylor coefficients at t = 0; known inputs generic"),
    Question.KNOWN_INITIAL_STATE_FREE_INPUT_JETS: (
        "local identifiability of the parameters and observability of the unknown initial states "
        "at the given initial state, with the unknown inputs' derivatives at t = 0 free unknowns: "
        "sufficient only ('determined' is proven, 'not determined up to order K' is not a proof)"),
    Question.EXPERIMENTS: (
        "local identifiability from several experiments: parameters shared, states, inputs and "
        "initial states per experiment; from the outputs' Taylor coefficients at t = 0"),
    Question.EXPERIMENTS_FREE_INPUT_JETS: (
        "local identifiability from several experiments with the unknown inputs' derivatives at "
        "t = 0 free unknowns: sufficient only"),
}


def refuse(what: str, why: str) -> ModelError:
    """The one-line refusal of a question a report does not answer (``what: why``)."""
    return ModelError(f"{what}: {why}")


#: Why a report has no global answer.
GLOBAL_NOT_ASKED = "the global question was not asked: uj.analyze(system, scope='global') (uio-jax analyze --global)"


def global_answer(report, what: str):
    """``report.global_answer`` (the :class:`~uio_jax.GlobalResult` of ``scope="global"``), or
    a one-line refusal naming ``what`` was asked."""
    if report.global_answer is None:
        raise refuse(what, GLOBAL_NOT_ASKED)
    return report.global_answer


class ReportQueries:
    """What both reports (:class:`Report`, the identifiability report at t = 0) answer alike."""

    @property
    def global_identifiability(self) -> Mapping:
        """Parameter or unknown initial state -> :class:`~uio_jax.GlobalVerdict` (``global``,
        ``local``, ``not``, ``undecided``), with ``scope="global"``; refused otherwise."""
        return global_answer(self, "global_identifiability").global_identifiability

    @property
    def value_counts(self) -> Mapping:
        """How many values each unknown takes where known (``scope="global"``)."""
        return global_answer(self, "value_counts").value_counts

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)


@dataclass(eq=False)
class FollowUps:
    """The follow-up answers computed on one report so far, each once (a cache the
    follow-up functions fill: :func:`uio_jax.observable_functions`,
    :func:`uio_jax.find_symmetries`). ``answers``: :class:`FollowUp` -> its result (an
    object with ``to_dict()``)."""

    answers: dict = field(default_factory=dict)

    def get(self, question: FollowUp):
        """The answer to ``question``, None when it was not asked yet."""
        return self.answers.get(question)

    def keep(self, question: FollowUp, answer):
        """Remember ``answer`` to ``question``; returns it."""
        self.answers[question] = answer
        return answer

    def to_dict(self) -> dict:
        """``{key: answer.to_dict()}`` of the questions answered (none asked: empty)."""
        return {q.value: a.to_dict() for q, a in self.answers.items()}


@dataclass(frozen=True, eq=False)
class Report(ReportQueries):
    """Result of :func:`uio_jax.analyze`.

    Attributes:
        method: the analysis that ran (:class:`~uio_jax._analysis.results.kinds.Method`, a
            ``str``: ``"orc"``, ``"series"``, ``"single_ui"``, ``"general_ui"``, ``"eorc"``).
        states: state names (order of the state vector).
        dim: generic dimension of the observable codistribution on the original state
            (on ``[x; p]`` when the System has parameters).
        observable: state name -> whether its differential lies in the codistribution.
        params: names of the unknown constant parameters (empty without ``params=``).
        identifiable: parameter name -> whether it is identifiable (its differential lies
            in the codistribution of the joint system ``[x; p]``, ``p' = 0``).
        history: one :class:`Step` per step m (per order k for the EORC).
        certificate: the sampling evidence behind every rank decision.
        generators: labels of the functions whose gradients span the final codistribution.
        stop: why the recursion stopped: a :class:`~uio_jax._analysis.results.stop.Stop`;
            ``stop_reason`` is its text.
        answer: what the verdicts prove (:class:`~uio_jax._analysis.results.kinds.Answer`),
            decided by the analysis that ran; :attr:`exact` reads it.
        notes: remarks (method choice, sufficiency of the EORC, corrections applied).
        details: method-specific results (``m_prime``, ``m_star``, ``k``, ...).
        semantics: what "unknown input" and "known input" mean in this answer.
        known_inputs: the meaning of the known inputs the answer is for: ``"switchable"``
            (they may jump), ``"smooth"`` (generic smooth functions of time) or ``"none"``.
        system_name: name of the analyzed System.
        route: how the codistribution was computed (:class:`~uio_jax._analysis.results.kinds.Route`).
        plan: what :func:`uio_jax._analysis.plan.plan` chose before any sample was drawn, and
            why (:class:`~uio_jax._analysis.results.kinds.Plan`; None without ``analyze``).
        space: the final codistribution as the report's queries read it (a
            :class:`~uio_jax._analysis.decisions.space.Space`).
        followups: the follow-up answers computed so far (:class:`FollowUps`).
        global_answer: the :class:`~uio_jax.GlobalResult` of ``scope="global"`` (None when the
            global question was not asked): :attr:`global_identifiability`, :attr:`value_counts`.
    """

    method: Method
    states: tuple[str, ...]
    dim: int
    observable: Mapping[str, bool]
    history: tuple[Step, ...]
    certificate: Certificate
    generators: tuple[str, ...]
    stop: Stop
    answer: Answer
    notes: tuple[str, ...] = ()
    details: Mapping = field(default_factory=dict)
    semantics: str = SEMANTICS
    system_name: str = ""
    params: tuple[str, ...] = ()
    identifiable: Mapping[str, bool] = field(default_factory=dict)
    known_inputs: str = "switchable"
    route: Route = Route.SYMBOLIC
    plan: Plan | None = None
    space: object = field(default=None, repr=False)
    followups: FollowUps = field(default_factory=FollowUps, repr=False)
    global_answer: object = field(default=None, repr=False)

    def __post_init__(self):
        params = tuple(self.params)
        observable = dict(self.observable)
        identifiable = dict(self.identifiable)
        for p in params:  # verdicts on parameters given among the states: move them
            if p in observable:
                identifiable[p] = observable.pop(p)
        object.__setattr__(self, "method", Method(self.method))
        object.__setattr__(self, "route", Route(self.route))
        object.__setattr__(self, "answer", Answer(self.answer))
        object.__setattr__(self, "params", params)
        object.__setattr__(self, "states", tuple(s for s in self.states if s not in params))
        object.__setattr__(self, "observable", MappingProxyType(observable))
        object.__setattr__(self, "identifiable", MappingProxyType(identifiable))
        object.__setattr__(self, "details", MappingProxyType(dict(self.details)))

    @property
    def question(self) -> Question:
        """The question answered: :attr:`Question.GENERIC_STATES` (the observable
        codistribution at generic states)."""
        return Question.GENERIC_STATES

    @property
    def stop_reason(self) -> str:
        """Why the recursion stopped, as text (:attr:`stop`'s message)."""
        return self.stop.message

    @property
    def variables(self) -> tuple[str, ...]:
        """Coordinates of the analysed vector: states, then parameters."""
        return self.states + self.params

    @property
    def n(self) -> int:
        """Dimension of the analysed vector (states plus parameters)."""
        return len(self.variables)

    @property
    def undecided(self) -> tuple[str, ...]:
        """The states and parameters whose verdict is not certified (empty when every rank
        decision was clear in float64 or settled beyond it).

        From the undecided escalations of the certificate: the membership of ``e_i``
        leaves variable ``i``'s verdict open; a generator kept on its float64 vote leaves
        open every "observable" verdict (the span may be smaller), one rejected every "not
        observable" one (the span may be larger).
        """
        names = self.variables
        verdict = {**dict(self.observable), **dict(self.identifiable)}
        open_ = set()
        for e in self.certificate.escalations:
            if e.result is not Finding.UNDECIDED:
                continue
            if e.coordinate is not None:  # a membership of d z_i
                if e.coordinate < len(names):
                    open_.add(names[e.coordinate])
                continue
            kept = e.vote is Finding.INDEPENDENT
            open_.update(v for v in names if verdict.get(v) == kept)
        return tuple(v for v in names if v in open_)

    @property
    def verdicts(self) -> Mapping:
        """Every state and parameter -> :class:`~uio_jax._analysis.results.kinds.Verdict`, as
        an identifiability report at t = 0 gives them: ``DETERMINED`` (observable,
        identifiable), ``NOT_DETERMINED`` (not, by a necessary and sufficient answer),
        ``UNDECIDED`` (its decision not certified, or "not shown" by a sufficient-only answer)."""
        open_ = set(self.undecided)
        proved_not = self.answer is not Answer.SUFFICIENT_ONLY
        return MappingProxyType({
            v: Verdict.UNDECIDED if v in open_ else Verdict.DETERMINED if ok else
            Verdict.NOT_DETERMINED if proved_not else Verdict.UNDECIDED
            for v, ok in {**self.observable, **self.identifiable}.items()})

    @property
    def fully_determined(self) -> bool:
        """:attr:`fully_observable` (the name an identifiability report at t = 0 uses)."""
        return self.fully_observable

    @property
    def fully_observable(self) -> bool:
        """True when every state component is observable and every parameter identifiable."""
        return all(self.observable.values()) and all(self.identifiable.values())

    @property
    def dims(self) -> tuple[int, ...]:
        """Dimension per step, ``tuple(step.dim for step in history)``."""
        return tuple(s.dim for s in self.history)

    def domain_centre(self) -> np.ndarray:
        """``(n,)``: the centre of the sampling box of every state and parameter
        (:func:`uio_jax._analysis.results.directions.domain_centre`)."""
        return directions.domain_centre(self, self.space)

    def unobservable_directions(self, x=None, p=None, t=None) -> np.ndarray:
        """Basis of the unobservable directions (null space of the codistribution) at a point.

        These are the continuous symmetries of the system: moving the state (and the
        parameters) along them does not change the outputs (e.g. a rotation about the
        feature; for ``x' = -(a + b) x`` the direction ``(0, 1, -1) / sqrt(2)`` on
        ``(x, a, b)``: only ``a + b`` is identifiable).

        Args:
            x: the point ``z = [x; p]``, shape ``(n,)`` with ``n = len(states) +
                len(params)`` (:attr:`variables`); or, with ``p``, the state alone, shape
                ``(len(states),)``. Default: :meth:`domain_centre`.
            p: the parameters, shape ``(len(params),)``, when ``x`` is the state alone.
            t: the time, for a time-varying System (default: the centre of its box, the
                time the printed directions state).

        Returns:
            ``(n, n - dim)`` array with orthonormal columns (rows: :attr:`variables`).

        Raises:
            ModelError: a point of the wrong shape or with NaN/inf, or a point where the
                codistribution is not defined.
        """
        z = directions.point(self, self.space, x, p, "unobservable_directions")
        return self.space.unobservable_directions(z) if t is None else self.space.unobservable_directions(z, at=t)

    def direction_summary(self, x=None, p=None) -> dict:
        """The unobservable directions at a point (default: the centre of the sampling box),
        labelled by the variables' names, with the identifiable parameter combinations:
        :func:`uio_jax._analysis.results.directions.direction_summary` says how."""
        return directions.direction_summary(self, self.space, x, p)

    def representative_point(self) -> tuple[np.ndarray, str]:
        """``(z, rule)``: where the report's directions are given (the centre of the sampling
        box where the rank is generic, else a fixed point off it:
        :func:`uio_jax._analysis.results.directions.representative_point`)."""
        return directions.representative_point(self, self.space)

    def format_directions(self, summary=None) -> str:
        """Text of :meth:`direction_summary` (default: at the centre of the sampling box).

        One line naming the point, one line per direction (components that print as
        zero at 3 decimals omitted), and for a model with parameters one line per
        identifiable combination of parameters that are not identifiable one by one.
        """
        return directions.format_directions(self, self.space, summary)

    def sample_singular_values(self) -> np.ndarray:
        """How sure the rank is: per-sample singular values of the final generators.

        The kept generators' gradients at every used sample, columns scaled by the
        sampling box and rows by their norm (as in every rank decision), give a matrix
        ``(r, n)`` per sample; its singular values divided by the largest are returned.
        ``certificate.rtol`` and ``certificate.sigma_next_max`` (largest rejected margin)
        lie below the last column at every sample at the generic rank: the gap is the
        evidence.

        Returns:
            ``(S_used, r)`` array, descending along each row (``r = 0``: shape ``(S, 0)``).
        """
        return self.space.sample_singular_values()

    def is_observable(self, fn) -> bool:
        """Whether the scalar function ``fn`` is observable (``d fn`` in the span).

        Args:
            fn: callable returning a scalar ``()``, traceable by JAX: ``fn(z)`` with
                ``z = [x; p]`` of shape ``(n,)`` (:attr:`variables`: states then
                parameters), or, for a model with parameters, ``fn(x, p)`` with ``x``
                of shape ``(len(states),)`` and ``p`` of shape ``(len(params),)``. The
                form is read from the number of required positional parameters.

        Raises:
            ModelError: not a callable, a signature of neither form, a function that
                fails on those shapes or does not return a scalar.
        """
        return self.space.is_observable(function_of_z(self, fn, "is_observable"))

    # ------------------------------------------------------------------ follow-up aliases
    # Thin aliases of the follow-up functions, kept for one release (0.2 drops them): the only
    # imports of this module above ``results/`` (tests/test_layout.py lists them).

    @property
    def named_functions(self):
        """Deprecated alias of :func:`uio_jax.observable_functions` ``(self)`` (the
        :class:`~uio_jax._analysis.followups.observable_functions.ObservableFunctions`)."""
        from ..followups.questions import observable_functions

        return observable_functions(self)

    @property
    def symmetries(self):
        """Deprecated alias of :func:`uio_jax.find_symmetries` ``(self)``."""
        from ..followups.questions import find_symmetries

        return find_symmetries(self)

    def reparametrised_model(self) -> dict | None:
        """Deprecated alias of :func:`uio_jax.reparametrise` ``(self)``."""
        from ..followups.questions import reparametrise

        return reparametrise(self)

    @property
    def observable_functions(self) -> tuple[str, ...]:
        """Deprecated alias of ``uj.observable_functions(self).texts``: the named observable
        functions as sympy-readable strings."""
        return self.named_functions.texts

    def to_dict(self) -> dict:
        """JSON-ready dictionary (no callables).

        For a model with parameters it also holds ``unobservable_directions`` (the
        directions of :meth:`direction_summary` as ``{name: coefficient}``, None when they
        cannot be computed there), ``identifiable_combinations`` and ``directions_at``
        (``{"rule": ..., "point": {name: value}}``, plus ``"error"`` when the directions
        failed): the point is the centre of the sampling box of every state and parameter.
        Reports without parameters have no such keys.
        """
        return jsonable({
            "system": self.system_name,
            "method": self.method,
            "question": self.question.value,
            "states": list(self.states),
            "dim": self.dim,
            "n": self.n,
            "fully_observable": self.fully_observable,
            "observable": dict(self.observable),
            "undecided": list(self.undecided),
            "params": list(self.params),
            "identifiable": dict(self.identifiable),
            "dims": list(self.dims),
            "history": [s.to_dict() for s in self.history],
            "generators": list(self.generators),
            "stop_reason": self.stop_reason,
            "stop": self.stop.reason.name.lower(),
            "certificate": self.certificate.to_dict(),
            "details": dict(self.details),
            "notes": list(self.notes),
            "semantics": self.semantics,
            "exact": self.exact,
            "known_inputs": self.known_inputs,
            "answer": self.answer.value,
            "route": self.route.value,
            "plan": None if self.plan is None else self.plan.to_dict(),
            **self.followups.to_dict(),
            **({} if self.global_answer is None else {"global": self.global_answer.to_dict()}),
            **(directions.directions_dict(self, self.space) if self.params else {}),
        })

    def answer_kind(self) -> str:
        """What the verdicts prove, in words (:attr:`answer` with the question it answers:
        :func:`~uio_jax._analysis.results.report_text.answer_text`)."""
        return answer_text(self)

    @property
    def exact(self) -> bool:
        """Whether the verdicts are exact: the question is the necessary and sufficient one
        (not a sufficient condition) and every decision was made in exact arithmetic, with
        the probability bound of the certificate (:attr:`answer` is ``Answer.EXACT``)."""
        return self.answer is Answer.EXACT

    def __str__(self) -> str:
        return report_text(self)
