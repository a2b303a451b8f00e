"""The instructions of the Taylor engine (:mod:`.taylor`): the graph nodes behind some roots,
rewritten into operations that have a recurrence on Taylor coefficients.

An instruction is ``(op, operands, param)`` on earlier instructions:

* ``x`` (coordinate ``param``), ``c`` (exact constant ``param``), ``add``, ``neg``, ``mul``,
  ``div``: the rational operations (integer powers become products);
* ``sin``/``cos``: the circle point of operand ``u`` (the sine's ``param`` is ``(cosine
  instruction, graph node of u)``, the cosine's the sine instruction); ``tan``, ...: their
  quotient;
* ``exp`` (``param``: the graph node of ``u``): ``sinh``, ``tanh``, ``logistic``, ... are
  rational functions of it;
* ``root``: ``w = u^alpha`` of operand ``u`` for a rational constant ``alpha``
  (``param``; ``sqrt`` is ``alpha = 1/2``): ``w_0`` a ``b``-th root of ``u_0^a``
  (``alpha = a/b``), then ``k u_0 w_k = sum_{j=1..k} ((alpha + 1) j - k) u_j w_{k-j}`` (from
  ``u w' = alpha u' w``); a power ``u^v`` with a non-constant exponent is ``exp(v log u)``
  (a logarithmic and an exponential kind);
* ``free``: a logarithmic kind (``log``, ``atan``, ``atan2``, ``asin``, ...): a random value
  at ``t = 0`` modulo p (the real one in float64 and mpmath), then ``a_k = R_{k-1} / k`` with
  ``R = a'`` the derivative rule ``sum_i c_i(u) u_i'`` (``c_i`` ordinary instructions, the
  product with the derivative series ``u_i'`` *lagged*). ``param = (key, pairs, kind,
  value operands)``: ``pairs`` the ``(c_i, u_i)`` whose order-0 values give the gradient of
  ``a_0``.
* ``deriv``: the derivative series ``D_m = (m + 1) u_{m+1}`` of operand ``u``.

A *lagged* instruction (``lagged``) is evaluated one order behind the others: at the pass of
order ``k`` it computes its coefficient ``k - 1`` (which needs ``u_k``).
"""

from fractions import Fraction

from . import graph_elementary


class Unsupported(ValueError):
    """A node the Taylor route does not evaluate (the symbolic route serves the model)."""


class _Emitter:
    def __init__(self):
        self.ins, self.lagged, self.consts = [], set(), {}

    def emit(self, op, operands=(), param=None, lag=False):
        self.ins.append((op, tuple(operands), param))
        if lag:
            self.lagged.add(len(self.ins) - 1)
        return len(self.ins) - 1

    def const(self, value):
        value = Fraction(value)
        if value not in self.consts:
            self.consts[value] = self.emit("c", (), value)
        return self.consts[value]

    def power(self, a, m):
        """``a^m`` for an integer ``m`` (products; a quotient for ``m < 0``)."""
        if m == 0:
            return self.const(1)
        out, base, e = None, a, abs(m)
        while e:
            if e & 1:
                out = base if out is None else self.emit("mul", (out, base))
            e >>= 1
            if e:
                base = self.emit("mul", (base, base))
        return out if m > 0 else self.emit("div", (self.const(1), out))

    def recip(self, a):
        return self.emit("div", (self.const(1), a))


def program(graph, roots):
    """``(instructions, slot, lagged)`` evaluating the graph nodes behind ``roots``:
    ``slot[node]`` the instruction of each node, ``lagged`` the lagged instructions.

    Raises:
        Unsupported: a node outside the kinds above (the symbolic route serves such a model).
    """
    em, slot, generators = _Emitter(), {}, {}
    for k in graph.reachable(roots):
        op, a = graph.op[k], [slot.get(b) for b in graph.args[k]]
        if op == "x":
            slot[k] = em.emit("x", (), graph.param[k])
        elif op == "c":
            value = graph.exact_value(k)
            if value is None:
                raise Unsupported("a constant known in float64 only")
            slot[k] = em.const(value)
        elif op in ("add", "mul", "div", "neg"):
            slot[k] = em.emit(op, a)
        elif op == "ipow":
            slot[k] = em.power(a[0], graph.param[k])
        elif op in graph_elementary.CIRCLE:
            if ("circle", a[0]) not in generators:
                s = em.emit("sin", (a[0],), None)
                c = em.emit("cos", (a[0],), s)
                em.ins[s] = ("sin", (a[0],), (c, graph.args[k][0]))
                generators["circle", a[0]] = (s, c)
            s, c = generators["circle", a[0]]
            slot[k] = s if op == "sin" else c if op == "cos" else em.emit("div", (s, c))
        elif op in graph_elementary.EXPONENTIAL:
            if ("exp", a[0]) not in generators:
                generators["exp", a[0]] = em.emit("exp", (a[0],), graph.args[k][0])
            slot[k] = _exponential_kind(op, generators["exp", a[0]], em)
        elif op == "sqrt":
            slot[k] = _root(em, a[0], generators, ("root", graph.args[k][0]))
        elif op == "pow":
            slot[k] = _power(graph, k, a, em, generators)
        elif op in graph_elementary.LOGARITHMIC:
            slot[k] = _logarithmic(em, op, a, (op, tuple(graph.args[k])), generators)
        else:
            raise Unsupported(f"{op} has no Taylor rule here")
    return em.ins, slot, em.lagged


def _root(em, u, generators, key, alpha=Fraction(1, 2)):
    """``u^alpha``; ``key`` names its branch (the same root in every program of one graph)."""
    if ("root", u, alpha) not in generators:
        generators["root", u, alpha] = em.emit("root", (u,), (alpha, key + (alpha,)))
    return generators["root", u, alpha]


def _power(graph, k, a, em, generators):
    """``u^e``: a constant rational ``e`` as a root instruction, any other exponent ``v`` as
    ``exp(v log u)``."""
    e = graph_elementary.rational_exponent(graph, k)
    if e is not None:
        if e.denominator == 1:
            return em.power(a[0], e.numerator)
        return _root(em, a[0], generators, ("root", graph.args[k][0]), e)
    u, v = graph.args[k]
    log = _logarithmic(em, "log", [a[0]], ("log", (u,)), generators)
    arg = em.emit("mul", (a[1], log))
    if ("exp", ("pow", k)) not in generators:
        generators["exp", ("pow", k)] = em.emit("exp", (arg,), ("pow", k))
    return generators["exp", ("pow", k)]


def _exponential_kind(op, E, em):
    """``op(u)`` as a rational function of ``E = exp u`` (instructions emitted)."""
    if op == "exp":
        return E
    if op == "expm1":
        return em.emit("add", (E, em.const(-1)))
    if op == "logistic":
        return em.emit("div", (E, em.emit("add", (E, em.const(1)))))
    E2 = em.emit("mul", (E, E))
    if op == "tanh":
        return em.emit("div", (em.emit("add", (E2, em.const(-1))), em.emit("add", (E2, em.const(1)))))
    sign = 1 if op == "cosh" else -1  # (E^2 +- 1) / (2 E)
    return em.emit("div", (em.emit("add", (E2, em.const(sign))), em.emit("mul", (em.const(2), E))))


def _slopes(em, op, a, key, generators):
    """The derivative rule of a logarithmic kind: ``[(c_i, u_i)]`` with ``d op = sum c_i du_i``."""
    u = a[0]
    u2 = em.emit("mul", (u, u))
    if op == "log":
        return [(em.recip(u), u)]
    if op == "log1p":
        return [(em.recip(em.emit("add", (u, em.const(1)))), u)]
    if op == "atan":
        return [(em.recip(em.emit("add", (u2, em.const(1)))), u)]
    if op == "atanh":
        return [(em.recip(em.emit("add", (em.const(1), em.emit("neg", (u2,))))), u)]
    if op in ("asin", "acos"):
        w = em.recip(_root(em, em.emit("add", (em.const(1), em.emit("neg", (u2,)))), generators, ("root", key)))
        return [(w if op == "asin" else em.emit("neg", (w,)), u)]
    if op in ("asinh", "acosh"):
        w = em.recip(_root(em, em.emit("add", (u2, em.const(1 if op == "asinh" else -1))), generators,
                           ("root", key)))
        return [(w, u)]
    v = a[1]  # atan2(u, v): (v du - u dv) / (u^2 + v^2)
    d = em.recip(em.emit("add", (u2, em.emit("mul", (v, v)))))
    return [(em.emit("mul", (v, d)), u), (em.emit("neg", (em.emit("mul", (u, d)),)), v)]


def _logarithmic(em, op, a, key, generators):
    """A logarithmic kind: its slopes, the lagged derivative ``R = sum c_i u_i'``, the value."""
    pairs = _slopes(em, op, a, key, generators)
    R = None
    for c, u in pairs:
        term = em.emit("mul", (c, em.emit("deriv", (u,), lag=True)), lag=True)
        R = term if R is None else em.emit("add", (R, term), lag=True)
    return em.emit("free", (R,), (key, tuple(pairs), op, tuple(a)))


__all__ = ["Unsupported", "program"]
