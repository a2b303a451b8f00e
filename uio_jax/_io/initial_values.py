"""Known initial values given as text (``--initial x2=2*k1``, a model file's ``[initial]``),
turned into what :func:`uio_jax.analyze` takes with ``initial=``: numbers, parameter names, and
functions of the parameter vector compiled from whitelisted expressions
(:mod:`uio_jax._io.expressions`)."""

from .expression_functions import to_function
from .expressions import parse_expression


class ParameterExpression:
    """A function ``p (len(params),) -> ()`` compiled from an expression text in the parameters.

    Attributes:
        text: the expression as given (reports show it).
    """

    def __init__(self, text, params, constants, what="initial value"):
        self.text = text
        self._fn = to_function(parse_expression(text, tuple(params) + tuple(constants), what=what),
                               tuple(params), dict(constants))

    def __call__(self, p):
        return self._fn(p)

    #: its expression is built without JAX (:mod:`uio_jax._engine.graph_trace`)
    graph_native = True

    def emit(self, p):
        """The expression at the parameters ``p`` (graph nodes)."""
        return self._fn.emit(p)


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
