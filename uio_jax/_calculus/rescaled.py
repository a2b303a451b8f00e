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
:class:`~uio_jax._calculus.generators.Node` whose callable computes ``B`` and ``a`` from
the identifiers' Lie derivatives at ``x`` (forward mode) and solves with ``B``:
Lie derivatives along it, and their gradients, differentiate through the solve.
In the System's expression graph (when every operand has an expression) the same fields
are expressions: ``B`` and ``a`` are Lie derivatives of the identifiers, and the solve is
the adjugate formula (:meth:`uio_jax._engine.graph.Graph.solve`; ``m`` is small).
"""

import jax
import jax.numpy as jnp

from .generators import Builder, Node


def _parts(drift, fields, identifiers):
    """``x -> (g0 (N,), G (mw, N), M (m, 1 + mw))`` at one state, ``M = [L_g0 h~, L_{g_j} h~]``.

    The Lie derivatives are forward-mode (one vmapped ``jvp`` of each identifier over the
    tangents ``g0, g_1..g_mw``): Lie derivatives of and along these fields then nest forward
    mode in forward mode, several times cheaper to trace than a gradient inside.
    """

    def at(x):
        g0 = drift(x)
        G = jnp.stack([g(x) for g in fields])
        T = jnp.concatenate([g0[None], G])
        M = jnp.stack([jax.vmap(lambda t, h=h: jax.jvp(h, (x,), (t,))[1])(T) for h in identifiers])
        return g0, G, M

    return at


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
    parts = _parts(drift.fn, tuple(f.fn for f in fields), tuple(h.fn for h in identifiers))
    ids = ",".join(h.label for h in identifiers)
    key = ("rescaled", drift.label, tuple(f.label for f in fields), ids)
    depth = max([drift.depth] + [f.depth for f in fields] + [h.depth for h in identifiers]) + 1

    exprs = _expressions(builder, drift, fields, identifiers)

    def make(kind, k, label, fn):
        expr = None if exprs is None else exprs[kind][k]
        return builder.node(key + (kind, k), lambda: builder.make(label, fn, "field", depth, "", expr))

    def g_hat0(x):
        g0, G, M = parts(x)
        return g0 - G[:m].T @ jnp.linalg.solve(M[:, 1:m + 1], M[:, 0])

    def g_hat(k):
        def f(x):
            _, G, M = parts(x)
            return G[:m].T @ jnp.linalg.solve(M[:, 1:m + 1], jnp.eye(m, dtype=x.dtype)[:, k])
        return f

    def G_tilde(k):
        def f(x):
            _, G, M = parts(x)
            coef = jnp.linalg.solve(M[:, 1:m + 1], M[:, 1 + k])  # B^-1 (L_{g_k} h~)
            return G[k] - G[:m].T @ coef
        return f

    hat0 = make("g^0", 0, f"{drift.label}^", g_hat0)
    hats = [make("g^", k, f"{names[k]}^", g_hat(k)) for k in range(m)]
    tildes = [make("G~", k, f"{names[k]}~", G_tilde(k)) for k in range(m, len(fields))]
    return hat0, hats, tildes


def _expressions(builder, drift, fields, identifiers):
    """The rescaled fields as expressions of the builder's graph:
    ``{"g^0": [g^0], "g^": [g^_1..g^_m], "G~": {k: G~_k}}`` (tuples of nodes), or None when
    an operand has no expression."""
    if any(nd.expr is None for nd in (drift, *fields, *identifiers)):
        return None
    g = builder.graph
    m = len(identifiers)
    G = [f.expr for f in fields]
    a = [g.jvp([h.expr], drift.expr)[0] for h in identifiers]
    L = [[g.jvp([h.expr], f.expr)[0] for f in fields] for h in identifiers]  # L[i][j] = L_{g_j} h~_i
    B = [row[:m] for row in L]
    units = [[g.one if i == k else g.zero for i in range(m)] for k in range(m)]
    rest = [[L[i][k] for i in range(m)] for k in range(m, len(fields))]
    solved = g.solve(B, [a] + units + rest)

    def combine(base, coef, sign):  # base + sign * sum_j coef_j G_j, per coordinate
        out = []
        for c in range(g.n):
            acc = g.dot(coef, [G[j][c] for j in range(m)])
            out.append(acc if base is None else (g.sub(base[c], acc) if sign < 0 else g.add(base[c], acc)))
        return tuple(out)

    return {"g^0": [combine(drift.expr, solved[0], -1)],
            "g^": [combine(None, solved[1 + k], 1) for k in range(m)],
            "G~": {k: combine(G[k], solved[1 + m + (k - m)], -1) for k in range(m, len(fields))}}
