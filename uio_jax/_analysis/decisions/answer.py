"""What a finished analysis proves (:class:`~uio_jax._analysis.results.kinds.Answer`), decided
once by the analysis that ran; ``Report.answer`` keeps the member and ``Report.exact`` reads it.

The rules (the papers' theorems):

* The ORC (Hermann-Krener, no unknown input), the series test (its final codistribution),
  Martinelli's single-unknown-input codistribution and his general solution are necessary and
  sufficient at generic states once the recursion converged.
* A recursion stopped by a cap (``max_order``, the step bound, the general solution's
  iterations) shows observability sufficiently only: "observable" is proven, "not
  observable" means not shown.
* The EORC is sufficient only, except where it stopped at the known-input bound
  (:mod:`uio_jax._analysis.recursions.known_bound`) or at the bound of its verified symmetries
  (:mod:`uio_jax._analysis.decisions.symmetry`).
* The general solution with smooth known inputs whose jets may have been truncated
  (``details["exact"] is False``) proves "observable" only.
* A necessary and sufficient answer is :attr:`~Answer.EXACT` when every decision was made in
  exact arithmetic modulo p within the caller's probability bound, else
  :attr:`~Answer.NOT_CERTIFIED`.
"""

from collections.abc import Mapping

from ..results.kinds import Answer, Arithmetic, Method
from ..results.stop import Stop


def eorc_at_bound(details: Mapping) -> bool:
    """Whether an EORC stopped at the known-input bound or the bound of its verified
    symmetries (``details["known_input_bound"]``/``details["symmetries"]`` reached)."""
    bound = details.get("known_input_bound")
    symmetric = details.get("symmetries")
    return bool(symmetric and symmetric.get("reached_at") is not None) or bool(
        bound and bound.get("reached_at") is not None)


def decide_answer(method, stop: Stop, details: Mapping, arithmetic: Arithmetic) -> Answer:
    """The :class:`~uio_jax._analysis.results.kinds.Answer` of an analysis (module docstring).

    Args:
        method: the :class:`~uio_jax._analysis.results.kinds.Method` that ran.
        stop: its :class:`~uio_jax._analysis.results.stop.Stop`.
        details: its method-specific details (``exact``, ``known_input_bound``,
            ``symmetries``).
        arithmetic: the certificate's :class:`~uio_jax._analysis.results.kinds.Arithmetic`.
    """
    method = Method(method)
    if method is Method.GENERAL_UI and details.get("exact") is False and not stop.reason.capped:
        return Answer.SUFFICIENT_ONLY
    if method is Method.EORC and not eorc_at_bound(details):
        return Answer.SUFFICIENT_ONLY
    if stop.reason.capped:
        return Answer.SUFFICIENT_ONLY
    return Answer.EXACT if arithmetic is Arithmetic.EXACT else Answer.NOT_CERTIFIED


__all__ = ["decide_answer", "eorc_at_bound"]
