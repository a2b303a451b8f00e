"""What a System the package derives from another one is: the constructor field
:attr:`uio_jax.System.derivation`.

The package builds Systems from Systems (the joint, autonomous and jet Systems, Systems made
of graph nodes, the analyses' working Systems, a renamed copy). What such a System is (which
trailing coordinates are known, which were parameters, the graph its functions are nodes of)
is given to its constructor as one :class:`Derivation`, never written onto it afterwards. A
user's System has the default, :data:`USER_SYSTEM`.
"""

from collections.abc import Mapping
from dataclasses import dataclass


@dataclass(frozen=True, eq=False)
class Derivation:
    """How a System was derived (every field's default: a user's System).

    Attributes:
        known_coordinates: trailing coordinates whose values are known (the time of
            :meth:`~uio_jax.System.autonomous`, the jets of smooth known inputs).
        time_name: the name of the time coordinate (time made the last state), or None.
        joint_params: the coordinates that are parameters of the user's model.
        known_outputs: the outputs that measure the known coordinates; None: the time
            output when there is one.
        graph: the :class:`~uio_jax._engine.graph.Graph` whose nodes the System's functions
            are (a System built of graph nodes); None: a new graph of the System's own.
        symmetry_fields: the declared symmetries as fields of the coordinates the analyses
            run on (``z = [x; p; t]``), carried by the joint System to its autonomous one;
            None: the System's own ``symmetries`` where they are such fields.
        same_functions_as: a System with the same functions whose translations into the
            graph, joint and autonomous Systems the new one takes over (renamed):
            :meth:`~uio_jax.System.with_name`. Not kept once the System is built.
    """

    known_coordinates: int = 0
    time_name: str | None = None
    joint_params: tuple = ()
    known_outputs: tuple | None = None
    graph: object = None
    symmetry_fields: Mapping | None = None
    same_functions_as: object = None


#: The derivation of a System a user builds: nothing derived.
USER_SYSTEM = Derivation()


__all__ = ["Derivation", "USER_SYSTEM"]
