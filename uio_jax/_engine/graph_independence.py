"""Whether the elementary functions of a graph may be evaluated as independent generators
modulo p (:mod:`.graph_elementary`, "Why the rank is the real one").

In each family (real: ``exp``, ``log``, ...; imaginary: ``sin``, ``atan``, ...) the
logarithmic differentials ``omega_j`` of the generators must be linearly independent over
the constants. A relation ``sum c_j omega_j = 0`` with constant ``c_j`` holds at every point,
so the matrix whose columns are the ``omega_j`` evaluated at ``K`` points (rows: point and
coordinate) has a kernel whenever the generators are related; with no relation its rank is
the number of generators except at the roots of a nonzero minor. A full rank modulo p
therefore proves the independence (certain), and a deficient one is taken as a relation (a
model refused the exact route, on the safe side).
"""

import math

import numpy as np

from . import graph_elementary
from .graph_exact import PRIME, ModularEvaluator, rank_mod_p
from .graph_numpy import columns as node_columns


def generator_keys(graph, roots, nodes=None) -> dict:
    """``{key: node}``: the generators of the elementary nodes behind ``roots`` (one node per
    key: sin and cos of one argument share their circle); ``nodes``: the nodes to look at
    instead (already walked by the caller)."""
    keys = {}
    for k in (graph.reachable(roots) if nodes is None else nodes):
        key = graph_elementary.generator_key(graph, k)
        if key is not None:
            keys.setdefault(key, k)
    return keys


def rationalizable(graph, roots) -> bool:
    """Whether every node behind ``roots`` is rational or a supported elementary function."""
    return all(graph_elementary.rationalizable(graph, k) for k in graph.reachable(roots))


def independent(graph, keys, rng, p: int = PRIME) -> tuple[bool, str]:
    """Whether the generators ``keys`` (:func:`generator_keys`) are independent (module doc).

    Args:
        graph: the graph.
        keys: ``{key: node}``.
        rng: a numpy Generator for the points.
        p: the prime.

    Returns:
        ``(True, "")``, or ``(False, why)`` naming the family with a relation.
    """
    by_family = {}
    for key in keys:
        by_family.setdefault(graph_elementary.family(key), []).append(key)
    for fam, members in by_family.items():
        # each point gives one row per coordinate the generators' arguments depend on: enough
        # points that the rank can reach their number (omegas on few coordinates need more)
        nodes = graph.reachable([keys[k] for k in members])
        cols, _ = node_columns(graph, nodes)
        involved = set().union(*(cols[keys[k]] for k in members))
        count = math.ceil(len(members) / max(len(involved), 1)) + 1
        for _ in range(4):  # a point where a root or a denominator fails: draw again
            words = rng.integers(0, 2**63, size=(count, graph.n, 3))
            points = [[((int(a) << 126) | (int(b) << 63) | int(c)) % p for a, b, c in row] for row in words]
            ev = ModularEvaluator(graph, points, p)
            try:
                ev.evaluate([keys[k] for k in members])
                columns = []
                for key in members:
                    col = np.zeros((count, graph.n), dtype=object)
                    for operand, factor in graph_elementary.omega_factors(graph, key, ev.V, p):
                        col = col + (ev.dense(operand) * factor).T
                    columns.append(col.reshape(-1) % p)
            except graph_elementary.Singular:
                continue
            break
        else:
            return False, f"the {fam} elementary functions could not be evaluated modulo p"
        if rank_mod_p(np.array(columns, dtype=object).T, p) < len(members):
            return False, (f"the {fam} elementary functions are related (their arguments are linearly "
                           "dependent, e.g. sin(x) with sin(2 x), or exp(u) with exp(-u))")
    return True, ""


__all__ = ["generator_keys", "rationalizable", "independent"]
