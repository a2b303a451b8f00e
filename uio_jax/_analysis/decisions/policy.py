"""The decision policy: one object that says, for every rank decision of an analysis, what is
settled again beyond its float64 vote, when, and how the outcome is recorded.

Every candidate's vote (:func:`~uio_jax._analysis.decisions.sampled_rank.decide_increase` over the
sampled states) is settled again in the System's expression graph by the analysis's
:class:`~uio_jax._analysis.decisions.settle.Settler`:

* a **weak** vote (:func:`~uio_jax._analysis.decisions.settle.is_weak`; or a rise the span expected that
  did not come, ``expect_rise``) exactly modulo p where the graph is made rational, else in
  extended precision, else undecided;
* a **clear** vote exactly modulo p where the graph is made rational; elsewhere the vote
  stands (:attr:`Reach.EXACT`), or it is settled in extended precision too
  (:attr:`Reach.ALL`: a span that must be proved, the EORC's known-input bound);
* a step that keeps nothing (a recursion's stop) has its rejections not settled yet
  settled beyond float64 (:meth:`DecisionPolicy.settle_stop`).

The outcome replaces the vote (an undecided one keeps it, marked); what was settled goes to a
:class:`Record`, which the caller owns, copies and merges.
"""

import dataclasses
import enum
from collections.abc import Callable
from dataclasses import replace

from ..results.evidence import Finding
from .sampled_rank import RankDecision, decide_increase
from .settle import is_weak, median_decades


class Reach(enum.Enum):
    """How far clear votes are settled again."""

    #: modulo p where the graph is made rational; elsewhere the float64 vote stands
    EXACT = "exact"
    #: and in extended precision elsewhere (undecided if that fails)
    ALL = "all"


@dataclasses.dataclass
class Record:
    """What the decisions of one span found beyond float64 (mutable, owned by the span).

    Attributes:
        escalations: the weak decisions settled again and the clear votes contradicted
            (:class:`~uio_jax._analysis.decisions.settle.Escalation`), each question once, in order.
        verified: clear rises (generators kept, non-members) confirmed.
        closure_verified: rejections of a step that kept nothing confirmed beyond float64
            (where :meth:`DecisionPolicy.decide` had not settled them already).
        rejections_verified: clear rejections and memberships confirmed.
        contradicted: whether a settled decision contradicted a float64 vote (round-off has
            reached ``rtol`` in this span's derivatives).
    """

    escalations: list = dataclasses.field(default_factory=list)
    verified: int = 0
    closure_verified: int = 0
    rejections_verified: int = 0
    contradicted: bool = False

    def add(self, esc) -> None:
        """Record an escalation once (the same question asked again is the same record)."""
        if not any(e is esc for e in self.escalations):
            self.escalations.append(esc)

    def merge(self, other: "Record") -> None:
        """Add another span's record (a trial span's decisions count in this one's)."""
        for esc in other.escalations:
            self.add(esc)
        self.verified += other.verified
        self.closure_verified += other.closure_verified
        self.rejections_verified += other.rejections_verified
        self.contradicted = self.contradicted or other.contradicted

    def copy(self) -> "Record":
        return dataclasses.replace(self, escalations=list(self.escalations))


def evidence(d: RankDecision, rho, valid, rtol, rank: int) -> str:
    """The float64 vote of a decision, for the record of its escalation."""
    said = "independent" if d.rank > rank else "dependent"
    return (f"{said} ({100 * d.fraction:.1f}% of samples, median rho "
            f"{median_decades(rho, valid, rtol):+.2f} decades from rtol)")


@dataclasses.dataclass(frozen=True)
class DecisionPolicy:
    """What every rank decision of an analysis settles beyond float64, and how.

    Args:
        settle: ``settle(kept nodes, candidate node, float64 text, exact_only=...) ->
            Escalation | None`` (:meth:`uio_jax._analysis.decisions.settle.Settler.settle`).
        reach: how far clear votes are settled (:class:`Reach`).
    """

    settle: Callable
    reach: Reach = Reach.EXACT

    def decide(self, rho, valid, rtol, kept, node, record: Record, *, expect_rise=False) -> RankDecision:
        """Whether ``node`` raises the rank of ``span{d k : k in kept}``: the float64 vote of the
        distances ``rho (S,)`` at the ``valid (S,)`` samples, settled again (module docstring);
        what was settled goes to ``record``."""
        rank = len(kept)
        d = decide_increase(rho, valid, rtol, rank)
        rises = d.rank > rank
        weak = (expect_rise and not rises) or is_weak(rho, valid, rtol, d.fraction)
        exact_only = not weak and self.reach is Reach.EXACT
        vote = Finding.INDEPENDENT if rises else Finding.DEPENDENT
        esc = self.settle(kept, node, evidence(d, rho, valid, rtol, rank), exact_only=exact_only, vote=vote)
        if esc is None:  # neither exact nor asked beyond: the float64 vote stands
            return d
        how = esc.how
        confirmed = esc.result == ("independent" if rises else "dependent")
        if confirmed and not weak:  # a clear vote confirmed: counted, not an escalation
            if rises:
                record.verified += 1
            else:
                record.rejections_verified += 1
            return replace(d, settled=how)
        record.add(esc)
        if esc.result == "undecided":
            return replace(d, settled="undecided")
        if not confirmed:  # float64 was wrong: round-off has reached rtol in this span
            record.contradicted = True
        return replace(d, rank=rank + (esc.result == "independent"), settled=how)

    def settle_stop(self, kept, node, text, record: Record):
        """A rejection of a step that keeps nothing, settled beyond float64 (modulo p, else in
        extended precision): the Escalation, None where neither applies. A confirmed
        dependence is counted; anything else is recorded."""
        esc = self.settle(kept, node, text, vote=Finding.DEPENDENT)
        if esc is None:
            return None
        if esc.result == "dependent":
            record.closure_verified += 1
        else:
            record.add(esc)
        return esc

    def reaching(self, reach: Reach) -> "DecisionPolicy":
        """This policy with clear votes settled as far as ``reach``."""
        return replace(self, reach=reach)


__all__ = ["Reach", "Record", "DecisionPolicy", "evidence"]
