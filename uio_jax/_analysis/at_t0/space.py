"""What an identifiability report at t = 0 answers about a function of the unknowns
(``IdentifiabilityReport.is_observable``): the span of ``d(y_0..y_K)`` at the known initial
state. ``phi(z)`` of ``z = [x; p]`` is *determined* when ``d phi`` (its known components
substituted) lies in that span, by the same exact membership and Settler as the verdicts on
single unknowns; *proved not determined* where the span is closed (no known component, no
unknown input); otherwise undecided up to order K, and the question is refused in one line.
"""

import dataclasses

from ..._calculus.generators import Node, builder_for
from ..._errors import ModelError
from ..results.evidence import Finding
from ..results.functions_of_z import function_of_z


@dataclasses.dataclass(frozen=True)
class _Variables:
    """The names a function of ``z = [x; p]`` reads (what :func:`function_of_z` checks)."""

    states: tuple
    params: tuple

    @property
    def n(self) -> int:
        return len(self.states) + len(self.params)


class InitialSpace:
    """The span of one finished analysis at t = 0 (module docstring).

    Args:
        span: the :class:`~uio_jax._analysis.at_t0.initial.Span` of the decisions.
        experiments: the :class:`~uio_jax._analysis.at_t0.initial.Experiment` list.
        closed: whether every experiment's span closed (a non-member is then proved not
            determined).
        order: the highest order reached.
    """

    def __init__(self, span, experiments, closed: bool, order: int):
        self.span, self.experiments, self.closed, self.order = span, list(experiments), closed, order

    def is_observable(self, fn) -> bool:
        """Whether ``fn(z)`` (``z = [x; p]`` of the System, or ``fn(x, p)``) is determined at
        the known initial state (module docstring).

        Raises:
            ModelError: several experiments (ask one experiment's report), a time-varying
                model, a bad function, or a function neither determined up to order K nor
                proved undeterminable (undecided).
        """
        if len(self.experiments) != 1:
            raise ModelError("is_observable: a function of several experiments' unknowns is not asked here; "
                             "analyze one experiment with its initial state to ask about one System's z")
        ex = self.experiments[0]
        system, joint = ex.system, ex.joint
        variables = _Variables(tuple(system.states), tuple(system.params))
        if joint.n != variables.n:
            raise ModelError("is_observable: the model depends on time; a function of z = [x; p] is not asked "
                             "at t = 0 here")
        of_z = function_of_z(variables, fn, "is_observable")
        builder = builder_for(joint)
        expr = builder.function("is_observable", of_z).expr
        target = ex.target.import_nodes(builder.graph, [expr], ex.coord_map[:joint.n])[0]
        esc = self.span.settler.settle(self.span.kept, Node("is_observable", "scalar", 0, target),
                                       "not voted: a function checked at the known initial state")
        self.span.escalations.append(esc)
        if esc.result is Finding.DEPENDENT:
            return True
        if esc.result is Finding.INDEPENDENT and self.closed:
            return False
        why = ("not determined up to order {0}, and no order bound is known at a specific initial state "
               "(raise max_order)" if esc.result is Finding.INDEPENDENT else "the exact decision could not be "
               "settled at order {0}").format(self.order)
        raise ModelError(f"is_observable: undecided: {why}")


__all__ = ["InitialSpace"]
