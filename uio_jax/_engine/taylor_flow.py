"""Taylor coefficients of an ODE flow by the coefficient recurrence: ``O(K^2)`` per operation.

:func:`uio_jax._engine.taylor.flow_series` finds the coefficients of ``x' = F(x)`` by running
F's whole series graph ``K`` times (pass k reads order k of ``F(x(t))``): every product
costs ``O(K^2)`` per pass, ``O(K^3)`` in all. The classical automatic Taylor method (Moore;
Griewank & Walther, "Evaluating Derivatives", 2nd ed., section 13.2; the "Taylor
integrators" of celestial mechanics) instead keeps the coefficient stack of every
intermediate quantity of F and, at order k, computes only its order-k coefficient from the
lower ones:

* linear operations: ``c[k] = op(a[k], b[k])`` (``O(1)``: on the order-k coefficients
  only, constants of additive positions entering at order 0);
* product ``c = a b``: ``c[k] = sum_{i <= k} a[i] b[k - i]`` (``O(K)``);
* quotient ``c = a / b``: ``c[k] = (a[k] - sum_{i < k} b[k - i] c[i]) / b[0]``;
* ``e = exp(a)``: ``e[k] = (1/k) sum_{i < k} (k - i) a[k - i] e[i]``;
* ``l = log(a)``: ``l[k] = (a[k] - (1/k) sum_{0 < i < k} i l[i] a[k - i]) / a[0]``;
* ``r = sqrt(a)``: ``r[k] = (a[k] - sum_{0 < i < k} r[i] r[k - i]) / (2 r[0])``;
* sin / cos through the complex exponential, integer powers by repeated squaring, all
  with intermediate stacks of their own;
* ``y' = g u'`` for a known derivative series ``g``:
  ``y[k] = (1/k) sum_{1 <= j <= k} j u[j] g[k - j]`` (:meth:`_Pass.integral`);
* the other elementary functions (atan2, atan, asin, acos, tanh, sinh, cosh, asinh, acosh,
  atanh, logistic, log1p, expm1, exp2, erf, erfc, cbrt, real powers): the recipes of
  :mod:`uio_jax._engine.elementary` over these blocks, shared with
  :mod:`uio_jax._engine.taylor`.

The stacks of the nonlinear results are the ``fori_loop`` carry (one array
``(K + 1, *shape)`` each, orders above k still zero), and so are the stacks of the linear
results that a nonlinear rule (or an order-0 decision) reads: a linear result is its
order-k coefficient only, its stack made on demand. F's graph is traced once, and the
whole flow costs ``O(K^2)`` per nonlinear operation and ``O(K)`` per linear one, instead
of ``O(K^3)``. Known series can enter F as extra arguments (e.g. the coefficients of a
known input ``u(t)``): their stacks are given in full from the start, and causality (order
k of a result reads orders ``<= k`` of its arguments only) keeps every rule exact.

Comparisons and other non-smooth operations act on the order-0 coefficients (constant
along t at a generic state), as in :mod:`uio_jax._engine.taylor`. The walk over F's jaxpr is
:func:`uio_jax._engine.interpreter.interpret` with this module's rule table, its state the
pass and the key prefix of the enclosing calls (the carried stacks are named by the path of
their equation); an operation without a rule raises
:class:`~uio_jax._engine.interpreter.NoTaylorRule` (a ``NotImplementedError``).

Constant states. A state whose derivative is a structural zero of F (a parameter joined
as a state with ``p' = 0``, see :meth:`uio_jax.System.joint`) keeps its order-0 value along
the flow. The state stack carries a mask of those elements through F's indexing
(``slice``, ``squeeze``, ``concatenate``, ...): an element, or a whole array, picked out of
constant elements only is an ordinary value again, not a series. A product of a parameter
and a series is then the linear rule (one multiplication per coefficient) instead of a
Cauchy product, and parameter-only subexpressions (``g**a``) are evaluated once.
"""

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .elementary import ELEMENTARY, extreme_mask, ranked, rem_quotient
from .interpreter import BILINEAR, CONSTANT, DATA_OPERANDS, LINEAR, NoTaylorRule, Rules, bind, call_body, interpret
from .sparsity import structural_zeros

#: indexing and reshaping primitives that move elements without combining them: a mask of
#: constant elements moves with them (operands other than the data, e.g. gather indices,
#: must be concrete)
_MOVING = {"slice", "squeeze", "reshape", "broadcast_in_dim", "concatenate", "transpose", "rev",
           "copy", "copy_p", "expand_dims", "dynamic_slice", "gather", "convert_element_type"}


class _T:
    """A series during pass k of the recurrence.

    ``ck``: its order-k coefficient (element shape). ``stack``: its coefficients
    ``(K + 1, *shape)`` (orders above k still zero) when carried (nonlinear results, the
    state, known series), else None: a result of linear operations, whose stack is made
    (carried under ``key``) only if a nonlinear rule or an order-0 decision reads it.
    ``const``: bool mask (element shape) of elements constant along t, or None.
    ``c0``: order-0 value, kept through element-moving operations of the state (so that
    constant elements picked out of it need no stack).
    """

    __slots__ = ("ck", "stack", "key", "const", "c0")

    def __init__(self, ck, stack=None, key=None, const=None, c0=None):
        self.ck, self.stack, self.key, self.const, self.c0 = ck, stack, key, const, c0


def _moved(ps, key, prim, params, ins):
    """An element-moving primitive where constant elements are tracked: outputs whose
    elements are all constant are plain values, others series with their mask; None when
    no operand carries that information (the ordinary rules apply)."""
    data = DATA_OPERANDS.get(prim.name, range(len(ins)))
    series = [isinstance(ins[i], _T) for i in data]
    tracked = [isinstance(ins[i], _T) and ins[i].c0 is not None for i in data]
    if not any(tracked) and (all(series) or not any(series)):
        return None  # no order-0 values to move (e.g. a product of two moving quantities)
    masks, c0s = [], []
    for i, v in enumerate(ins):
        if i not in data:
            if isinstance(v, (_T, jax.core.Tracer)):
                return None  # indices not known while tracing: no mask
            masks.append(v)
            c0s.append(v)
        elif isinstance(v, _T):
            masks.append(np.zeros(v.ck.shape, bool) if v.const is None else v.const)
            c0s.append(ps.order0(v))
        else:
            masks.append(np.ones(np.shape(v), bool))
            c0s.append(v)
    with jax.ensure_compile_time_eval():
        if prim.name == "convert_element_type":
            out = [masks[0]]
        else:
            out = prim.bind(*masks, **params)
            out = list(out) if prim.multiple_results else [out]
    out = [np.asarray(m, bool) for m in out]
    c0 = prim.bind(*c0s, **params)
    c0 = list(c0) if prim.multiple_results else [c0]
    if all(m.all() for m in out):  # constant: the order-0 values
        return c0
    res = _linear(ps, key, prim, params, ins)
    return [_T(r.ck, key=r.key, const=m if m.any() else None, c0=v0) for r, m, v0 in zip(res, out, c0)]


def _linear(ps, key, prim, params, ins):
    """A primitive linear in its series operands, at order k: ``c[k] = op(a[k], b[k])``
    with constants of additive positions lifted (their value at order 0, zero above) and
    constant factors, indices and predicates used as they are."""
    name = prim.name
    if name == "select_n":  # predicate constant along t
        args = [ps.order0(ins[0])] + [ps.at(v) for v in ins[1:]]
    elif name in DATA_OPERANDS:  # indices constant along t, not lifted
        data = DATA_OPERANDS[name]
        if any(isinstance(v, _T) for i, v in enumerate(ins) if i not in data):
            raise NoTaylorRule(name, " with moving indices")
        args = [ps.at(v) if i in data else v for i, v in enumerate(ins)]
    elif name in BILINEAR or name == "div":  # one series operand, the other a constant factor
        args = [v.ck if isinstance(v, _T) else v for v in ins]
    else:
        args = [ps.at(v) for v in ins]
    out = prim.bind(*args, **params)
    outs = out if prim.multiple_results else [out]
    return [_T(o, key=key + (j,)) for j, o in enumerate(outs)]


class _Pass:
    """One order k of the recurrence: reads the carried stacks, writes their order k."""

    def __init__(self, k, K, state):
        self.k, self.K = k, K
        self.old = state
        self.new = {}

    # -- helpers on stacks -------------------------------------------------------------
    def lift(self, v):
        """A series' stack, or a constant as a series: value at order 0, zeros above."""
        if isinstance(v, _T):
            return self.stack(v)
        v = jnp.asarray(v)
        return jnp.concatenate([v[None], jnp.zeros((self.K,) + v.shape, v.dtype)])

    def at_k(self, c):
        return lax.dynamic_index_in_dim(c, self.k, keepdims=False)

    def stack(self, v):
        """The coefficient stack of a series value (made and carried if not yet)."""
        if v.stack is None:
            v.stack = self.slot(v.key + ("lin",), lambda own: v.ck, v.ck.shape, v.ck.dtype)
        return v.stack

    def order0(self, v):
        """Order-0 value of a series or constant."""
        if not isinstance(v, _T):
            return v
        return v.c0 if v.c0 is not None else self.stack(v)[0]

    def at(self, v):
        """Order-k coefficient of a series, or of a constant (its value at order 0, else 0)."""
        if isinstance(v, _T):
            return v.ck
        v = jnp.asarray(v)
        if isinstance(self.k, int):
            return v if self.k == 0 else jnp.zeros_like(v)
        return jnp.where(self.k == 0, v, jnp.zeros_like(v))

    def series(self, stack):
        """A nonlinear result: its stack, with order k read from it."""
        return _T(self.at_k(stack), stack=stack)

    def conv(self, a, b):
        """``sum_{i <= k} a[i] b[k - i]`` for stacks ``a``, ``b`` (broadcasting elements)."""
        ra, rb = a.ndim, b.ndim
        if ra < rb:
            a = a.reshape(a.shape[:1] + (1,) * (rb - ra) + a.shape[1:])
        elif rb < ra:
            b = b.reshape(b.shape[:1] + (1,) * (ra - rb) + b.shape[1:])
        if isinstance(self.k, int):  # concrete order: a static slice
            w = jnp.flip(b[: self.k + 1], axis=0)
            return jnp.sum(a[: self.k + 1] * w, axis=0)
        return jnp.sum(a * self.window(b), axis=0)

    def window(self, b):
        """``w[i] = b[k - i]`` for ``i <= k``, 0 above: a window of the reversed, zero-padded b."""
        K = self.K
        rev = jnp.flip(jnp.concatenate([jnp.zeros((K,) + b.shape[1:], b.dtype), b]), axis=0)
        return lax.dynamic_slice_in_dim(rev, K - self.k, K + 1)

    def slot(self, key, coef_fn, shape, dtype):
        """The stack named ``key`` with its order-k coefficient ``coef_fn(own)`` written."""
        key = "/".join(map(str, key))  # pytree dict keys must sort
        own = self.old.get(key)
        if own is None:
            own = jnp.zeros((self.K + 1,) + tuple(shape), dtype)
        ck = jnp.asarray(coef_fn(own), dtype)
        ck = jnp.broadcast_to(ck, tuple(shape))
        if isinstance(self.k, int):
            c = own.at[self.k].set(ck)
        else:
            c = lax.dynamic_update_index_in_dim(own, ck, self.k, 0)
        self.new[key] = c
        return c

    def orders(self, like):
        K = self.K
        return jnp.arange(K + 1, dtype=like.real.dtype).reshape((K + 1,) + (1,) * (like.ndim - 1))

    def kk(self, dtype):
        return jnp.asarray(self.k, dtype)

    # -- nonlinear rules (each returns a stack) ------------------------------------------
    def mul(self, key, a, b, shape, dtype):
        return self.slot(key, lambda own: self.conv(a, b), shape, dtype)

    def div(self, key, a, b, shape, dtype):
        return self.slot(key, lambda own: (self.at_k(a) - self.conv(b, own)) / b[0], shape, dtype)

    def exp(self, key, a, shape, dtype):
        at = self.orders(a) * a

        def coef(own):
            k = jnp.maximum(self.kk(at.real.dtype), 1)
            return jnp.where(self.k == 0, jnp.exp(a[0]), self.conv(at, own) / k)

        return self.slot(key, coef, shape, dtype)

    def log(self, key, a, shape, dtype):
        def coef(own):
            lt = self.orders(own) * own
            k = jnp.maximum(self.kk(a.dtype), 1)
            return jnp.where(self.k == 0, jnp.log(a[0]), (self.at_k(a) - self.conv(a, lt) / k) / a[0])

        return self.slot(key, coef, shape, dtype)

    def sqrt(self, key, a, shape, dtype):
        def coef(own):
            return jnp.where(self.k == 0, jnp.sqrt(a[0]), (self.at_k(a) - self.conv(own, own)) / (2 * own[0]))

        return self.slot(key, coef, shape, dtype)

    def integral(self, key, pairs, shape, dtype):
        """``y[0] = 0``, ``y[k] = (1/k) sum_(g, u) sum_{j <= k} j u[j] g[k - j]``: the series
        with ``y' = sum g u'`` (stacks ``g``, ``u``)."""
        def coef(own):
            k = jnp.maximum(self.kk(dtype), 1)
            return sum(self.conv(self.orders(u) * u, g) for g, u in pairs) / k

        return self.slot(key, coef, shape, dtype)

    def ipow(self, key, a, p, shape, dtype):
        if p == 0:
            return self.lift(jnp.ones(shape, dtype))
        if p < 0:
            pos = self.ipow(key + ("+",), a, -p, shape, dtype)
            return self.div(key, self.lift(jnp.ones(shape, dtype)), pos, shape, dtype)
        out, base, i = None, a, 0
        while p:
            if p & 1:
                out = base if out is None else self.mul(key + ("o", i), out, base, shape, dtype)
            p >>= 1
            if p:
                base = self.mul(key + ("b", i), base, base, shape, dtype)
            i += 1
        return out


class _Blocks:
    """The building blocks of :data:`uio_jax._engine.elementary.ELEMENTARY` in pass k: each
    nonlinear block a carried stack, named ``key + (n,)`` in the order the recipe calls them
    (the same in every pass), of the equation's output shape and dtype."""

    def __init__(self, ps, key, shape, dtype, moving):
        self.ps, self.key, self.shape, self.dtype, self.moving = ps, key, shape, dtype, moving
        self.n = 0

    def _block(self, name, *args):
        self.n += 1
        return getattr(self.ps, name)(self.key + (self.n,), *args, self.shape, self.dtype)

    def mul(self, a, b):
        return self._block("mul", a, b)

    def div(self, a, b):
        return self._block("div", a, b)

    def exp(self, a):
        return self._block("exp", a)

    def log(self, a):
        return self._block("log", a)

    def sqrt(self, a):
        return self._block("sqrt", a)

    def integral(self, pairs):
        return self._block("integral", pairs)


# -- the rule table (state: the pass and the key prefix of the enclosing calls) -------------
# A rule of the table is ``rule((ps, prefix), i, eqn, ins)`` (see
# :class:`~.interpreter.Rules`); the rules proper are ``rule(ps, key, eqn, ins)``, with
# ``key = prefix + (i,)`` naming the carried stacks of the equation, applied by
# :func:`_on_series` when an operand is a series.

def _on_series(rule):
    """The table rule of a recurrence rule: ``rule`` when an operand is a series, else the
    primitive on the plain values (constant along t)."""
    def apply(scope, i, eqn, ins):
        for v in ins:
            if isinstance(v, _T):
                return rule(scope[0], scope[1] + (i,), eqn, ins)
        return bind(eqn, ins)

    return apply


def _constant(scope, i, eqn, ins):
    """A piecewise constant primitive: on the order-0 values."""
    ps = scope[0]
    return bind(eqn, [ps.order0(v) for v in ins])


def _call(scope, i, eqn, ins):
    """A call primitive: its sub-jaxpr inline, its stacks named under the call's key."""
    body = call_body(eqn.params)
    if body is None:
        raise NoTaylorRule(eqn.primitive.name)
    return interpret(body[0], body[1], ins, _RULES, (scope[0], scope[1] + (i,)))


def _missing(ps, key, eqn, ins):
    raise NoTaylorRule(eqn.primitive.name)


def _lin(ps, key, eqn, ins):
    return _linear(ps, key, eqn.primitive, eqn.params, ins)


def _move(ps, key, eqn, ins):
    out = _moved(ps, key, eqn.primitive, eqn.params, ins)
    return out if out is not None else _linear(ps, key, eqn.primitive, eqn.params, ins)


def _aval(eqn):
    out = eqn.outvars[0].aval
    return out.shape, out.dtype


def _abs(ps, key, eqn, ins):
    return [_T(jnp.sign(ps.order0(ins[0])) * ins[0].ck, key=key + (0,))]


def _max_min(ps, key, eqn, ins):
    a0, b0 = ps.order0(ins[0]), ps.order0(ins[1])
    pick = (a0 >= b0) if eqn.primitive.name == "max" else (a0 <= b0)
    return [_T(jnp.where(pick, ps.at(ins[0]), ps.at(ins[1])), key=key + (0,))]


def _mul(ps, key, eqn, ins):
    if not (isinstance(ins[0], _T) and isinstance(ins[1], _T)):  # a constant factor
        return _lin(ps, key, eqn, ins)
    shape, dtype = _aval(eqn)
    return [ps.series(ps.mul(key, ps.stack(ins[0]), ps.stack(ins[1]), shape, dtype))]


def _dot(ps, key, eqn, ins):
    if not (isinstance(ins[0], _T) and isinstance(ins[1], _T)):  # a constant factor
        return _lin(ps, key, eqn, ins)
    prim, params = eqn.primitive, eqn.params
    a, b = ps.stack(ins[0]), ps.stack(ins[1])

    def coef(own):  # sum_i dot(a[i], b[k - i])
        return jnp.sum(jax.vmap(lambda x, y: prim.bind(x, y, **params))(a, ps.window(b)), axis=0)

    return [ps.series(ps.slot(key, coef, *_aval(eqn)))]


def _div(ps, key, eqn, ins):
    if not isinstance(ins[1], _T):  # a constant divisor
        return _lin(ps, key, eqn, ins)
    return [ps.series(ps.div(key, ps.lift(ins[0]), ps.stack(ins[1]), *_aval(eqn)))]


def _elementary(ps, key, eqn, ins):
    """A primitive of :data:`~uio_jax._engine.elementary.ELEMENTARY`: its recipe on the operands'
    stacks, order 0 the primitive on the order-0 values."""
    shape, dtype = _aval(eqn)
    stacks = ranked([ps.lift(v) for v in ins])
    blocks = _Blocks(ps, key, shape, dtype, tuple(isinstance(v, _T) for v in ins))
    out = ELEMENTARY[eqn.primitive.name](blocks, *stacks)
    (v0,) = bind(eqn, [ps.order0(v) for v in ins])
    return [ps.series(jnp.broadcast_to(out, (ps.K + 1,) + tuple(shape)).astype(dtype).at[0].set(v0))]


def _clamp(ps, key, eqn, ins):
    """``clamp(lo, x, hi)``: the operand the order-0 values pick."""
    lo, x, hi = (ps.order0(v) for v in ins)
    pick = jnp.where(x < lo, ps.at(ins[0]), jnp.where(x > hi, ps.at(ins[2]), ps.at(ins[1])))
    return [_T(pick, key=key + (0,))]


def _reduce_max_min(ps, key, eqn, ins):
    """``reduce_max`` / ``reduce_min``: the elements extreme at order 0 (their mean on ties)."""
    axes = eqn.params["axes"]
    pick = extreme_mask(eqn.primitive, eqn.params, ps.order0(ins[0]))
    return [_T(jnp.sum(jnp.where(pick, ins[0].ck, 0), axis=axes) / jnp.sum(pick, axis=axes), key=key + (0,))]


def _rem(ps, key, eqn, ins):
    """``rem(a, b) = a - q b``, the integer quotient ``q`` constant along t."""
    q = rem_quotient(ps.order0(ins[0]), ps.order0(ins[1]))
    return [_T(ps.at(ins[0]) - q * ps.at(ins[1]), key=key + (0,))]


def _unary(f):
    """A rule from ``f(ps, key, eqn, a, shape, dtype) -> stack`` of the first operand's
    stack ``a``."""
    def rule(ps, key, eqn, ins):
        a = ps.stack(ins[0])
        return [ps.series(f(ps, key, eqn, a, *_aval(eqn)))]

    return rule


def _trig(ps, key, eqn, a, shape, dtype):
    """sin, cos, tan through ``exp(i a)``."""
    cdt = jnp.result_type(dtype, jnp.complex64)
    z = ps.exp(key + ("z",), 1j * a.astype(cdt), shape, cdt)
    s, c = jnp.imag(z), jnp.real(z)
    name = eqn.primitive.name
    if name == "sin":
        return s
    if name == "cos":
        return c
    return ps.div(key, s, c, shape, dtype)


def _rsqrt(ps, key, eqn, a, shape, dtype):
    r = ps.sqrt(key + ("r",), a, shape, dtype)
    return ps.div(key, ps.lift(jnp.ones(shape, dtype)), r, shape, dtype)


_RULES = Rules({
    **{name: _on_series(_lin) for name in LINEAR},
    **{name: _on_series(_move) for name in _MOVING},
    **{name: _constant for name in CONSTANT},
    "mul": _on_series(_mul),
    "dot_general": _on_series(_dot),
    "div": _on_series(_div),
    "abs": _on_series(_abs),
    "max": _on_series(_max_min),
    "min": _on_series(_max_min),
    **{name: _on_series(_elementary) for name in ELEMENTARY},
    "clamp": _on_series(_clamp),
    "reduce_max": _on_series(_reduce_max_min),
    "reduce_min": _on_series(_reduce_max_min),
    "rem": _on_series(_rem),
    "integer_pow": _on_series(_unary(lambda ps, key, eqn, a, s, d: ps.ipow(key, a, eqn.params["y"], s, d))),
    "square": _on_series(_unary(lambda ps, key, eqn, a, s, d: ps.mul(key, a, a, s, d))),
    "sin": _on_series(_unary(_trig)),
    "cos": _on_series(_unary(_trig)),
    "tan": _on_series(_unary(_trig)),
    "exp": _on_series(_unary(lambda ps, key, eqn, a, s, d: ps.exp(key, a, s, d))),
    "log": _on_series(_unary(lambda ps, key, eqn, a, s, d: ps.log(key, a, s, d))),
    "sqrt": _on_series(_unary(lambda ps, key, eqn, a, s, d: ps.sqrt(key, a, s, d))),
    "rsqrt": _on_series(_unary(_rsqrt)),
}, default=_on_series(_missing), calls=_call)


def flow_coefficients(F, x, K, known=(), constants=True):
    """Normalized coefficients ``(K, N)`` of orders 1..K of the solution of ``x' = F(x, *s)``.

    Args:
        F: ``(x (N,), *known values) -> (N,)`` traceable vector field.
        x: ``(N,)`` initial state (order 0).
        K: highest order (>= 1).
        known: stacks ``(K + 1, *shape)`` of known series entering F (e.g. an input
            ``u(t) = sum_k a_k t^k`` given as ``a``), in full.
        constants: treat states with a structurally zero derivative as constants
            (:func:`constant_states`; same coefficients, less work).

    Returns:
        ``(K, N)``: ``x[k] = x^(k)(0) / k!`` for ``k = 1..K`` (equal to
        :func:`uio_jax._engine.taylor.flow_series` up to round-off).
    """
    known = tuple(jnp.asarray(s) for s in known)
    closed = jax.make_jaxpr(F)(x, *[s[0] for s in known])
    N = x.shape[0]
    const = constant_states(F, x, known) if constants else np.zeros(N, bool)

    def run(k, xs, state):
        ps = _Pass(k, K, state)
        root = _T(ps.at_k(xs), stack=xs, const=const if const.any() else None, c0=xs[0])
        args = [root] + [_T(ps.at_k(s), stack=s) for s in known]
        (out,) = interpret(closed.jaxpr, closed.consts, args, _RULES, (ps, ()))
        fk = ps.at(out)
        fk = jnp.broadcast_to(jnp.asarray(fk, xs.dtype), (N,))
        nxt = fk / jnp.asarray(k + 1, xs.dtype)
        if isinstance(k, int):
            xs = xs.at[k + 1].set(nxt)
        else:
            xs = lax.dynamic_update_index_in_dim(xs, nxt, k + 1, 0)
        return xs, ps.new

    xs = jnp.zeros((K + 1, N), x.dtype).at[0].set(x)
    xs, state = run(0, xs, {})  # order 0 fixes the shapes of every carried stack
    if K > 1:
        xs, state = lax.fori_loop(1, K, lambda k, c: run(k, *c), (xs, state))
    return xs[1:]


def constant_states(F, x, known=()):
    """Bool ``(N,)``: the states whose derivative ``F(x, *known)_i`` is a structural zero
    (zero for every state and every value of the known series), hence constant along the
    flow."""
    N = x.shape[0]
    sizes = [int(np.prod(s.shape[1:])) for s in known]

    def flat(z):  # the state and one value of every known series in one vector
        vals, at = [], N
        for s, size in zip(known, sizes):
            vals.append(z[at:at + size].reshape(s.shape[1:]))
            at += size
        return jnp.ravel(F(z[:N], *vals))

    z = jnp.concatenate([jnp.ravel(x)] + [jnp.ravel(s[0]) for s in known])
    zeros = structural_zeros(flat, z)
    return zeros if zeros.shape == (N,) else np.zeros(N, bool)


__all__ = ["flow_coefficients", "constant_states"]
