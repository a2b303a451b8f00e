"""The shapes of an experiment's functions, checked by tracing them once (``jax.eval_shape``,
nothing computed) before the filter is compiled: a wrong shape is a one-line ModelError
that names the function, not a JAX error from inside the filter."""

import jax
import jax.numpy as jnp
import numpy as np

from .._errors import ModelError


def check_shapes(exp):
    """The input law ``inputs(istate, z) -> (istate, u, w)`` keeps the shape of
    ``istate0`` and gives as many known (unknown) inputs as the system has; every named
    quantity ``q(x)`` is a scalar. Call with float64 on (``jax.enable_x64``).

    Raises:
        ModelError: the first function that fails on those shapes or returns another one.
    """
    f64 = jnp.float64
    istate0 = np.asarray(exp.istate0, np.float64)
    m, p = len(exp.system.known), len(exp.system.unknown)
    what = f"experiment {exp.name!r}: inputs(istate, z)"
    out = _trace(what, exp.inputs, jax.ShapeDtypeStruct(istate0.shape, f64),
                 jax.ShapeDtypeStruct((exp.n_input_normals,), f64),
                 given=f"istate of shape {istate0.shape} and z of shape ({exp.n_input_normals},)")
    if not isinstance(out, (tuple, list)) or len(out) != 3:
        raise ModelError(f"{what} must return (istate, u, w), got {type(out).__name__}")
    for name, got, size in (("istate", out[0], istate0.size), ("u", out[1], m), ("w", out[2], p)):
        shape = tuple(np.shape(got)) if not hasattr(got, "shape") else tuple(got.shape)
        if int(np.prod(shape)) != size:
            want = f"the shape of istate0 {istate0.shape}" if name == "istate" else \
                f"{size} {'known' if name == 'u' else 'unknown'} input{'s' if size != 1 else ''}"
            raise ModelError(f"{what} returns {name} of shape {shape}, expected {want}")
    for q in exp.quantities:
        what = f"experiment {exp.name!r}: quantity {q.name!r}"
        out = _trace(what, q.fn, jax.ShapeDtypeStruct((exp.n,), f64), given=f"x of shape ({exp.n},)")
        if tuple(getattr(out, "shape", (None,))) != ():
            raise ModelError(f"{what} must return a scalar (), got shape {tuple(getattr(out, 'shape', ()))}")


def _trace(what, fn, *args, given):
    try:
        return jax.eval_shape(fn, *args)
    except ModelError:
        raise
    except Exception as exc:  # the user's function: any failure is a bad function
        msg = (str(exc).strip().splitlines() or [""])[0][:160]
        raise ModelError(f"{what} fails on {given}: {type(exc).__name__}{': ' + msg if msg else ''}") from None
