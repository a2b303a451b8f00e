"""Lie calculus on plain callables, by forward-mode automatic differentiation.

All functions here act on one state ``x`` of shape ``(n,)`` and are pure; batching over
states is done by the caller with ``jax.vmap``.

* Lie derivative of a scalar ``phi`` along a field ``v``: ``L_v phi (x) = dphi(x) . v(x)``,
  one ``jax.jvp`` (no dense Jacobian).
* Lie bracket ``[a, b](x) = (db/dx) a(x) - (da/dx) b(x)``, two ``jax.jvp``.
"""

import jax
import jax.numpy as jnp


def lie_derivative(phi, v):
    """Return ``x (n,) -> L_v phi (x) = dphi(x) . v(x)``, shape ``()``, for a scalar ``phi``
    ``(n,) -> ()`` and a field ``v`` ``(n,) -> (n,)``."""

    def lie(x):
        return jax.jvp(phi, (x,), (v(x),))[1]

    return lie


def lie_bracket(a, b):
    """Return ``x (n,) -> [a, b](x) = (db/dx) a(x) - (da/dx) b(x)``, shape ``(n,)``, for
    fields ``a, b: (n,) -> (n,)``."""

    def bracket(x):
        db_a = jax.jvp(b, (x,), (a(x),))[1]
        da_b = jax.jvp(a, (x,), (b(x),))[1]
        return db_a - da_b

    return bracket


def scaled_field(v, s):
    """Return ``x (n,) -> v(x) / s(x)``, shape ``(n,)``, for a field ``v`` and a scalar ``s``."""

    def scaled(x):
        return v(x) / s(x)

    return scaled


def ratio(num, den, power=1):
    """Return ``x (n,) -> num(x) / den(x) ** power``, shape ``()``, for scalar functions."""

    def r(x):
        return num(x) / den(x) ** power

    return r


def stacked_gradients(fns):
    """Return ``x -> (c, n)`` matrix whose rows are the gradients of the scalar ``fns``.

    One forward-mode Jacobian of the stacked function, so the primal work shared by the
    functions (common sub-expressions of nested Lie derivatives) is traced once.
    """

    def stacked(x):
        return jnp.stack([jnp.asarray(f(x)).reshape(()) for f in fns])

    return jax.jacfwd(stacked)


def lie_derivative_gradients(phis, fields):
    """Return ``x -> (len(phis) * len(fields), n)``: the gradients of ``L_v phi``.

    Rows are ordered phi-major (``for phi in phis for v in fields``). For each ``phi`` the
    Lie derivatives along all fields are one vmapped ``jvp`` (``dphi . v_j``), and their
    gradients one ``jacfwd`` of that vector: the trace of ``phi`` is shared by all fields,
    which keeps the compiled graph (and compile time) several times smaller than one
    nested closure per pair.
    """

    def field_matrix(x):
        return jnp.stack([v(x) for v in fields])

    def block(x):
        rows = []
        for phi in phis:

            def along_all(y, phi=phi):
                return jax.vmap(lambda t: jax.jvp(phi, (y,), (t,))[1])(field_matrix(y))

            rows.append(jax.jacfwd(along_all)(x))
        return jnp.concatenate(rows)

    return block
