"""Known initial values given as text (``--initial x2=2*k1``, a model file's ``[initial]``),
turned into what :func:`uio_jax.analyze` takes with ``initial=``: numbers, parameter names, and
functions of the parameter vector compiled from whitelisted expressions
(:mod:`uio_jax._io.expressions`). The analysis checks every value the same way, whichever way
it arrived (:func:`uio_jax._analysis.initial.initial_value`)."""

import numpy as np

from .expression_functions import to_function
from .expressions import Binary, Call, Name, Num, Unary, parse_expression

#: The name of the traced zero every constant of an initial-value expression is added to.
_ANCHOR = "\x00zero"


class ParameterExpression:
    """A function ``p (len(params),) -> ()`` compiled from an expression text in the parameters.

    Every constant of the text is added to a traced zero (``0 * sum(p)``), so that the
    arithmetic on constants happens in the model's expression graph and not in float64
    before it: ``1/3`` is the exact ``1/3``, ``3*1`` the exact ``3``, and ``sin(pi)`` a
    constant known in float64 only (the analysis then decides nothing with it exactly),
    never the decimal ``1.2246467991473532e-16`` taken as exact.

    Attributes:
        text: the expression as given (reports show it).
    """

    def __init__(self, text, params, constants, what="initial value"):
        self.text = text
        tree = parse_expression(text, tuple(params) + tuple(constants), what=what)
        self._fn = to_function(_anchored(tree, set(params)), tuple(params) + (_ANCHOR,), dict(constants))

    def __call__(self, p):
        if isinstance(p, np.ndarray):
            xp = np
        else:  # a JAX tracer: JAX is imported (a Python model's analysis)
            import jax.numpy as xp
        p = xp.reshape(xp.asarray(p, dtype=float), (-1,))
        return self._fn(xp.concatenate([p, 0.0 * xp.sum(p, keepdims=True)]))

    #: its expression is built without JAX (:mod:`uio_jax._engine.graph_trace`)
    graph_native = True

    def emit(self, p):
        """The expression at the parameters ``p`` (graph nodes; the anchor a graph zero, so
        that the constants' arithmetic happens in the graph), None without a parameter (then
        it is traced)."""
        flat = list(np.asarray(p, dtype=object).reshape(-1))
        if not flat:
            return None
        return self._fn.emit(flat + [flat[0] * 0])


def _anchored(e, params):
    """The tree with every constant (a number, ``pi``, a model constant) plus the anchor; the
    constant exponents of powers are kept as they are (integer powers stay integer powers)."""
    if isinstance(e, Num) or (isinstance(e, Name) and e.id not in params):
        return Binary("+", e, Name(_ANCHOR))
    if isinstance(e, Unary):
        return Unary(e.op, _anchored(e.operand, params))
    if isinstance(e, Binary):
        right = e.right if e.op == "**" and _constant_number(e.right) else _anchored(e.right, params)
        return Binary(e.op, _anchored(e.left, params), right)
    if isinstance(e, Call):
        args = [_anchored(a, params) for a in e.args]
        if e.func in ("pow", "Pow") and len(e.args) == 2 and _constant_number(e.args[1]):
            args[1] = e.args[1]
        return Call(e.func, tuple(args))
    return e


def _constant_number(e) -> bool:
    return isinstance(e, Num) or (isinstance(e, Unary) and isinstance(e.operand, Num))


def initial_values(system, values) -> dict:
    """``{state: value}`` for ``uj.analyze(system, initial=...)`` from ``values`` (``state -> a
    number or a text``): a text that reads as a number becomes that number, a parameter's name
    stays a name, any other text is an expression in the parameters (and the model file's
    constants) compiled to a :class:`ParameterExpression`.

    Raises:
        ExpressionError: a text that does not parse, or names something other than a
            parameter or a constant (one line naming it).
    """
    params = tuple(system.params)
    constants = dict(getattr(system.source, "constants", None) or {})
    out = {}
    for state, value in values.items():
        if not isinstance(value, str):
            out[state] = value
            continue
        text = value.strip()
        if text in params or _is_number(text):
            out[state] = text  # read exactly (its decimal value) by the analysis
            continue
        out[state] = ParameterExpression(text, params, constants, what=f"initial value of {state}")
    return out


def _is_number(text) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def file_initial(system) -> dict:
    """The ``[initial]`` table of the model file ``system`` was loaded from (empty otherwise)."""
    return dict(getattr(system.source, "initial", None) or {})


__all__ = ["ParameterExpression", "initial_values", "file_initial"]
