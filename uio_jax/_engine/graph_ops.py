"""The operations of the expression graph (:mod:`.graph`), by kind."""

#: operations whose value is a rational function of their operands (exact modulo a prime)
RATIONAL_OPS = frozenset({"x", "c", "add", "mul", "div", "neg", "ipow"})

#: piecewise constant operations: derivative zero (comparisons, logic, rounding)
PIECEWISE_CONSTANT = frozenset({"lt", "le", "gt", "ge", "eq", "ne", "and", "or", "not",
                                "sign", "floor", "ceil", "round"})

#: elementary functions of one operand (``log`` is the natural logarithm)
UNARY = frozenset({"neg", "sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "atan", "asin",
                   "acos", "sinh", "cosh", "asinh", "acosh", "atanh", "abs", "log1p", "expm1",
                   "logistic", "erf", "cbrt", "sign", "floor", "ceil", "round", "not"})

#: operations of two operands
BINARY = frozenset({"add", "mul", "div", "pow", "atan2", "lt", "le", "gt", "ge", "eq", "ne",
                    "and", "or"})




def unary_slopes(m):
    """``op -> (a, v) -> d op(a) / da`` from the operand ``a`` and the value ``v = op(a)``,
    in the arithmetic of the namespace ``m`` (``numpy``, or an mpmath context): its
    ``sqrt``, ``sin``, ``cos``, ``sinh``, ``cosh``, ``sign``, ``exp`` and ``pi``. One table
    for the float64 walk and the extended-precision one."""
    return {
        "sin": lambda a, v: m.cos(a), "cos": lambda a, v: -m.sin(a),
        "tan": lambda a, v: 1 + v * v, "exp": lambda a, v: v, "log": lambda a, v: 1 / a,
        "sqrt": lambda a, v: 1 / (2 * v), "tanh": lambda a, v: 1 - v * v,
        "atan": lambda a, v: 1 / (1 + a * a), "asin": lambda a, v: 1 / m.sqrt(1 - a * a),
        "acos": lambda a, v: -1 / m.sqrt(1 - a * a), "sinh": lambda a, v: m.cosh(a),
        "cosh": lambda a, v: m.sinh(a), "asinh": lambda a, v: 1 / m.sqrt(a * a + 1),
        "acosh": lambda a, v: 1 / m.sqrt(a * a - 1), "atanh": lambda a, v: 1 / (1 - a * a),
        "abs": lambda a, v: m.sign(a), "log1p": lambda a, v: 1 / (1 + a),
        "expm1": lambda a, v: v + 1, "logistic": lambda a, v: v * (1 - v),
        "erf": lambda a, v: 2 / m.sqrt(m.pi) * m.exp(-a * a),
        "cbrt": lambda a, v: 1 / (3 * v * v),
    }


__all__ = ["unary_slopes", "BINARY", "PIECEWISE_CONSTANT", "RATIONAL_OPS", "UNARY"]
