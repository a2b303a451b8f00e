"""The recursion driver shared by the analyses (ORC, single_ui, series, EORC, the general
solution, the Taylor route).

Every analysis grows a codistribution ``Omega_0 -> Omega_1 -> ... -> Omega_M`` (M: the step
at which it stops) and differs only in how a step is formed and in when it has converged. As
optimistix's ``_iterate`` (one loop for all root finders, with ``init``, ``step``,
``terminate``, ``postprocess``; the loop owns ``max_steps``), this module holds the loop once:

* :class:`Recursion`, the interface an analysis implements: its ``terminate`` says only
  whether it has *converged*;
* :class:`Cap`, the bound on the steps and the :class:`~uio_jax._analysis.results.stop.Stop`
  reported when it is reached (``max_order``, ``2n + 3``, ``k_max``, the general solution's
  30 iterations): the caller gives it, the loop enforces it;
* :func:`iterate`, the one loop: it records every step and announces it exactly once
  (:func:`uio_jax._progress.announce_step`), stops at the cap, and returns a
  :class:`RecursionResult`.

``terminate`` is asked after ``init`` and after every step, so a stop at ``m = 0`` (full rank
from the outputs alone) needs no step; the cap is tested after it, so that a step that
converges exactly at the cap reports its convergence.
"""

import abc
import dataclasses
from collections.abc import Sequence
from typing import Any

from ..._progress import announce_step
from ..results.evidence import Step
from ..results.stop import Stop, StopReason


@dataclasses.dataclass(frozen=True)
class Cap:
    """The driver's bound on a recursion: after step ``m = steps`` it stops with ``stop``.

    Attributes:
        steps: the last step the driver runs (``0``: Omega_0 only).
        stop: the :class:`~uio_jax._analysis.results.stop.Stop` it reports when the bound is
            reached before the recursion converged (``StopReason.MAX_ORDER``, ``STEP_CAP``,
            ``K_MAX``, ``GENERAL_CAP``).
    """

    steps: int
    stop: Stop

    @staticmethod
    def tightest(*caps: "Cap | None") -> "Cap":
        """The cap with the fewest steps among ``caps`` (None entries ignored; the first of
        equal ones, so the caller lists them in the order their reasons take precedence)."""
        given = [c for c in caps if c is not None]
        if not given:
            raise ValueError("a recursion needs a cap")
        return min(given, key=lambda c: c.steps)


class Recursion(abc.ABC):
    """One analysis' recursion ``Omega_0 -> Omega_1 -> ...``, run by :func:`iterate`.

    Implement :meth:`init`, :meth:`step` and :meth:`terminate` (and :meth:`postprocess` for
    a result built from the finished history). State between calls lives on ``self``; the
    driver passes only its step counter ``m`` and the history so far.
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
        """After Omega_m (``m = 0`` after :meth:`init`): a :class:`Stop` when the recursion has
        converged (or found its answer), None to go on. The bound on the steps is not the
        recursion's: :func:`iterate` applies the caller's :class:`Cap` after this.

        ``history``: every Step recorded so far, Omega_m last.
        """

    def postprocess(self, history: Sequence[Step], stop: "Stop") -> Any:
        """A result built once the recursion stopped (default None); :attr:`RecursionResult.result`."""
        return None


@dataclasses.dataclass(frozen=True)
class RecursionResult:
    """What :func:`iterate` returns.

    Attributes:
        history: every Step, ``history[-1]`` is Omega_M (a list, so an analysis may still
            annotate its entries before building the Report).
        stop: why it stopped (``str(stop)`` is the Report's ``stop_reason``): the
            recursion's convergence, or the :class:`Cap`'s stop.
        m: the driver's last step counter M (0 when it stopped after :meth:`Recursion.init`).
        result: :meth:`Recursion.postprocess`'s value.
    """

    history: list
    stop: Stop
    m: int
    result: Any = None

    @property
    def capped(self) -> bool:
        """Whether the cap stopped it before it converged."""
        return self.stop.reason.capped


def iterate(recursion: Recursion, history: Sequence[Step] = (), *, cap: Cap) -> RecursionResult:
    """Run ``recursion`` until :meth:`Recursion.terminate` returns a :class:`Stop`, or until
    ``cap`` is reached.

    Every Step the recursion returns is announced (:func:`uio_jax._progress.announce_step`,
    seen by a :func:`uio_jax._progress.step_listener`) and appended to the history, which
    starts with ``history`` (Steps recorded before, already announced).

    Args:
        recursion: the analysis' :class:`Recursion`.
        history: Steps that precede Omega_0 or are Omega_0 itself (see :meth:`Recursion.init`).
        cap: the bound on the steps and its Stop (:class:`Cap`).

    Returns:
        :class:`RecursionResult` ``(history, stop, m, result)``.
    """
    history = list(history)
    first = recursion.init()
    if first is not None:
        history.append(announce_step(first))
    if not history:
        raise ValueError("Recursion.init returned no Step and no history was given")
    m = 0
    while (stop := recursion.terminate(m, history)) is None:
        if m >= cap.steps:
            stop = cap.stop
            break
        m += 1
        history.append(announce_step(recursion.step(m)))
    return RecursionResult(history, stop, m, recursion.postprocess(history, stop))


__all__ = ["StopReason", "Stop", "Cap", "Recursion", "RecursionResult", "iterate"]
