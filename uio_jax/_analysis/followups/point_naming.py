"""Observable functions named at one point: the Taylor route's naming
(``Report.named_functions`` where the analysis keeps no symbolic generators).

The Taylor route keeps no graph nodes of its generators, so the ansatzes of
:mod:`.observable_functions` (which need the unobservable directions at many points) do not
apply; the candidates that need no ansatz do (the coordinates, the model's subexpressions,
ratios and products of two of the simplest), ranked by simplicity. Each is kept when its
gradient lies in the span (the route's own exact membership, in every lane of its
machine-word primes) and raises the rank of those kept at one random point modulo
``2^127 - 1`` (an independence at a point is certain).
"""

import time

from ..._engine import graph_exact
from ..._engine.graph_numpy import columns
from .expression_text import Printer
from .observable_functions import MAX_SUBEXPRESSIONS, PAIR_POOL, ObservableFunctions, Source, make_candidate, simplicity


def name_at_point(space, dim: int, generators) -> ObservableFunctions:
    """Name observable functions where the analysis keeps no symbolic generators (the module
    docstring: the candidates of :func:`name_functions` that need no ansatz, each kept by the
    route's own exact membership, :meth:`~uio_jax._analysis.decisions.taylor_space.TaylorSpace.member`).

    Args:
        space: the report's :class:`~uio_jax._analysis.decisions.taylor_space.TaylorSpace`.
        dim: the observable dimension.
        generators: labels of the kept generators.
    """
    start, first_bound = time.perf_counter(), space.error_bound
    graph, roots, names = space.naming_graph()
    n = len(names)
    printer = Printer(graph, names)
    variables = [c for c in (make_candidate(graph, printer, names, graph.coords[i], Source.VARIABLE)
                             for i in range(n)) if c]
    order = graph.reachable(roots)
    cols = columns(graph, order)[0]
    reach = [k for k in order if graph.op[k] not in ("x", "c") and cols[k] and max(cols[k]) < n]
    subs = sorted((c for c in (make_candidate(graph, printer, names, k, Source.SUBEXPRESSION) for k in reach) if c),
                  key=simplicity)[:MAX_SUBEXPRESSIONS]
    chosen, kept = [], graph_exact.Echelon()

    def select(cands):
        cands = sorted(cands, key=simplicity)
        rows = space.rows_at_point([node for _, node in cands])
        for fn, node in cands:
            if len(chosen) >= dim:
                return
            row = rows.get(node)
            if row is None or not any(kept.reduce(row)):
                continue
            if space.member(node):
                kept.add(row)
                chosen.append(fn)

    select(variables + subs)
    if len(chosen) < dim:
        named = {fn.text for fn in chosen if fn.source is Source.VARIABLE}
        pool = [c for c in variables if c[0].text not in named] + subs[:PAIR_POOL]
        pairs = []
        for i, a in enumerate(pool):
            for b in pool[i + 1:]:
                for node in (graph.div(a[1], b[1]), graph.div(b[1], a[1]), graph.mul(a[1], b[1])):
                    pairs.append(make_candidate(graph, printer, names, node, Source.COMBINATION))
        select([c for c in pairs if c])
    return ObservableFunctions(tuple(chosen), (), dim, tuple(generators), "exact mod p",
                               space.error_bound - first_bound, time.perf_counter() - start)


__all__ = ["name_at_point"]
