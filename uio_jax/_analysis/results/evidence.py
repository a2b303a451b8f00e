"""The evidence of an analysis: one :class:`Step` per step of its recursion, and the
:class:`Certificate` of its rank decisions (how sure each is, which were settled beyond
float64). :class:`~uio_jax._analysis.results.report.Report` carries both.
"""

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from .kinds import Arithmetic, TextEnum


@dataclass(frozen=True)
class Step:
    """One step m of a recursion.

    Attributes:
        m: step index (the order k for the EORC).
        dim: dimension of the codistribution after the step.
        added: labels of the generators kept at this step.
        fraction: the smallest fraction of samples agreeing with a rank decision of the
            step (kept and rejected candidates; for the EORC: the decisions that kept the
            order's generators); 1.0 for a step that decided nothing.
        extra: method-specific facts of the step (e.g. ``tau_in_omega``).
    """

    m: int
    dim: int
    added: tuple[str, ...]
    fraction: float
    extra: Mapping = field(default_factory=dict)

    def to_dict(self):
        return {"m": self.m, "dim": self.dim, "added": list(self.added),
                "fraction": self.fraction, **jsonable(dict(self.extra))}


@dataclass(frozen=True)
class Certificate:
    """How sure the rank decisions of an analysis are.

    Attributes:
        samples: states requested.
        used: states used (finite everywhere).
        dropped: states dropped because a generator was NaN/inf there.
        capped: states not evaluated on the final span because its gradients there would
            exceed :data:`uio_jax._analysis.decisions.memory.CERTIFY_BYTES` (a deep EORC).
        fraction: fraction of the used samples where the final codistribution has its
            generic rank in float64 (SVD of the row-scaled generator gradients).
        min_fraction: the smallest agreeing fraction over the rank decisions that rest on
            their float64 vote (those settled beyond float64 are in ``escalations``).
        sigma_r_min: smallest margin among the agreeing samples over every direction that
            was counted on its float64 vote: the distance of the unit-scaled covector to the
            span it was added to (up to a factor in [1/sqrt(2), 1], ``s_{r+1} / s_1``).
        sigma_next_max: the same margin, largest value over every direction that was
            *not* counted: how close round-off came to faking a rank.
        rtol: the relative tolerance between them.
        conditioning: smallest ``s_r / s_1`` of the final generator matrix among the
            samples at the generic rank (small values flag samples near the singular set).
        decisions: number of rank decisions taken.
        escalations: the weak decisions settled again beyond float64, and the clear float64
            rises that exact arithmetic contradicted (:class:`Escalation`).
        verified: clear float64 rank increases confirmed beyond float64 (modulo p where the
            model is made rational).
        closure_verified: float64 rejections of a step that kept nothing confirmed in
            extended precision (where the model is not made rational).
        rejections_verified: clear float64 rejections and memberships confirmed beyond
            float64 (modulo p where the model is made rational; and those of a span that
            must be proved, the EORC's known-input bound).
        exact_decisions, extended_decisions, float64_decisions: how many decisions (of the
            span, memberships, zero tests and ranks outside it) were made modulo p, in
            extended precision, on float64 votes alone (or left undecided).
        error_bound: the probability that some decision made modulo p is wrong (a union
            bound over them: Schwartz-Zippel, degree over ``prime`` per point); 0 when none.
        prime: the prime of the modular decisions.
        prob_threshold: the probability of correctness the caller asked for: the exact
            decisions are certified when ``error_bound <= 1 - prob_threshold``.
        screen_only: every decision was exact, so the final span was not re-decided on
            every sample: ``capped`` counts the samples the float64 screen did not use.
    """

    samples: int
    used: int
    dropped: int
    fraction: float
    min_fraction: float
    sigma_r_min: float
    sigma_next_max: float
    rtol: float
    decisions: int
    conditioning: float = 1.0
    escalations: tuple = ()
    verified: int = 0
    capped: int = 0
    closure_verified: int = 0
    rejections_verified: int = 0
    exact_decisions: int = 0
    extended_decisions: int = 0
    float64_decisions: int = 0
    error_bound: float = 0.0
    prime: int = 0
    prob_threshold: float = 0.0
    screen_only: bool = False

    @property
    def arithmetic(self) -> Arithmetic:
        """How the decisions were made (:class:`Arithmetic`): the weakest one decides."""
        if self.float64_decisions or self.undecided or self.error_bound > 1 - self.prob_threshold:
            return Arithmetic.FLOAT64
        return Arithmetic.EXTENDED if self.extended_decisions else Arithmetic.EXACT

    @property
    def escalated(self) -> int:
        """Number of weak decisions settled again beyond float64."""
        return len(self.escalations)

    @property
    def undecided(self) -> int:
        """Number of decisions that neither float64 nor the escalation could settle: the
        verdicts of the report are then not certified (:attr:`status`)."""
        return sum(e.result is Finding.UNDECIDED for e in self.escalations)

    @property
    def status(self) -> str:
        """``"ok"`` (every decision clear in float64), ``"escalated"`` (some settled
        beyond float64, all settled) or ``"undecided"`` (some could not be settled)."""
        return "undecided" if self.undecided else "escalated" if self.escalations else "ok"

    @property
    def gap_decades(self) -> float:
        """``log10(sigma_r_min / sigma_next_max)``: the margin of the weakest decision."""
        if self.sigma_next_max <= 0:
            return math.inf
        return math.log10(self.sigma_r_min / self.sigma_next_max)

    def to_dict(self):
        d = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "escalations"}
        d["gap_decades"] = self.gap_decades
        d["status"] = self.status
        d["arithmetic"] = self.arithmetic.name.lower()
        d["prime"] = str(self.prime)  # 2^127 - 1 exceeds what JSON readers keep exactly
        d["escalations"] = [e.to_dict() for e in self.escalations]
        return jsonable(d)

    def __str__(self):
        gap = "inf" if math.isinf(self.gap_decades) else f"{self.gap_decades:.1f}"
        why = "every decision exact: the float64 screen stopped at the decision samples" if self.screen_only \
            else "its size"
        capped = (f", {self.capped} not evaluated on the final span ({why})" if self.capped else "")
        return (
            f"{self.used}/{self.samples} samples used ({self.dropped} dropped{capped}), "
            f"{100 * self.fraction:.1f}% at the generic rank (worst decision "
            f"{100 * self.min_fraction:.1f}%); margins: smallest kept "
            f"{self.sigma_r_min:.2e}, largest rejected {self.sigma_next_max:.2e} "
            f"(gap {gap} decades around rtol {self.rtol:.0e}); final s_r/s_1 >= "
            f"{self.conditioning:.1e}"
        ) + self._escalation_text() + self._arithmetic_text()

    def _arithmetic_text(self) -> str:
        if not self.decisions:
            return ""
        prime = "2^127 - 1" if self.prime == 2**127 - 1 else str(self.prime)
        text = (f"; decisions: {self.exact_decisions} exact modulo p = {prime}, {self.extended_decisions} in "
                f"extended precision, {self.float64_decisions} on float64 votes")
        if self.exact_decisions:
            text += (f"; P(some exact decision wrong) <= {self.error_bound:.1e} (required "
                     f"<= {1 - self.prob_threshold:.0e})")
        return text

    def _escalation_text(self) -> str:
        if not self.escalations:
            return self._verified_text()
        settled = self.escalated - self.undecided
        text = f"; {self.escalated} weak decision{'s' if self.escalated > 1 else ''} escalated"
        if settled:
            text += f" ({settled} settled beyond float64)"
        if self.undecided:
            text += f"; UNDECIDED: {self.undecided} decision{'s' if self.undecided > 1 else ''}"
        return text + self._verified_text()

    def _verified_text(self) -> str:
        parts = [f"{self.verified} rank increases"] if self.verified else []
        if self.closure_verified:
            parts.append(f"{self.closure_verified} rejections at the stopping step")
        if self.rejections_verified:
            parts.append(f"{self.rejections_verified} other rejections")
        return f"; {' and '.join(parts)} verified exactly" if parts else ""


class Settlement(TextEnum):
    """How a decision was made beyond its float64 vote (a ``str``: compares equal to its
    value, and is written as it in JSON)."""

    #: the float64 vote alone (or the samples that re-decided it)
    NONE = ""
    #: modulo p at random points (:mod:`uio_jax._analysis.decisions.settle`)
    EXACT = "exact mod p"
    #: in extended precision (mpmath at two precisions)
    EXTENDED = "mpmath"
    #: neither could settle it: the float64 majority kept, not certified
    UNDECIDED = "undecided"
    #: implied by the span: a span of every direction contains every covector
    IMPLIED = "implied"


class Finding(TextEnum):
    """What a decision settled beyond float64 found (also the float64 vote it settled)."""

    INDEPENDENT = "independent"
    DEPENDENT = "dependent"
    UNDECIDED = "undecided"


@dataclasses.dataclass(frozen=True)
class Escalation:
    """One decision settled again beyond its float64 vote (a weak one, or a clear one that
    exact arithmetic contradicted).

    Attributes:
        what: the candidate (label) and the rank of the span it was tested against.
        float64: what the float64 vote said, with its evidence (agreeing fraction, median
            ``log10 rho``), as text for the record.
        how: the :class:`Settlement` that decided it (:attr:`Settlement.NONE`: more
            samples).
        result: a :class:`Finding`.
        bound: for a dependence found modulo ``p``, the probability bound that it is wrong
            (independence found there is certain: 0.0); None otherwise.
        detail: the rest of the text of ``how`` (the prime and the points, the digits, why
            it could not decide): ``how_text`` is ``how`` followed by it.
        vote: the float64 vote that was settled (a :class:`Finding`; None when unknown).
        coordinate: ``i`` when the candidate is the unit covector ``d z_i`` (a membership
            that decides variable ``i``'s verdict), None otherwise.
    """

    what: str
    float64: str
    how: Settlement
    result: Finding
    bound: float | None = None
    detail: str = ""
    vote: Finding | None = None
    coordinate: int | None = None

    def __post_init__(self):
        object.__setattr__(self, "how", Settlement(self.how))
        object.__setattr__(self, "result", Finding(self.result))
        if self.vote is not None:
            object.__setattr__(self, "vote", Finding(self.vote))

    @property
    def how_text(self) -> str:
        """How it was settled, in words (``"exact mod p = 2^127 - 1 at 1 point"``)."""
        return f"{self.how.value}{self.detail}"

    def to_dict(self) -> dict:
        return {"what": self.what, "float64": self.float64, "how": self.how_text,
                "result": self.result.value, "bound": self.bound}


def jsonable(obj):
    """``obj`` with numpy scalars and arrays as Python numbers and lists, mappings with
    string keys, non-finite floats as strings: what ``json.dumps`` takes."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else str(v)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj


__all__ = ["Arithmetic", "Step", "Certificate", "Settlement", "Finding", "Escalation", "jsonable"]
