"""The known-input bound: when the EORC's verdicts can no longer change.

The EORC (:mod:`.eorc`) has no convergence test of its own for several unknown inputs with
switchable known ones: it runs to ``k_max`` unless ``Omega-bar`` closes or every state is
observable. This module gives a sound early stop.

**The bound.** Make every unknown input a known (switchable) one: the System
``x' = f0 + sum_i f_i u_i + sum_j g_j w_j`` with ``w`` measured. Its observation space
``O`` is the span (over the reals) of the iterated Lie derivatives of the outputs along
``f0, f_i, g_j``, closed under each of them, and ``Omega_known = span{d psi : psi in O}``
(the ORC's final codistribution; the series test gives its generic rank, :mod:`.series`).

*Every EORC generator is* ``sum_a p_a(w, w^(1), ..) psi_a(x)`` *with* ``psi_a in O`` *and*
``p_a`` *polynomials.* True for ``h``; ``L_F0`` maps ``p psi`` to
``p (L_f0 psi + sum_j w_j L_gj psi) + sum_d (dp/dw^(d)) w^(d+1) psi`` and ``L_Fi`` to
``p L_fi psi``, both of that form. So at every point of the extended space, the
x-components of a generator's gradient lie in ``Omega_known(x)``; a covector of
``Omega-bar_k`` with no component along ``w`` is ``sum_i a_i d phi_i`` with the ``w``-parts
cancelling, so ::

    Omega-bar_k  intersected with  span{dx}   is contained in   Omega_known(x)

at every point and every order ``k``, in every extension. Hence ``dim_k <= r``, the generic
rank of ``Omega_known`` (the state coordinates only; no known coordinates). When
``dim_k = r`` at some order, the two spaces coincide at generic points for every later
order: no state verdict changes any more (and they are those of the known-input ORC).

**The inputs.** If ``e_{w^(d)}`` lies in ``Omega-bar_k`` then ``e_{w^(d+1)}`` lies in
``Omega-bar_{k+1}``: ``L_F0 d w^(d) = d L_F0 w^(d) = d w^(d+1)``, and ``Omega-bar_{k+1}``
contains ``L_F0`` of every covector of ``Omega-bar_k`` (``L_F0 sum a_i dphi_i =
sum (L_F0 a_i) dphi_i + a_i d L_F0 phi_i``). So once every unknown input ``w_j`` is
observable at order ``k``, every derivative ``w_j^(d)`` is observable at order ``k + d``.

With both, the EORC stops at ``k`` (:attr:`~uio_jax._analysis.recursions.driver.StopReason.KNOWN_BOUND`):
the states are final, every input and each derivative is observable; only the augmented
rank would keep growing.

**Soundness of r.** ``r`` must not be underestimated (an early stop would then hide a
direction): the series test runs with every float64 rejection settled again
(``DecisionPolicy.reaching(Reach.ALL)``: exact modulo p for rational models, mpmath
at two precisions otherwise) and its rises verified exactly where rational; a decision
left undecided, a series stopped by its cap, or a model the series cannot expand gives no
bound (the EORC goes on as before).
"""

import dataclasses

from ..._model.smooth_inputs import known_coordinates
from ..._model.system import System, derived_system
from ..decisions.context import Context
from ..decisions.policy import Reach
from ..decisions.settle import DEFAULT_PROB_THRESHOLD
from .series import run_series


@dataclasses.dataclass(frozen=True)
class KnownBound:
    """The generic rank ``r`` of ``Omega_known`` and how it was obtained.

    Attributes:
        dim: ``r``, the dimension of the observation space with every input known.
        order: the order of the output series at which the span closed (or reached n).
        settled: rejections and rises settled beyond float64 in reaching it.
    """

    dim: int
    order: int
    settled: int


def known_input_system(system: System) -> System:
    """``system`` with its unknown inputs made known (switchable): same states, outputs,
    drift; known fields ``f_i`` then ``g_j`` (names kept)."""
    with derived_system():
        return dataclasses.replace(system, known={**system.known, **system.unknown}, unknown={})


def known_input_bound(system: System, *, samples: int, seed: int, rtol: float,
                      prob_threshold: float = DEFAULT_PROB_THRESHOLD) -> KnownBound | None:
    """The bound ``r`` of the module docstring for the EORC of ``system``, or None.

    Args:
        system: the System the EORC runs on (its unknown inputs are made known here).
        samples, seed, rtol: the sampling options of the analysis (the series decides on
            the first decision samples, :func:`~uio_jax._analysis.decisions.memory.decision_count`).

    Returns:
        :class:`KnownBound`, or None where no sound bound is available: known coordinates
        (time, jets of smooth inputs), a series stopped by its cap, or an undecided decision.
    """
    if known_coordinates(system) or not system.unknown:
        return None
    known = known_input_system(system)
    ctx = Context(known, samples, seed, rtol, prob_threshold)
    ctx.codist.policy = ctx.codist.policy.reaching(Reach.ALL)
    history, reason, k = run_series(ctx, seed=seed)
    codist = ctx.codist
    if any(e.result == "undecided" for e in codist.record.escalations):
        return None
    if ctx.dim < known.n and history[-1].added:  # stopped by the cap, not closed
        return None
    record = codist.record
    return KnownBound(ctx.dim, k, len(record.escalations) + record.rejections_verified + record.verified)


def stop_note(bound: KnownBound, k: int, dim_k: int, dim_all: int, hidden, held: bool) -> str:
    """The Report's note on an EORC stopped at the bound at order ``k``: why no later order
    changes a verdict (and which states are then not observable even with every input
    known), or, when the stop's premise did not hold on the certifying samples (``held``
    False: they gave ``dim_all``), that the verdicts are the EORC's usual sufficient ones."""
    if not held:
        return (f"the early stop at k={k} (dim {dim_k} = the known-input bound) did not hold "
                f"on every certifying sample (dim {dim_all}): the verdicts are sufficient only")
    text = (f"k={k}: every unknown input is observable and the states reach the known-input bound "
            f"{bound.dim} (the rank of the observation space with every input known, series order "
            f"{bound.order}), which bounds Omega-bar_k on the states at every order: no higher order "
            "changes a verdict, and each derivative w^(d) of an unknown input is observable at "
            "order k + d")
    if hidden:
        text += f"; {', '.join(hidden)}: not observable even with every input known (exact, analytic model)"
    return text


__all__ = ["KnownBound", "known_input_bound", "known_input_system", "stop_note"]
