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
  Python loop over k would trace ``O(K^2)`` of them). Integer powers: repeated squaring;
* the other elementary functions (atan2, atan, asin, acos, tanh, sinh, cosh, asinh, acosh,
  atanh, logistic, log1p, expm1, exp2, erf, erfc, cbrt, real powers): the recipes of
  :mod:`uio_jax._engine.elementary` over these blocks, shared with the Taylor flow;
  ``clamp``, ``reduce_max`` / ``reduce_min`` and ``rem`` pick or shift by the order-0 values.

Comparisons and other non-smooth primitives act on the order-0 coefficient only (their
outputs are constant along t for a generic state). The walk over the jaxpr is
:func:`uio_jax._engine.interpreter.interpret` with this module's rule table (one rule per
primitive, its state the order K); a primitive without a rule raises
:class:`~uio_jax._engine.interpreter.NoTaylorRule` (a ``NotImplementedError``), which
callers with another route (``jax.experimental.jet``, nested jvp) catch.

Lie derivatives along a field F (``L_F^j psi (x) = d^j/dt^j psi(x(t))``, ``x' = F(x)``):
:func:`flow_series` builds the coefficients of the flow order by order,
``x[k+1] = F(x(t))[k] / (k + 1)``, and :func:`lie_powers` reads ``j! psi(x(t))[j]``.
"""

import math

import jax
import jax.numpy as jnp

from .elementary import ELEMENTARY, extreme_mask, ranked, rem_quotient
from .interpreter import CONSTANT, DATA_OPERANDS, LINEAR, NoTaylorRule, Rules, inline, interpret


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


# -- the building blocks of the elementary functions (:mod:`.elementary`) -----------------

class _Blocks:
    """The building blocks of :data:`~uio_jax._engine.elementary.ELEMENTARY` on whole stacks
    (state: K)."""

    def __init__(self, K, moving):
        self.K, self.moving = K, moving

    def mul(self, a, b):
        return _mul_series(_S(a), _S(b), self.K).c

    def div(self, a, b):
        return _recip_div(_S(a), _S(b), self.K).c

    def exp(self, a):
        return _exp_coeffs(a, self.K)

    def log(self, a):
        return _log(_S(a), self.K).c

    def sqrt(self, a):
        return _sqrt(_S(a), self.K).c

    def integral(self, pairs):
        """``y[0] = 0``, ``k y[k] = sum_(g, u) (g * (j u[j]))[k]`` (Cauchy products)."""
        v = sum(self.mul(g, _orders(self.K, u) * u) for g, u in pairs)
        return jnp.concatenate([jnp.zeros_like(v[:1]), v[1:] / _orders(self.K, v)[1:]])


# -- the rule table (state: K) -------------------------------------------------------------
# A rule of the table is ``rule(K, i, eqn, ins)`` (see :class:`~.interpreter.Rules`); the
# Taylor rules proper are ``rule(prim, params, ins, K)``, applied by :func:`_on_series`
# when an operand is a series.

def _plain(K, i, eqn, ins):
    """Constant along t (no series operand, or a piecewise constant primitive): the
    primitive on the order-0 values."""
    prim = eqn.primitive
    out = prim.bind(*[v.c[0] if isinstance(v, _S) else v for v in ins], **eqn.params)
    return out if prim.multiple_results else [out]


def _on_series(rule):
    """The table rule of a Taylor rule: ``rule`` when an operand is a series, else
    :func:`_plain`."""
    def apply(K, i, eqn, ins):
        for v in ins:
            if isinstance(v, _S):
                return rule(eqn.primitive, eqn.params, ins, K)
        return _plain(K, i, eqn, ins)

    return apply


def _call(K, i, eqn, ins):
    """A call primitive: its sub-jaxpr, inline."""
    out = inline(_RULES, K, eqn, ins)
    if out is None:
        raise NoTaylorRule(eqn.primitive.name)
    return out


def _missing(prim, params, ins, K):
    raise NoTaylorRule(prim.name)


def _linear(prim, params, ins, K):
    """Linear and structural primitives: vmapped over the coefficient axis."""
    cs = [_series(v, K).c for v in ins]
    out = jax.vmap(lambda *c: prim.bind(*c, **params))(*cs)
    return [_S(o) for o in out] if prim.multiple_results else [_S(out)]


def _select(prim, params, ins, K):
    """``select_n``: the predicate constant along t, linear in the cases."""
    pred = ins[0].c[0] if isinstance(ins[0], _S) else ins[0]
    cases = [_series(v, K).c for v in ins[1:]]
    return [_S(jax.vmap(lambda *cs: prim.bind(pred, *cs, **params))(*cases))]


def _indexing(prim, params, ins, K):
    """Indexing: indices constant along t, linear in the data operands."""
    data = DATA_OPERANDS[prim.name]
    if any(isinstance(v, _S) for i, v in enumerate(ins) if i not in data):
        raise NoTaylorRule(prim.name, " with moving indices")
    args = [_series(v, K).c if i in data else v for i, v in enumerate(ins)]
    axes = [0 if i in data else None for i in range(len(ins))]
    out = jax.vmap(lambda *a: prim.bind(*a, **params), in_axes=axes)(*args)
    return [_S(out)]


def _bilinear(prim, params, ins, K):
    """``mul``, ``dot_general``: linear with a constant operand, else a Cauchy product."""
    a, b = ins
    if not isinstance(a, _S) or not isinstance(b, _S):  # linear in the series
        fixed, ser, first = (b, a, True) if isinstance(a, _S) else (a, b, False)
        f = (lambda c: prim.bind(c, fixed, **params)) if first else (
            lambda c: prim.bind(fixed, c, **params))
        return [_S(jax.vmap(f)(ser.c))]
    if prim.name == "mul":
        return [_mul_series(a, b, K)]
    pair = jax.vmap(jax.vmap(lambda x, y: prim.bind(x, y, **params), (None, 0)), (0, None))
    return [_S(_antidiagonal(pair(a.c, b.c)))]


def _div(prim, params, ins, K):
    """``a / b``: linear in the numerator for a constant ``b``, else a Toeplitz solve."""
    if not isinstance(ins[1], _S):
        return [_S(jax.vmap(lambda c: prim.bind(c, ins[1], **params))(ins[0].c))]
    return [_recip_div(_series(ins[0], K), ins[1], K)]


def _elementary(prim, params, ins, K):
    """A primitive of :data:`~uio_jax._engine.elementary.ELEMENTARY`: its recipe on the
    operands' stacks, order 0 the primitive on the order-0 values."""
    v0 = prim.bind(*[v.c[0] if isinstance(v, _S) else v for v in ins], **params)
    stacks = ranked([_series(v, K).c for v in ins])
    out = ELEMENTARY[prim.name](_Blocks(K, tuple(isinstance(v, _S) for v in ins)), *stacks)
    return [_S(jnp.broadcast_to(out, (K + 1,) + v0.shape).astype(v0.dtype).at[0].set(v0))]


def _max_min(prim, params, ins, K):
    a, b = _align(_series(ins[0], K), _series(ins[1], K))
    pick = (a.c[0] >= b.c[0]) if prim.name == "max" else (a.c[0] <= b.c[0])
    return [_S(jnp.where(pick, a.c, b.c))]


def _clamp(prim, params, ins, K):
    """``clamp(lo, x, hi)``: the operand the order-0 values pick."""
    lo, x, hi = ranked([_series(v, K).c for v in ins])
    return [_S(jnp.where(x[0] < lo[0], lo, jnp.where(x[0] > hi[0], hi, x)))]


def _reduce_max_min(prim, params, ins, K):
    """``reduce_max`` / ``reduce_min``: the elements extreme at order 0 (their mean on ties)."""
    a = ins[0].c
    pick = extreme_mask(prim, params, a[0])
    return [_S(jax.vmap(lambda c: jnp.sum(jnp.where(pick, c, 0), axis=params["axes"]))(a)
               / jnp.sum(pick, axis=params["axes"]))]


def _rem(prim, params, ins, K):
    """``rem(a, b) = a - q b``, the integer quotient ``q`` constant along t."""
    a, b = ranked([_series(v, K).c for v in ins])
    return [_S(a - rem_quotient(a[0], b[0]) * b)]


def _tan(a, K):
    s, c = _sincos(a, K)
    return _recip_div(s, c, K)


def _unary(f):
    """A rule from ``f(a, K) -> series`` of the first operand's series ``a``."""
    return lambda prim, params, ins, K: [f(_series(ins[0], K), K)]


_RULES = Rules({
    **{name: _on_series(_linear) for name in LINEAR},
    "select_n": _on_series(_select),
    **{name: _on_series(_indexing) for name in DATA_OPERANDS},
    **{name: _plain for name in CONSTANT},
    "mul": _on_series(_bilinear),
    "dot_general": _on_series(_bilinear),
    "div": _on_series(_div),
    **{name: _on_series(_elementary) for name in ELEMENTARY},
    "max": _on_series(_max_min),
    "min": _on_series(_max_min),
    "clamp": _on_series(_clamp),
    "reduce_max": _on_series(_reduce_max_min),
    "reduce_min": _on_series(_reduce_max_min),
    "rem": _on_series(_rem),
    "integer_pow": _on_series(lambda prim, params, ins, K: [_ipow(_series(ins[0], K), params["y"], K)]),
    "square": _on_series(_unary(lambda a, K: _mul_series(a, a, K))),
    "sin": _on_series(_unary(lambda a, K: _sincos(a, K)[0])),
    "cos": _on_series(_unary(lambda a, K: _sincos(a, K)[1])),
    "tan": _on_series(_unary(_tan)),
    "exp": _on_series(_unary(_exp)),
    "log": _on_series(_unary(_log)),
    "sqrt": _on_series(_unary(_sqrt)),
    "rsqrt": _on_series(_unary(lambda a, K: _exp(_S(-0.5 * _log(a, K).c), K))),
    "abs": _on_series(_unary(lambda a, K: _S(jnp.sign(a.c[0]) * a.c))),
}, default=_on_series(_missing), calls=_call)


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
    (out,) = interpret(closed.jaxpr, closed.consts, [series], _RULES, K)
    return _series(out, K).c


def flow_series(F, x, K):
    """Normalized coefficients ``(K, N)`` of orders 1..K of the flow of ``F`` from ``x``.

    The solution of ``x' = F(x)``, ``x(0) = x`` is ``x(t) = sum_k x[k] t^k`` with
    ``x[k+1] = F(x(t))[k] / (k + 1)``: pass k runs :func:`taylor` of F on the series
    truncated at order k (all that ``F(x(t))[k]`` depends on), ``K`` passes in all.

    Args:
        F: ``(N,) -> (N,)`` traceable vector field.
        x: ``(N,)`` initial state.
        K: highest order (an int >= 1).
    """
    coeffs = []
    for k in range(K):
        known = jnp.stack(coeffs) if coeffs else jnp.zeros((0,) + x.shape, x.dtype)
        coeffs.append(taylor(F, x, known)[k] / (k + 1))
    return jnp.stack(coeffs)


def lie_powers(psi, F, j):
    """``x -> [L_F^0 psi, ..., L_F^j psi](x)``, the Lie derivatives in one Taylor pass.

    ``L_F^i psi (x) = d^i/dt^i psi(x(t))`` at ``t = 0`` along ``x' = F(x)``, ``x(0) = x``:
    ``i!`` times the order-i coefficient of :func:`taylor` of ``psi`` on the flow's
    coefficients (:func:`flow_series`).

    Args:
        psi: ``(N,) -> out_shape`` traceable function.
        F: ``(N,) -> (N,)`` traceable vector field.
        j: highest order (an int >= 0).

    Returns:
        a function ``(N,) -> (j + 1, *out_shape)``.
    """

    def powers(x):
        c = taylor(psi, x, flow_series(F, x, j))
        fact = jnp.asarray([math.factorial(i) for i in range(j + 1)], c.dtype)
        return c * fact

    return powers


__all__ = ["taylor", "flow_series", "lie_powers", "NoTaylorRule"]
