"""Functions of the unknowns: is ``f(theta)`` locally identifiable, and how many values does it take?

A function ``f`` of the parameters and initial states (``a b`` in ``x' = -a b x``) is asked the
same two questions as an unknown.

**Locally**: ``f`` is locally identifiable when ``df`` lies in the row space of the Jacobian of
the output coefficients. The project's local machinery decides it exactly
(:class:`~uio_jax._analysis.initial.Experiment` for the coefficients, a
:class:`~uio_jax._analysis.initial.Span` of the rows up to the order the local test reached,
and the :class:`~uio_jax._analysis.settle.Settler`'s membership decision modulo ``2^127 - 1``,
with its Schwartz-Zippel bound added to the error bound). "Not" needs the span complete: the
local test closed it (every unknown determined, or an order that added nothing).

**Globally**: a new variable ``w_f`` with the equation ``den_f w_f - num_f = 0`` joins the
fibre; its values on the solutions are counted as an unknown's. ``w_f`` is a function of the
other variables, so the fibre stays zero-dimensional.
"""

from collections.abc import Mapping

from ..._calculus.generators import Node, builder_for
from ..._engine.graph import Graph
from ..._engine.graph_trace import GraphFunction
from ..._errors import OptionError
from ..at_t0.initial import NO_VOTE, Coordinates, Experiment, Span
from ..decisions.settle import Settler
from ..results.evidence import Finding


def check_functions(system, functions) -> dict:
    """``{name: callable}`` checked: names that are identifiers and not taken by an unknown,
    callables taking the arguments of the System's outputs (``(x, p)`` with parameters)."""
    if functions is None:
        return {}
    if not isinstance(functions, Mapping):
        raise OptionError(f"functions must be a mapping name -> function, got {type(functions).__name__}")
    taken = set(system.states) | set(system.params) | set(system.known) | set(system.outputs)
    out = {}
    for name, fn in functions.items():
        if not isinstance(name, str) or not name.isidentifier() or name in taken:
            raise OptionError(f"functions: {name!r} must be a new identifier (not a state, parameter, input "
                              "or output name)")
        if not callable(fn):
            raise OptionError(f"functions: {name!r} is not callable (a function of (x, p) as the outputs are)")
        out[name] = fn
    return out


def joint_function(system, fn):
    """``fn`` as a function of the joint coordinates ``z = [x; p]``."""
    n = len(system.states)
    if system.params:
        return lambda z: fn(z[:n], z[n:])
    return lambda z: fn(z)


def function_nodes(system, functions) -> dict:
    """``{name: node}`` of each function in the joint System's expression graph (a
    :class:`~uio_jax._engine.graph_trace.GraphFunction` of that graph, such as a named
    observable function of the analysis, is its node already)."""
    joint = system.joint()
    builder = builder_for(joint)
    return {name: fn.expr if isinstance(fn, GraphFunction) and fn.graph is builder.graph else
            builder.function(f"function {name}", joint_function(system, fn)).expr
            for name, fn in functions.items()}


def local_functions(system, checked_initial, functions, order, seed, prob_threshold, closed):
    """``({name: Finding}, error bound)``: each function's membership in the span of the
    output coefficients' rows up to ``order``; an independent one counts as not identifiable
    only when ``closed`` (the span complete), else undecided."""
    if not functions:
        return {}, 0.0
    coords = Coordinates()
    ex = Experiment(system, checked_initial, coords, max(order, 1))
    target = Graph(len(coords.names))
    ex.attach(target)
    lo, hi = coords.box()
    settler = Settler(target, lo, hi, seed + 0x46, prob_threshold)
    span = Span(settler, ex.seeds)
    for k in range(order + 1):
        span.absorb(ex.order(k))
    builder = builder_for(ex.joint)
    z_map = ex.coord_map[:len(ex.z_index)]
    out = {}
    for name, node in function_nodes(system, functions).items():
        expr = target.import_nodes(builder.graph, [node], z_map)[0]
        if target.op[expr] == "c":
            out[name] = Finding.DEPENDENT  # a constant is determined
            continue
        result = settler.settle(span.kept, Node(name, "scalar", 0, expr), NO_VOTE).result
        out[name] = Finding.UNDECIDED if (result is Finding.INDEPENDENT and not closed) else result
    return out, settler.error_bound


__all__ = ["check_functions", "function_nodes", "local_functions", "joint_function"]
