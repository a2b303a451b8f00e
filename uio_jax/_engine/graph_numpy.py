"""The expression graph (:mod:`.graph`) evaluated in float64 over many states, with numpy.

No program is compiled: the nodes behind the requested roots are visited once in
ascending order (a topological order) and each is one or two vectorised numpy operations
over the samples. Gradients are forward-mode: every node carries its value ``(S,)`` and
its gradient ``(n, S)`` (``None`` for a node that depends on no coordinate), combined by the
chain rule of its operation. A node's arrays are freed after its last use in the walk,
and the samples are taken in chunks sized so that the live arrays stay within
:data:`CHUNK_BYTES`.

Cost: about one numpy call on ``(S,)`` and one on ``(n, S)`` per node; for the seed models
(graphs of 10^2-10^4 nodes) milliseconds to a fraction of a second at 4096 samples,
against seconds of XLA compilation for the same program
(``docs/benchmarks/engine.md``).
"""

import math

import numpy as np

#: Bytes the live values and gradients of one chunk of samples may take.
CHUNK_BYTES = 256 * 2**20

_UNARY_VALUE = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
    "sqrt": np.sqrt, "tanh": np.tanh, "atan": np.arctan, "asin": np.arcsin, "acos": np.arccos,
    "sinh": np.sinh, "cosh": np.cosh, "asinh": np.arcsinh, "acosh": np.arccosh,
    "atanh": np.arctanh, "abs": np.abs, "log1p": np.log1p, "expm1": np.expm1,
    "logistic": lambda a: 1.0 / (1.0 + np.exp(-a)), "cbrt": np.cbrt, "sign": np.sign,
    "floor": np.floor, "ceil": np.ceil, "round": np.round,
    "not": lambda a: (a == 0).astype(np.float64),
    "erf": np.vectorize(math.erf, otypes=[np.float64]),
}

#: ``d op(a) / da`` from the operand ``a`` and the value ``v = op(a)``
_UNARY_SLOPE = {
    "sin": lambda a, v: np.cos(a), "cos": lambda a, v: -np.sin(a),
    "tan": lambda a, v: 1.0 + v * v, "exp": lambda a, v: v, "log": lambda a, v: 1.0 / a,
    "sqrt": lambda a, v: 0.5 / v, "tanh": lambda a, v: 1.0 - v * v,
    "atan": lambda a, v: 1.0 / (1.0 + a * a), "asin": lambda a, v: 1.0 / np.sqrt(1.0 - a * a),
    "acos": lambda a, v: -1.0 / np.sqrt(1.0 - a * a), "sinh": lambda a, v: np.cosh(a),
    "cosh": lambda a, v: np.sinh(a), "asinh": lambda a, v: 1.0 / np.sqrt(a * a + 1.0),
    "acosh": lambda a, v: 1.0 / np.sqrt(a * a - 1.0), "atanh": lambda a, v: 1.0 / (1.0 - a * a),
    "abs": lambda a, v: np.sign(a), "log1p": lambda a, v: 1.0 / (1.0 + a),
    "expm1": lambda a, v: v + 1.0, "logistic": lambda a, v: v * (1.0 - v),
    "cbrt": lambda a, v: (1.0 / 3.0) / (v * v),
    "erf": lambda a, v: (2.0 / math.sqrt(math.pi)) * np.exp(-a * a),
}

_COMPARE = {"lt": np.less, "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal,
            "eq": np.equal, "ne": np.not_equal, "and": np.logical_and, "or": np.logical_or}

_FLAT = frozenset({"sign", "floor", "ceil", "round", "not"})


def schedule(graph, roots):
    """``(order, frees, peak)``: the nodes behind ``roots`` ascending, per position the
    nodes whose last use it is (freed after it), and the most nodes alive at once."""
    order = graph.reachable(roots)
    last_use = {}
    args = graph.args
    for p, k in enumerate(order):
        for a in args[k]:
            last_use[a] = p
    keep = set(roots)
    frees = [[] for _ in order]
    for a, p in last_use.items():
        if a not in keep:
            frees[p].append(a)
    peak = live = 0
    for p in range(len(order)):
        live += 1
        peak = max(peak, live)
        live -= len(frees[p])
    return order, frees, peak


def columns(graph, order):
    """Per node, the coordinates it depends on (a sorted tuple), and per (node, operand) the
    rows of the operand's gradient inside the node's (an index array, None when equal).

    A node's gradient is zero outside its coordinates: with sparse gradients each node
    carries ``(len(cols), S)`` instead of ``(n, S)`` (on the EORC's extended states the
    average node depends on a quarter of them). Both are kept in ``graph.facts`` (a node
    never changes), so each node is worked out once over every evaluation.
    """
    ops, args, params = graph.op, graph.args, graph.param
    cols = graph.facts.setdefault("columns", {})
    where = graph.facts.setdefault("operand_rows", {})
    for k in order:
        if k in cols:
            continue
        if ops[k] == "x":
            cols[k] = (params[k],)
            continue
        if not args[k]:
            cols[k] = ()
            continue
        united = set()
        for a in args[k]:
            united.update(cols[a])
        c = tuple(sorted(united))
        cols[k] = c
        pos = None
        for a in args[k]:
            ca = cols[a]
            if ca == c or not ca:
                where[k, a] = None
                continue
            if pos is None:
                pos = {v: i for i, v in enumerate(c)}
            where[k, a] = np.fromiter((pos[v] for v in ca), dtype=np.intp, count=len(ca))
    return cols, where


#: Sparse gradients (:func:`columns`) from this many gradient entries per node (``n S``):
#: below it, dense ``(n, S)`` arrays cost less than the bookkeeping.
SPARSE_FROM = 32768


def _add(a, b):
    if a is None:
        return b
    if b is None:
        return a
    return a + b


def evaluate(graph, roots, xs, gradients: bool = True):
    """Values (and gradients) of graph nodes at many states.

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph`.
        roots: node numbers (R of them).
        xs: states, ``(S, n)`` float64.
        gradients: also return the gradients.

    Returns:
        ``values (S, R)``, and with ``gradients`` ``grads (S, R, n)``: NaN/inf where a node
        is undefined (no warning is raised).
    """
    roots = list(roots)
    xs = np.asarray(xs, dtype=np.float64)
    S, n = xs.shape
    order, frees, peak = schedule(graph, roots)
    per_sample = 8 * (1 + (n if gradients else 0)) * max(peak, 1)
    chunk = max(64, min(S, CHUNK_BYTES // per_sample)) if S else 1
    sparse = gradients and n * min(S, chunk) >= SPARSE_FROM
    cols, where = columns(graph, order) if sparse else (None, None)
    values = np.empty((S, len(roots)))
    grads = np.zeros((S, len(roots), n)) if gradients else None
    for start in range(0, S, chunk):
        part = xs[start:start + chunk]
        v, g = _walk(graph, order, frees, part, gradients, cols, where)
        for r, root in enumerate(roots):
            values[start:start + chunk, r] = v[root]
            gr = g.get(root) if gradients else None
            if gr is not None:
                if sparse:
                    grads[start:start + chunk, r][:, list(cols[root])] = gr.T
                else:
                    grads[start:start + chunk, r] = gr.T
    return (values, grads) if gradients else values


def _walk(graph, order, frees, xs, gradients, cols=None, where=None):
    """Values ``{node: (S,)}`` and gradients ``{node: (rows, S) or None}`` of the nodes of
    ``order``; ``cols``/``where`` (:func:`columns`): sparse gradients, rows = the node's
    coordinates; None: dense, rows = every coordinate."""
    S, n = xs.shape
    ops, args, params = graph.op, graph.args, graph.param
    V, G = {}, {}
    sparse = cols is not None

    def term(k, a, factor=None):
        """The operand's gradient (times ``factor``) in the node's rows."""
        g = G[a]
        if g is None:
            return None
        if factor is not None:
            g = g * factor
        if not sparse:
            return g
        idx = where.get((k, a))
        if idx is None:
            return g
        out = np.zeros((len(cols[k]), S))
        out[idx] = g
        return out

    with np.errstate(all="ignore"):
        for p, k in enumerate(order):
            op, a = ops[k], args[k]
            g = None
            if op == "x":
                i = params[k]
                v = xs[:, i]
                if gradients:
                    if sparse:
                        g = np.ones((1, S))
                    else:
                        g = np.zeros((n, S))
                        g[i] = 1.0
            elif op == "c":
                v = np.full(S, graph.value_of(k))
            elif op == "add":
                v = V[a[0]] + V[a[1]]
                if gradients:
                    g = _add(term(k, a[0]), term(k, a[1]))
            elif op == "mul":
                va, vb = V[a[0]], V[a[1]]
                v = va * vb
                if gradients:
                    g = _add(term(k, a[0], vb), term(k, a[1], va))
            elif op == "neg":
                v = -V[a[0]]
                if gradients and G[a[0]] is not None:
                    g = -G[a[0]]
            elif op == "div":
                va, vb = V[a[0]], V[a[1]]
                v = va / vb
                if gradients:
                    inv = 1.0 / vb
                    g = _add(term(k, a[0], inv), term(k, a[1], -v * inv))
            elif op == "ipow":
                kk = params[k]
                va = V[a[0]]
                v = va ** kk
                if gradients and G[a[0]] is not None:
                    g = G[a[0]] * (kk * va ** (kk - 1))
            elif op == "select":
                pred = V[a[0]] != 0
                v = np.where(pred, V[a[2]], V[a[1]])
                if gradients:
                    gf, gt = term(k, a[1]), term(k, a[2])
                    if gf is not None or gt is not None:
                        g = np.where(pred, 0.0 if gt is None else gt, 0.0 if gf is None else gf)
            elif op in _COMPARE:
                v = _COMPARE[op](V[a[0]], V[a[1]]).astype(np.float64)
            elif op == "pow":
                va, vb = V[a[0]], V[a[1]]
                v = va ** vb
                if gradients:
                    g = _add(term(k, a[0], v * vb / va), term(k, a[1], v * np.log(va)))
            elif op == "atan2":
                va, vb = V[a[0]], V[a[1]]
                v = np.arctan2(va, vb)
                if gradients:
                    den = va * va + vb * vb
                    g = _add(term(k, a[0], vb / den), term(k, a[1], -va / den))
            else:  # unary elementary function
                va = V[a[0]]
                v = _UNARY_VALUE[op](va)
                if gradients and op not in _FLAT and G[a[0]] is not None:
                    g = G[a[0]] * _UNARY_SLOPE[op](va, v)
            V[k] = v
            if gradients:
                G[k] = g
            for dead in frees[p]:
                del V[dead]
                if gradients:
                    del G[dead]
    return V, G


__all__ = ["evaluate", "schedule", "columns", "CHUNK_BYTES", "SPARSE_FROM"]
