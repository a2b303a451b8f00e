"""The recursion driver shared by the analyses (ORC, single_ui, series, EORC).

Every analysis of the package grows a codistribution step by step::

    Omega_0  ->  Omega_1  ->  ...  ->  Omega_M          (M: the step at which it stops)

and differs only in how a step is formed (Lie derivatives along fields, brackets of the
unknown-input field, Taylor coefficients of the output, orders of the extended system) and
in when it may stop. As optimistix's ``_iterate`` (one loop for all root finders, with
``init``, ``step``, ``terminate``, ``postprocess``) and diffrax's ``RESULTS`` (one
enumeration of the ways a solve ends), this module holds the loop once:

* :class:`Recursion`, the interface an analysis implements (one file of mathematics);
* :func:`iterate`, the one loop that runs it: it records every step, announces it for
  progress (:func:`uio_jax._progress.announce_step`) and returns the history, the step
  reached and the stop reason;
* :class:`StopReason`, the enumeration of the ways a recursion stops, each member carrying
  the exact text a :class:`~uio_jax.Report` shows in ``stop_reason`` (reports are compared
  bit for bit, so the text is part of the format), and :class:`Stop`, a member with its
  values (``Stop.message`` is the text).

The loop, with ``m`` the driver's step counter (``m = 0`` is Omega_0)::

    step = rec.init()                 # Omega_0 (None: it is already the last of `history`)
    history = [*history, step]        # announced
    m = 0
    while (stop := rec.terminate(m, history)) is None:
        m += 1
        history.append(rec.step(m))   # Omega_m from Omega_{m-1}; announced
    return Outcome(history, stop, m, rec.postprocess(history, stop))

``terminate`` is asked after ``init`` and after every step, so a stop at ``m = 0`` (full rank
from the outputs alone) needs no step; its order of tests is the analysis' own (e.g. the ORC
first asks whether the last step added nothing, then whether the rank is full, then whether
the cap is reached). A recursion that keeps its own state (the frontier, ``m'``) keeps it on
``self``: the driver only counts and records.

Announcing: :meth:`~uio_jax._analysis.decisions.context.Context.step` only builds a Step; the driver
announces each step it records, exactly once.
"""

import abc
import dataclasses
import enum
import re
from collections.abc import Sequence
from typing import Any

from ..._progress import announce_step
from ..results.evidence import Step


class StopReason(enum.Enum):
    """Why a recursion stopped. The value of a member is the template of the text a Report
    shows (``str.format`` fields named after the values the analysis passes).

    ``m``/``k``: the step (order) at which the recursion stopped, as the Report numbers it;
    ``prev``: the step before (``m - 1``); ``n``: the dimension of the state.
    """

    #: ORC, single_ui: ``dim Omega_m = n``.
    FULL_RANK = "full rank {n} at m={m}"
    #: series: the output coefficients ``y_0 .. y_k`` already span ``n`` directions.
    FULL_RANK_ORDER = "full rank {n} at order {k}"
    #: ORC: ``Omega_m = Omega_{m-1}`` (the last step added no generator).
    CONVERGED = "Omega_{m} = Omega_{prev}"
    #: single_ui: ``Omega_m = Omega_{m-1}`` with ``m - 1 >= m'`` (and the correction
    #: ``m* = m - 1 >= 1`` unless every ``phi^i_1`` vanishes).
    CONVERGED_AFTER_M_PRIME = "Omega_{m} = Omega_{prev} with m >= m'"
    #: series: order ``k`` adds nothing, and no later order can (non-increasing increments).
    SPAN_CLOSED = "order {k} adds nothing: span closed"
    #: ORC, single_ui, series: the user's cap ``max_order`` was reached first.
    MAX_ORDER = "max_order={max_order} reached before convergence"
    #: single_ui: ``d tau`` never entered Omega within ``cap = 2n + 3`` steps (Lemma 8 of 004).
    STEP_CAP = "no convergence certified within {cap} steps"
    #: single_ui: the unknown input does not affect the outputs; the ORC of the known fields.
    KNOWN_FIELDS_ORC = "ORC of the known fields converged"
    #: EORC: every component of the original state is observable at order ``k``.
    ALL_STATES = "every state component observable at k={k}"
    #: EORC: the highest order ``k_max`` was reached.
    K_MAX = "k_max={k_max} reached"
    #: EORC: ``dim_k`` equals the known-input bound and every unknown input is observable
    #: (:mod:`uio_jax._analysis.recursions.known_bound`): no later order changes a verdict.
    KNOWN_BOUND = ("every unknown input observable and the states at the known-input bound {bound} "
                   "at k={k}: no higher order changes a verdict")
    #: EORC: ``dim_k`` equals the bound of the verified symmetries and every unknown input is
    #: observable or moved by one of them (:mod:`uio_jax._analysis.decisions.symmetry`).
    SYMMETRY_BOUND = ("the states at the bound {bound} of the verified symmetries at k={k}, every unknown "
                      "input observable or proved unobservable: no higher order changes a verdict")
    #: EORC: ``Omega-bar_k = Omega-bar_{k-1}``.
    EXTENSION_CLOSED = ("Omega-bar_{k} = Omega-bar_{prev}: no higher order (in any extension) "
                        "adds a generator")

    #: general_ui, no unknown input: the closure of the outputs along the drift converged.
    CLOSURE_CONVERGED = "closure along the drift converged at iteration {m}"
    #: general_ui: canonic (m = m_w); the closure under the rescaled fields converged.
    CANONIC_CLOSURE = "canonic at iteration {m}: the closure under the rescaled fields converged"
    #: general_ui: every unreconstructed field G~_k vanishes; the closure converged.
    REMAINING_UIS_VANISH = ("iteration {m}: every unreconstructed unknown-input field vanishes; "
                            "the closure under the rescaled fields converged")
    #: general_ui: the guarded closure met no generator moved by an unreconstructed input.
    GUARD_PASSED = "iteration {m}: the guarded closure converged without meeting an unreconstructed input"
    #: general_ui: m = 0 and the closure of the UI-free generators added nothing.
    GENERAL_STALLED = "iteration {m}: no progress (m = 0 and nothing new); no convergence certified"
    #: general_ui: the bound on the iterations of the main loop.
    GENERAL_CAP = "no convergence within {cap} iterations"

    def stop(self, **values) -> "Stop":
        """This reason with its values, e.g. ``StopReason.FULL_RANK.stop(n=3, m=2)``."""
        stop = Stop(self, tuple(sorted(values.items())))
        stop.message  # noqa: B018 - a missing value fails here, not when the report is built
        return stop

    @property
    def converged(self) -> bool:
        """Whether the recursion reached its final codistribution (not a cap)."""
        return self not in (StopReason.MAX_ORDER, StopReason.STEP_CAP, StopReason.K_MAX,
                            StopReason.GENERAL_STALLED, StopReason.GENERAL_CAP)

    @property
    def capped(self) -> bool:
        """Whether a cap on the steps stopped a recursion that is exact once converged (the
        ORC, single_ui, the general solution): its answer is then sufficient only. The
        EORC's ``K_MAX`` is not one: the EORC is sufficient at every order, exact at a bound."""
        return self in (StopReason.MAX_ORDER, StopReason.STEP_CAP, StopReason.GENERAL_STALLED,
                        StopReason.GENERAL_CAP)

    def _pattern(self):
        parts = re.split(r"\{(\w+)\}", self.value)
        regex = "".join(re.escape(p) if i % 2 == 0 else f"(?P<{p}>-?[0-9]+)"
                        for i, p in enumerate(parts))
        return re.compile(regex + r"\Z")

    def matches(self, text: str) -> bool:
        """Whether ``text`` (a Report's ``stop_reason``) is this reason's message."""
        return self._pattern().match(text) is not None

    @classmethod
    def parse(cls, text: str) -> "Stop":
        """The :class:`Stop` whose message is ``text`` (values as ints); ValueError if none."""
        for reason in cls:
            found = reason._pattern().match(text)
            if found is not None:
                return reason.stop(**{k: int(v) for k, v in found.groupdict().items()})
        raise ValueError(f"not a stop reason: {text!r}")


@dataclasses.dataclass(frozen=True)
class Stop:
    """A :class:`StopReason` with its values; :attr:`message` is the Report's text.

    Attributes:
        reason: the member.
        values: ``(name, value)`` pairs, sorted by name (the template's fields).
    """

    reason: StopReason
    values: tuple = ()

    @property
    def message(self) -> str:
        """The text of ``Report.stop_reason``, e.g. ``"full rank 3 at m=2"``."""
        return self.reason.value.format(**dict(self.values))

    def __str__(self) -> str:
        return self.message


class Recursion(abc.ABC):
    """One analysis' recursion ``Omega_0 -> Omega_1 -> ...``, run by :func:`iterate`.

    Implement :meth:`init`, :meth:`step` and :meth:`terminate` (and :meth:`postprocess` if
    the analysis wants a result built from the finished history). State between calls (the
    frontier of generators kept at the last step, counters, what is known of ``m'``) lives
    on ``self``; the driver passes only its step counter ``m`` and the history so far.
    """

    @abc.abstractmethod
    def init(self) -> Step | None:
        """Build Omega_0 and return its Step (``m = 0``), not yet announced.

        Return None when Omega_0 is already the last Step of the ``history`` given to
        :func:`iterate` (e.g. single_ui, whose Omega_0 is the level of the chosen output).
        """

    @abc.abstractmethod
    def step(self, m: int) -> Step:
        """Build Omega_m from Omega_{m-1} (``m >= 1``) and return its Step, not yet announced
        (a Context builds it with ``ctx.step``). ``Step.m`` is the analysis' own numbering
        (it may differ from ``m``, e.g. single_ui's ``m + offset``)."""

    @abc.abstractmethod
    def terminate(self, m: int, history: Sequence[Step]) -> "Stop | None":
        """After Omega_m (``m = 0`` after :meth:`init`): a :class:`Stop` to end, None to go on.

        ``history``: every Step recorded so far, Omega_m last. Must return a Stop after
        finitely many steps (every analysis has a cap: n - 1, max_order, 2n + 3, k_max).
        """

    def postprocess(self, history: Sequence[Step], stop: "Stop") -> Any:
        """A result built once the recursion stopped (default None); :attr:`Outcome.result`."""
        return None


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What :func:`iterate` returns.

    Attributes:
        history: every Step, ``history[-1]`` is Omega_M (a list, so an analysis may still
            annotate its entries before building the Report).
        stop: why it stopped (``str(stop)`` is the Report's ``stop_reason``).
        m: the driver's last step counter M (0 when it stopped after :meth:`Recursion.init`).
        result: :meth:`Recursion.postprocess`'s value.
    """

    history: list
    stop: Stop
    m: int
    result: Any = None


def iterate(recursion: Recursion, history: Sequence[Step] = ()) -> Outcome:
    """Run ``recursion`` until :meth:`Recursion.terminate` returns a :class:`Stop`.

    Every Step the recursion returns is announced (:func:`uio_jax._progress.announce_step`,
    seen by a :func:`uio_jax._progress.step_listener`) and appended to the history, which
    starts with ``history`` (Steps recorded before, already announced).

    Args:
        recursion: the analysis' :class:`Recursion`.
        history: Steps that precede Omega_0 or are Omega_0 itself (see :meth:`Recursion.init`).

    Returns:
        :class:`Outcome` ``(history, stop, m, result)``.
    """
    history = list(history)
    first = recursion.init()
    if first is not None:
        history.append(announce_step(first))
    if not history:
        raise ValueError("Recursion.init returned no Step and no history was given")
    m = 0
    while (stop := recursion.terminate(m, history)) is None:
        m += 1
        history.append(announce_step(recursion.step(m)))
    return Outcome(history, stop, m, recursion.postprocess(history, stop))


__all__ = ["StopReason", "Stop", "Recursion", "Outcome", "iterate"]
