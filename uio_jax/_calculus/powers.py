"""Powers of a field, ``L_F^j psi``: the one policy by which every analysis evaluates them.

``L_F^j psi (x) = d^j/dt^j psi(x(t)) |_{t=0}`` along the flow ``x' = F(x)``, ``x(0) = x``.
Three ways to build it, from the cheapest trace to the most general:

* ``"taylor"``: one pass of stacked Taylor coefficients along the flow
  (:func:`uio_jax._engine.taylor.lie_powers`); the traced graph grows linearly in ``j``.
* ``"jet"``: ``jax.experimental.jet``, one ``jet`` of ``F`` per order (:func:`flow_derivatives`);
  the graph grows like ``j^2`` (Griewank & Walther, "Evaluating Derivatives", ch. 13).
* ``"nested"``: ``j`` nested ``jax.jvp``; the graph grows like ``2.5^j`` (each level doubles
  the one below it, common sub-expressions are not shared), but every primitive JAX can
  differentiate has a rule.

**The rule** (:func:`lie_power`): ``j = 0`` is ``psi``; ``j < taylor_from`` (the caller's
threshold: below it a power is small enough nested) is nested jvp; otherwise the first of
``taylor``, ``jet``, ``nested`` that has a rule for every primitive of ``psi`` and ``F``,
decided once per ``(psi, F)`` on the first call (an abstract evaluation, no compile). Only "no
rule for this primitive" moves to the next way: the Taylor interpreter's
:class:`~uio_jax._engine.interpreter.NoTaylorRule` and jet's ``KeyError`` of a primitive
(or its ``NotImplementedError``). Any other error (a bug in the
model, a shape mismatch) propagates.
"""

import weakref

import jax

from .._engine.interpreter import NoTaylorRule
from .._engine.taylor import lie_powers
from . import lie as _lie

#: The ways to evaluate ``L_F^j psi``, in the order :func:`lie_power` tries them.
MODES = ("taylor", "jet", "nested")


_MODE_OF: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()  # psi -> {key: mode}


def flow_derivatives(F, x, order):
    """Time derivatives ``x^(1)..x^(order)`` at t = 0 of the flow ``x' = F(x)``, ``x(0) = x``.

    ``x^(i+1) = d^i/dt^i F(x(t))``: one ``jet`` of F per order, fed with the derivatives
    found so far (jet's convention, ``x(t) = sum_i x^(i) t^i / i!``).

    Args:
        F: field ``(N,) -> (N,)``; x: ``(N,)``; order: >= 1.

    Returns:
        list of ``order`` arrays ``(N,)``.
    """
    from jax.experimental.jet import jet

    series = [F(x)]
    for _ in range(1, order):
        _, out = jet(F, (x,), (tuple(series),))
        series.append(out[-1])
    return series


def taylor_power(psi, F, j):
    """``x (N,) -> L_F^j psi (x) ()`` by one stacked-coefficient Taylor pass (``j >= 1``)."""
    powers = lie_powers(psi, F, j)
    return lambda x: powers(x)[j]


def jet_power(psi, F, j):
    """``x (N,) -> L_F^j psi (x) ()`` by ``jax.experimental.jet`` along the flow (``j >= 1``):
    ``d^j/dt^j psi(x(t))`` with the flow's derivatives of :func:`flow_derivatives`."""
    from jax.experimental.jet import jet

    def power(x):
        series = flow_derivatives(F, x, j)
        _, out = jet(psi, (x,), (tuple(series),))
        return out[j - 1]

    return power


def nested_power(psi, F, j):
    """``x (N,) -> L_F^j psi (x) ()`` by ``j`` nested ``jax.jvp``: ``L_F (L_F^(j-1) psi)``."""
    fn = psi
    for _ in range(j):
        fn = _lie.lie_derivative(fn, F)
    return fn


_BUILD = {"taylor": taylor_power, "jet": jet_power, "nested": nested_power}


def _no_jet_rule(exc: KeyError) -> bool:
    """Whether a KeyError is jet's lookup of a primitive it has no rule for."""
    from jax.extend.core import Primitive

    return bool(exc.args) and isinstance(exc.args[0], Primitive)


def power_mode(psi, F, like) -> str:
    """The way :func:`lie_power` evaluates every power ``L_F^j psi`` (``j >= 1``) at states
    like ``like`` (a ``jax.ShapeDtypeStruct`` ``(N,)``).

    The first of :data:`MODES` whose abstract trace of ``L_F^1 psi`` meets a rule for every
    primitive. A rule is per primitive and the pass to ``j = 1`` already runs every
    equation of ``psi`` and ``F`` through the interpreter, so one trace decides every
    power; memoized per ``(psi, F, shape, dtype)``.
    """
    key = (F, tuple(like.shape), str(like.dtype))
    known = _MODE_OF.setdefault(psi, {})
    mode = known.get(key)
    if mode is not None:
        return mode
    mode = "nested"
    try:
        jax.eval_shape(lie_powers(psi, F, 1), like)
        mode = "taylor"
    except NoTaylorRule:
        try:
            jax.eval_shape(jet_power(psi, F, 2), like)  # jet's rules meet psi at order 2
            mode = "jet"
        except (KeyError, NotImplementedError) as exc:  # jet: no rule for a primitive
            if isinstance(exc, KeyError) and not _no_jet_rule(exc):
                raise
    known[key] = mode
    return mode


def lie_power(psi, F, j, *, taylor_from=1):
    """``x (N,) -> L_F^j psi (x) ()`` by the module's one rule (see the module docstring).

    Args:
        psi: scalar function ``(N,) -> ()``.
        F: field ``(N,) -> (N,)``.
        j: power, ``>= 0``.
        taylor_from: the smallest ``j`` worth a Taylor pass; below it, nested jvp. The
            EORC uses 1 (its chain programs take every power from one Taylor pass, and a
            block must compute the same numbers as a chain's row); the node graph's
            repeated ``L_v`` uses :data:`uio_jax._calculus.generators.TAYLOR_FROM`.

    Returns:
        The function; for ``j >= taylor_from`` its way is decided on its first call.
    """
    if j == 0:
        return psi
    if j < taylor_from:
        return nested_power(psi, F, j)
    chosen = {}

    def power(x):
        fn = chosen.get("fn")
        if fn is None:
            mode = power_mode(psi, F, jax.ShapeDtypeStruct(x.shape, x.dtype))
            fn = chosen["fn"] = _BUILD[mode](psi, F, j)
        return fn(x)

    return power


def taylor_series(psi, F, j, like):
    """``x (N,) -> [L_F^0 psi .. L_F^j psi](x) (j + 1,)`` from one Taylor pass, or None
    where :func:`power_mode` would not evaluate ``L_F^j psi`` by Taylor (a primitive of
    ``psi`` or ``F`` without a Taylor rule): every power of one pass, for programs that
    need them all (the EORC's chains, :mod:`uio_jax._calculus.blocks`).

    Args:
        psi, F, j: as :func:`lie_power` (``j >= 1``).
        like: ``jax.ShapeDtypeStruct`` ``(N,)`` of the states.
    """
    return lie_powers(psi, F, j) if power_mode(psi, F, like) == "taylor" else None


__all__ = ["MODES", "taylor_series", "flow_derivatives", "taylor_power", "jet_power", "nested_power",
           "power_mode", "lie_power"]
