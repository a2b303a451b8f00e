"""Structural sparsity of a Jacobian, read from the function's jaxpr.

``jacobian_pattern(fn, x)`` answers "which output elements can depend on which input
elements" for ``fn: (q,) -> (n,)`` without evaluating anything: every jaxpr variable gets a
boolean array ``dep`` of shape ``(*var.shape, q)`` (element ``e`` of the variable may depend
on input ``j`` when ``dep[e, j]``), propagated equation by equation:

* element-wise primitives (``add``, ``mul``, ``sin``, ``select_n``, ...): the union of the
  operands' deps, element by element (scalars broadcast);
* structural primitives (``slice``, ``squeeze``, ``reshape``, ``broadcast_in_dim``,
  ``concatenate``, ``stack``, ``split``, ``transpose``, ``rev``): the deps moved with the
  elements;
* calls (``pjit``, ``closed_call``, ``custom_jvp_call``, ...): their sub-jaxpr, recursively;
* anything else (``dot_general``, reductions, gathers, loops such as ``scan`` and
  ``while``, ...): every output element depends on everything any operand depends on.

Each element also carries a flag "exactly zero whatever the input" (literals and constants
equal to 0, ``jnp.zeros``, products with such an element, ...): such an element depends on
nothing. The result is a superset of the true pattern (the last rule is always safe), exact
for functions written element by element, as vector fields of models are.
"""

import jax
import numpy as np

from .._engine.interpreter import Rules, call_body, interpret

#: Primitives whose output element ``e`` depends on operand elements ``e`` only.
_ELEMENTWISE = frozenset("""
abs acos acosh add and asin asinh atan atan2 atanh cbrt ceil clamp conj convert_element_type
copy copy_p cos cosh digamma div eq erf erf_inv erfc exp exp2 expm1 floor ge gt igamma imag
integer_pow is_finite le lgamma log log1p logistic lt max min mul ne neg nextafter not or pow
real reduce_precision rem round rsqrt select_n sign sin sinh sqrt square stop_gradient sub
tan tanh xor
""".split())

#: Element-wise primitives with ``f(0) = 0``: an exact zero stays one.
_ZERO_PRESERVING = frozenset("""
abs asin asinh atan atanh cbrt convert_element_type copy copy_p erf expm1 imag log1p neg
real reduce_precision sign sin sinh sqrt square stop_gradient tan tanh
""".split())



def jacobian_pattern(fn, x) -> np.ndarray:
    """Boolean ``(n, q)``: ``True`` where ``d fn(x)_i / d x_j`` may be non-zero.

    Should the propagation meet a jaxpr it cannot read (a rule failing on an unusual
    primitive's parameters), the answer is the dense pattern: never a missed dependence.

    Args:
        fn: ``(q,) -> (n,)`` (any array-in, array-out JAX function).
        x: an example argument (its shape and dtype only are used).
    """
    out, q = _output_states(fn, x)
    if out is None:  # a jaxpr form the rules do not know: no zeros claimed
        return np.ones((_out_size(fn, x), q), bool)
    return out[..., :q].reshape(-1, q)


def structural_zeros(fn, x) -> np.ndarray:
    """Boolean ``(n,)``: ``True`` where ``fn(x)_i`` is exactly zero for every input.

    Same propagation as :func:`jacobian_pattern` (literal and constant zeros, ``jnp.zeros``
    padding, products with such an element, ...); a jaxpr the rules cannot read claims no
    zero.
    """
    out, q = _output_states(fn, x)
    if out is None:
        return np.zeros(_out_size(fn, x), bool)
    return out[..., q].reshape(-1)


def _out_size(fn, x) -> int:
    """Number of output elements of ``fn(x)``."""
    return sum(int(np.prod(o.shape)) for o in jax.tree.leaves(jax.eval_shape(fn, jax.numpy.asarray(x))))


def _output_states(fn, x):
    """The propagated state ``(*out shape, q + 1)`` of ``fn``'s single output and ``q``;
    ``(None, q)`` when a rule fails."""
    x = jax.numpy.asarray(x)
    closed = jax.make_jaxpr(fn)(x)
    q = x.size
    state_in = np.zeros(x.shape + (q + 1,), bool)
    state_in[..., :q] = np.eye(q, dtype=bool).reshape(x.shape + (q,))
    try:
        (out,) = interpret(closed.jaxpr, closed.consts, [state_in], _RULES, q)
    except Exception:
        return None, q
    return out, q


# A variable's state: bool array (*shape, q + 1); [..., :q] the inputs an element may
# depend on, [..., q] whether it is exactly zero for every input.

def _known(value, q):
    value = np.asarray(value)
    state = np.zeros(value.shape + (q + 1,), bool)
    state[..., q] = value == 0
    return state


def _shape(v):
    return tuple(getattr(v.aval, "shape", ()))


def _elementwise(name, ins, shape, q):
    full = [np.broadcast_to(st, shape + (q + 1,)) for st in ins]
    dep = np.zeros(shape + (q,), bool)
    for st in full:
        dep |= st[..., :q]
    zeros = [st[..., q] for st in full]
    if name == "mul":
        zero = np.logical_or.reduce(zeros)
    elif name == "div" or name in _ZERO_PRESERVING or (
            name == "integer_pow" and len(zeros) == 1):
        zero = zeros[0]
    elif name in ("add", "sub"):
        zero = np.logical_and.reduce(zeros)
    elif name == "select_n":
        zero = np.logical_and.reduce(zeros[1:])
    else:
        zero = np.zeros(shape, bool)
    out = np.concatenate([dep & ~zero[..., None], zero[..., None]], axis=-1)
    return out


# -- the rule table (state: q) --------------------------------------------------------------
# A rule is ``rule(q, i, eqn, ins) -> output states`` (see :class:`~.interpreter.Rules`).

def _dense(q, i, eqn, ins):
    """The safe default: every output element depends on everything any operand depends on."""
    union = np.zeros(q + 1, bool)
    for st in ins:
        union[:q] |= np.any(st[..., :q].reshape(-1, q), axis=0)
    return [np.broadcast_to(union, _shape(v) + (q + 1,)).copy() for v in eqn.outvars]


def _pointwise(q, i, eqn, ins):
    """An element-wise primitive (:data:`_ELEMENTWISE`) whose operands have its output's
    shape or are scalars; else :func:`_dense`."""
    if len(eqn.outvars) != 1:
        return _dense(q, i, eqn, ins)
    out = _shape(eqn.outvars[0])
    if not all(st.shape[:-1] in ((), out) for st in ins):
        return _dense(q, i, eqn, ins)
    name = eqn.primitive.name
    if name == "integer_pow" and eqn.params.get("y", 1) <= 0:
        name = "pow"                                       # x**-k: 0 is not kept
    return [_elementwise(name, ins, out, q)]


def _reshape(q, i, eqn, ins):
    if eqn.primitive.name == "reshape" and eqn.params.get("dimensions") is not None:
        return _dense(q, i, eqn, ins)
    return [ins[0].reshape(_shape(eqn.outvars[0]) + (q + 1,))]


def _broadcast_in_dim(q, i, eqn, ins):
    shape, src = _shape(eqn.outvars[0]), ins[0]
    kept = [1] * len(shape)
    for axis, d in enumerate(eqn.params["broadcast_dimensions"]):
        kept[d] = src.shape[axis]                  # 1 where a size-1 axis is broadcast
    return [np.broadcast_to(src.reshape(tuple(kept) + (q + 1,)), shape + (q + 1,)).copy()]


def _slice(q, i, eqn, ins):
    p = eqn.params
    idx = tuple(slice(s, e, st) for s, e, st in zip(
        p["start_indices"], p["limit_indices"], p["strides"] or (1,) * len(_shape(eqn.outvars[0]))))
    return [ins[0][idx]]


def _stack(q, i, eqn, ins):
    axis, out = eqn.params["axis"], _shape(eqn.outvars[0])
    part = out[:axis] + out[axis + 1:] + (q + 1,)
    return [np.stack([np.broadcast_to(st, part) for st in ins], axis=axis)]


def _call(q, i, eqn, ins):
    """A call: its sub-jaxpr, recursively (when its arguments and outputs match)."""
    body = call_body(eqn.params)
    if body is not None and len(body[0].invars) == len(ins):
        res = interpret(body[0], body[1], ins, _RULES, q)
        if [st.shape[:-1] for st in res] == [_shape(v) for v in eqn.outvars]:
            return res
    return _dense(q, i, eqn, ins)


_RULES = Rules({
    **{name: _pointwise for name in _ELEMENTWISE},
    "squeeze": _reshape,
    "reshape": _reshape,
    "broadcast_in_dim": _broadcast_in_dim,
    "slice": _slice,
    "concatenate": lambda q, i, eqn, ins: [np.concatenate(ins, axis=eqn.params["dimension"])],
    "stack": _stack,
    "split": lambda q, i, eqn, ins: list(np.split(ins[0], np.cumsum(eqn.params["sizes"])[:-1],
                                                  axis=eqn.params["axis"])),
    "rev": lambda q, i, eqn, ins: [np.flip(ins[0], axis=tuple(eqn.params["dimensions"]))],
    "transpose": lambda q, i, eqn, ins: [np.transpose(ins[0], tuple(eqn.params["permutation"])
                                                      + (len(_shape(eqn.outvars[0])),))],
}, default=_dense, calls=_call, literal=lambda q, value: _known(value, q))
