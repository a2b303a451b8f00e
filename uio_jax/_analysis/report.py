"""The result of an analysis: dimensions per step, verdicts, evidence, symmetries.

:class:`Report` holds the answer; its unobservable directions are computed by
:mod:`uio_jax._analysis.directions`, the functions handed to :meth:`Report.is_observable`
checked by :mod:`uio_jax._analysis.functions_of_z`, its text written by
:mod:`uio_jax._analysis.report_text`.
"""

import enum
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .._errors import ModelError
from . import directions
from .driver import Stop
from .evidence import Arithmetic, Certificate, Step, jsonable
from .found_symmetries import FoundSymmetries, find_symmetries
from .functions_of_z import function_of_z
from .observable_functions import ObservableFunctions, name_functions
from .point_naming import name_at_point
from .reparametrise import reparametrised_model
from .report_text import report_text

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


class Question(str, enum.Enum):
    """Which question a report answers (a ``str``: written as its value in JSON).

    ``GENERIC_STATES``: the observable codistribution at generic states (every
    :class:`Report`). The others are answered by :func:`uio_jax.analyze` with ``initial=``
    or several experiments (:mod:`uio_jax._analysis.initial`): local identifiability of
    the parameters and of the unknown initial states at the given initial state, from the
    output's Taylor coefficients at ``t = 0``; ``*_FREE_INPUT_JETS``: with unknown inputs,
    whose derivatives at ``t = 0`` are free unknowns (sufficient only: "determined" is
    proven, the rest is not shown).
    """

    GENERIC_STATES = "generic_states"
    KNOWN_INITIAL_STATE = "known_initial_state"
    KNOWN_INITIAL_STATE_FREE_INPUT_JETS = "known_initial_state_free_input_jets"
    EXPERIMENTS = "experiments"
    EXPERIMENTS_FREE_INPUT_JETS = "experiments_free_input_jets"

    @property
    def sufficient_only(self) -> bool:
        """Whether only "determined" verdicts are proofs (unknown inputs with free jets)."""
        return self.value.endswith("free_input_jets")

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


@dataclass(frozen=True, eq=False)
class Report:
    """Result of :func:`uio_jax.analyze`.

    Attributes:
        method: analysis that ran (``"orc"``, ``"single_ui"``, ``"eorc"`` or ``"series"``).
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
        stop: why the recursion stopped: a :class:`~uio_jax._analysis.driver.Stop` (its
            :class:`~uio_jax._analysis.driver.StopReason` member and values); ``stop_reason``
            is its text.
        notes: remarks (method choice, sufficiency of the EORC, corrections applied).
        details: method-specific results (``m_prime``, ``m_star``, ``k``, ...).
        semantics: what "unknown input" and "known input" mean in this answer.
        known_inputs: the meaning of the known inputs the answer is for: ``"switchable"``
            (they may jump), ``"smooth"`` (generic smooth functions of time) or ``"none"``
            (the System has no known input: one meaning).
        system_name: name of the analyzed System.
    """

    method: str
    states: tuple[str, ...]
    dim: int
    observable: Mapping[str, bool]
    history: tuple[Step, ...]
    certificate: Certificate
    generators: tuple[str, ...]
    stop: Stop
    notes: tuple[str, ...] = ()
    details: Mapping = field(default_factory=dict)
    semantics: str = SEMANTICS
    system_name: str = ""
    params: tuple[str, ...] = ()
    identifiable: Mapping[str, bool] = field(default_factory=dict)
    known_inputs: str = "switchable"
    _space: object = field(default=None, repr=False)
    _named: list = field(default_factory=list, repr=False, compare=False)
    _found: list = field(default_factory=list, repr=False, compare=False)

    def __post_init__(self):
        params = tuple(self.params)
        observable = dict(self.observable)
        identifiable = dict(self.identifiable)
        for p in params:  # verdicts on parameters given among the states: move them
            if p in observable:
                identifiable[p] = observable.pop(p)
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
            if e.result != "undecided":
                continue
            head = e.what.split(" ", 1)[0]
            if head.startswith("e_") and head[2:].isdigit():
                i = int(head[2:])
                if i < len(names):
                    open_.add(names[i])
                continue
            kept = e.float64.startswith("independent")
            open_.update(v for v in names if verdict.get(v) == kept)
        return tuple(v for v in names if v in open_)

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
        (:func:`uio_jax._analysis.directions.domain_centre`)."""
        return directions.domain_centre(self, self._space)

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
        z = directions.point(self, self._space, x, p, "unobservable_directions")
        return self._space.unobservable_directions(z) if t is None else self._space.unobservable_directions(z, at=t)

    def direction_summary(self, x=None, p=None) -> dict:
        """The unobservable directions at a point (default: the centre of the sampling box),
        labelled by the variables' names, with the identifiable parameter combinations:
        :func:`uio_jax._analysis.directions.direction_summary` says how."""
        return directions.direction_summary(self, self._space, x, p)

    def representative_point(self) -> tuple[np.ndarray, str]:
        """``(z, rule)``: where the report's directions are given (the centre of the sampling
        box where the rank is generic, else a fixed point off it:
        :func:`uio_jax._analysis.directions.representative_point`)."""
        return directions.representative_point(self, self._space)

    def format_directions(self, summary=None) -> str:
        """Text of :meth:`direction_summary` (default: at the centre of the sampling box).

        One line naming the point, one line per direction (components that print as
        zero at 3 decimals omitted), and for a model with parameters one line per
        identifiable combination of parameters that are not identifiable one by one.
        """
        return directions.format_directions(self, self._space, summary)

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
        return self._space.sample_singular_values()

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
        return self._space.is_observable(function_of_z(self, fn, "is_observable"))

    @property
    def named_functions(self) -> ObservableFunctions:
        """Readable observable functions that span the observable codistribution, each
        checked exactly (:mod:`uio_jax._analysis.observable_functions`: candidates, ranking,
        checks). Computed on first access (it costs about as much as a small analysis) and
        kept."""
        if not self._named and not hasattr(self._space, "parts"):  # the Taylor route: no symbolic generators
            self._named.append(name_at_point(self._space, self.dim, self.generators))
        if not self._named:
            inputs = len(self.details.get("extended_state", ())) - self.n if self.method == "eorc" else 0
            self._named.append(name_functions(self._space.parts(), inputs=max(inputs, 0)))
        return self._named[0]

    @property
    def symmetries(self) -> FoundSymmetries:
        """The unobservable distribution as verified closed-form symmetries: polynomial vector
        fields of degree at most 1 (translations, rotations, scalings) found by an exact
        ansatz and verified by the symmetry check of declared symmetries
        (:mod:`uio_jax._analysis.found_symmetries`). Computed on first access and kept."""
        if not self._found and not hasattr(self._space, "parts"):
            self._found.append(FoundSymmetries((), self.n - self.dim, "" if self.n == self.dim else
                                               "the Taylor route keeps no symbolic generators to search against"))
        if not self._found:
            parts = self._space.parts()
            self._found.append(find_symmetries(parts, parts.original))
        return self._found[0]

    def reparametrised_model(self) -> dict | None:
        """A model whose parameters are all identifiable, in the model-file schema
        (:func:`uio_jax.save_model` writes it as TOML), or None when every parameter is
        identifiable already: the parameters of a cross-section of the unobservable
        directions fixed (0 where a symmetry translates them, 1 where one scales them, else
        the centre of their box), the others standing for identifiable combinations
        (:mod:`uio_jax._analysis.reparametrise`).

        Raises:
            ModelError: the analysis ran on more coordinates than the report's (EORC, a
                time-varying model), or a function of the model has no expression text.
        """
        if all(self.identifiable.values()):
            return None
        parts = self._space.parts()
        if parts.builder.graph.n != self.n:
            raise ModelError("reparametrised_model: the analysis ran on more coordinates than the "
                             "states and parameters (EORC, general_ui extension or time)")
        try:
            return reparametrised_model(parts, self, self.symmetries)
        except ValueError as exc:
            raise ModelError(f"reparametrised_model: {exc}") from None

    @property
    def observable_functions(self) -> tuple[str, ...]:
        """The named observable functions as expressions in the model's names (sympy-readable
        strings; ``sympy.sympify(text, locals={name: Symbol(name)})``): independent, each in
        the observable codistribution, ``dim`` of them when all could be named
        (:attr:`named_functions` says how many and how they were decided)."""
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
            "observable_functions": self.named_functions.to_dict(),
            "found_symmetries": self.symmetries.to_dict(),
            **(directions.directions_dict(self, self._space) if self.params else {}),
        })

    def answer_kind(self) -> str:
        """Which question the verdicts answer: exact, or a sufficient condition only.

        The ORC (Hermann-Krener rank condition, no unknown input), the series test (its
        final codistribution) and Martinelli's single-unknown-input codistribution are
        exact at generic states once the recursion converged; the EORC, or a recursion
        stopped by a cap (``max_order``, the step cap), shows observability sufficiently
        only: "observable" is proven, "not observable" means not shown. An EORC stopped at
        the known-input bound (:mod:`uio_jax._analysis.known_bound`) is exact: a state it
        does not show is not observable even with every input known; so is one whose states
        reach the bound of its verified symmetries (:mod:`uio_jax._analysis.symmetry`): a
        state it does not show is moved by a symmetry.
        """
        capped = self.stop.reason.capped
        if self.method == "general_ui" and self.details.get("exact") is False and not capped:
            return ("not certified exact (general_ui: the jets of the known inputs may have "
                    "been truncated, see the notes): 'observable' is proven")
        bound = self.details.get("known_input_bound") if self.method == "eorc" else None
        symmetric = self.details.get("symmetries") if self.method == "eorc" else None
        by_symmetry = bool(symmetric and symmetric.get("reached_at") is not None)
        if self.method == "eorc" and not (by_symmetry or bound and bound.get("reached_at") is not None):
            return ("sufficient only (EORC): 'observable' is proven; 'not observable' means "
                    "not shown observable up to the last order k")
        if capped:
            return ("sufficient only (the recursion was capped before it converged): "
                    "'observable' is proven; 'not observable' means not shown")
        what = {"orc": "observability rank condition, no unknown input",
                "series": "rank of the output series, the ORC's final codistribution",
                "single_ui": "Martinelli's observable codistribution, one unknown input",
                "general_ui": "Martinelli's general solution, any number of unknown inputs",
                "eorc": "EORC at the bound of its verified symmetries: every state it does not "
                        "show is moved by one" if by_symmetry else
                        "EORC at the known-input bound: its span on the states is that of the "
                        "ORC with every input known"}
        meaning = {"smooth": "; known inputs generic smooth functions of time",
                   "switchable": "; known inputs switchable (may jump)"}.get(self.known_inputs, "")
        question = f"({what.get(self.method, self.method)}{meaning}): the observable functions at generic states"
        arithmetic = self.certificate.arithmetic
        if arithmetic is Arithmetic.EXACT:
            return f"exact {question}, every decision in exact arithmetic modulo p"
        return f"necessary and sufficient {question}; decided in {arithmetic.value}: not certified exact"

    @property
    def exact(self) -> bool:
        """Whether the verdicts are exact: the question is the necessary and sufficient one
        (not a sufficient condition) and every decision was made in exact arithmetic, with
        the probability bound of the certificate (:meth:`answer_kind`,
        :attr:`Certificate.arithmetic`)."""
        return self.answer_kind().startswith("exact")

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)

    def __str__(self) -> str:
        return report_text(self)
