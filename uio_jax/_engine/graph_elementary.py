"""The elementary functions made rational: exact evaluation modulo p of graphs with
``sin``, ``exp``, ``log``, ``sqrt``, ``atan``, ...

A Lie derivative of a model with ``sin(u)`` is not a rational function of the state, but it
is a rational function of the state and of finitely many new *generators*: every Lie
derivative, bracket and rescaled field of the graph is built by the chain rule from the
derivative rules ``d sin u = cos u du``, ``d exp u = exp u du``, ``d log u = du / u``, ...
(:meth:`uio_jax._engine.graph.Graph.jvp`). So the graph is evaluated modulo ``p`` at random
points of the *variety* of the generators, not of the states alone:

* **circle** (``sin u``, ``cos u``, ``tan u``): one point ``(s, c)`` of ``s^2 + c^2 = 1`` per
  argument node ``u``, drawn by the rational parametrisation ``s = 2t/(1+t^2)``,
  ``c = (1-t^2)/(1+t^2)`` at a random ``t``; ``tan u = s / c``.
* **exponential** (``exp``, ``expm1``, ``sinh``, ``cosh``, ``tanh``, ``logistic`` of ``u``):
  one random nonzero ``E = exp u`` per argument node; ``sinh u = (E - 1/E)/2``, ``tanh u =
  (E^2 - 1)/(E^2 + 1)``, ``logistic u = E/(1 + E)``.
* **logarithmic** (``log``, ``log1p``, ``atan``, ``atan2``, ``atanh``, ``asin``, ``acos``,
  ``asinh``, ``acosh``): a random value per node, with its derivative rule (``du/u``,
  ``du/(1+u^2)``, ``du/sqrt(1-u^2)``, ...).
* **algebraic** (``sqrt u``, ``u ** (m/b)`` for an exact rational exponent): the ``b``-th root
  of the value of ``u`` at the point (square roots ``r = u^((p+1)/4)``, ``p = 3 mod 4``; roots
  of an odd order prime to ``p - 1`` unique), to the power ``m``; a point where some ``u``
  has no such root modulo ``p`` is drawn again (:class:`NotSquare`, half of the points per
  square root). A power ``u ** v`` with a non-constant exponent is ``exp(v log u)`` in the
  graph (an exponential and a logarithmic kind).

**Why the rank is the real one.** The gradients are rational functions ``M(x, theta)`` of
the states and the generators, equal to the real gradients on ``theta = theta(x)``. Their
generic rank on the variety equals the generic rank of the real model when the transcendental
generators are algebraically independent over the rational functions of ``x`` (then no
nonzero minor vanishes on ``theta = theta(x)``); if they were dependent, the variety's rank
could exceed the real one. By the Risch-Rosenlicht structure theorem (exponentials and
logarithms over a differential field; ``sin``, ``atan``, ``asin`` are complex exponentials and
logarithms, so the circle and ``atan`` kinds form the imaginary family, ``exp`` and ``log`` the
real one) they are independent when, in each family, the *logarithmic differentials*
``omega`` (``du`` for ``exp u`` and ``sin u``; ``du/u`` for ``log u``; ``du/(1+u^2)`` for
``atan u``; ...) are linearly independent over the constants. :func:`check_independence` tests
that exactly at random points (a relation with constant coefficients holds at every point, so
it is always found); a model where it fails (``sin x`` with ``sin 2x``, ``exp u`` with
``exp(-u)``, ``atan2(a, b)`` with ``atan(a/b)``) is not made rational, and its decisions stay in
extended precision, labelled so.

Not made rational: ``erf``, ``cbrt``, ``abs``, ``sign``, rounding, comparisons and ``select``,
and constants known in float64 only (a power of a base known in float64 only among them).
"""

import math

import numpy as np

#: argument node -> one point of the circle (sin, cos, tan of that node)
CIRCLE = frozenset({"sin", "cos", "tan"})
#: argument node -> one random exp(u)
EXPONENTIAL = frozenset({"exp", "expm1", "sinh", "cosh", "tanh", "logistic"})
#: one random value per node
LOGARITHMIC = frozenset({"log", "log1p", "atan", "atan2", "atanh", "asin", "acos", "asinh", "acosh"})
#: square roots of the argument's value
ALGEBRAIC = frozenset({"sqrt", "pow"})
ELEMENTARY = CIRCLE | EXPONENTIAL | LOGARITHMIC | ALGEBRAIC

#: the imaginary family (complex exponentials and logarithms); the others are real
IMAGINARY = frozenset({"sin", "cos", "tan", "atan", "atan2", "asin", "acos"})


class Singular(ArithmeticError):
    """A denominator vanished at the point (modulo the prime): draw another point."""


class NotSquare(Singular):
    """The argument of a square root has no square root modulo p at the point."""


def rational_exponent(graph, k):
    """For a ``pow`` node with an exact constant exponent: the exponent (a Fraction); else
    None (``pow`` with an integer exponent is ``ipow``; a non-constant exponent is
    ``exp(v log u)`` in the graph, :meth:`uio_jax._engine.graph.Graph.binary`)."""
    b = graph.args[k][1]
    return graph.exact_value(b) if graph.op[b] == "c" else None


def root_mod_p(a, b: int, p: int):
    """``b``-th roots of residues ``a (P,)`` modulo ``p = 3 mod 4``: the unique root of the odd
    part of ``b`` where it is prime to ``p - 1``, then principal square roots.

    Raises:
        NotSquare: a square root that does not exist at the point, or an odd root that is
            not unique modulo ``p``.
    """
    e = (b & -b).bit_length() - 1
    odd = b >> e
    out = np.array([int(v) % p for v in a], dtype=object)
    if odd > 1:
        if math.gcd(odd, p - 1) != 1:
            raise NotSquare(f"roots of order {odd} are not unique modulo p")
        inv = pow(odd, -1, p - 1)
        out = np.array([pow(int(v), inv, p) for v in out], dtype=object)
    for _ in range(e):
        out = sqrt_mod_p(out, p)
    return out


def rationalizable(graph, k) -> bool:
    """Whether node ``k`` is rational or an elementary function made rational here."""
    op = graph.op[k]
    if graph.is_rational_node(k):
        return True
    if op == "pow":
        return rational_exponent(graph, k) is not None
    return op in ELEMENTARY


def generator_key(graph, k):
    """The generator a node's value is a function of: ``("circle", u)``, ``("exp", u)``, or
    ``(op, args)`` for a logarithmic kind; None for rational and algebraic nodes."""
    op, a = graph.op[k], graph.args[k]
    if op in CIRCLE:
        return ("circle", a[0])
    if op in EXPONENTIAL:
        return ("exp", a[0])
    if op in LOGARITHMIC:
        return (op, a)
    return None


def sqrt_mod_p(a, p):
    """The square roots ``r`` with ``r^2 = a`` of residues ``a (P,)`` (``p = 3 mod 4``).

    Raises:
        NotSquare: some ``a`` is not a square modulo ``p``.
    """
    out = np.empty(len(a), dtype=object)
    for i, v in enumerate(a):
        v = int(v) % p
        r = pow(v, (p + 1) // 4, p)
        if r * r % p != v:
            raise NotSquare("the argument of a square root has no root modulo p here")
        out[i] = r
    return out


class Draws:
    """The random values of the generators at the ``P`` points of one evaluator (drawn once
    per generator key, the same for every node that shares it).

    Args:
        p: the prime.
        P: number of points.
        seed: integers that fix the draws (the evaluator's points).
    """

    def __init__(self, p, P, seed):
        self.p, self.P = p, P
        self.rng = np.random.default_rng(seed)
        self.values = {}

    def _uniform(self):
        words = self.rng.integers(0, 2**63, size=(self.P, 3))
        return np.array([((int(a) << 126) | (int(b) << 63) | int(c)) % self.p for a, b, c in words], dtype=object)

    def get(self, key):
        """The values of generator ``key``: ``(s, c)`` for a circle, ``E`` (nonzero) for an
        exponential, a residue for a logarithmic kind."""
        found = self.values.get(key)
        if found is None:
            p = self.p
            t = self._uniform()
            if key[0] == "circle":
                inv = np.array([pow(int(1 + v * v) % p, -1, p) for v in t], dtype=object)
                found = ((2 * t * inv) % p, ((1 - t * t) * inv) % p)
            elif key[0] == "exp":
                found = np.where(t == 0, 1, t)
            else:
                found = t
            self.values[key] = found
        return found


def inverse_mod_p(a, p):
    """The inverses of residues ``a (P,)`` modulo ``p`` (an object array).

    Raises:
        Singular: some ``a`` is zero modulo ``p`` (a denominator vanishes at the point).
    """
    out = np.empty(len(a), dtype=object)
    for i, v in enumerate(a):
        v = int(v) % p
        if v == 0:
            raise Singular("division by zero modulo p")
        out[i] = pow(v, -1, p)
    return out


def evaluate(graph, k, V, draws):
    """Value ``(P,)`` of elementary node ``k`` and its slopes (one ``(P,)`` array per operand:
    the derivative of the node with respect to that operand), modulo ``draws.p``.

    Args:
        graph: the graph.
        k: the node (``rationalizable`` and not rational).
        V: node -> values ``(P,)`` of the evaluated operands.
        draws: the :class:`Draws` of the points.

    Raises:
        NotSquare: a square root does not exist at a point.
        Singular: a denominator vanishes at a point.
    """
    p = draws.p
    op, a = graph.op[k], graph.args[k]
    u = V[a[0]] % p
    if op in CIRCLE:
        s, c = draws.get(("circle", a[0]))
        if op == "sin":
            return s, (c,)
        if op == "cos":
            return c, ((-s) % p,)
        v = s * inverse_mod_p(c, p) % p
        return v, ((1 + v * v) % p,)
    if op in EXPONENTIAL:
        E = draws.get(("exp", a[0]))
        if op == "exp":
            return E, (E,)
        if op == "expm1":
            return (E - 1) % p, (E,)
        Ei = inverse_mod_p(E, p)
        half = pow(2, -1, p)
        plus, minus = (E + Ei) * half % p, (E - Ei) * half % p
        if op == "sinh":
            return minus, (plus,)
        if op == "cosh":
            return plus, (minus,)
        if op == "tanh":
            v = (E * E - 1) * inverse_mod_p(E * E + 1, p) % p
            return v, ((1 - v * v) % p,)
        v = E * inverse_mod_p(E + 1, p) % p  # logistic
        return v, (v * (1 - v) % p,)
    if op in LOGARITHMIC:
        v = draws.get((op, a))
        return v, _log_slopes(op, u, V[a[1]] % p if len(a) > 1 else None, p)
    if op == "sqrt":
        r = sqrt_mod_p(u, p)
        return r, (inverse_mod_p(2 * r, p),)
    e = rational_exponent(graph, k)  # u ** (m/b) = root_b(u) ** m, slope (m/b) u^(m/b) / u
    m = e.numerator
    r = root_mod_p(u, e.denominator, p)
    v = np.array([pow(int(x), m, p) if m >= 0 else pow(int(y), -m, p) for x, y in
                  zip(r, inverse_mod_p(r, p) if m < 0 else r)], dtype=object)
    return v, (m * v * inverse_mod_p(e.denominator * u, p) % p,)


def _log_slopes(op, u, b, p):
    """The derivative rules of the logarithmic kinds (their slopes, per operand)."""
    if op == "log":
        return (inverse_mod_p(u, p),)
    if op == "log1p":
        return (inverse_mod_p(u + 1, p),)
    if op == "atan":
        return (inverse_mod_p(1 + u * u, p),)
    if op == "atanh":
        return (inverse_mod_p(1 - u * u, p),)
    if op in ("asin", "acos"):
        w = inverse_mod_p(sqrt_mod_p((1 - u * u) % p, p), p)
        return (w if op == "asin" else (-w) % p,)
    if op == "asinh":
        return (inverse_mod_p(sqrt_mod_p((u * u + 1) % p, p), p),)
    if op == "acosh":
        return (inverse_mod_p(sqrt_mod_p((u * u - 1) % p, p), p),)
    d = inverse_mod_p(u * u + b * b, p)  # atan2(u, b): (b du - u db) / (u^2 + b^2)
    return (b * d % p, (-u) * d % p)


def omega_factors(graph, key, V, p):
    """The logarithmic differential of generator ``key`` as ``[(operand, factor (P,))]``:
    ``omega = sum factor * d operand`` (``du`` for a circle or an exponential, the slopes of
    the derivative rule for a logarithmic kind)."""
    if key[0] in ("circle", "exp"):
        return [(key[1], np.ones(len(V[key[1]]), dtype=object))]
    op, a = key
    slopes = _log_slopes(op, V[a[0]] % p, V[a[1]] % p if len(a) > 1 else None, p)
    return list(zip(a, slopes))


def family(key) -> str:
    """``"imaginary"`` (circle, atan, asin, ...) or ``"real"`` (exp, log, ...)."""
    kind = "sin" if key[0] == "circle" else "exp" if key[0] == "exp" else key[0]
    return "imaginary" if kind in IMAGINARY else "real"


__all__ = ["Singular", "ELEMENTARY", "CIRCLE", "EXPONENTIAL", "LOGARITHMIC", "ALGEBRAIC", "NotSquare", "Draws",
           "rationalizable", "generator_key", "evaluate", "omega_factors", "family", "sqrt_mod_p",
           "rational_exponent", "root_mod_p", "inverse_mod_p"]
