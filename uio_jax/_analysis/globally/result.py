"""The answer of the global question: a verdict per unknown, counts, symmetries, the bound."""

import dataclasses
import enum
import json
from collections.abc import Mapping
from types import MappingProxyType

from ..._output import printable


class GlobalVerdict(str, enum.Enum):
    """The global verdict on one unknown (a ``str``: written as its value in JSON).

    ``GLOBAL``: one value for generic values of the unknowns (globally identifiable, or an
    unknown initial state globally observable). ``LOCAL``: finitely many values, more than
    one (``value_counts`` says how many where known). ``NOT``: not locally identifiable
    (infinitely many values). ``UNDECIDED``: a limit was hit (the result's
    ``undecided_reason`` says which) or the local test did not decide.
    """

    GLOBAL = "global"
    LOCAL = "local"
    NOT = "not"
    UNDECIDED = "undecided"


@dataclasses.dataclass(frozen=True, eq=False)
class GlobalResult:
    """What :func:`uio_jax.global_identifiability` answers.

    Attributes:
        system_name: the System's name.
        states: the unknown initial states asked about.
        params: the parameters.
        functions: the functions of the unknowns asked about (``functions=``).
        global_identifiability: unknown (or function) -> :class:`GlobalVerdict`.
        value_counts: unknown -> how many values it takes (over the algebraic closure, at a
            generic point), where known: 1 for global ones, more for local ones.
        solution_count: how many solutions the specialised system has (None when not solved).
        symmetries: the simple discrete symmetries read from the solutions, as text
            (``k21 <-> k31, k12 <-> k13, x2 <-> x3``).
        symmetry_kinds: per symmetry, ``"permutation"``, ``"sign change"`` or both.
        specialised: the not-identifiable unknowns fixed at their drawn values to make the
            system zero-dimensional (a transcendence basis over the output coefficients).
        initial: known initial states, ``name -> value`` as text.
        order: the highest order of output coefficient the local test used.
        error_bound: the probability that a verdict is wrong, the modular reduction aside:
            the local test's bound plus SIAN's bound of the random point.
        point_bound: SIAN's bound of the point (part of ``error_bound``).
        local_error_bound: the local test's (part of ``error_bound``).
        prime: the prime of the solve.
        prob_threshold: the caller's threshold.
        undecided_reason: why some verdict is undecided (the limit that was hit), or None.
        seconds: ``{"local": .., "build": .., "solve": ..}``.
        notes: remarks (where the answer holds only generically, the modular reduction).
    """

    system_name: str
    states: tuple
    params: tuple
    functions: tuple
    global_identifiability: Mapping
    value_counts: Mapping
    solution_count: int | None
    symmetries: tuple
    symmetry_kinds: tuple
    specialised: tuple
    initial: Mapping
    order: int
    error_bound: float
    point_bound: float
    local_error_bound: float
    prime: int | None
    prob_threshold: float
    undecided_reason: str | None
    seconds: Mapping
    notes: tuple

    def __post_init__(self):
        for name in ("global_identifiability", "value_counts", "initial", "seconds"):
            object.__setattr__(self, name, MappingProxyType(dict(getattr(self, name))))

    def names(self, verdict: GlobalVerdict) -> list[str]:
        """The unknowns with ``verdict``."""
        return [k for k, v in self.global_identifiability.items() if v is verdict]

    def to_dict(self) -> dict:
        """JSON-ready: the verdicts as their values, every field."""
        d = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        d["global_identifiability"] = {k: v.value for k, v in self.global_identifiability.items()}
        for name in ("value_counts", "initial", "seconds"):
            d[name] = dict(d[name])
        for name in ("states", "params", "functions", "symmetries", "symmetry_kinds", "specialised", "notes"):
            d[name] = list(d[name])
        return d

    def to_json(self, **kwargs) -> str:
        """:meth:`to_dict` as JSON text."""
        return json.dumps(self.to_dict(), **kwargs)

    def lines(self) -> list[str]:
        """The text report, one line each."""
        name = self.system_name or "system"
        out = [f"global identifiability of {name}" + (
            f" at {', '.join(f'{k}(0) = {v}' for k, v in self.initial.items())}" if self.initial else "")]
        width = max((len(k) for k in self.global_identifiability), default=0)
        for k, v in self.global_identifiability.items():
            kind = "initial state" if k in self.states else "function" if k in self.functions else "parameter"
            count = self.value_counts.get(k)
            extra = f"  ({count} values)" if v is GlobalVerdict.LOCAL and count else ""
            out.append(f"  {k.ljust(width)}  {v.value}{extra}  [{kind}]")
        if self.solution_count is not None:
            out.append(f"solutions of the specialised system: {self.solution_count}")
        for text, kind in zip(self.symmetries, self.symmetry_kinds):
            out.append(f"discrete symmetry ({kind}): {text}")
        if self.specialised:
            out.append(f"fixed at their drawn values (not identifiable): {', '.join(self.specialised)}")
        if self.undecided_reason:
            out.append(f"undecided: {self.undecided_reason}")
        prime = f", solved modulo p = {self.prime}" if self.prime else ""
        out.append(f"orders 0..{self.order}; error bound {self.error_bound:.2g} (local test "
                   f"{self.local_error_bound:.2g}, random point {self.point_bound:.2g}){prime}")
        out += [f"note: {n}" for n in self.notes]
        return [printable(line) for line in out]

    def __str__(self) -> str:
        return "\n".join(self.lines())


__all__ = ["GlobalVerdict", "GlobalResult"]
