"""The expression graph (:mod:`.graph`) evaluated in float64 over many states, with numpy.

No program is compiled: the nodes behind the requested roots are visited once in
ascending order (a topological order) and each is one or two vectorised numpy operations
over the samples. Gradients are forward-mode: every node carries its value ``(S,)`` and
its gradient ``(n, S)`` (``None`` for a node that depends on no coordinate), combined by the
chain rule of its operation. A node's arrays are freed after its last use in the walk,
and the samples are taken in chunks sized so that the live arrays stay within
:data:`CHUNK_BYTES`.

Successive walks at the same states (the orders of a recursion, each differentiating the
last one's nodes) share a :class:`WalkMemo`: a walk starts at the nodes an earlier one
kept, so each layer of a growing graph is evaluated about once.

Cost: about one numpy call on ``(S,)`` and one on ``(n, S)`` per node; for the seed models
(graphs of 10^2-10^4 nodes) milliseconds to a fraction of a second at 4096 samples,
against seconds of XLA compilation for the same program
(``docs/benchmarks/engine.md``).
"""

import math

import numpy as np

from .graph_ops import unary_slopes

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

#: ``d op(a) / da`` from the operand ``a`` and the value ``v = op(a)`` (float64)
_UNARY_SLOPE = unary_slopes(np)

_COMPARE = {"lt": np.less, "le": np.less_equal, "gt": np.greater, "ge": np.greater_equal,
            "eq": np.equal, "ne": np.not_equal, "and": np.logical_and, "or": np.logical_or}

_FLAT = frozenset({"sign", "floor", "ceil", "round", "not"})


def schedule(graph, roots):
    """``(order, frees, peak)``: the nodes behind ``roots`` ascending, per position the
    nodes whose last use it is (freed after it), and the most nodes alive at once."""
    order = graph.reachable(roots)
    return (order, *_lifetimes(graph, order, roots))


def _lifetimes(graph, order, keep):
    """``(frees, peak)`` of a walk over ``order``: per position the nodes whose last use it
    is (never the ``keep`` nodes), and the most nodes alive at once."""
    last_use = {}
    args = graph.args
    for p, k in enumerate(order):
        for a in args[k]:
            last_use[a] = p
    keep = set(keep)
    frees = [[] for _ in order]
    for a, p in last_use.items():
        if a not in keep:
            frees[p].append(a)
    peak = live = 0
    for p in range(len(order)):
        live += 1
        peak = max(peak, live)
        live -= len(frees[p])
    return frees, peak


#: Operations whose derivative reads no operand value (linear, or of zero derivative).
_READS_NO_OPERAND = frozenset({"add", "neg", *_COMPARE, *_FLAT})

#: Bytes a :class:`WalkMemo` may hold.
MEMO_BYTES = 128 * 2**20


def _nbytes(value, grad) -> int:
    return value.nbytes + (0 if grad is None else grad.nbytes)


class WalkMemo:
    """Values and gradients of graph nodes at one set of states, kept from one walk to the next.

    A recursion that differentiates its last nodes again (the ORC and EORC orders: order
    ``k + 1`` holds ``L_v phi`` for the generators ``phi`` of order ``k``) walks a graph
    that grows by a layer per order; walked from the bottom every time, order ``k`` costs
    the whole graph so far (``O(k^2)`` node visits in all where the layers are the same
    size). A derivative node reads the values of the operands of the nonlinear operations
    of what it differentiates (``d(a b) = da b + a db``, ``d sin a = cos a da``;
    ``d(a + b) = da + db`` reads none), so after each walk the memo keeps, with their
    gradients:

    * the roots and the operands of the walk's nonlinear nodes (what the next layer may
      read);
    * of the nodes kept before, those some walk has read (a later layer reads them again:
      a Taylor-like recursion reads every lower order).

    The next walk stops at memo nodes (:meth:`Graph.reachable` with ``known``), so each
    layer is evaluated about once. Held at most :data:`MEMO_BYTES`: past it the memo
    keeps what was read and the roots, else nothing (a walk then starts lower, with the
    same result). For one set of states at a time (others empty it), walked in one chunk
    (:func:`evaluate`).
    """

    def __init__(self, budget: int = MEMO_BYTES):
        self.budget = budget
        self.values: dict = {}  # node -> (S,)
        self.grads: dict = {}  # node -> (rows, S) or None
        self.read: set = set()  # memo nodes some walk has read
        self.states = None  # (S, n) the states of the arrays held
        self.sparse = None  # whether their gradients are sparse rows
        self.nbytes = 0

    def usable(self, xs, sparse) -> dict:
        """The nodes held for the states ``xs`` ``(S, n)`` and gradients laid out
        sparse or dense; other states or another layout empty the memo."""
        same = (self.states is not None and self.states.shape == xs.shape and self.sparse == sparse
                and np.array_equal(self.states, xs))
        if not same:
            self.values, self.grads, self.read, self.nbytes = {}, {}, set(), 0
            self.states, self.sparse = xs.copy(), sparse
        return self.values

    @staticmethod
    def to_keep(graph, order) -> set:
        """The operands of the nonlinear nodes of ``order``, which later derivatives read."""
        ops, args = graph.op, graph.args
        return {a for k in order if ops[k] not in _READS_NO_OPERAND for a in args[k]}

    def update(self, read, kept, V, G, roots):
        """After a walk: the memo nodes in ``read`` were read; the ``kept`` nodes of the
        walk and its ``roots`` are alive in its values ``V`` and gradients ``G``."""
        self.read |= read
        held = {k: (self.values[k], self.grads[k]) for k in self.values if k in self.read}
        nbytes = sum(_nbytes(*vg) for vg in held.values())
        new = [k for k in dict.fromkeys((*roots, *kept)) if k in V and k not in held]
        roots = set(roots)
        for subset in (new, [k for k in new if k in roots], []):  # what fits in the budget
            extra = sum(_nbytes(V[k], G.get(k)) for k in subset)
            if nbytes + extra <= self.budget:
                break
        else:  # what was read alone is past it
            held, nbytes, extra, subset = {}, 0, 0, []
        held.update((k, (V[k], G.get(k))) for k in subset)
        self.values = {k: vg[0] for k, vg in held.items()}
        self.grads = {k: vg[1] for k, vg in held.items()}
        self.nbytes = nbytes + extra


def columns(graph, order):
    """Per node, the coordinates it depends on (a sorted tuple), and per (node, operand) the
    rows of the operand's gradient inside the node's (an index array, None when equal).

    A node's gradient is zero outside its coordinates: with sparse gradients each node
    carries ``(len(cols), S)`` instead of ``(n, S)`` (on the EORC's extended states the
    average node depends on a quarter of them). An operand's rows are a ``slice`` where
    they are a run of the node's rows (most are: the extended coordinates enter in order),
    else an index array. Both are kept in ``graph.facts`` (a node never changes), so each
    node is worked out once over every evaluation.
    """
    ops, args, params = graph.op, graph.args, graph.param
    cols = graph.facts.setdefault("columns", {})
    where = graph.facts.setdefault("operand_rows", {})
    arrays = graph.facts.setdefault("column_arrays", {})  # node -> cols as an index array
    for k in order:
        if k in cols:
            continue
        if ops[k] == "x":
            cols[k] = (params[k],)
            continue
        if not args[k]:
            cols[k] = ()
            continue
        c = cols[k] = tuple(sorted(set().union(*(cols[a] for a in args[k]))))
        at = None
        for a in args[k]:
            ca = cols[a]
            if ca == c or not ca:
                where[k, a] = None
                continue
            if at is None:
                at = arrays[k] = np.array(c, dtype=np.intp)
            own = arrays.get(a)
            if own is None:
                own = arrays[a] = np.array(ca, dtype=np.intp)
            rows = at.searchsorted(own)  # the operand's rows inside the node's
            lo, hi = int(rows[0]), int(rows[-1]) + 1
            # a run of rows as a slice (a view, no copy: most operands hold one)
            where[k, a] = slice(lo, hi) if hi - lo == len(rows) else rows
    return cols, where


#: Sparse gradients (:func:`columns`) from this many gradient entries per node (``n S``),
#: or from :data:`SPARSE_COORDS` coordinates whatever ``S``: below both, dense ``(n, S)``
#: arrays cost less than the bookkeeping (``docs/benchmarks/engine.md``).
SPARSE_FROM = 32768
SPARSE_COORDS = 64


def place_rows(g, factor, idx, rows: int, dtype=np.float64):
    """An operand's gradient ``(r, W)`` times ``factor`` (None: 1) in a node's ``rows``
    rows: at ``idx`` (a slice or index array from :func:`columns`; None: the same rows);
    None (a zero gradient) stays None. Shared by the float64 walk and the modular one."""
    if g is None:
        return None
    if factor is not None:
        g = g * factor
    if idx is None:
        return g
    out = np.zeros((rows, g.shape[1]), dtype=dtype)
    out[idx] = g
    return out


def _sparse(n: int, S: int) -> bool:
    return n * S >= SPARSE_FROM or n >= SPARSE_COORDS


def evaluate(graph, roots, xs, gradients: bool = True, memo: WalkMemo | None = None):
    """Values (and gradients) of graph nodes at many states.

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph`.
        roots: node numbers (R of them).
        xs: states, ``(S, n)`` float64.
        gradients: also return the gradients.
        memo: a :class:`WalkMemo` for these states (successive calls at the same ``xs``):
            the walk starts at the nodes it holds, and it keeps what the next call may
            read. Used with ``gradients`` when the samples fit in one chunk.

    Returns:
        ``values (S, R)``, and with ``gradients`` ``grads (S, R, n)``: NaN/inf where a node
        is undefined (no warning is raised).
    """
    roots = list(roots)
    xs = np.asarray(xs, dtype=np.float64)
    S, n = xs.shape
    per_node = 8 * (1 + (n if gradients else 0))
    given = None
    if memo is not None and gradients and S:
        sparse = _sparse(n, S)
        held = memo.usable(xs, sparse)
        order = graph.reachable(roots, held)
        keep = WalkMemo.to_keep(graph, order) | set(roots)
        frees, peak = _lifetimes(graph, order, keep)
        if S <= CHUNK_BYTES // (per_node * max(peak, 1)):
            inside = set(order)
            read = {a for k in order for a in graph.args[k] if a not in inside}
            read.update(r for r in roots if r not in inside)
            given = ({k: held[k] for k in read}, {k: memo.grads[k] for k in read})
    if given is None:
        order, frees, peak = schedule(graph, roots)
    chunk = max(64, min(S, CHUNK_BYTES // (per_node * max(peak, 1)))) if S else 1
    sparse = gradients and _sparse(n, min(S, chunk))
    cols, where = columns(graph, order) if sparse else (None, None)
    values = np.empty((S, len(roots)))
    grads = np.zeros((S, len(roots), n)) if gradients else None
    for start in range(0, S, chunk):
        part = xs[start:start + chunk]
        v, g = _walk(graph, order, frees, part, gradients, cols, where, given)
        if given is not None:
            memo.update(set(given[0]), keep, v, g, roots)
        for r, root in enumerate(roots):
            values[start:start + chunk, r] = v[root]
            gr = g.get(root) if gradients else None
            if gr is not None:
                if sparse:
                    grads[start:start + chunk, r][:, list(cols[root])] = gr.T
                else:
                    grads[start:start + chunk, r] = gr.T
    return (values, grads) if gradients else values


class _Rows:
    """How a node's gradient is assembled from its operands' gradients ``G`` (node ->
    ``(rows, S)`` or None): dense (rows = every coordinate) or, with ``cols``/``where``
    (:func:`columns`), sparse (rows = the node's coordinates)."""

    def __init__(self, G, cols, where, S, n):
        self.G, self.cols, self.where, self.S, self.n = G, cols, where, S, n
        self.sparse = cols is not None

    def unit(self, i):
        """The gradient of coordinate ``x_i``."""
        if self.sparse:
            return np.ones((1, self.S))
        g = np.zeros((self.n, self.S))
        g[i] = 1.0
        return g

    def term(self, k, a, factor=None):
        """The operand's gradient (times ``factor``) in the node's rows."""
        if not self.sparse:
            return place_rows(self.G[a], factor, None, self.n)
        return place_rows(self.G[a], factor, self.where.get((k, a)), len(self.cols[k]))

    def combine(self, k, a0, f0, a1, f1):
        """``f0 d a0 + f1 d a1`` in the node's rows (a factor None is 1), accumulated in
        one new array: the operand covering every row of the node (if one does) is its
        start, the other is added into its rows in place."""
        G, where = self.G, self.where
        if G[a0] is None:
            return self.term(k, a1, f1)
        if G[a1] is None:
            return self.term(k, a0, f0)
        i0, i1 = (where.get((k, a0)), where.get((k, a1))) if self.sparse else (None, None)
        if i0 is not None and i1 is None:
            a0, f0, i0, a1, f1, i1 = a1, f1, i1, a0, f0, i0
        g0, g1 = G[a0], G[a1]
        if i0 is None and i1 is None and f0 is None and f1 is None:
            return g0 + g1
        if i0 is None and f0 is None and f1 is None and isinstance(i1, slice):
            out = np.empty_like(g0)  # each row written once: the sum where a1 has rows
            np.add(g0[i1], g1, out=out[i1])
            out[:i1.start], out[i1.stop:] = g0[:i1.start], g0[i1.stop:]
            return out
        if i0 is None:
            out = g0 * f0 if f0 is not None else g0.copy()
        else:
            out = np.zeros((len(self.cols[k]), self.S))
            out[i0] = g0 if f0 is None else g0 * f0
        if i1 is None:
            out += g1 if f1 is None else g1 * f1
        else:
            out[i1] += g1 if f1 is None else g1 * f1
        return out

    def select(self, k, a, pred):
        """The gradient of ``select(pred, a[1], a[2])`` (None when neither branch has one)."""
        gf, gt = self.term(k, a[1]), self.term(k, a[2])
        if gf is None and gt is None:
            return None
        return np.where(pred, 0.0 if gt is None else gt, 0.0 if gf is None else gf)


def _walk(graph, order, frees, xs, gradients, cols=None, where=None, given=None):
    """Values ``{node: (S,)}`` and gradients ``{node: (rows, S) or None}`` of the nodes of
    ``order``; ``cols``/``where`` (:func:`columns`): sparse gradients, rows = the node's
    coordinates; None: dense, rows = every coordinate (:class:`_Rows`). ``given``:
    ``(values, gradients)`` of nodes outside ``order`` that it reads (from a :class:`WalkMemo`)."""
    S, n = xs.shape
    ops, args, params = graph.op, graph.args, graph.param
    V, G = (dict(given[0]), dict(given[1])) if given is not None else ({}, {})
    rows = _Rows(G, cols, where, S, n)
    combine = rows.combine
    with np.errstate(all="ignore"):
        for p, k in enumerate(order):
            op, a = ops[k], args[k]
            g = None
            if op == "x":
                v = xs[:, params[k]]
                if gradients:
                    g = rows.unit(params[k])
            elif op == "c":
                v = np.full(S, graph.value_of(k))
            elif op == "add":
                v = V[a[0]] + V[a[1]]
                if gradients:
                    g = combine(k, a[0], None, a[1], None)
            elif op == "mul":
                va, vb = V[a[0]], V[a[1]]
                v = va * vb
                if gradients:
                    g = combine(k, a[0], vb, a[1], va)
            elif op == "neg":
                v = -V[a[0]]
                if gradients and G[a[0]] is not None:
                    g = -G[a[0]]
            elif op == "div":
                va, vb = V[a[0]], V[a[1]]
                v = va / vb
                if gradients:
                    inv = 1.0 / vb
                    g = combine(k, a[0], inv, a[1], -v * inv)
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
                    g = rows.select(k, a, pred)
            elif op in _COMPARE:
                v = _COMPARE[op](V[a[0]], V[a[1]]).astype(np.float64)
            elif op == "pow":
                va, vb = V[a[0]], V[a[1]]
                v = va ** vb
                if gradients:
                    g = combine(k, a[0], v * vb / va, a[1], v * np.log(va))
            elif op == "atan2":
                va, vb = V[a[0]], V[a[1]]
                v = np.arctan2(va, vb)
                if gradients:
                    den = va * va + vb * vb
                    g = combine(k, a[0], vb / den, a[1], -va / den)
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


__all__ = ["evaluate", "schedule", "columns", "place_rows", "WalkMemo", "CHUNK_BYTES", "MEMO_BYTES", "SPARSE_FROM",
           "SPARSE_COORDS"]
