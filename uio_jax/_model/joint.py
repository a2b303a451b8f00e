"""The parameter-free System on ``z = [x; p]`` of a System with parameters
(:meth:`uio_jax.System.joint`): every field padded with ``p' = 0``, every callable reading
``x = z[:n]``, ``p = z[n:]``.

The callables are small objects rather than closures: numpy on numpy arrays, ``jax.numpy`` on
JAX arrays, and their own expression (``emit``) when the user's function builds one, so that
the joint System of a model file reaches the graph without JAX.
"""

import numpy as np

from .._engine.graph_trace import graph_native
from .derivation import Derivation


def append_constants(v, values):
    """The vector ``v`` followed by the constants ``values``: numpy for a numpy ``v``, else
    ``jax.numpy`` (the constants in ``v``'s dtype)."""
    if isinstance(v, (np.ndarray, np.generic, float)):
        return np.concatenate([np.reshape(np.asarray(v, dtype=np.float64), -1), np.asarray(values, dtype=np.float64)])
    import jax.numpy as jnp

    v = jnp.asarray(v)
    return jnp.concatenate([v, jnp.asarray(values, dtype=v.dtype)])


class PaddedFunction:
    """``z -> fn(z[:n], z[n:])`` (``(z, t) -> fn(z[:n], z[n:], t)`` for a time-varying System;
    ``fn(z[:n])`` without ``rest``), followed by ``pad`` zeros (a field's ``p' = 0``; 0 for an
    output).

    Args:
        fn: the function of ``(x, p)`` (or ``(x, p, t)``; of ``x`` alone without ``rest``).
        n: the number of coordinates ``x``.
        pad: the number of zeros appended (the number of coordinates after ``x`` for a field,
            0 for an output).
        rest: whether ``fn`` also takes the coordinates after ``x`` (``p``).
    """

    __slots__ = ("fn", "n", "pad", "rest", "__weakref__")

    def __init__(self, fn, n, pad, rest=True):
        self.fn, self.n, self.pad, self.rest = fn, n, pad, rest

    @property
    def graph_native(self) -> bool:
        """Whether ``fn`` builds its own expression (then so does this function)."""
        return graph_native(self.fn)

    def _args(self, z, t):
        return (z[:self.n], z[self.n:], *t) if self.rest else (z[:self.n], *t)

    def __call__(self, z, *t):
        out = self.fn(*self._args(z, t))
        return append_constants(out, [0.0] * self.pad) if self.pad else out

    def emit(self, z, *t):
        """The expression at ``z`` (and ``t``), when ``fn`` builds its own; else None."""
        if not graph_native(self.fn):
            return None
        out = self.fn.emit(*self._args(z, t))
        return out if not self.pad else list(out) + [0.0] * self.pad


class Coordinate:
    """``z -> z[i]``: one coordinate, measured (the time of the autonomous System, a jet of a
    smooth known input, a promoted known input)."""

    __slots__ = ("i", "__weakref__")
    graph_native = True

    def __init__(self, i):
        self.i = int(i)

    def __call__(self, z):
        return z[self.i]

    def emit(self, z):
        """The coordinate's node."""
        return z[self.i]


def build_joint(self, symmetry_fields=None):
    """The System on ``z = [x; p]`` of ``self`` (:meth:`uio_jax.System.joint`); it validates
    itself. ``symmetry_fields``: the declared symmetries as fields of the coordinates the
    analyses run on (:func:`uio_jax._model.symmetries.lifted_symmetries`), or None."""
    n, P = self.n, len(self.params)
    return type(self)(  # System, without importing it back (no import cycle)
        self.states + tuple(self.params),
        {k: PaddedFunction(fn, n, 0) for k, fn in self.outputs.items()},
        known={k: PaddedFunction(fn, n, P) for k, fn in self.known.items()},
        unknown={k: PaddedFunction(fn, n, P) for k, fn in self.unknown.items()},
        drift=None if self.drift is None else PaddedFunction(self.drift, n, P),
        domain={**self.domain, **self.params},
        angles=self.angles,
        name=self.name,
        notes=self.notes,
        time=self.time,
        derivation=Derivation(joint_params=tuple(self.params), symmetry_fields=symmetry_fields),
    )


__all__ = ["Coordinate", "PaddedFunction", "append_constants", "build_joint"]
