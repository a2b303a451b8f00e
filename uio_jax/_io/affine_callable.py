"""The affine split of :mod:`uio_jax._io.affine` for JAX callables (StrikePy modules, ``load_system``
on a function ``f(x, p, u, w)``): the same drift, fields, affinity threshold, promotions and
notes, measured at the samples with JAX where the expression route reads the model's text.
"""

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ModelError
from .affine import Parts, build_parts
from .affinity import (
    AFFINE_RTOL,
    AFFINE_SAMPLES,
    TINY,
    affine_points,
    pattern_from_derivatives,
    promotion_reasons,
    sample_boxes,
)


def split_callable(states, dynamics, outputs, known_inputs, unknown_inputs, params, domain, angles, *,
                   seed: int = 0, samples: int = AFFINE_SAMPLES) -> Parts:
    """:func:`uio_jax._io.affine.split_general` for JAX callables: ``dynamics(x, p, u, w) -> (n,)``,
    ``outputs[name](x, p, u, w) -> ()`` (``x (n,)``, ``p (P,)``, ``u (len(known),)``,
    ``w (len(unknown),)``).

    The same split and the same rules (:mod:`uio_jax._io.affine`): fields ``d f / d v`` at
    ``v = 0`` by ``jax.jvp``, the Hessian in ``v`` by ``jax.hessian`` at the same points and
    threshold, the same promotions and notes. Where the expression route reads the model's
    text, this one measures at the samples:

    * an input is used by the dynamics (or an output) when a derivative in it is non-zero
      at some finite sample; unused inputs are dropped with the same note;
    * the syntactic ``abs/sign/min/max`` test becomes a check that the affine part at 0 is
      the function, for the inputs that pass the Hessian test: input ``a`` is promoted
      when, at some sample where ``f`` is finite,
      ``f(x, p, v_a e_a)`` is not finite or differs from ``f(x, p, 0) + d_a f(x, p, 0) v_a``
      by more than ``AFFINE_RTOL`` of the terms' size (a kink, a branch or a singularity
      between 0 and the input's box, which a Hessian at the samples cannot see).

    Returns:
        :class:`Parts` on ``z = [x; promoted inputs; p]`` (functions of JAX arrays).

    Raises:
        ModelError: the dynamics are not finite at any sampled point.
    """
    states, known_inputs, unknown_inputs = tuple(states), tuple(known_inputs), tuple(unknown_inputs)
    pnames = tuple(params)
    n0, P, nk = len(states), len(pnames), len(known_inputs)
    inputs = known_inputs + unknown_inputs
    m = len(inputs)
    notes = []
    reasons = {}
    if m:
        zs = affine_points(sample_boxes(states, params, inputs, domain, angles), seed, samples)
        with jax.enable_x64(True):
            f, J, H, J0, gaps, finite0, out_grads = _measure(dynamics, outputs, zs, n0, P, nk)
        finite = np.isfinite(f).all(axis=1)
        if not finite.any():
            raise ModelError(f"the dynamics are not finite at any of {samples} sampled points "
                             "(states, parameters and inputs in their boxes)")
        with np.errstate(all="ignore"):
            used = (np.abs(np.nan_to_num(J[finite])).sum(axis=(0, 1)) > 0) | (
                np.abs(np.nan_to_num(H[finite])).sum(axis=(0, 1, 3)) > 0) | (
                np.abs(np.nan_to_num(J0[finite])).sum(axis=(0, 1)) > 0)
            in_outputs = {inputs[a] for g in out_grads.values()
                          for a in range(m) if np.any(np.nan_to_num(g[:, a]) != 0)}
            kinked = {inputs[a] for a in range(m)
                      if np.any(finite & ((~finite0[a]) | (gaps[a] > AFFINE_RTOL)))}
        # sign(w): no derivative anywhere, yet f(w) is not f(0): used (kinked), not dropped
        dropped = [v for a, v in enumerate(inputs) if not used[a] and v not in in_outputs and v not in kinked]
        for v in dropped:  # the same note as the expression route's (tests/test_general_form.py)
            kind = "known" if v in known_inputs else "unknown"
            notes.append(f"{kind} input {v!r} appears in no equation: dropped")
        keep = [a for a, v in enumerate(inputs) if v not in dropped]
        kept = tuple(inputs[a] for a in keep)
        kept_unknown = tuple(v for v in unknown_inputs if v in kept)
        reasons = promotion_reasons(
            kept, kept_unknown, in_outputs, {},
            lambda: pattern_from_derivatives(f, J[:, :, keep], H[:, :, keep][:, :, :, keep], zs[:, n0 + P:][:, keep]),
            after={v: "is not affine between 0 and its box (a kink, branch or singularity: abs/sign/min/max, "
                      "where, ...)" for v in kinked})
    else:
        dropped = []
    return _assemble_callable(states, dynamics, outputs, known_inputs, unknown_inputs, dropped, reasons,
                              params, domain, angles, tuple(notes))


def _measure(dynamics, outputs, zs, n0, P, nk):
    """Values at the affinity samples ``zs`` ``(S, n0 + P + m)`` (numpy, float64).

    Returns ``f (S, n)``, ``J (S, n, m)`` and ``H (S, n, m, m)`` at the samples, ``J0`` the
    Jacobian at ``v = 0``, ``gaps (m, S)`` the relative distance of ``f(z, v_a e_a)`` from
    its affine part at 0, ``finite0 (m, S)`` where that check is finite, and output name ->
    ``(S, m)`` gradient in ``v``.
    """
    m = zs.shape[1] - n0 - P

    def F(zp, v):
        return jnp.asarray(dynamics(zp[:n0], zp[n0:], v[:nk], v[nk:])).astype(zp.dtype)

    def one(zp, v):
        zero = jnp.zeros_like(v)
        f0 = F(zp, zero)
        J0 = jax.jacfwd(F, 1)(zp, zero)

        def gap(a):
            va = zero.at[a].set(v[a])
            fa = F(zp, va)
            lin = f0 + J0[:, a] * v[a]
            scale = jnp.abs(f0) + jnp.abs(J0[:, a] * v[a]) + TINY
            ok = jnp.all(jnp.isfinite(fa)) & jnp.all(jnp.isfinite(lin))
            return jnp.max(jnp.where(jnp.isfinite(fa - lin), jnp.abs(fa - lin) / scale, 0.0)), ok

        gaps, oks = jax.vmap(gap)(jnp.arange(m))
        grads = {k: jax.grad(lambda vv, h=h: jnp.asarray(h(zp[:n0], zp[n0:], vv[:nk], vv[nk:])).astype(vv.dtype))(v)
                 for k, h in outputs.items()}
        return F(zp, v), jax.jacfwd(F, 1)(zp, v), jax.hessian(F, 1)(zp, v), J0, gaps, oks, grads

    zs = jnp.asarray(zs)
    f, J, H, J0, gaps, oks, grads = jax.jit(jax.vmap(one))(zs[:, :n0 + P], zs[:, n0 + P:])
    return (np.asarray(f), np.asarray(J), np.asarray(H), np.asarray(J0), np.asarray(gaps).T,
            np.asarray(oks).T, {k: np.asarray(g) for k, g in grads.items()})


def _assemble_callable(states, dynamics, outputs, known_inputs, unknown_inputs, dropped, reasons, params,
                       domain, angles, notes):
    """:func:`uio_jax._io.affine._assemble` for callables: the System's functions on ``z = [x; promoted; p]``."""
    pnames = tuple(params)
    n0, nk = len(states), len(known_inputs)
    inputs = known_inputs + unknown_inputs
    m = len(inputs)
    kept_known = tuple(v for v in known_inputs if v not in dropped)
    kept_unknown = tuple(v for v in unknown_inputs if v not in dropped)
    promoted = tuple(v for v in kept_known + kept_unknown if v in reasons)
    rest = tuple(v for v in kept_known + kept_unknown if v not in promoted)
    new_states = tuple(states) + promoted
    n = len(new_states)
    at_promoted = np.array([inputs.index(v) for v in promoted], dtype=int)
    at_rest = np.array([inputs.index(v) for v in rest], dtype=int)
    nrest = len(rest)

    def split(z, r):
        """``x, p, u, w`` of the user's callables from ``z = [x; promoted; p]`` and the inputs ``r``."""
        z = jnp.asarray(z)
        dtype = jnp.result_type(z.dtype, float)
        v = jnp.zeros(m, dtype=dtype)
        if len(promoted):
            v = v.at[at_promoted].set(z[n0:n])
        if nrest:
            v = v.at[at_rest].set(jnp.asarray(r, dtype=dtype))
        return z[:n0], z[n:], v[:nk], v[nk:]

    def rows(z, r):
        out = jnp.asarray(dynamics(*split(z, r))).astype(jnp.result_type(jnp.asarray(z).dtype, float))
        return jnp.concatenate([out, jnp.zeros(n - n0, dtype=out.dtype)]) if n > n0 else out

    def drift(z):
        return rows(z, jnp.zeros(nrest))

    def field_of(i):
        def fi(z):
            r0 = jnp.zeros(nrest, dtype=jnp.result_type(jnp.asarray(z).dtype, float))
            return jax.jvp(lambda r: rows(z, r), (r0,), (r0.at[i].set(1.0),))[1]

        return fi

    def unit(j):
        def ej(z):
            return jnp.zeros(n, dtype=jnp.result_type(jnp.asarray(z).dtype, float)).at[j].set(1.0)

        return ej

    def output_of(h):
        def y(z):
            return jnp.asarray(h(*split(z, jnp.zeros(nrest))))

        return y

    def has_drift(boxes):
        with jax.enable_x64(True):
            vals = np.asarray(jax.jit(jax.vmap(drift))(jnp.asarray(affine_points(boxes, 1))))
        finite = np.isfinite(vals).all(axis=1)
        return not (finite.any() and not np.any(vals[finite] != 0.0))

    taken = set(states) | set(pnames) | set(inputs) | set(outputs)
    return build_parts(states, promoted, kept_known, kept_unknown, outputs, reasons, params, domain, angles, notes,
                  taken, field_of=field_of, output_of=output_of, unit=unit, drift=drift, has_drift=has_drift)
