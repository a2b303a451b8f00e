"""The rescaled fields of Martinelli's general unknown-input solution (canonization).

With the drift ``g0`` (time and smooth known inputs folded in), the unknown-input fields
``g_1..g_mw`` ordered so that the reconstructable ones come first, and ``m`` UI identifiers
``h~_1..h~_m`` (scalar functions with ``B_ij = L_{g_j} h~_i``, ``i, j <= m``, invertible)::

    a_i      = L_g0 h~_i                                  (m,)
    g^0      = g0 - sum_j (B^-1 a)_j g_j                  UI-decoupled drift: L_{g^0} h~_i = 0
    g^_k     = sum_j (B^-1)_jk g_j,        k <= m         L_{g^_k} h~_i = delta_ik
    G~_k     = g_k - sum_{j<=m} g^_j L_{g_k} h~_j,  k > m  L_{G~_k} h~_i = 0

In the new unknown inputs ``v_j = d h~_j / dt`` the dynamics read
``x' = g^0 + sum_{j<=m} v_j g^_j + sum_{k>m} w_k G~_k``. Each field is one
:class:`~uio_jax._calculus.generators.Node`, an expression of the System's graph: ``B``
and ``a`` are Lie derivatives of the identifiers, and the solve is the adjugate formula
(:meth:`uio_jax._engine.graph.Graph.solve`; ``m`` is small).
"""

from .generators import Builder, Node


def rescaled_fields(builder: Builder, drift: Node, fields, identifiers, names=None):
    """The fields ``g^0``, ``g^_1..g^_m`` and ``G~_{m+1}..G~_mw`` as Nodes.

    Args:
        builder: the Builder of the System the nodes live on.
        drift: field node ``g0``.
        fields: the ``mw`` unknown-input field nodes, the ``m`` reconstructable ones first.
        identifiers: the ``m >= 1`` scalar identifier nodes ``h~_1..h~_m``.
        names: labels of the unknown inputs (default: the field labels).

    Returns:
        ``(g_hat0, g_hat (list of m), G_tilde (list of mw - m))``, field Nodes.
    """
    fields, identifiers = tuple(fields), tuple(identifiers)
    m = len(identifiers)
    names = tuple(names or (f.label for f in fields))
    ids = ",".join(h.label for h in identifiers)
    key = ("rescaled", drift.label, tuple(f.label for f in fields), ids)
    depth = max([drift.depth] + [f.depth for f in fields] + [h.depth for h in identifiers]) + 1

    exprs = _expressions(builder, drift, fields, identifiers)

    def make(kind, k, label):
        return builder.node(key + (kind, k), lambda: builder.make(label, "field", depth, exprs[kind][k]))

    hat0 = make("g^0", 0, f"{drift.label}^")
    hats = [make("g^", k, f"{names[k]}^") for k in range(m)]
    tildes = [make("G~", k, f"{names[k]}~") for k in range(m, len(fields))]
    return hat0, hats, tildes


def _expressions(builder, drift, fields, identifiers):
    """The rescaled fields as expressions of the builder's graph:
    ``{"g^0": [g^0], "g^": [g^_1..g^_m], "G~": {k: G~_k}}`` (tuples of nodes)."""
    g = builder.graph
    m = len(identifiers)
    G = [f.expr for f in fields]
    a = [g.jvp([h.expr], drift.expr)[0] for h in identifiers]
    L = [[g.jvp([h.expr], f.expr)[0] for f in fields] for h in identifiers]  # L[i][j] = L_{g_j} h~_i
    B = [row[:m] for row in L]
    units = [[g.one if i == k else g.zero for i in range(m)] for k in range(m)]
    rest = [[L[i][k] for i in range(m)] for k in range(m, len(fields))]
    solved = g.solve(B, [a] + units + rest)

    def combine(base, coef):  # base - sum_j coef_j G_j, per coordinate (no base: the sum)
        out = []
        for c in range(g.n):
            acc = g.dot(coef, [G[j][c] for j in range(m)])
            out.append(acc if base is None else g.sub(base[c], acc))
        return tuple(out)

    return {"g^0": [combine(drift.expr, solved[0])],
            "g^": [combine(None, solved[1 + k]) for k in range(m)],
            "G~": {k: combine(G[k], solved[1 + k]) for k in range(m, len(fields))}}
