"""The result of the known-initial-state and several-experiment analyses
(:mod:`uio_jax._analysis.at_t0.identifiability`): a verdict per unknown, the question answered, the
order reached and the exact certificate."""

import dataclasses
import enum
from collections.abc import Mapping
from types import MappingProxyType

from ..._output import printable, wrapped
from .evidence import Arithmetic, jsonable
from .kinds import Answer, Verdict
from .report import Question, ReportQueries, refuse


class StopKind(enum.Enum):
    """Why the orders stopped (the value is the text a report shows)."""

    ALL_DETERMINED = "every unknown determined"
    SPAN_CLOSED = "an order added nothing to a span that no later order can change"
    MAX_ORDER = "the highest order was reached with unknowns undetermined"


#: Why the generic report's directions are not asked at t = 0.
AT_T0 = ("the answer at a known initial state is one verdict per unknown (rep.verdicts, rep.is_observable(fn)); "
         "it has no codistribution at generic states to take directions of: analyze the System without initial=")


@dataclasses.dataclass(frozen=True, eq=False)
class IdentifiabilityReport(ReportQueries):
    """The answer of :func:`uio_jax.analyze` with ``initial=`` or several experiments.

    Attributes:
        question: the :class:`~uio_jax._analysis.results.report.Question` answered.
        system_name: the (first) System's name.
        states: the unknown initial states asked about (``x1``; ``x1[2]`` in experiment 2).
        params: the parameters (shared ones by name, the others with their experiment).
        observable: unknown initial state -> :class:`Verdict` (determined at ``t = 0``).
        identifiable: parameter -> :class:`Verdict`.
        initial: the known initial states, ``name -> value`` as text.
        order: the highest order ``K`` of the output coefficients used.
        ranks: the rank of ``d(y_0..y_k)`` per order (the experiments' orders one after
            another).
        stop: a :class:`StopKind`.
        arithmetic: the weakest :class:`~uio_jax._analysis.results.evidence.Arithmetic` of the decisions.
        decisions: how many rank and membership decisions were made.
        undecided_decisions: how many of them could not be settled.
        error_bound: the probability that some exact decision is wrong (union bound).
        prime, prob_threshold: the prime of the modular decisions; the caller's bound.
        notes: remarks.
        experiments: per experiment: ``name``, ``initial``, ``order``, ``closed`` and
            ``added`` (the unknowns it made determined).
        global_answer: the :class:`~uio_jax.GlobalResult` of ``scope="global"`` (None when
            not asked): :attr:`global_identifiability`, :attr:`value_counts`.
        space: the span of the decisions, which :meth:`is_observable` queries
            (:class:`~uio_jax._analysis.at_t0.space.InitialSpace`).
        generic_experiments: for each distinct System, the smallest number of generic
            experiments (copies with independent states and inputs) reaching the maximal
            rank of the shared parameters (``minimal``; ``ranks`` per count; ``determined``
            per count), or None where it is not computed (unknown inputs, no parameter).
    """

    question: Question
    system_name: str
    states: tuple
    params: tuple
    observable: Mapping
    identifiable: Mapping
    initial: Mapping
    order: int
    ranks: tuple
    stop: StopKind
    arithmetic: Arithmetic
    decisions: int
    undecided_decisions: int
    error_bound: float
    prime: int
    prob_threshold: float
    notes: tuple = ()
    experiments: tuple = ()
    generic_experiments: tuple = ()
    space: object = dataclasses.field(default=None, repr=False)
    global_answer: object = dataclasses.field(default=None, repr=False)

    def __post_init__(self):
        for name in ("observable", "identifiable", "initial"):
            object.__setattr__(self, name, MappingProxyType(dict(getattr(self, name))))

    @property
    def verdicts(self) -> Mapping:
        """Every unknown asked about -> :class:`Verdict` (states, then parameters)."""
        return MappingProxyType({**self.observable, **self.identifiable})

    @property
    def undecided(self) -> tuple:
        """The unknowns neither determined nor proved undeterminable."""
        return tuple(k for k, v in self.verdicts.items() if v is Verdict.UNDECIDED)

    @property
    def fully_determined(self) -> bool:
        """Whether every unknown is determined."""
        return all(v is Verdict.DETERMINED for v in self.verdicts.values())

    @property
    def exact(self) -> bool:
        """Whether the verdicts are complete and exact: every decision made modulo p, no
        verdict undecided, and a question that is not sufficient only."""
        return (self.arithmetic is Arithmetic.EXACT and not self.undecided
                and not self.question.sufficient_only and not self.undecided_decisions)

    @property
    def answer(self) -> Answer:
        """What the verdicts prove: ``EXACT`` (:attr:`exact`), ``SUFFICIENT_ONLY`` (unknown
        inputs with free jets: "determined" is proven), else ``NOT_CERTIFIED`` (some verdict
        undecided, or some decision not exact)."""
        if self.exact:
            return Answer.EXACT
        return Answer.SUFFICIENT_ONLY if self.question.sufficient_only else Answer.NOT_CERTIFIED

    def is_observable(self, fn) -> bool:
        """Whether the function ``fn(z)`` of the System's ``z = [x; p]`` (or ``fn(x, p)``) is
        determined at the known initial state: its differential in the span of the output
        coefficients' gradients, decided exactly (:mod:`uio_jax._analysis.at_t0.space`). True
        where it is, False where it is proved not to be (a closed span).

        Raises:
            ModelError: undecided up to the order reached (no answer given as certain), several
                experiments, a bad function.
        """
        if self.space is None:
            raise refuse("is_observable", "this report keeps no span (built without uj.analyze)")
        return self.space.is_observable(fn)

    def unobservable_directions(self, x=None, p=None, t=None):
        """Refused: the question at t = 0 has no codistribution at generic states."""
        raise refuse("unobservable_directions", AT_T0)

    def direction_summary(self, x=None, p=None):
        """Refused: the question at t = 0 has no codistribution at generic states."""
        raise refuse("direction_summary", AT_T0)

    def format_directions(self, summary=None):
        """Refused: the question at t = 0 has no codistribution at generic states."""
        raise refuse("format_directions", AT_T0)

    def answer_kind(self) -> str:
        """The answer line: what the verdicts prove."""
        if self.arithmetic is not Arithmetic.EXACT:
            head = f"decided in {self.arithmetic.value}"
        else:
            head = "every decision exact modulo p"
        if self.question.sufficient_only:
            return f"sufficient only ({head}): 'determined' is proven, the rest is not shown"
        if self.undecided:
            return (f"partial ({head}): 'determined' and 'not determined' are proven; "
                    f"{len(self.undecided)} undecided up to order {self.order}")
        return f"exact ({head})" if self.arithmetic is Arithmetic.EXACT else head

    def to_dict(self) -> dict:
        """JSON-ready dictionary (enumerations as their values)."""
        return jsonable({
            "system": self.system_name,
            "question": self.question.value,
            "answer": self.answer_kind(),
            "exact": self.exact,
            "states": list(self.states),
            "params": list(self.params),
            "observable": {k: v.value for k, v in self.observable.items()},
            "identifiable": {k: v.value for k, v in self.identifiable.items()},
            "undecided": list(self.undecided),
            "initial": dict(self.initial),
            "order": self.order,
            "ranks": list(self.ranks),
            "stop": self.stop.name.lower(),
            "certificate": {"arithmetic": self.arithmetic.name.lower(), "decisions": self.decisions,
                            "undecided": self.undecided_decisions, "error_bound": self.error_bound,
                            "prime": str(self.prime), "prob_threshold": self.prob_threshold},
            "experiments": [dict(e) for e in self.experiments],
            "generic_experiments": [dict(g) for g in self.generic_experiments],
            "notes": list(self.notes),
            **({} if self.global_answer is None else {"global": self.global_answer.to_dict()}),
        })

    def __str__(self) -> str:
        title = f"uio_jax report: {self.system_name or 'system'} (identifiability at t = 0)"
        lines = [title, "=" * len(title), f"answer: {self.answer_kind()}",
                 f"question: {self.question.value} ({self.question.description})"]
        if self.initial:
            lines.append("known initial state: " + ", ".join(f"{k} = {v}" for k, v in self.initial.items()))
        lines.append(f"orders: 0..{self.order}, ranks {list(self.ranks)}; stopped: {self.stop.value}")
        for title_, table in (("initial states", self.observable), ("parameters", self.identifiable)):
            if table:
                lines.append(f"{title_}:")
                width = max(len(k) for k in table)
                lines += [f"  {k:<{width}}  {v.value.replace('_', ' ')}" for k, v in table.items()]
        for e in self.experiments:
            added = ", ".join(e["added"]) or "nothing new"
            lines.append(f"experiment {e['name']}: orders 0..{e['order']}, determines {added}")
        for g in self.generic_experiments:
            lines.append(f"generic experiments of {g['system']}: {g['minimal']} reach the maximal rank "
                         f"{g['ranks'][-1]} of the shared parameters (ranks by count {g['ranks']})")
        prime = "2^127 - 1" if self.prime == 2**127 - 1 else str(self.prime)
        lines.append(f"certificate: {self.decisions} decisions ({self.undecided_decisions} undecided), "
                     f"{self.arithmetic.value}, p = {prime}, P(some exact decision wrong) <= "
                     f"{self.error_bound:.1e} (required <= {1 - self.prob_threshold:.0e})")
        lines += [] if self.global_answer is None else self.global_answer.lines()
        lines += [f"note: {n}" for n in self.notes]
        return wrapped("\n".join(map(printable, lines)))


__all__ = ["Verdict", "StopKind", "IdentifiabilityReport", "AT_T0"]
