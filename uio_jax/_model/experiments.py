"""Several experiments on shared parameters: a description, analysed by :func:`uio_jax.analyze`."""

from collections.abc import Mapping
from dataclasses import dataclass

from .._errors import OptionError
from .system import System


@dataclass(frozen=True)
class Experiments:
    """Several experiments whose parameters named in ``shared`` are the same unknowns.

    Each experiment is a System with its own states, known and unknown inputs and
    (optionally) known initial state; a parameter not in ``shared`` is one unknown per
    experiment. ``uj.analyze(uj.Experiments(...))`` answers which parameters and initial
    states the experiments together determine, what each added experiment determines, and
    how many generic experiments reach the maximal rank (:mod:`uio_jax._analysis.at_t0.identifiability`).

    Args:
        systems: the experiments' Systems (the same System twice: two experiments of one model).
        shared: the shared parameter names (default None: every parameter common to all).
        initial: per experiment, its known initial state ``state -> value`` (None or ``{}``:
            unknown), as for ``uj.analyze(..., initial=...)``.

    Raises:
        OptionError: no System, an entry that is not a System, ``initial`` of another
            length than ``systems`` or with an entry that is not a mapping.

    Example:
        >>> exps = uj.Experiments([sys, sys], shared=("k1", "k2"), initial=[{"x1": 0.0}, None])
        >>> rep = uj.analyze(exps)
    """

    systems: tuple
    shared: tuple | None = None
    initial: tuple | None = None

    def __post_init__(self):
        systems = tuple(self.systems) if not isinstance(self.systems, System) else (self.systems,)
        if not systems or not all(isinstance(s, System) for s in systems):
            raise OptionError("Experiments needs a sequence of uio_jax.System")
        object.__setattr__(self, "systems", systems)
        if self.shared is not None:
            if isinstance(self.shared, str):
                raise OptionError("shared must be a sequence of parameter names, got a string")
            object.__setattr__(self, "shared", tuple(self.shared))
        if self.initial is not None:
            initial = tuple({} if i is None else i for i in self.initial)
            if len(initial) != len(systems):
                raise OptionError(f"initial gives {len(initial)} initial states for {len(systems)} experiments")
            if not all(isinstance(i, Mapping) for i in initial):
                raise OptionError("each experiment's initial state must be a mapping state -> value (or None)")
            object.__setattr__(self, "initial", initial)


__all__ = ["Experiments"]
