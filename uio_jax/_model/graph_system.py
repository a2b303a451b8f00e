"""Systems built on an expression graph: the Systems the analyses derive.

The extended system of the EORC and the systems of a UI extension are built of the
expressions of the analysed System (imported into a new graph), never written as JAX closures
and traced again: their functions are :class:`~uio_jax._engine.graph_trace.GraphFunction`
objects of that graph, which is the System's own.
"""

from .._engine.graph_trace import GraphFunction
from .derivation import Derivation
from .system import System, derived_system


def graph_system(graph, states, outputs, *, known=None, unknown=None, drift=None, domain=None,
                 angles=(), name="", known_coordinates=0) -> System:
    """A System on the ``graph.n`` coordinates of ``graph`` (the states, in order).

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph` of every function.
        states: the names of its coordinates.
        outputs: name -> node (an int).
        known, unknown: name -> field (a tuple of ``n`` nodes).
        drift: a tuple of ``n`` nodes, or None.
        domain, angles, name: as for :class:`System`.
        known_coordinates: the trailing coordinates whose values are known
            (:attr:`~uio_jax.System.known_coordinates`).
    """
    def field(nodes):
        return GraphFunction(graph, tuple(int(k) for k in nodes))

    with derived_system():  # parts built from a validated System: no traced checks
        system = System(states=tuple(states), outputs={k: GraphFunction(graph, int(e)) for k, e in outputs.items()},
                        known={k: field(f) for k, f in (known or {}).items()},
                        unknown={k: field(f) for k, f in (unknown or {}).items()},
                        drift=None if drift is None else field(drift), domain=domain or {}, angles=angles,
                        name=name,  # the System's expressions are the graph's nodes
                        derivation=Derivation(known_coordinates=known_coordinates, graph=graph))
    return system


__all__ = ["graph_system"]
