"""The model's expressions as rational functions: numerator and denominator polynomials.

The expression graph (:mod:`uio_jax._engine.graph`) of a rational model is made of
coordinates, exact constants and ``add``, ``mul``, ``div``, ``neg``, ``ipow``: each node is a
rational function of the coordinates, built here bottom-up as a pair ``(num, den)`` of
polynomials over the rationals (python-flint's ``fmpq_mpoly``), the common factor of the pair
divided out after each quotient and sum, so the degrees stay those of the reduced fraction.

A node of any other operation (``sin``, ``sqrt``, ``select``, a constant known in float64
only) is not a rational function of the coordinates: SIAN's theorem does not cover it and the
node is refused in one line naming it (:class:`~uio_jax._errors.ModelError`).
"""

from fractions import Fraction

from ..._errors import ModelError
from ..followups.expression_text import Printer


class Fractions:
    """Rational functions of graph nodes, memoized per node.

    Args:
        graph: the :class:`~uio_jax._engine.graph.Graph`.
        coords: one polynomial (``fmpq_mpoly``) per coordinate of ``graph``: what ``x(i)`` is.
        names: the coordinates' names (for the refusal's message).
        what: what the expressions are (``"the model"``), for the message.
    """

    def __init__(self, graph, coords, names, what="the model"):
        self.graph, self.coords, self.names, self.what = graph, list(coords), list(names), what
        self.ctx = self.coords[0].context() if self.coords else None
        self.memo = {}

    def of(self, roots) -> list[tuple]:
        """``(num, den)`` per node of ``roots``, ``den`` with leading coefficient 1.

        Raises:
            ModelError: a node behind ``roots`` is not rational (the operation and the
                expression named).
        """
        g = self.graph
        for k in g.reachable(roots, known=self.memo):
            self.memo[k] = self._node(k)
        return [self.memo[r] for r in roots]

    def _refuse(self, k, why):
        text = Printer(self.graph, self.names).text(k) or f"an expression with {self.graph.op[k]!r}"
        raise ModelError(f"global identifiability needs a rational model: {self.what} uses {text}, {why} "
                         "(SIAN's theorem covers rational functions of the states, parameters and inputs; "
                         "write the model with polynomials and quotients, e.g. measure r^2 instead of r)")

    def _node(self, k):
        g, memo = self.graph, self.memo
        op, args = g.op[k], g.args[k]
        one = self.ctx.constant(1)
        if op == "x":
            return self.coords[g.param[k]], one
        if op == "c":
            value = g.exact_value(k)
            if value is None:
                self._refuse(k, "a constant known in float64 only")
            return self.ctx.constant(flint_fmpq(value)), one
        if op == "neg":
            num, den = memo[args[0]]
            return -num, den
        if op == "ipow":
            num, den = memo[args[0]]
            e = int(g.param[k])
            if e < 0:
                if num.is_zero():
                    self._refuse(k, "a negative power of zero")
                num, den, e = den, num, -e
            return normal_fraction(num ** e, den ** e)
        if op == "add":
            return fraction_sum(memo[args[0]], memo[args[1]])
        if op == "mul":
            (a, b), (c, d) = memo[args[0]], memo[args[1]]
            return normal_fraction(a * c, b * d)
        if op == "div":
            (a, b), (c, d) = memo[args[0]], memo[args[1]]
            if c.is_zero():
                self._refuse(k, "a division by zero")
            return normal_fraction(a * d, b * c)
        self._refuse(k, f"the operation {op!r}, which is not a rational function")


def flint_fmpq(value):
    """python-flint's exact rational of a :class:`~fractions.Fraction` (or an int)."""
    import flint

    value = Fraction(value)
    return flint.fmpq(value.numerator, value.denominator)


def fraction_sum(x, y):
    """``x + y`` of two fractions ``(num, den)``, reduced."""
    (a, b), (c, d) = x, y
    if b == d:
        return normal_fraction(a + c, b)
    return normal_fraction(a * d + c * b, b * d)


def normal_fraction(num, den):
    """``num / den`` with the common factor divided out and ``den`` monic (leading
    coefficient 1 in the ring's order)."""
    if num.is_zero():
        return num, den.context().constant(1)
    if not den.is_constant():
        g = num.gcd(den)
        if not g.is_constant():
            num, den = num / g, den / g
    lc = den.leading_coefficient()
    if lc != 1:
        num, den = num / lc, den / lc
    return num, den


__all__ = ["Fractions", "flint_fmpq", "normal_fraction", "fraction_sum"]
