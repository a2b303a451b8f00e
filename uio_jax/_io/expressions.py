"""Whitelisted arithmetic expressions: parse user text safely, compile it to JAX, print it back.

Model files and importers give right-hand sides as text, e.g. ``"x1*cos(x3) - p1"``. The
text is parsed with :func:`ast.parse` (``mode="eval"``) and converted into a small tree of
:class:`Expr` nodes under a strict whitelist; nothing of the text is ever executed
(no ``eval``/``exec``). Accepted:

* numbers (``2``, ``0.5``, ``1e-3``; not complex, not booleans);
* names: the variables given by the caller (states, parameters, inputs, constants) and the
  constants ``pi`` and ``E`` (a variable of the same name takes precedence);
* unary ``+``/``-`` and binary ``+ - * / **`` (``^`` is refused with a hint to use ``**``);
* calls, by bare name and positional arguments only, of the functions in :data:`FUNCTIONS`
  (``sin cos tan sec csc cot asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp log
  sqrt abs Abs sign min max Min Max pow Pow``; the capitalised ones are sympy's spellings).

Everything else (attributes such as ``os.system`` or ``x.__class__``, subscripts, lambdas,
comprehensions, keyword arguments, strings, comparisons, unknown names) raises
:class:`ExpressionError` with one line naming the expression, the 1-based column of the
offending token and what is allowed.

The tree is compiled to functions by :mod:`uio_jax._io.expression_functions`.
:func:`to_text` prints a tree back with the fewest parentheses that parse into the same
tree: ``parse(to_text(e)) == e``.
"""

import ast
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

from .._errors import ExpressionError

#: Longest expression text accepted (characters); longer text is refused before parsing.
MAX_LENGTH = 100_000
#: Deepest expression tree accepted (a flat sum of N terms is N deep). Printing, compiling
#: and evaluating walk the tree recursively, so this keeps them far from Python's
#: recursion limit.
MAX_DEPTH = 400
#: Most nodes of an expression tree, counted with repetitions (the StrikePy reader inlines
#: named subexpressions: ``b = a*a; c = b*b; ...`` doubles the tree at each line).
MAX_NODES = 200_000
#: Integer exponents up to this size use ``lax.integer_pow``; larger ones ``jnp.power``.
MAX_INTEGER_POW = 64
#: Names of mathematical constants, usable in every expression unless a variable shadows them.
CONSTANTS = {"pi": math.pi, "E": math.e}


# ----------------------------------------------------------------------------- the tree
@dataclass(frozen=True)
class Num:
    """A number constant (always stored as a float)."""

    value: float


@dataclass(frozen=True)
class Name:
    """A variable (or ``pi``/``E``), by name."""

    id: str


@dataclass(frozen=True)
class Unary:
    """``+a`` or ``-a`` (``op`` is ``"+"`` or ``"-"``)."""

    op: str
    operand: "Expr"


@dataclass(frozen=True)
class Binary:
    """``a op b`` with ``op`` one of ``+ - * / **``."""

    op: str
    left: "Expr"
    right: "Expr"


@dataclass(frozen=True)
class Call:
    """``func(args...)`` with ``func`` a key of :data:`FUNCTIONS`."""

    func: str
    args: tuple


Expr = Num | Name | Unary | Binary | Call


#: Whitelisted functions: name -> number of arguments (``(k, None)``: at least k).
#: Implementations: :data:`_JAX_OPS` (``jnp``) and :data:`_NUMPY_OPS`; aliases in :data:`ALIASES`.
FUNCTIONS: dict[str, object] = {
    "sin": 1, "cos": 1, "tan": 1, "sec": 1, "csc": 1, "cot": 1,
    "asin": 1, "acos": 1, "atan": 1, "atan2": 2,
    "sinh": 1, "cosh": 1, "tanh": 1, "asinh": 1, "acosh": 1, "atanh": 1,
    "exp": 1, "log": 1, "sqrt": 1, "abs": 1, "Abs": 1, "sign": 1,
    "min": (2, None), "max": (2, None), "Min": (2, None), "Max": (2, None),
    "pow": 2, "Pow": 2,
}
#: Functions that are another function's spelling.
ALIASES = {"Abs": "abs", "Min": "min", "Max": "max", "Pow": "pow"}


_BINOPS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
_HINTS = {
    ast.BitXor: "'^' is not a power here: use '**'",
    ast.FloorDiv: "'//' is not allowed: use '/'",
    ast.Mod: "'%' is not allowed",
    ast.MatMult: "'@' is not allowed",
}


# ----------------------------------------------------------------------------- parsing
def parse_expression(text: str, names: Iterable[str], *, what: str = "expression") -> Expr:
    """Parse ``text`` into an :class:`Expr` tree, allowing only whitelisted constructs.

    Args:
        text: the expression, e.g. ``"x1*cos(x3) - p1"``. Newlines count as spaces;
            surrounding blanks are ignored.
        names: the variables the expression may use (states, parameters, inputs,
            constants); ``pi`` and ``E`` are always allowed.
        what: how the expression is named in error messages (e.g. ``"dynamics of 'r'"``).

    Returns:
        The tree (frozen dataclasses :class:`Num`, :class:`Name`, :class:`Unary`,
        :class:`Binary`, :class:`Call`); equal texts give equal trees.

    Raises:
        ExpressionError: one line ``<what> 'TEXT' at column C: PROBLEM`` (C is 1-based).
    """
    names = tuple(names)
    if not isinstance(text, str):
        if isinstance(text, (int, float)) and not isinstance(text, bool) and math.isfinite(text):
            text = repr(text)
        else:
            raise ExpressionError(f"{what} must be a string, got {type(text).__name__} {text!r}")
    text = text.replace("\r", " ").replace("\n", " ").strip()
    if not text:
        raise ExpressionError(f"{what} is empty")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{what} is longer than {MAX_LENGTH} characters")
    tree = _parse_ast(text, what)
    known = set(names)

    def on_name(node):
        if node.id in known or node.id in CONSTANTS:
            return Name(node.id)
        return None

    def fail(node, message):
        raise ExpressionError(f"{what} {_quote(text)} at column {_column(text, node)}: {message}")

    def describe_names():
        return _describe_names(names)

    return Converter(on_name, None, fail, describe_names).convert(tree.body)


def _parse_ast(text, what):
    try:
        return ast.parse(text, mode="eval")
    except SyntaxError as exc:
        if "Exceeds the limit" in (exc.msg or ""):  # Python's limit on integer literals' digits
            run = max(re.finditer(r"\d+", text), key=lambda mt: len(mt.group()))
            raise ExpressionError(
                f"{what} {_quote(text)} at column {run.start() + 1}: a number of {len(run.group())} digits "
                "is too large"
            ) from None
        if _parses(text + " 1"):
            raise ExpressionError(
                f"{what} {_quote(text)} at column {len(text) + 1}: incomplete expression (an operand is missing)"
            ) from None
        col = exc.offset or 1
        if exc.lineno and exc.lineno > 1:  # cannot happen after newline removal; be safe
            col = len(text)
        msg = (exc.msg or "invalid syntax").split(" (")[0]
        raise ExpressionError(f"{what} {_quote(text)} at column {col}: {msg}") from None
    except (RecursionError, MemoryError):
        raise ExpressionError(f"{what} {_quote(text[:60])} is nested too deeply") from None
    except ValueError as exc:  # e.g. null bytes
        raise ExpressionError(f"{what} {_quote(text)}: {exc}") from None


def _parses(text: str) -> bool:
    try:
        ast.parse(text, mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return False
    return True


def _quote(text: str) -> str:
    shown = text if len(text) <= 200 else text[:197] + "..."
    return repr(shown)


def _column(text: str, node) -> int:
    """1-based character column of an ast node (ast gives UTF-8 byte offsets)."""
    off = getattr(node, "col_offset", 0) or 0
    return len(text.encode("utf-8")[:off].decode("utf-8", errors="ignore")) + 1


def _describe_names(names: Sequence[str], limit: int = 12) -> str:
    shown = list(names[:limit])
    more = f", ... ({len(names)} in all)" if len(names) > limit else ""
    known = (", ".join(shown) + more) if shown else "none"
    return f"known names: {known}; constants: pi, E; functions: {', '.join(FUNCTIONS)}"


class Converter:
    """ast -> Expr under the whitelist; shared by the expression parser and the StrikePy reader.

    ``on_name(ast.Name) -> Expr | None`` resolves a bare name (None: not allowed);
    ``on_call(ast.Call) -> Expr | None`` may resolve a call the whitelist does not know
    (e.g. ``sym.exp(x)``), None to fall back on the bare-name rules; ``fail(node, msg)``
    raises the caller's one-line error.
    """

    def __init__(self, on_name, on_call, fail, describe_names):
        self.on_name = on_name
        self.on_call = on_call
        self.fail = fail
        self.describe_names = describe_names

    def convert(self, node) -> Expr:
        try:
            out = self._visit(node)
        except RecursionError:
            self.fail(node, f"nested too deeply (more than {MAX_DEPTH} levels)")
        if depth(out) > MAX_DEPTH:
            self.fail(node, f"nested too deeply (more than {MAX_DEPTH} levels; a sum of N terms is N levels)")
        if size(out) > MAX_NODES:
            self.fail(node, f"too large (more than {MAX_NODES} operations once named subexpressions are inlined)")
        return out

    def _visit(self, node) -> Expr:
        if isinstance(node, ast.Constant):
            return self._constant(node)
        if isinstance(node, ast.Name):
            out = self.on_name(node)
            if out is None:
                self.fail(node, f"name {node.id!r} is not allowed ({self.describe_names()})")
            return out
        if isinstance(node, ast.UnaryOp):
            if isinstance(node.op, ast.USub):
                return Unary("-", self._visit(node.operand))
            if isinstance(node.op, ast.UAdd):
                return Unary("+", self._visit(node.operand))
            self.fail(node, f"operator {_op_symbol(node.op)!r} is not allowed (use + - * / **)")
        if isinstance(node, ast.BinOp):
            op = _BINOPS.get(type(node.op))
            if op is None:
                hint = _HINTS.get(type(node.op), f"operator {_op_symbol(node.op)!r} is not allowed")
                self.fail(_operator_node(node), hint + " (allowed: + - * / **)")
            return Binary(op, self._visit(node.left), self._visit(node.right))
        if isinstance(node, ast.Call):
            return self._call(node)
        if isinstance(node, ast.Attribute):
            if isinstance(node.value, (ast.Attribute, ast.Call, ast.Subscript)):
                self._visit(node.value)  # report the first offence in reading order
            self.fail(_attribute_node(node), _refusal(node))
        self.fail(node, _refusal(node))

    def _constant(self, node) -> Expr:
        v = node.value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            kind = "string" if isinstance(v, (str, bytes)) else type(v).__name__
            self.fail(node, f"{kind} constant {v!r} is not allowed (numbers only)")
        try:
            value = float(v)
        except OverflowError:
            self.fail(node, "number too large")
        if not math.isfinite(value):
            self.fail(node, "number too large")
        return Num(value)

    def _call(self, node) -> Expr:
        if self.on_call is not None:
            out = self.on_call(node, self)
            if out is not None:
                return out
        if isinstance(node.func, ast.Attribute):
            self._visit(node.func)  # raises, naming the attribute (or an earlier offence)
        if not isinstance(node.func, ast.Name):
            self.fail(node.func, f"{_refusal(node.func)}; call whitelisted functions by bare name "
                                 f"({', '.join(FUNCTIONS)})")
        return self.whitelisted_call(node, node.func.id, node.func)

    def whitelisted_call(self, node, fname, where) -> Expr:
        """A call of the whitelisted function ``fname`` with the arguments of ``node``."""
        if fname not in FUNCTIONS:
            self.fail(where, f"function {fname!r} is not allowed (functions: {', '.join(FUNCTIONS)})")
        if node.keywords:
            self.fail(node.keywords[0].value if node.keywords[0].arg else node,
                      f"keyword arguments are not allowed in a call of {fname!r}")
        for a in node.args:
            if isinstance(a, ast.Starred):
                self.fail(a, f"'*' arguments are not allowed in a call of {fname!r}")
        arity = FUNCTIONS[fname]
        n = len(node.args)
        if isinstance(arity, tuple):
            if n < arity[0]:
                self.fail(node, f"{fname}() takes at least {arity[0]} arguments, got {n}")
        elif n != arity:
            self.fail(node, f"{fname}() takes {arity} argument{'s' if arity > 1 else ''}, got {n}")
        return Call(fname, tuple(self._visit(a) for a in node.args))


def _attribute_node(node: ast.Attribute):
    """A stand-in node located at the attribute's name (``.attr``)."""
    fake = ast.Name(id="", ctx=ast.Load())
    fake.lineno = getattr(node, "end_lineno", None) or getattr(node, "lineno", None)
    end = getattr(node, "end_col_offset", None)
    fake.col_offset = node.col_offset if end is None else max(end - len(node.attr), node.col_offset)
    return fake


def _operator_node(node: ast.BinOp):
    """A stand-in node located just after the left operand (where the operator is)."""
    col = getattr(node.left, "end_col_offset", None)
    fake = ast.Name(id="", ctx=ast.Load())
    fake.lineno = getattr(node.left, "end_lineno", None) or getattr(node, "lineno", None)
    fake.col_offset = col if col is not None else node.col_offset
    return fake


def _op_symbol(op) -> str:
    return {ast.BitXor: "^", ast.BitAnd: "&", ast.BitOr: "|", ast.LShift: "<<", ast.RShift: ">>",
            ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.Invert: "~",
            ast.Not: "not"}.get(type(op), type(op).__name__)


def _refusal(node) -> str:
    if isinstance(node, ast.Attribute):
        return f"attribute access '.{node.attr}' is not allowed"
    if isinstance(node, ast.Subscript):
        return "subscripts ('[...]') are not allowed"
    if isinstance(node, ast.Lambda):
        return "lambda is not allowed"
    if isinstance(node, (ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp)):
        return "comprehensions are not allowed"
    if isinstance(node, (ast.Compare, ast.BoolOp)):
        return "comparisons and boolean operators are not allowed"
    if isinstance(node, ast.IfExp):
        return "conditional expressions are not allowed"
    if isinstance(node, (ast.List, ast.Tuple, ast.Set, ast.Dict)):
        return f"{type(node).__name__.lower()} displays are not allowed"
    if isinstance(node, (ast.JoinedStr, ast.FormattedValue)):
        return "strings are not allowed"
    if isinstance(node, ast.NamedExpr):
        return "assignment expressions are not allowed"
    if isinstance(node, (ast.Await, ast.Yield, ast.YieldFrom)):
        return f"{type(node).__name__.lower()} is not allowed"
    return f"{type(node).__name__} is not allowed"


# ----------------------------------------------------------------------------- queries
def names_of(expr: Expr) -> set[str]:
    """The variable names an expression uses (``pi``/``E`` included when used)."""
    out, stack = set(), [expr]
    while stack:
        e = stack.pop()
        if isinstance(e, Name):
            out.add(e.id)
        stack.extend(_children(e))
    return out


def _children(e: Expr) -> tuple:
    if isinstance(e, Unary):
        return (e.operand,)
    if isinstance(e, Binary):
        return (e.left, e.right)
    if isinstance(e, Call):
        return e.args
    return ()


def _fold(expr: Expr, combine) -> int:
    """Bottom-up value over the DAG of shared subtrees (memoised by identity, no recursion)."""
    memo, stack = {}, [expr]
    while stack:
        e = stack[-1]
        if id(e) in memo:
            stack.pop()
            continue
        todo = [c for c in _children(e) if id(c) not in memo]
        if todo:
            stack.extend(todo)
            continue
        stack.pop()
        memo[id(e)] = combine([memo[id(c)] for c in _children(e)])
    return memo[id(expr)]


def depth(expr: Expr) -> int:
    """Number of levels of a tree (a leaf is 1)."""
    return _fold(expr, lambda kids: 1 + max(kids, default=0))


def size(expr: Expr) -> int:
    """Number of nodes of a tree, shared subtrees counted every time they occur."""
    return _fold(expr, lambda kids: 1 + sum(kids))


def substitute(expr: Expr, mapping: Mapping[str, Expr]) -> Expr:
    """Replace every :class:`Name` found in ``mapping`` by its tree."""
    if isinstance(expr, Name):
        return mapping.get(expr.id, expr)
    if isinstance(expr, Unary):
        return Unary(expr.op, substitute(expr.operand, mapping))
    if isinstance(expr, Binary):
        return Binary(expr.op, substitute(expr.left, mapping), substitute(expr.right, mapping))
    if isinstance(expr, Call):
        return Call(expr.func, tuple(substitute(a, mapping) for a in expr.args))
    return expr


# ----------------------------------------------------------------------------- printing
_PREC = {"+": 1, "-": 1, "*": 2, "/": 2, "unary": 3, "**": 4, "atom": 5}


def _prec(e: Expr) -> int:
    if isinstance(e, Binary):
        return _PREC[e.op]
    if isinstance(e, Unary):
        return _PREC["unary"]
    return _PREC["atom"]


def _number_text(v: float) -> str:
    if v.is_integer() and abs(v) < 1e16:
        return str(int(v))
    return repr(v)


def to_text(expr: Expr) -> str:
    """Print a tree as expression text that :func:`parse_expression` reads back to the same tree.

    Parentheses are added only where Python's precedence needs them (``**`` is
    right-associative and binds tighter than unary minus on its left; same-precedence
    right operands of ``+ - * /`` keep theirs so that the tree, not only the value, is kept).
    """
    if isinstance(expr, Num):
        return _number_text(expr.value)
    if isinstance(expr, Name):
        return expr.id
    if isinstance(expr, Call):
        return f"{expr.func}({', '.join(to_text(a) for a in expr.args)})"
    if isinstance(expr, Unary):
        inner = to_text(expr.operand)
        if _prec(expr.operand) < _PREC["unary"]:
            inner = f"({inner})"
        elif isinstance(expr.operand, Unary) or (isinstance(expr.operand, Num) and inner[0] in "+-"):
            inner = f"({inner})"
        return f"{expr.op}{inner}"
    if isinstance(expr, Binary):
        p = _PREC[expr.op]
        left, right = to_text(expr.left), to_text(expr.right)
        if expr.op == "**":
            if _prec(expr.left) <= p:
                left = f"({left})"
            if _prec(expr.right) < _PREC["unary"]:
                right = f"({right})"
        else:
            if _prec(expr.left) < p:
                left = f"({left})"
            if _prec(expr.right) <= p:
                right = f"({right})"
        return f"{left} {expr.op} {right}" if p == 1 else f"{left}{expr.op}{right}"
    raise TypeError(f"not an expression tree: {expr!r}")
