"""Elementary functions for the two Taylor engines, written once with their building blocks.

Both Taylor engines (:mod:`uio_jax._engine.taylor`, whole coefficient stacks;
:mod:`uio_jax._engine.taylor_flow`, the order-k recurrence) expand a primitive of
:data:`ELEMENTARY` by the same recipe, ``ELEMENTARY[name](E, *stacks) -> stack``, over their
own blocks ``E``:

* a stack is an array ``(K + 1, *shape)`` of normalized coefficients ``a[k] = a^(k)(0) / k!``
  (the operands given one rank by :func:`ranked`, constants lifted: value at order 0, zeros
  above); linear operations are plain ``jnp`` on stacks;
* the nonlinear blocks are ``E.mul(a, b)``, ``E.div(a, b)``, ``E.exp(a)``, ``E.log(a)``,
  ``E.sqrt(a)`` (the classical recurrences, Griewank & Walther, "Evaluating Derivatives",
  2nd ed., table 13.2) and ``E.integral(pairs)``: the series ``y`` with ``y[0] = 0`` and
  ``y' = sum g u'`` over the pairs ``(g, u)``, i.e.
  ``y[k] = (1/k) sum_(g, u) sum_{1 <= j <= k} j u[j] g[k - j]``: a function with a known
  derivative, ``f(u)' = f'(u) u'``, from the series of ``g = f'(u)`` (atan, asin, acos,
  asinh, acosh, atanh, atan2, log1p, erf, erfc);
* ``E.moving[i]``: whether operand ``i`` is a series (else a constant).

Others come from exp: tanh as ``s (1 - e) / (1 + e)`` with ``e = exp(-2 s u)``,
``s = sign(u0)`` (no overflow), logistic as ``(1 + tanh(u / 2)) / 2``, sinh and cosh from
``exp(u)`` and ``exp(-u)``, expm1 and exp2; cbrt as ``s exp(log(s u) / 3)``; a real power
``a ** b = exp(b log a)``, with a constant exponent on a negative base ``s^b exp(b log(s a))``
(real where the primal is). Only orders >= 1 of a recipe count: the engines set order 0 to
the primitive on the order-0 values (exact, the primal's own value).

The module also holds what the engines' selection rules share (:func:`extreme_mask` for
``reduce_max`` / ``reduce_min``, :func:`rem_quotient` for ``rem``).
"""

import math

import jax
import jax.numpy as jnp


def _one(a):
    """The constant 1 as a stack like ``a``."""
    return jnp.zeros_like(a).at[0].set(1)


def _sgn(a):
    """``sign(a[0])`` with 0 read as 1 (element shape): the branch of an odd function."""
    return jnp.where(a[0] < 0, -1.0, 1.0).astype(a.dtype)


def _tanh(E, u):
    """``s (1 - e) / (1 + e)``, ``e = exp(-2 s u)``, ``s = sign(u0)``: no overflow."""
    s = _sgn(u)
    e = E.exp(-2.0 * s * u)
    return E.div(s * (_one(u) - e), _one(u) + e)


def _pow_recipe(E, a, b):
    """``a ** b = exp(b log a)``; a constant exponent on a negative base: ``s^b |a|^b``."""
    if E.moving[1]:
        return E.exp(E.mul(E.log(a), b))
    s = _sgn(a)
    return jnp.power(s, b[0]) * E.exp(b[0] * E.log(s * a))


def _rsq(E, d):
    """``1 / sqrt(d)``."""
    return E.div(_one(d), E.sqrt(d))


def _atan2(E, a, b):
    """``atan2(a, b)' = (b a' - a b') / (a^2 + b^2)``."""
    r2 = E.mul(a, a) + E.mul(b, b)
    return E.integral([(E.div(b, r2), a), (E.div(-a, r2), b)])


#: primitive name -> recipe ``(E, *stacks) -> stack`` (see the module docstring)
ELEMENTARY = {
    "atan": lambda E, u: E.integral([(E.div(_one(u), _one(u) + E.mul(u, u)), u)]),
    "asin": lambda E, u: E.integral([(_rsq(E, _one(u) - E.mul(u, u)), u)]),
    "acos": lambda E, u: E.integral([(-_rsq(E, _one(u) - E.mul(u, u)), u)]),
    "asinh": lambda E, u: E.integral([(_rsq(E, _one(u) + E.mul(u, u)), u)]),
    "acosh": lambda E, u: E.integral([(_rsq(E, E.mul(u - _one(u), u + _one(u))), u)]),
    "atanh": lambda E, u: E.integral([(E.div(_one(u), _one(u) - E.mul(u, u)), u)]),
    "atan2": _atan2,
    "tanh": _tanh,
    "logistic": lambda E, u: 0.5 * (_one(u) + _tanh(E, 0.5 * u)),
    "sinh": lambda E, u: 0.5 * (E.exp(u) - E.exp(-u)),
    "cosh": lambda E, u: 0.5 * (E.exp(u) + E.exp(-u)),
    "expm1": lambda E, u: E.exp(u),
    "exp2": lambda E, u: E.exp(math.log(2.0) * u),
    "log1p": lambda E, u: E.integral([(E.div(_one(u), _one(u) + u), u)]),
    "erf": lambda E, u: E.integral([((2 / math.sqrt(math.pi)) * E.exp(-E.mul(u, u)), u)]),
    "erfc": lambda E, u: E.integral([((-2 / math.sqrt(math.pi)) * E.exp(-E.mul(u, u)), u)]),
    "cbrt": lambda E, u: _sgn(u) * E.exp(E.log(_sgn(u) * u) / 3.0),
    "pow": _pow_recipe,
}


def ranked(stacks):
    """Stacks ``(K + 1, *shape)`` given one rank (leading singleton element axes)."""
    r = max(c.ndim for c in stacks)
    return [c.reshape(c.shape[:1] + (1,) * (r - c.ndim) + c.shape[1:]) for c in stacks]


def extreme_mask(prim, params, a0):
    """Bool (shape of ``a0``): the elements of ``a0`` equal to their ``reduce_max`` /
    ``reduce_min`` over ``params["axes"]`` (``prim`` either of them)."""
    m = prim.bind(a0, **params)
    keep = [d for d in range(a0.ndim) if d not in params["axes"]]
    return a0 == jax.lax.broadcast_in_dim(m, a0.shape, keep)


def rem_quotient(a0, b0):
    """``q`` with ``rem(a, b) = a - q b`` near the order-0 values (integral, constant along t)."""
    return jnp.round((a0 - jax.lax.rem(a0, b0)) / b0)


__all__ = ["ELEMENTARY", "ranked", "extreme_mask", "rem_quotient"]
