"""The rule table that translates a jaxpr into the expression graph (:mod:`.graph`).

One rule per primitive, for :func:`uio_jax._engine.interpreter.interpret`
(:data:`RULES`; the walk itself and the public entry points are in :mod:`.graph_trace`).
A value of the walk is a numpy array of the variable's shape:

* **concrete** (a numeric dtype): a constant of the model, an index, a literal; rules
  on concrete operands compute with numpy (``x[5]`` of a 2-vector shows up here as an
  index computed from literals);
* **symbolic** (``dtype=object``): one graph node number per element.

Elementwise primitives make one node per element (this module); structural primitives
(slice, reshape, concatenate, broadcast, transpose, indexing with constant indices,
``.at[]``, ...) move node numbers around with numpy and ``dot_general`` and reductions make
sums of products (:mod:`.graph_structural`); calls are inlined. The values of the walk and
the errors: :mod:`.graph_values`. A primitive without a rule, or one that would need the value
of a state (an index computed from the state, a loop condition), raises
:class:`Untranslatable`; loops with a static trip count are unrolled (:mod:`.graph_loops`).
"""

import math

import numpy as np

from .graph_loops import loop_rules
from .graph_structural import STRUCTURAL
from .graph_values import Untranslatable, as_nodes, elementwise, is_symbolic
from .interpreter import Rules, inline


# ---------------------------------------------------------------------- helpers
def _concrete_rule(np_fn):
    """A rule that computes with numpy when every operand is concrete, else symbolically
    by ``sym(graph, ins, eqn)``."""

    def wrap(sym):
        def rule(graph, i, eqn, ins):
            if not any(is_symbolic(v) for v in ins):
                return [np.asarray(np_fn(*[np.asarray(v) for v in ins]))]
            return [sym(graph, ins, eqn)]

        return rule

    return wrap


def _unary(op):
    np_fn = {"neg": np.negative, "sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp,
             "log": np.log, "sqrt": np.sqrt, "tanh": np.tanh, "atan": np.arctan,
             "asin": np.arcsin, "acos": np.arccos, "sinh": np.sinh, "cosh": np.cosh,
             "asinh": np.arcsinh, "acosh": np.arccosh, "atanh": np.arctanh, "abs": np.abs,
             "log1p": np.log1p, "expm1": np.expm1, "sign": np.sign, "floor": np.floor,
             "ceil": np.ceil, "round": np.round, "cbrt": np.cbrt,
             "logistic": lambda a: 1 / (1 + np.exp(-a)), "not": np.logical_not,
             "erf": np.vectorize(math.erf, otypes=[np.float64])}[op]

    @_concrete_rule(np_fn)
    def rule(graph, ins, eqn):
        return elementwise(graph, lambda a: graph.unary(op, a), ins)

    return rule


def _binary(op, np_fn):
    @_concrete_rule(np_fn)
    def rule(graph, ins, eqn):
        return elementwise(graph, lambda a, b: graph.binary(op, a, b), ins)

    return rule


@_concrete_rule(np.subtract)
def _sub(graph, ins, eqn):
    return elementwise(graph, graph.sub, ins)


def _integer_pow(graph, i, eqn, ins):
    k = eqn.params.get("y", 2)  # (square: integer_pow without parameters)
    if not is_symbolic(ins[0]):
        return [np.asarray(ins[0]) ** k]
    return [elementwise(graph, lambda a: graph.ipow(a, k), ins)]


@_concrete_rule(lambda a: 1 / np.sqrt(a))
def _rsqrt(graph, ins, eqn):
    return elementwise(graph, lambda a: graph.div(graph.one, graph.unary("sqrt", a)), ins)


@_concrete_rule(np.exp2)
def _exp2(graph, ins, eqn):
    two = graph.const(2.0)
    return elementwise(graph, lambda a: graph.binary("pow", two, a), ins)


def _max_min(greater):
    def rule(graph, i, eqn, ins):
        if not any(is_symbolic(v) for v in ins):
            return [(np.maximum if greater else np.minimum)(*ins)]
        cmp = "gt" if greater else "lt"
        return [elementwise(graph, lambda a, b: graph.select(graph.binary(cmp, a, b), b, a), ins)]

    return rule


def _clamp(graph, i, eqn, ins):
    lo, x, hi = ins
    if not any(is_symbolic(v) for v in ins):
        return [np.clip(x, lo, hi)]

    def one(lo_, x_, hi_):
        y = graph.select(graph.binary("lt", x_, lo_), x_, lo_)
        return graph.select(graph.binary("gt", y, hi_), y, hi_)

    return [elementwise(graph, one, ins)]


def _select_n(graph, i, eqn, ins):
    pred, *cases = ins
    if not is_symbolic(pred):
        pred = np.asarray(pred)
        if all(not is_symbolic(c) for c in cases):
            return [np.choose(pred.astype(int), [np.asarray(c) for c in cases])]
        cases = np.broadcast_arrays(*[as_nodes(graph, c) for c in cases])
        which = np.broadcast_to(pred.astype(int), cases[0].shape)
        out = np.empty(cases[0].shape, dtype=object)  # nodes stay nodes (np.choose makes ints)
        for idx in np.ndindex(out.shape):
            out[idx] = cases[which[idx]][idx]
        return [out]
    if len(cases) != 2:
        raise Untranslatable("select_n", "more than two cases with a state-dependent choice")
    return [elementwise(graph, graph.select, [pred, cases[0], cases[1]])]


def _convert(graph, i, eqn, ins):
    (a,) = ins
    new = np.dtype(eqn.params["new_dtype"])
    if not is_symbolic(a):
        return [np.asarray(a).astype(new)]
    if np.issubdtype(new, np.floating) or new == np.bool_:
        return [a]
    if np.issubdtype(new, np.complexfloating):
        raise Untranslatable("convert_element_type", "complex values")
    # float -> integer truncates: allowed only where the node is a 0/1 logical value
    if all(graph.op[k] in ("lt", "le", "gt", "ge", "eq", "ne", "and", "or", "not", "c")
           for k in a.reshape(-1)):
        return [a]
    raise Untranslatable("convert_element_type", f"a state-dependent value cast to {new}")


def _call(graph, i, eqn, ins):
    outs = inline(RULES, graph, eqn, ins)
    if outs is None:
        raise Untranslatable(eqn.primitive.name, "no sub-jaxpr")
    return outs


def _untranslatable(graph, i, eqn, ins):
    """A primitive without a rule: evaluated as it is when none of its operands depends on
    the state (an index computed from a loop counter, ``(i + 1) % n``; the result is a
    constant of the model), refused otherwise."""
    if any(is_symbolic(v) for v in ins) or eqn.primitive.multiple_results:
        raise Untranslatable(eqn.primitive.name)
    try:
        out = eqn.primitive.bind(*[np.asarray(v) for v in ins], **eqn.params)
    except Exception:  # a primitive that cannot run on concrete numpy values
        raise Untranslatable(eqn.primitive.name) from None
    return [np.asarray(out)]


_TABLE = {
    **{op: _unary(op) for op in ("neg", "sin", "cos", "tan", "exp", "log", "sqrt", "tanh",
                                 "atan", "asin", "acos", "sinh", "cosh", "asinh", "acosh",
                                 "atanh", "abs", "log1p", "expm1", "sign", "floor", "ceil",
                                 "round", "cbrt", "logistic", "not", "erf")},
    "add": _binary("add", np.add), "add_any": _binary("add", np.add),
    "mul": _binary("mul", np.multiply), "div": _binary("div", np.divide),
    "pow": _binary("pow", np.power), "atan2": _binary("atan2", np.arctan2),
    "lt": _binary("lt", np.less), "le": _binary("le", np.less_equal),
    "gt": _binary("gt", np.greater), "ge": _binary("ge", np.greater_equal),
    "eq": _binary("eq", np.equal), "ne": _binary("ne", np.not_equal),
    "and": _binary("and", np.logical_and), "or": _binary("or", np.logical_or),
    "sub": _sub, "integer_pow": _integer_pow, "square": _integer_pow, "rsqrt": _rsqrt,
    "exp2": _exp2, "max": _max_min(True), "min": _max_min(False), "clamp": _clamp,
    "select_n": _select_n, "convert_element_type": _convert,
    **STRUCTURAL,
}

RULES = Rules(_TABLE, default=_untranslatable, calls=_call)
RULES.update(loop_rules(RULES))  # static trip counts unrolled


__all__ = ["RULES"]
