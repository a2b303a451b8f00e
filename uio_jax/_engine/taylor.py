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
* div, exp, log (and from them sin/cos through ``exp(i a)``, sqrt, pow): the classical
  recurrences (Griewank & Walther, "Evaluating Derivatives", 2nd ed., table 13.2) are
  lower-triangular Toeplitz systems in the unknown coefficients, solved by one forward
  substitution loop each: a handful of traced primitives per operation whatever K is (a
  Python loop over k would trace ``O(K^2)`` of them). Integer powers: repeated squaring.

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

LINEAR = {
    "neg", "slice", "squeeze", "reshape", "broadcast_in_dim", "concatenate", "transpose",
    "convert_element_type", "reduce_sum", "copy", "copy_p", "expand_dims", "rev", "pad",
    "add", "sub", "add_any", "dynamic_slice", "gather", "real", "imag", "cumsum",
    "select_n", "dynamic_update_slice", "reduce_precision", "stack", "split",
    "scatter", "scatter-add", "scatter_add", "tile", "repeat", "reduce_and_broadcast",
}
BILINEAR = {"mul", "dot_general"}
#: indexing primitives: their data operands (the others are indices, constant along t)
DATA_OPERANDS = {"dynamic_slice": (0,), "gather": (0,), "dynamic_update_slice": (0, 1),
                 "scatter": (0, 2), "scatter-add": (0, 2), "scatter_add": (0, 2)}
#: call-like primitives: their sub-jaxpr is evaluated inline
CALLS = ("jit", "pjit", "closed_call", "core_call", "remat", "checkpoint", "custom_jvp_call",
         "custom_vjp_call", "custom_vjp_call_jaxpr")


def call_body(params):
    """``(jaxpr, consts)`` of the sub-jaxpr of a call-like primitive (:data:`CALLS`), or
    None when its parameters hold none."""
    sub = params.get("jaxpr") or params.get("call_jaxpr") or params.get("fun_jaxpr")
    if sub is None:
        return None
    return (sub.jaxpr, sub.consts) if hasattr(sub, "consts") else (sub, ())


CONSTANT = {  # outputs treated as constant along t (evaluated on order 0)
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


#: Series of at most this many coefficients are solved by unrolled substitution (a graph
#: quadratic in the length, fast to run); longer ones by a loop (a graph independent of it).
UNROLL_MAX = 8


def _solve_toeplitz(b, rhs, diag=None):
    """Solve ``T x = rhs`` for the lower-triangular Toeplitz ``T[k, j] = b[k - j]`` (``j <= k``).

    ``T`` is the matrix of "Cauchy product with the series ``b``"; ``diag`` (``n`` numbers),
    if given, replaces its diagonal. ``b``, ``rhs``: stacks ``(n, *e)`` (``b`` may
    broadcast). Forward substitution: unrolled up to :data:`UNROLL_MAX` rows, else one
    ``fori_loop`` over the rows (row k of T is a window of the reversed, zero-padded ``b``,
    so memory stays ``O(n)`` per element and the loop body is traced once).
    """
    n = rhs.shape[0]
    shape = jnp.broadcast_shapes(b.shape, rhs.shape)
    dtype = jnp.result_type(b, rhs)
    b = jnp.broadcast_to(b, shape).astype(dtype)
    rhs = jnp.broadcast_to(rhs, shape).astype(dtype)
    if n <= UNROLL_MAX:  # short series: unrolled substitution, XLA fuses it (faster to run)
        xs = []
        for k in range(n):
            lower = jnp.sum(b[k:0:-1] * jnp.stack(xs), axis=0) if k else 0.0
            dk = b[0] if diag is None else jnp.asarray(diag[k], dtype)
            xs.append((rhs[k] - lower) / dk)
        return jnp.stack(xs)
    rev = jnp.flip(jnp.concatenate([jnp.zeros((n - 1,) + shape[1:], dtype), b]), axis=0)  # rev[n-1-k+j] = b[k-j]
    d = b[0] if diag is None else None

    def row(k, x):  # x[j] = 0 for j >= k
        window = jax.lax.dynamic_slice_in_dim(rev, n - 1 - k, n)
        lower = jnp.sum(window * x, axis=0)  # sum_{j < k} b[k - j] x[j]
        dk = d if diag is None else jax.lax.dynamic_index_in_dim(jnp.asarray(diag, dtype), k, keepdims=False)
        rk = jax.lax.dynamic_index_in_dim(rhs, k, keepdims=False)
        return jax.lax.dynamic_update_index_in_dim(x, (rk - lower) / dk, k, 0)

    return jax.lax.fori_loop(0, n, row, jnp.zeros(shape, dtype))


def _recip_div(a, b, K):
    """``c = a / b``: ``b c = a`` is the triangular Toeplitz system ``T(b) c = a``."""
    a, b = _align(a, b)
    return _S(_solve_toeplitz(b.c, a.c))


def _orders(K, like):
    """``[0, 1, .., K]`` shaped to broadcast against a stack like ``like``."""
    return jnp.arange(K + 1, dtype=like.dtype).reshape((K + 1,) + (1,) * (like.ndim - 1))


def _exp_coeffs(a, K):
    """``e = exp(a)`` from ``e' = a' e``: ``k e[k] - sum_{j<k} (k - j) a[k - j] e[j] = 0``,
    ``e[0] = exp(a[0])``: one triangular Toeplitz solve (``a`` real or complex)."""
    rhs = jnp.zeros_like(a).at[0].set(jnp.exp(a[0]))
    diag = [max(k, 1) for k in range(K + 1)]
    return _solve_toeplitz(-_orders(K, a) * a, rhs, diag)


def _sincos(a, K):
    z = _exp_coeffs(1j * a.c.astype(jnp.result_type(a.c.dtype, jnp.complex64)), K)
    return _S(jnp.imag(z)), _S(jnp.real(z))


def _exp(a, K):
    return _S(_exp_coeffs(a.c, K))


def _log(a, K):
    """``l = log(a)`` from ``a l' = a'``: ``T(a) v = k a[k]`` for ``v[k] = k l[k]``."""
    ks = _orders(K, a.c)
    v = _solve_toeplitz(a.c, ks * a.c)
    return _S(jnp.concatenate([jnp.log(a.c[:1]), v[1:] / ks[1:]]))


def _sqrt(a, K):
    return _exp(_S(0.5 * _log(a, K).c), K)


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
    if name in CALLS:
        body = call_body(params)
        if body is None:
            raise NotImplementedError(f"no Taylor rule for {name}")
        return _eval(*body, ins, K)
    if not any(isinstance(v, _S) for v in ins) or name in CONSTANT:
        vals = [v.c[0] if isinstance(v, _S) else v for v in ins]
        out = prim.bind(*vals, **params)
        return out if prim.multiple_results else [out]
    if name in LINEAR:
        if name == "select_n":  # predicate constant along t
            pred = ins[0].c[0] if isinstance(ins[0], _S) else ins[0]
            cases = [_series(v, K).c for v in ins[1:]]
            return [_S(jax.vmap(lambda *cs: prim.bind(pred, *cs, **params))(*cases))]
        # indexing: indices constant along t, linear in the data operands
        data = DATA_OPERANDS.get(name)
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
    if name in BILINEAR:
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
        if not isinstance(ins[1], _S):  # linear in the numerator
            return [_S(jax.vmap(lambda c: prim.bind(c, ins[1], **params))(ins[0].c))]
        return [_recip_div(_series(ins[0], K), ins[1], K)]
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
        return [_exp(_S(-0.5 * _log(a, K).c), K)]
    if name == "pow":  # a ** b = exp(b log a), base and exponent either constant or moving
        return [_exp(_mul_series(_log(_series(ins[0], K), K), _series(ins[1], K), K), K)]
    if name == "abs":
        return [_S(jnp.sign(a.c[0]) * a.c)]
    if name in ("max", "min"):
        a, b = _align(a, _series(ins[1], K))
        pick = (a.c[0] >= b.c[0]) if name == "max" else (a.c[0] <= b.c[0])
        return [_S(jnp.where(pick, a.c, b.c))]
    raise NotImplementedError(f"no Taylor rule for {name}")


def interpret(jaxpr, consts, args, apply):
    """Run a jaxpr with ``apply(i, eqn, input values) -> output values`` per equation ``i``."""
    env = {}

    def read(v):
        return v.val if isinstance(v, jcore.Literal) else env[v]

    for v, c in zip(jaxpr.constvars, consts):
        env[v] = c
    for v, a in zip(jaxpr.invars, args):
        env[v] = a
    for i, eqn in enumerate(jaxpr.eqns):
        outs = apply(i, eqn, [read(v) for v in eqn.invars])
        for v, o in zip(eqn.outvars, outs):
            env[v] = o
    return [read(v) for v in jaxpr.outvars]


def _eval(jaxpr, consts, args, K):
    return interpret(jaxpr, consts, args, lambda i, eqn, ins: _apply(eqn.primitive, eqn.params, ins, K))


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
