"""The arguments of a :class:`~uio_jax.System`, checked and normalized: names, callables,
parameter and domain boxes, the time name. Each check raises a one-line
:class:`~uio_jax.ModelError` that names the argument and the problem."""

import keyword
import math
from collections.abc import Callable, Mapping
from types import MappingProxyType

from .._errors import ModelError

#: Sampling box of a state that is not listed in ``System.domain`` (and not an angle).
#: It stays away from 0, where many models have their singular set (1/r, atan2, norms);
#: for analytic models the generic rank is the same on every open set of a connected domain.
DEFAULT_BOX = (0.5, 1.5)
#: Sampling box of the time variable (``System.time``) when ``domain`` does not list it, in
#: seconds (any open interval gives the same generic ranks for an analytic model; list the time
#: name in ``domain`` to move it away from a singular instant such as the 0 of ``1/t``).
DEFAULT_TIME_BOX = (0.0, 1.0)
#: Sampling box of a state listed in ``System.angles``.
ANGLE_BOX = (-math.pi, math.pi)
def check_input_names(known, unknown, states, params):
    """An input may not share its name with a state or a parameter (as in model files)."""
    for kind, table in (("known", known), ("unknown", unknown)):
        for k in table:
            if k in states:
                raise ModelError(f"{kind} input {k!r} has the name of a state")
            if k in params:
                raise ModelError(f"{kind} input {k!r} has the name of a parameter")


def check_identifiers(kinds) -> None:
    """The names that expressions use (states, parameters) are identifiers (letters, digits and
    ``_``, not starting with a digit), as in model files (``kinds``: kind -> names); one-line
    ModelError otherwise. A Python keyword is a name here (the HIV model's ``lambda``), though
    an expression of a model file cannot use it; outputs and inputs are only keys."""
    for kind, names in kinds.items():
        for nm in names:
            if not nm.isidentifier():
                raise ModelError(f"{kind} name {nm!r} is not a valid name (letters, digits and _, "
                                 "not starting with a digit), as in model files")


def as_names(names, what) -> tuple[str, ...]:
    """``names`` as a tuple of distinct non-empty strings; ``what`` names the argument in errors."""
    if isinstance(names, str):
        raise ModelError(f"{what} must be a sequence of names, got the string {names!r}")
    try:
        names = tuple(names)
    except TypeError:
        raise ModelError(f"{what} must be a sequence of names, got {type(names).__name__}") from None
    check_names(names, lambda nm: not isinstance(nm, str) or not nm,
                what + " entries must be non-empty strings, got {nm!r}", "duplicate name {nm!r} in " + what)
    return names


def check_names(names, invalid, invalid_message: str, twice_message: str) -> None:
    """One-line ModelErrors for a sequence of names: the first ``nm`` with ``invalid(nm)``,
    then the first one listed twice (messages: ``str.format`` templates with ``{nm!r}``)."""
    bad = next((nm for nm in names if invalid(nm)), None)
    if bad is not None:
        raise ModelError(invalid_message.format(nm=bad))
    seen = set()
    for nm in names:
        if nm in seen:
            raise ModelError(twice_message.format(nm=nm))
        seen.add(nm)


def as_mapping(value, what: str, of: str) -> Mapping:
    """``value`` as a mapping (None: empty); ``of`` says what it maps, in the error."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ModelError(f"{what} must be a mapping {of}, got {type(value).__name__}")
    return value


def as_callables(mapping, what) -> Mapping[str, Callable]:
    """``mapping`` (name -> function) as a read-only mapping, each name a non-empty string
    that is not a Python keyword and each value callable."""
    out = {}
    for k, fn in as_mapping(mapping, what, "name -> function").items():
        if not isinstance(k, str) or not k:
            raise ModelError(f"{what} names must be non-empty strings, got {k!r}")
        if keyword.iskeyword(k):
            raise ModelError(f"{what} name {k!r} is a Python keyword")
        if not callable(fn):
            raise ModelError(f"{what} entry {k!r} is not callable (got {type(fn).__name__})")
        out[k] = fn
    return MappingProxyType(out)


def as_params(params, states) -> Mapping[str, tuple[float, float]]:
    """The parameters as name -> sampling box ``(lo, hi)`` (a sequence of names: ``DEFAULT_BOX``
    each); a name may not be a state's."""
    if params is None:
        params = {}
    if not isinstance(params, Mapping) and not isinstance(params, str):
        try:  # a sequence of names: the default box
            params = {k: DEFAULT_BOX for k in as_names(params, "params")}
        except ModelError:
            pass
    out = {}
    for k, box in as_mapping(params, "params", "name -> (lo, hi)").items():
        if not isinstance(k, str) or not k:
            raise ModelError(f"parameter names must be non-empty strings, got {k!r}")
        if k in states:
            raise ModelError(f"parameter {k!r} has the name of a state")
        out[k] = as_box(box, f"box of parameter {k!r}")
    return MappingProxyType(out)


def as_box(box, what: str) -> tuple[float, float]:
    """A sampling box ``(lo, hi)``: two finite floats with ``lo < hi``; ``what`` names it in errors."""
    try:
        lo, hi = (float(v) for v in box)
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be a pair (lo, hi), got {box!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ModelError(f"{what} must be finite, got ({lo}, {hi})")
    if lo >= hi:
        raise ModelError(f"{what} is empty: lo={lo} >= hi={hi}")
    if not math.isfinite(hi - lo):  # the samples lo + u (hi - lo) would be inf, and blame the model
        raise ModelError(f"{what} [{lo:g}, {hi:g}] is too wide: its width overflows float64; give the "
                         "range where the model is meant to be evaluated")
    return lo, hi


def as_domain(domain, states, angles, time=None) -> Mapping[str, tuple[float, float]]:
    """Every state's (and the time's) sampling box: the given ones checked, the others
    ``ANGLE_BOX`` for angles, ``DEFAULT_BOX`` for states, ``DEFAULT_TIME_BOX`` for time."""
    out = {}
    for k, box in as_mapping(domain, "domain", "state -> (lo, hi)").items():
        if k not in states and k != time:
            extra = f", time: {time}" if time is not None else ""
            raise ModelError(f"domain given for unknown state {k!r} (states: {', '.join(states)}{extra})")
        out[k] = as_box(box, f"domain of {k!r}")
    for s in states:
        if s not in out:
            out[s] = ANGLE_BOX if s in angles else DEFAULT_BOX
    if time is not None and time not in out:
        out[time] = DEFAULT_TIME_BOX
    return MappingProxyType(out)


def as_time(time, states, params, known, unknown, outputs) -> str | None:
    """The time name: None, or an identifier that names nothing else of the System."""
    if time is None:
        return None
    if not isinstance(time, str) or not time.isidentifier() or keyword.iskeyword(time):
        raise ModelError(f"time must be the name of the time variable (an identifier such as 't'), "
                         f"got {time!r}")
    for what, table in (("state", states), ("parameter", params), ("known input", known),
                        ("unknown input", unknown), ("output", outputs)):
        if time in table:
            raise ModelError(f"time {time!r} has the name of {'an' if what[0] in 'aeiou' else 'a'} {what} "
                             "(the time variable needs its own name)")
    return time
