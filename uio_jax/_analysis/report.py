"""The result of an analysis: dimensions per step, verdicts, evidence, symmetries."""

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

#: What every analysis answers, as in the papers (Martinelli 2015/2017).
SEMANTICS = (
    "Unknown inputs are smooth (analytic) functions of time and known inputs may be chosen "
    "freely (they may jump), as in Martinelli's papers: a direction that could only be "
    "hidden by an unknown input that jumps together with a known input counts as "
    "observable. Tools such as STRIKE-GOLDD/StrikePy by default model an unknown input as "
    "a polynomial in time of fixed degree, which answers a different question."
)


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
                "fraction": self.fraction, **_jsonable(dict(self.extra))}


@dataclass(frozen=True)
class Certificate:
    """How sure the rank decisions of an analysis are.

    Attributes:
        samples: states requested.
        used: states used (finite everywhere).
        dropped: states dropped because a generator was NaN/inf there.
        fraction: fraction of the used samples where the final codistribution has its
            generic rank (SVD of the row-scaled generator gradients).
        min_fraction: the smallest agreeing fraction over every rank decision of the run.
        sigma_r_min: smallest margin among the agreeing samples over every direction that
            was counted (kept generators, non-member covectors): the distance of the
            unit-scaled covector to the span it was added to (for an orthonormal span
            plus one unit row this is, up to a factor in [1/sqrt(2), 1], the last
            singular value ``s_{r+1} / s_1``). How close a counted direction came to
            vanishing.
        sigma_next_max: the same margin, largest value over every direction that was
            *not* counted (pruned candidates, member covectors): how close round-off
            came to faking a rank.
        rtol: the relative tolerance between them.
        conditioning: smallest ``s_r / s_1`` of the final generator matrix among the
            samples at the generic rank (how close the kept set comes to a singular
            state; small values flag samples near the singular set).
        decisions: number of rank decisions taken.
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

    @property
    def gap_decades(self) -> float:
        """``log10(sigma_r_min / sigma_next_max)``: the margin of the weakest decision."""
        if self.sigma_next_max <= 0:
            return math.inf
        return math.log10(self.sigma_r_min / self.sigma_next_max)

    def to_dict(self):
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["gap_decades"] = self.gap_decades
        return _jsonable(d)

    def __str__(self):
        gap = "inf" if math.isinf(self.gap_decades) else f"{self.gap_decades:.1f}"
        return (
            f"{self.used}/{self.samples} samples used ({self.dropped} dropped), "
            f"{100 * self.fraction:.1f}% at the generic rank (worst decision "
            f"{100 * self.min_fraction:.1f}%); margins: smallest kept "
            f"{self.sigma_r_min:.2e}, largest rejected {self.sigma_next_max:.2e} "
            f"(gap {gap} decades around rtol {self.rtol:.0e}); final s_r/s_1 >= "
            f"{self.conditioning:.1e}"
        )


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
        stop_reason: why the recursion stopped.
        notes: remarks (method choice, sufficiency of the EORC, corrections applied).
        details: method-specific results (``m_prime``, ``m_star``, ``k``, ...).
        semantics: what "unknown input" means in this answer.
        system_name: name of the analyzed System.
    """

    method: str
    states: tuple[str, ...]
    dim: int
    observable: Mapping[str, bool]
    history: tuple[Step, ...]
    certificate: Certificate
    generators: tuple[str, ...]
    stop_reason: str
    notes: tuple[str, ...] = ()
    details: Mapping = field(default_factory=dict)
    semantics: str = SEMANTICS
    system_name: str = ""
    params: tuple[str, ...] = ()
    identifiable: Mapping[str, bool] = field(default_factory=dict)
    _space: object = field(default=None, repr=False)

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
    def variables(self) -> tuple[str, ...]:
        """Coordinates of the analysed vector: states, then parameters."""
        return self.states + self.params

    @property
    def n(self) -> int:
        """Dimension of the analysed vector (states plus parameters)."""
        return len(self.variables)

    @property
    def fully_observable(self) -> bool:
        """True when every state component is observable and every parameter identifiable."""
        return all(self.observable.values()) and all(self.identifiable.values())

    @property
    def dims(self) -> tuple[int, ...]:
        """Dimension per step, ``tuple(step.dim for step in history)``."""
        return tuple(s.dim for s in self.history)

    def unobservable_directions(self, x) -> np.ndarray:
        """Basis of the unobservable directions (null space of the codistribution) at ``x``.

        These are the continuous symmetries of the system: moving the state along them
        does not change the outputs (e.g. a rotation about the feature).

        Args:
            x: a state, shape ``(n,)`` (states then parameters when there are any).

        Returns:
            ``(n, n - dim)`` array with orthonormal columns.
        """
        return self._space.unobservable_directions(x)

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
        """Whether the scalar function ``fn(x)`` is observable (``d fn`` in the span).

        Args:
            fn: callable ``x (n,) -> ()``, traceable by JAX.
        """
        return self._space.is_observable(fn)

    def to_dict(self) -> dict:
        """JSON-ready dictionary (no callables)."""
        return _jsonable({
            "system": self.system_name,
            "method": self.method,
            "states": list(self.states),
            "dim": self.dim,
            "n": self.n,
            "fully_observable": self.fully_observable,
            "observable": dict(self.observable),
            "params": list(self.params),
            "identifiable": dict(self.identifiable),
            "dims": list(self.dims),
            "history": [s.to_dict() for s in self.history],
            "generators": list(self.generators),
            "stop_reason": self.stop_reason,
            "certificate": self.certificate.to_dict(),
            "details": dict(self.details),
            "notes": list(self.notes),
            "semantics": self.semantics,
        })

    def to_json(self, **kw) -> str:
        """``json.dumps(self.to_dict())``."""
        return json.dumps(self.to_dict(), **kw)

    def __str__(self) -> str:
        title = f"uio_jax report: {self.system_name or 'system'} ({self.method})"
        lines = [title, "=" * len(title)]
        obs = [s for s in self.states if self.observable[s]]
        of = f"{self.n}" + (" (states and parameters)" if self.params else "")
        lines.append(f"observable codistribution: dim {self.dim} of {of}"
                     + ("  (fully observable)" if self.fully_observable else ""))
        label = "k" if self.method in ("eorc", "series") else "m"
        lines.append("steps:")
        for st in self.history:
            extra = "".join(f", {k}={v}" for k, v in st.extra.items())
            added = ", ".join(st.added) if st.added else "-"
            lines.append(f"  {label}={st.m}: dim {st.dim}  (+ {added}{extra})")
        lines.append(f"stopped: {self.stop_reason}")
        for k, v in self.details.items():
            lines.append(f"{k}: {v}")
        lines.append("states:")
        width = max(len(s) for s in self.states)
        for s in self.states:
            verdict = "observable" if self.observable[s] else "not observable"
            lines.append(f"  {s:<{width}}  {verdict}")
        if not obs:
            lines.append("  (no single state component is observable)")
        if self.params:
            lines.append("parameters:")
            width = max(len(p) for p in self.params)
            for p in self.params:
                verdict = "identifiable" if self.identifiable[p] else "not identifiable"
                lines.append(f"  {p:<{width}}  {verdict}")
        lines.append(f"certificate: {self.certificate}")
        for note in self.notes:
            lines.append(f"note: {note}")
        return "\n".join(lines)


def _jsonable(obj):
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else str(v)
    if isinstance(obj, np.bool_):
        return bool(obj)
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    return obj
