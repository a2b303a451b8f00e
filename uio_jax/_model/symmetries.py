"""Declared symmetries of a System: the user's claim, carried to the analysed coordinates.

A symmetry is a vector field ``xi`` on ``z = [x; p]`` along which the user believes the model
invariant; the analyses verify the claim before they use it
(:mod:`uio_jax._analysis.decisions.symmetry`). A symmetry callable takes the arguments of every
other callable of the System and returns shape ``(n + len(params),)``: its components along the
states, then along the parameters. It never moves time.
"""

from types import MappingProxyType

import numpy as np

from .._errors import ModelError
from .arguments import as_callables


def as_symmetries(mapping):
    """The ``symmetries=`` argument as a read-only mapping name -> callable."""
    return as_callables({} if mapping is None else mapping, "symmetries")


def check_symmetry_shapes(system) -> None:
    """Trace each declared symmetry once on the System's arguments: it must return a real
    array of shape ``(n + len(params),)``.

    Raises:
        ModelError: it fails to trace, returns another shape, or a complex value, or it is
            NaN/inf at every one of a few states of the box (its centre and three others).
    """
    if not system.symmetries:
        return
    import jax
    import jax.numpy as jnp

    n, P = system.n, len(system.params)
    args = [jax.ShapeDtypeStruct((n,), jnp.float64)]
    if P:
        args.append(jax.ShapeDtypeStruct((P,), jnp.float64))
    if system.time is not None:
        args.append(jax.ShapeDtypeStruct((), jnp.float64))
    want = n + P
    with jax.enable_x64(True):
        for name, fn in system.symmetries.items():
            try:
                out = jax.eval_shape(fn, *args)
            except Exception as exc:  # the user's function fails to trace
                msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                raise ModelError(f"symmetry {name!r} fails on the System's arguments: "
                                 f"{type(exc).__name__}: {msg}") from None
            shape = tuple(getattr(out, "shape", ()) or ())
            if shape != (want,):
                of = f"{n} states + {P} parameters" if P else f"{n} states"
                raise ModelError(f"symmetry {name!r} returns shape {shape}, expected ({want},) ({of})")
            if np.issubdtype(np.dtype(getattr(out, "dtype", np.float64)), np.complexfloating):
                raise ModelError(f"symmetry {name!r} returns a complex value; a symmetry must be real")
            if not any(np.isfinite(np.asarray(fn(*point))).all() for point in _probe_points(system)):
                raise ModelError(f"symmetry {name!r} is NaN/inf at every state tried in the domain "
                                 "(its centre and three others): check the field")


def _probe_points(system):
    """The arguments of a System's functions at the centre of its box and three other fixed
    states of it (parameters and time likewise)."""
    import jax.numpy as jnp

    lo, hi = system.box()  # the states
    boxes = [system.params[p] for p in system.params]  # parameters, then time
    if system.time is not None:
        boxes.append(system.time_box)
    for t in (0.5, 0.21, 0.63, 0.87):
        args = [jnp.asarray(lo + t * (hi - lo))]
        extra = [float(a) + t * (float(b) - float(a)) for a, b in boxes]
        if system.params:
            args.append(jnp.asarray(extra[:len(system.params)]))
        if system.time is not None:
            args.append(jnp.asarray(extra[-1]))
        yield args


def lifted_symmetries(system):
    """The declared symmetries of a System with parameters or time as fields of the
    coordinates its analyses run on (:meth:`~uio_jax.System.autonomous`, ``z = [x; p; t]``:
    zero along time), name -> ``z (N,) -> (N,)``, read-only; None without symmetries or when
    they are such fields already (no parameter, no time)."""
    if not system.symmetries or (not system.params and system.time is None):
        return None
    n, P, timed = system.n, len(system.params), system.time is not None
    return MappingProxyType({k: _lift(fn, n, P, timed) for k, fn in system.symmetries.items()})


def _lift(fn, n, P, timed):
    def xi(z):
        import jax.numpy as jnp

        args = [z[:n]] + ([z[n:n + P]] if P else []) + ([z[n + P]] if timed else [])
        v = fn(*args)
        return jnp.concatenate([v, jnp.zeros(1, dtype=z.dtype)]) if timed else v

    xi.__doc__ = getattr(fn, "__doc__", None)
    return xi


def symmetry_fields(analysed) -> "MappingProxyType":
    """The declared symmetries of an analysed System (:meth:`~uio_jax.System.autonomous`) as
    fields of its coordinates, name -> ``z (N,) -> (N,)``; empty when none was declared."""
    return analysed.symmetry_fields
