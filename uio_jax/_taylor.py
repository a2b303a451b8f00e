"""Univariate Taylor arithmetic on stacked coefficients: ``L_F^j psi`` in a small graph.

``jax.experimental.jet`` propagates a series as a Python list of terms, so its rule for a
product emits ``O(K^2)`` operations and the traced graph of a K-th order Taylor pass grows
like ``K^2`` times the function (and XLA compile time with it). Here a series is one array
``a`` of shape ``(K + 1, *shape)`` holding the *normalized* coefficients
``a[i] = x^(i)(0) / i!`` of ``x(t) = sum_i a[i] t^i``, and every rule acts on the whole
stack at once:

* linear and structural primitives (add, slice, concatenate, dot with a constant, ...):
  the primitive ``vmap``-ed over the coefficient axis;
* bilinear primitives (mul, dot_general): all pairwise products, then a Cauchy sum
  ``c[k] = sum_{i+j=k} a[i] b[j]`` by one ``einsum`` with a constant 0/1 tensor;
* div, sin/cos, exp, log, sqrt, integer powers: the classical recurrences
  (Griewank & Walther, "Evaluating Derivatives", 2nd ed., table 13.2), one short loop
  over k each.

Comparisons and other non-smooth primitives act on the order-0 coefficient only (their
outputs are constant along t for a generic state). A primitive without a rule raises
``NotImplementedError``; callers fall back to ``jax.experimental.jet`` or nested jvp.

Lie derivatives along a field F (``L_F^j psi (x) = d^j/dt^j psi(x(t))``, ``x' = F(x)``):
:func:`flow_series` builds the coefficients of the flow order by order,
``x[k+1] = F(x(t))[k] / (k + 1)``, and :func:`lie_powers` reads ``j! psi(x(t))[j]``.
"""

import math

import jax
import jax.numpy as jnp
from jax.extend import core as jcore

_LINEAR = {
    "neg", "slice", "squeeze", "reshape", "broadcast_in_dim", "concatenate", "transpose",
    "convert_element_type", "reduce_sum", "copy", "copy_p", "expand_dims", "rev", "pad",
    "add", "sub", "add_any", "dynamic_slice", "gather", "real", "imag", "cumsum",
    "select_n", "dynamic_update_slice", "reduce_precision", "stack", "split",
    "scatter", "scatter-add", "scatter_add", "tile", "repeat", "reduce_and_broadcast",
}
_BILINEAR = {"mul", "dot_general"}
_CONSTANT = {  # outputs treated as constant along t (evaluated on order 0)
    "lt", "le", "gt", "ge", "eq", "ne", "and", "or", "not", "sign", "floor", "ceil",
    "round", "is_finite", "stop_gradient", "iota", "argmax", "argmin",
}


class _S:
    """A series: ``c`` of shape ``(K + 1, *shape)``."""

    __slots__ = ("c",)

    def __init__(self, c):
        self.c = c


def _series(v, K):
    """Promote a constant to a series (value at order 0, zeros above)."""
    if isinstance(v, _S):
        return v
    v = jnp.asarray(v)
    return _S(jnp.concatenate([v[None], jnp.zeros((K,) + v.shape, v.dtype)]))


def _antidiagonal(P):
    """``c[k] = sum_{i+j=k} P[i, j]`` for ``P`` of shape ``(n, n, *e)``: ``(n, *e)``.

    Skew trick (O(n^2) work, five operations): pad the second axis to 2n, flatten, drop the
    last n entries and reshape to ``(n, 2n-1)``: entry ``(r, s)`` is ``P[r, s-r]``.
    """
    n, e = P.shape[0], P.shape[2:]
    Q = jnp.pad(P, [(0, 0), (0, n)] + [(0, 0)] * len(e)).reshape((2 * n * n,) + e)
    Q = Q[: 2 * n * n - n].reshape((n, 2 * n - 1) + e)
    return jnp.sum(Q, axis=0)[:n]


def _align(a, b):
    """Give two series element arrays of the same rank (leading singleton axes)."""
    ra, rb = a.c.ndim, b.c.ndim
    if ra < rb:
        a = _S(a.c.reshape(a.c.shape[:1] + (1,) * (rb - ra) + a.c.shape[1:]))
    elif rb < ra:
        b = _S(b.c.reshape(b.c.shape[:1] + (1,) * (ra - rb) + b.c.shape[1:]))
    return a, b


def _mul_series(a, b, K):
    a, b = _align(a, b)
    p = a.c.reshape((K + 1, 1) + a.c.shape[1:]) * b.c.reshape((1, K + 1) + b.c.shape[1:])
    return _S(_antidiagonal(p))


def _rev(cs):
    """``[c[k-1], ..., c[0]]`` stacked, from the list ``cs = [c[0], .., c[k-1]]``."""
    return jnp.stack(cs[::-1])


def _recip_div(a, b, K):
    """``c = a / b``: ``c[k] = (a[k] - sum_{i=1..k} b[i] c[k-i]) / b[0]``."""
    a, b = _align(a, b)
    b0 = b.c[0]
    cs = [a.c[0] / b0]
    for k in range(1, K + 1):
        acc = jnp.sum(b.c[1 : k + 1] * _rev(cs), axis=0)
        cs.append((a.c[k] - acc) / b0)
    return _S(jnp.stack(cs))


def _weighted(k, a, cs):
    """``sum_{i=1..k} i a[i] c[k-i]`` (the recurrence core of exp, sin, cos, log)."""
    w = jnp.arange(1, k + 1, dtype=a.dtype).reshape((k,) + (1,) * (a.ndim - 1))
    return jnp.sum(w * a[1 : k + 1] * _rev(cs[:k]), axis=0)


def _sincos(a, K):
    s, c = [jnp.sin(a.c[0])], [jnp.cos(a.c[0])]
    for k in range(1, K + 1):
        sk = _weighted(k, a.c, c) / k
        ck = -_weighted(k, a.c, s) / k
        s.append(sk)
        c.append(ck)
    return _S(jnp.stack(s)), _S(jnp.stack(c))


def _exp(a, K):
    e = [jnp.exp(a.c[0])]
    for k in range(1, K + 1):
        e.append(_weighted(k, a.c, e) / k)
    return _S(jnp.stack(e))


def _log(a, K):
    lg = [jnp.log(a.c[0])]
    for k in range(1, K + 1):
        # k l[k] a[0] = k a[k] - sum_{i=1}^{k-1} i l[i] a[k-i]
        if k > 1:
            w = jnp.arange(1, k, dtype=a.c.dtype).reshape((k - 1,) + (1,) * (a.c.ndim - 1))
            acc = jnp.sum(w * jnp.stack(lg[1:k]) * a.c[k - 1 : 0 : -1], axis=0)
        else:
            acc = 0.0
        lg.append((a.c[k] - acc / k) / a.c[0])
    return _S(jnp.stack(lg))


def _sqrt(a, K):
    s = [jnp.sqrt(a.c[0])]
    for k in range(1, K + 1):
        acc = jnp.sum(jnp.stack(s[1:k]) * _rev(s[1:k]), axis=0) if k > 1 else 0.0
        s.append((a.c[k] - acc) / (2 * s[0]))
    return _S(jnp.stack(s))


def _ipow(a, p, K):
    if p == 0:
        return _series(jnp.ones_like(a.c[0]), K)
    if p < 0:
        return _recip_div(_series(jnp.ones_like(a.c[0]), K), _ipow(a, -p, K), K)
    out, base = None, a
    while p:
        if p & 1:
            out = base if out is None else _mul_series(out, base, K)
        p >>= 1
        if p:
            base = _mul_series(base, base, K)
    return out


def _apply(prim, params, ins, K):
    name = prim.name
    if name in ("jit", "pjit", "closed_call", "core_call", "remat", "checkpoint", "custom_jvp_call",
                "custom_vjp_call", "custom_vjp_call_jaxpr"):
        sub = params.get("jaxpr") or params.get("call_jaxpr") or params.get("fun_jaxpr")
        if sub is None:
            raise NotImplementedError(f"no Taylor rule for {name}")
        closed = sub if hasattr(sub, "consts") else jcore.ClosedJaxpr(sub, ())
        return _eval(closed.jaxpr, closed.consts, ins, K)
    if not any(isinstance(v, _S) for v in ins) or name in _CONSTANT:
        vals = [v.c[0] if isinstance(v, _S) else v for v in ins]
        out = prim.bind(*vals, **params)
        return out if prim.multiple_results else [out]
    if name in _LINEAR:
        if name == "select_n":  # predicate constant along t
            pred = ins[0].c[0] if isinstance(ins[0], _S) else ins[0]
            cases = [_series(v, K).c for v in ins[1:]]
            return [_S(jax.vmap(lambda *cs: prim.bind(pred, *cs, **params))(*cases))]
        # indexing: indices constant along t, linear in the data operands
        data = {"dynamic_slice": (0,), "gather": (0,), "dynamic_update_slice": (0, 1),
                "scatter": (0, 2), "scatter-add": (0, 2), "scatter_add": (0, 2)}.get(name)
        if data is not None:
            if any(isinstance(v, _S) for i, v in enumerate(ins) if i not in data):
                raise NotImplementedError(f"no Taylor rule for {name} with moving indices")
            args = [_series(v, K).c if i in data else v for i, v in enumerate(ins)]
            axes = [0 if i in data else None for i in range(len(ins))]
            out = jax.vmap(lambda *a: prim.bind(*a, **params), in_axes=axes)(*args)
            return [_S(out)]
        cs = [_series(v, K).c for v in ins]
        out = jax.vmap(lambda *c: prim.bind(*c, **params))(*cs)
        return [_S(o) for o in out] if prim.multiple_results else [_S(out)]
    if name in _BILINEAR:
        a, b = ins
        if not isinstance(a, _S) or not isinstance(b, _S):  # linear in the series
            fixed, ser, first = (b, a, True) if isinstance(a, _S) else (a, b, False)
            f = (lambda c: prim.bind(c, fixed, **params)) if first else (
                lambda c: prim.bind(fixed, c, **params))
            return [_S(jax.vmap(f)(ser.c))]
        if name == "mul":
            return [_mul_series(a, b, K)]
        pair = jax.vmap(jax.vmap(lambda x, y: prim.bind(x, y, **params), (None, 0)), (0, None))
        return [_S(_antidiagonal(pair(a.c, b.c)))]
    a = ins[0] if isinstance(ins[0], _S) else _series(ins[0], K)
    if name == "div":
        return [_recip_div(_series(ins[0], K), _series(ins[1], K), K)]
    if name == "integer_pow":
        return [_ipow(a, params["y"], K)]
    if name == "square":
        return [_mul_series(a, a, K)]
    if name == "sin":
        return [_sincos(a, K)[0]]
    if name == "cos":
        return [_sincos(a, K)[1]]
    if name == "tan":
        s, c = _sincos(a, K)
        return [_recip_div(s, c, K)]
    if name == "exp":
        return [_exp(a, K)]
    if name == "log":
        return [_log(a, K)]
    if name == "sqrt":
        return [_sqrt(a, K)]
    if name == "rsqrt":
        return [_recip_div(_series(jnp.ones_like(a.c[0]), K), _sqrt(a, K), K)]
    if name == "pow" and not isinstance(ins[1], _S):
        return [_exp(_mul_series(_log(a, K), _series(ins[1], K), K), K)]
    if name == "abs":
        return [_S(jnp.sign(a.c[0]) * a.c)]
    if name in ("max", "min"):
        a, b = _align(a, _series(ins[1], K))
        pick = (a.c[0] >= b.c[0]) if name == "max" else (a.c[0] <= b.c[0])
        return [_S(jnp.where(pick, a.c, b.c))]
    raise NotImplementedError(f"no Taylor rule for {name}")


def _eval(jaxpr, consts, args, K):
    env = {}

    def read(v):
        return v.val if isinstance(v, jcore.Literal) else env[v]

    for v, c in zip(jaxpr.constvars, consts):
        env[v] = c
    for v, a in zip(jaxpr.invars, args):
        env[v] = a
    for eqn in jaxpr.eqns:
        outs = _apply(eqn.primitive, eqn.params, [read(v) for v in eqn.invars], K)
        for v, o in zip(eqn.outvars, outs):
            env[v] = o
    return [read(v) for v in jaxpr.outvars]


def taylor(fn, x, coeffs):
    """Normalized Taylor coefficients of ``fn(x(t))``.

    Args:
        fn: ``(N,) -> output`` traceable function.
        x: ``(N,)`` the point (order 0).
        coeffs: ``(K, N)`` normalized coefficients of orders 1..K of ``x(t)``.

    Returns:
        ``(K + 1, *out_shape)`` normalized coefficients of ``fn(x(t))``.
    """
    K = coeffs.shape[0]
    closed = jax.make_jaxpr(fn)(x)
    series = _S(jnp.concatenate([x[None], coeffs]))
    (out,) = _eval(closed.jaxpr, closed.consts, [series], K)
    return _series(out, K).c


def flow_series(F, x, K):
    """Normalized coefficients ``(K, N)`` of orders 1..K of the flow of ``F`` from ``x``.

    ``x[k+1] = F(x(t))[k] / (k + 1)``: pass k runs F on the series truncated at order k
    (all that ``F(x(t))[k]`` depends on).
    """
    coeffs = []
    for k in range(K):
        known = jnp.stack(coeffs) if coeffs else jnp.zeros((0,) + x.shape, x.dtype)
        coeffs.append(taylor(F, x, known)[k] / (k + 1))
    return jnp.stack(coeffs)


def lie_powers(psi, F, j):
    """``x -> [L_F^0 psi, ..., L_F^j psi](x)`` (shape ``(j + 1,)``) in one Taylor pass."""

    def powers(x):
        c = taylor(psi, x, flow_series(F, x, j))
        fact = jnp.asarray([math.factorial(i) for i in range(j + 1)], c.dtype)
        return c * fact

    return powers


__all__ = ["taylor", "flow_series", "lie_powers"]
