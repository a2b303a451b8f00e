"""Graph nodes printed as expressions in the model's own names.

A node of the expression graph is printed as Python/sympy syntax that
``sympy.sympify(text, locals={name: Symbol(name)})`` reads back to the same function (``log1p
u`` printed ``log(1 + u)``, ``logistic u`` ``1/(1 + exp(-u))``; exact constants as fractions,
float64 ones as their ``repr``). A node that uses a comparison, ``select`` or rounding, or
whose text would be longer than a cap, has no text (None).
"""

from fractions import Fraction

#: Unary operations printed as a call of the same name (sympy's spelling).
_CALLS = {"sin", "cos", "tan", "exp", "log", "sqrt", "tanh", "atan", "asin", "acos", "sinh",
          "cosh", "asinh", "acosh", "atanh", "abs", "erf"}
#: Precedences: sum 1, product 2, unary minus 3, power 4, atom 5.
_SUM, _PRODUCT, _UNARY, _POWER, _ATOM = 1, 2, 3, 4, 5

#: Longest text printed (characters): past it a node is not a readable function.
MAX_TEXT = 400


def _const_text(value):
    """``(text, precedence)`` of a constant."""
    if isinstance(value, Fraction):
        if value.denominator == 1:
            return str(value.numerator), (_ATOM if value >= 0 else _UNARY)
        return f"{value.numerator}/{value.denominator}", _PRODUCT
    return repr(float(value)), _ATOM


def _wrap(text_prec, below):
    text, prec = text_prec
    return f"({text})" if prec < below else text


class Printer:
    """Texts of the nodes of one graph in the given coordinate names, memoized.

    Args:
        graph: the expression graph.
        names: the name of each coordinate the printed nodes may use (coordinates past
            ``len(names)`` make a node unprintable).
        cap: longest text kept (:data:`MAX_TEXT`).
    """

    def __init__(self, graph, names, cap: int = MAX_TEXT):
        self.graph, self.names, self.cap = graph, tuple(names), cap
        self._memo = {}  # node -> (text, precedence) or None

    def text(self, node) -> str | None:
        """The expression text of ``node``, or None (unprintable or longer than the cap)."""
        found = self._pair(node)
        return None if found is None else found[0]

    def _pair(self, node):
        memo, graph = self._memo, self.graph
        for k in graph.reachable([node], known=memo):
            memo[k] = self._print(k)
        return memo[node]

    def _print(self, k):
        g, memo = self.graph, self._memo
        op, args = g.op[k], g.args[k]
        if op == "x":
            i = g.param[k]
            return (self.names[i], _ATOM) if i < len(self.names) else None
        if op == "c":
            return _const_text(g.param[k]) if g.param[k] != "nan" else None
        parts = [memo[a] for a in args]
        if any(p is None for p in parts):
            return None
        out = self._compose(op, parts, k)
        if out is not None and len(out[0]) > self.cap:
            return None
        return out

    def _compose(self, op, parts, k):
        g = self.graph
        if op == "add":
            a, b = parts
            if b[0].startswith("-") and b[1] >= _UNARY:
                return f"{a[0]} - {_wrap((b[0][1:], _UNARY), _PRODUCT)}", _SUM
            if a[0].startswith("-") and a[1] >= _UNARY:
                return f"{b[0]} - {_wrap((a[0][1:], _UNARY), _PRODUCT)}", _SUM
            return f"{a[0]} + {b[0]}", _SUM
        if op == "neg":
            return f"-{_wrap(parts[0], _POWER if parts[0][1] == _UNARY else _PRODUCT)}", _UNARY
        if op == "mul":
            a, b = parts
            if g.op[g.args[k][1]] == "c":  # the constant first: 2*x, not x*2
                a, b = b, a
            if a[0] == "-1":
                return f"-{_wrap(b, _POWER if b[1] == _UNARY else _PRODUCT)}", _UNARY
            if b[1] == _UNARY and b[0].startswith("-"):  # x*-c -> -(x*c)
                inner = f"{_wrap(a, _PRODUCT)}*{_wrap((b[0][1:], _UNARY), _PRODUCT)}"
                return f"-{inner}", _UNARY
            return f"{_wrap(a, _PRODUCT)}*{_wrap(b, _PRODUCT)}", _PRODUCT
        if op == "div":
            a, b = parts
            return f"{_wrap(a, _PRODUCT)}/{_wrap(b, _POWER)}", _PRODUCT
        if op == "ipow":
            e = g.param[k]
            exp = str(e) if e > 0 else f"({e})"
            return f"{_wrap(parts[0], _ATOM)}**{exp}", _POWER
        if op == "pow":
            return f"{_wrap(parts[0], _ATOM)}**{_wrap(parts[1], _ATOM)}", _POWER
        if op == "atan2":
            return f"atan2({parts[0][0]}, {parts[1][0]})", _ATOM
        if op in _CALLS:
            return f"{'Abs' if op == 'abs' else op}({parts[0][0]})", _ATOM
        if op == "log1p":
            return f"log(1 + {parts[0][0]})", _ATOM
        if op == "expm1":
            return f"exp({parts[0][0]}) - 1", _SUM
        if op == "logistic":
            return f"1/(1 + exp(-{_wrap(parts[0], _POWER)}))", _PRODUCT
        if op == "cbrt":
            return f"{_wrap(parts[0], _ATOM)}**(1/3)", _POWER
        return None  # comparisons, select, rounding: no readable function


def text_size(text: str) -> int:
    """The simplicity rank of a printed function: its operators, calls and names, counted
    in the text (``x`` 1, ``x*y`` 3, ``cos(theta - phi)`` 4), then its length breaks ties."""
    ops = sum(text.count(c) for c in "+-*/") - text.count("**")
    calls = text.count("(") - text.count("((")
    tokens = len([t for t in _tokens(text) if t])
    return ops + calls + tokens


def _tokens(text: str):
    word = ""
    for ch in text:
        if ch.isalnum() or ch in "_.":
            word += ch
        else:
            yield word
            word = ""
    yield word


__all__ = ["Printer", "text_size", "MAX_TEXT"]
