"""A user's function of the analysed vector, for :meth:`uio_jax.Report.is_observable`.

``fn(z)`` with ``z = [x; p]``, or ``fn(x, p)`` for a model with parameters, turned into a
function of ``z`` and checked on shapes (numpy first, which raises on an index JAX would
clamp; then ``jax.eval_shape``) before anything is evaluated.
"""

import inspect

import numpy as np

from ..._errors import ModelError


def function_of_z(report, fn, what):
    """``fn`` as a function of ``z (n,)`` of the report's variables, checked on shapes.

    ``fn(z)``, or ``fn(x, p)`` for a model with parameters, read from the number of required
    positional parameters (:func:`positional_arity`).

    Raises:
        ModelError: one line: not a callable, a signature of neither form, a function that
            indexes outside its arguments, fails on those shapes or does not return a scalar.
    """
    ns, npar = len(report.states), len(report.params)
    forms = (f"fn(x) with x ({report.n},)" if not npar else
             f"fn(z) with z = [x; p] ({report.n},) or fn(x, p) with x ({ns},), p ({npar},)")
    if not callable(fn):
        raise ModelError(f"{what} needs a callable {forms}, got {type(fn).__name__}")
    nargs = positional_arity(fn)
    if nargs == 2 and npar:
        def of_z(z):
            return fn(z[:ns], z[ns:])
        of_z.__name__ = getattr(fn, "__name__", "fn")
        form = f"fn(x, p) with x ({ns},), p ({npar},)"
    elif nargs in (None, 1):
        of_z = fn
        form = f"fn(z) with z ({report.n},)" if npar else f"fn(x) with x ({report.n},)"
    else:
        has = "no parameters" if not npar else f"{npar} parameters"
        raise ModelError(f"{what} needs {forms} (this model has {has}); got a function "
                         f"of {nargs} required positional arguments")
    try:  # JAX clamps an index past the end (p[5] of 2): plain numpy raises instead
        of_z(np.full(report.n, 0.75))
    except IndexError as exc:
        raise ModelError(f"{what}: {form} indexes outside its arguments ({exc})") from None
    except Exception:  # numpy input not supported by this function: the trace decides
        pass
    import jax  # the user's JAX callable
    import jax.numpy as jnp

    with jax.enable_x64(True):
        try:
            out = jax.eval_shape(of_z, jax.ShapeDtypeStruct((report.n,), jnp.float64))
        except Exception as exc:  # the user's function: any failure is a bad function
            msg = (str(exc).strip().splitlines() or [""])[0][:160]
            raise ModelError(f"{what}: {form} fails ({type(exc).__name__}"
                             f"{': ' + msg if msg else ''}); expected {forms}") from None
    if getattr(out, "shape", None) != ():
        raise ModelError(f"{what}: function must return a scalar (), got shape "
                         f"{getattr(out, 'shape', None)}")
    if np.issubdtype(np.dtype(getattr(out, "dtype", np.float64)), np.complexfloating):
        raise ModelError(f"{what}: function returns a complex value ({out.dtype}); it must be real")
    return of_z


def positional_arity(fn):
    """Required positional parameters of ``fn``; None when it takes ``*args`` or is opaque."""
    try:
        sig = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    kinds = [q.kind for q in sig.parameters.values()]
    if inspect.Parameter.VAR_POSITIONAL in kinds:
        return None
    positional = [q for q in sig.parameters.values()
                  if q.kind in (q.POSITIONAL_ONLY, q.POSITIONAL_OR_KEYWORD)]
    required = sum(1 for q in positional if q.default is q.empty)
    return required if required or not positional else 1


__all__ = ["function_of_z", "positional_arity"]
