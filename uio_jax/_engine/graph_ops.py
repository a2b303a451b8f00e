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


__all__ = ["BINARY", "PIECEWISE_CONSTANT", "RATIONAL_OPS", "UNARY"]
