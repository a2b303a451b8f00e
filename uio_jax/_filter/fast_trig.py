"""Vectorizable float64 sine and cosine for the Monte Carlo filter.

XLA's CPU backend evaluates float64 ``sin`` and ``cos`` one element at a time, many times
slower than a multiply-add in a vectorized loop, and the unicycle's filter needs four of
them per trial-step (the truth's and the estimate's heading). Here they are written with
ordinary arithmetic, which XLA vectorizes:

* **Reduction** (Cody-Waite, as fdlibm's ``__ieee754_rem_pio2`` for medium arguments):
  ``k = round(x 2/pi)``, ``r = (((x - k P1) - k P2) - k P3) - k P4`` with ``pi/2`` split
  into four parts (the first three of 33 bits, so that their products with ``|k| < 2^20``
  are exact, and the cancellation near multiples of ``pi/2`` keeps its digits); quadrant
  ``q = k mod 4``.
* **Kernels** on ``|r| <= pi/4``: fdlibm's ``__kernel_sin`` / ``__kernel_cos`` minimax
  polynomials (degree 13 and 14), error below 1 ulp.

Accuracy (against mpmath at 40 digits, ``tests/test_fast_trig.py``): within 1 ulp for
``|x| <= 1e3`` rad, as XLA's and numpy's own, and within 2 ulp up to ``2^19 pi`` (about
1.6e6 rad; 0.06-0.09 % of random arguments there are 2 ulp off): the range of every
physical angle of a simulation. Beyond it the reduction loses digits; ``r`` is clipped to
``[-0.79, 0.79]`` so that the result stays bounded (a filter whose angle estimate reaches a
million radians has diverged long before). The derivatives are the functions' own
(``d sin = cos dx`` by the same kernels), not those of the polynomials.

:func:`with_vectorized_trig` applies them to a model function: it traces the function to a
jaxpr and evaluates it by :func:`uio_jax._engine.interpreter.interpret` with this module's
rule table (float64 ``sin`` / ``cos`` replaced, calls inline, every other primitive as it
is, each repeated equation once); measurements in ``docs/benchmarks/engine.md``.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from .._engine.interpreter import Rules, bind, inline, interpret

# fdlibm's __kernel_sin and __kernel_cos coefficients (|r| <= pi/4)
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
# pi/2 = _P1 + _P2 + _P3 + _P4 (fdlibm's pio2_1, pio2_2, pio2_3 of 33 bits each, pio2_3t)
_P1, _P2, _P3 = 1.57079632673412561417e+00, 6.07710050630396597660e-11, 2.02226624871116645580e-21
_P4 = 8.47842766036889956997e-32
#: below this magnitude (2^19 pi) the results are within 2 ulp (1 ulp below 1e3)
ACCURATE_BELOW = 2.0**19 * np.pi


# Written with lax operators: jnp's round / clip / floor / where are each a small jitted
# function, which costs a nested call per use at every trace and lowering.
def _reduce(x):
    """``(r, q)``: ``x = r + (pi/2) k``, ``|r| <= pi/4`` (clipped), quadrant ``q = k mod 4``."""
    k = lax.round(x * (2.0 / np.pi), lax.RoundingMethod.TO_NEAREST_EVEN)
    r = (((x - k * _P1) - k * _P2) - k * _P3) - k * _P4
    r = lax.min(lax.max(r, lax.full_like(r, -0.79)), lax.full_like(r, 0.79))
    return r, k - 4.0 * lax.floor(0.25 * k)


def _kernel_sin(r):
    z = r * r
    return r + z * r * (_S[0] + z * (_S[1] + z * (_S[2] + z * (_S[3] + z * (_S[4] + z * _S[5])))))


def _kernel_cos(r):
    z = r * r
    tail = z * z * (_C[0] + z * (_C[1] + z * (_C[2] + z * (_C[3] + z * (_C[4] + z * _C[5])))))
    half = 0.5 * z
    w = 1.0 - half
    return w + (((1.0 - w) - half) + tail)


def _quadrant(q, a, b):
    """``a, b, -a, -b`` for ``q = 0, 1, 2, 3``."""
    def is_(v):
        return lax.eq(q, lax.full_like(q, v))

    return lax.select(is_(0.0), a, lax.select(is_(1.0), b, lax.select(is_(2.0), -a, -b)))


@jax.custom_jvp
def sincos(x):
    """``(sin(x), cos(x))`` for float64 ``x`` of any shape (two arrays of that shape).

    One reduction ``x = r + k pi/2`` (``|r| <= pi/4``, Cody-Waite, module doc), the fdlibm
    kernels ``s = sin r``, ``c = cos r``, and the quadrant ``q = k mod 4``: ``sin x`` is
    ``s, c, -s, -c`` and ``cos x`` is ``c, -s, -c, s`` for ``q = 0, 1, 2, 3``. Derivatives
    ``d sin = cos dx``, ``d cos = -sin dx`` by the same kernels.
    """
    r, q = _reduce(x)
    s, c = _kernel_sin(r), _kernel_cos(r)
    return _quadrant(q, s, c), _quadrant(q, c, -s)


@sincos.defjvp
def _sincos_jvp(primals, tangents):
    s, c = sincos(primals[0])
    return (s, c), (c * tangents[0], -s * tangents[0])


def sin(x):
    """``sin(x)`` for float64 ``x`` of any shape (same shape), by vectorizable arithmetic
    (:func:`sincos`)."""
    return sincos(x)[0]


def cos(x):
    """``cos(x)`` for float64 ``x`` of any shape (same shape), by vectorizable arithmetic
    (:func:`sincos`)."""
    return sincos(x)[1]


class _Shared:
    """The state of one evaluation: ``trig``, ``id(operand) -> (operand, (sin, cos))``;
    ``seen``, ``(primitive, params, operand ids) -> (operands, outputs)`` (the operands
    kept: their ids stay theirs)."""

    __slots__ = ("trig", "seen")

    def __init__(self):
        self.trig, self.seen = {}, {}


def _trig(state, i, eqn, ins):
    """``sin`` / ``cos``: of a float64 tracer by :func:`sincos` (one per operand), of a
    float64 constant numpy's, else the primitive."""
    x = ins[0]
    if jnp.result_type(x) != jnp.float64:
        return bind(eqn, ins)
    name = eqn.primitive.name
    if not isinstance(x, jax.core.Tracer):  # a constant (cos(gamma)): numpy's
        return [(np.sin if name == "sin" else np.cos)(np.asarray(x))]
    trig = state.trig
    if id(x) not in trig:
        trig[id(x)] = (x, sincos(x))  # the operand kept: its id stays its own
    return [trig[id(x)][1][0 if name == "sin" else 1]]


def _call(state, i, eqn, ins):
    """Sub-functions inline (as the graph translation does), their sin / cos replaced too."""
    out = inline(_RULES, state, eqn, ins)
    return out if out is not None else bind(eqn, ins)


def _shared(rule):
    """``rule`` evaluated once per repeated equation (same primitive, parameters and
    operand objects): common-subexpression elimination on the equations.

    A model writes ``cos(x[2])`` and ``sin(x[2])``: two slices, so two operands, so two
    reductions and four kernels, unless the second slice is recognised as the first (XLA would
    merge them only after tracing and lowering have paid for them).
    """
    def apply(state, i, eqn, ins):
        key = _equation_key(eqn, ins)
        if key is None:
            return rule(state, i, eqn, ins)
        seen = state.seen
        if key not in seen:
            seen[key] = (ins, rule(state, i, eqn, ins))  # the operands kept: their ids stay theirs
        return seen[key][1]

    return apply


def _plain(state, i, eqn, ins):
    """Any other primitive, as it is."""
    prim = eqn.primitive
    out = prim.bind(*ins, **eqn.params)
    return out if prim.multiple_results else [out]


#: The rule table: float64 ``sin`` and ``cos`` by :func:`sincos`, calls inline, every
#: other primitive as it is; each equation once (:func:`_shared`).
_RULES = Rules({"sin": _shared(_trig), "cos": _shared(_trig)}, default=_shared(_plain), calls=_shared(_call))


def _equation_key(eqn, ins):
    """A hashable key of a pure equation applied to these operand objects, or None."""
    if eqn.effects:
        return None
    key = (eqn.primitive, tuple(sorted(eqn.params.items())), tuple(id(x) for x in ins))
    try:
        hash(key)
    except TypeError:  # a parameter that is not hashable (an array): no sharing
        return None
    return key


def with_vectorized_trig(fn):
    """``fn`` with its float64 ``sin`` and ``cos`` evaluated by :func:`sincos`.

    ``fn`` takes and returns arrays (or pytrees of them); the result has the same shapes and
    ``fn``'s values within the kernels' accuracy (1 ulp for ``|x| <= 1e3``, 2 ulp below
    :data:`ACCURATE_BELOW`). It is traced once per call (at the caller's trace time under
    ``jit``). Sub-functions are evaluated inline, their float64 ``sin`` / ``cos`` replaced too.
    """

    @functools.wraps(fn)
    def wrapped(*args):
        closed, out_shape = jax.make_jaxpr(fn, return_shape=True)(*args)
        flat = jax.tree.leaves(args)
        out = interpret(closed.jaxpr, closed.consts, flat, _RULES, _Shared())
        return jax.tree.unflatten(jax.tree.structure(out_shape), out)

    return wrapped


__all__ = ["sin", "cos", "sincos", "with_vectorized_trig", "ACCURATE_BELOW"]
