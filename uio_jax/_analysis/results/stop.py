"""Why a recursion stopped: :class:`StopReason`, the enumeration of the ways every analysis
of the package ends, and :class:`Stop`, a member with its values (the record a
:class:`~uio_jax.Report` keeps; :mod:`uio_jax._analysis.recursions.driver` returns it).

Each member carries the exact text a Report shows in ``stop_reason`` (reports are compared
bit for bit, so the text is part of the format); the text is derived from the member,
never parsed back into a decision (:meth:`StopReason.parse` reads a report written
earlier).
"""

import dataclasses
import enum
import re


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


__all__ = ["StopReason", "Stop"]
