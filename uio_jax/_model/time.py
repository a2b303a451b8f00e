"""Time-varying Systems made autonomous: time as a known state with ``t' = 1``.

A time-varying :class:`~uio_jax.System` (``time="t"``) has callables of ``(x, t)``
(``(x, p, t)`` with parameters). Its parameters are first made states by
:meth:`System.joint` (``[x; p]``, ``p' = 0``; the joint System is still time-varying), then
:func:`build_autonomous` appends the time coordinate::

    z = [x; p; t],   z' = [f0(x, p, t); 0; 1] + sum_i [f_i(x, p, t); 0; 0] u_i
                           + sum_j [g_j(x, p, t); 0; 0] w_j,
    y = (h(x, p, t), t).

Time is measured (the extra output named like the time variable reads ``z[-1]``), so ``dt``
is in every codistribution from the start; ``known_coordinates = 1`` and ``time_name`` make
the analyses leave ``t`` out of their verdicts. This is exact: ``t(s) = t0 + s``, ``t0`` known.
"""

import numpy as np

from .._engine.graph_trace import graph_native
from .derivation import Derivation
from .joint import Coordinate, append_constants


class TimedFunction:
    """``z -> fn(z[:n], z[n])`` (the time is the last coordinate), followed by the constants
    ``tail`` (a field's ``t' = 0``, the drift's ``t' = 1``; none for an output); ``fn`` None:
    no drift, ``z -> [0, .., 0] + tail``. Computes with numpy on numpy arrays, with
    ``jax.numpy`` on JAX arrays, and builds its own expression (``emit``) when ``fn`` does
    (:mod:`uio_jax._engine.graph_trace`).
    """

    __slots__ = ("fn", "n", "tail", "__weakref__")

    def __init__(self, fn, n, tail=()):
        self.fn, self.n, self.tail = fn, n, tuple(tail)

    @property
    def graph_native(self) -> bool:
        """Whether ``fn`` builds its own expression (then so does this function)."""
        return self.fn is None or graph_native(self.fn)

    def __call__(self, z):
        if self.fn is None:
            if isinstance(z, np.ndarray):
                return append_constants(np.zeros(self.n), self.tail)
            import jax.numpy as jnp

            return append_constants(jnp.zeros(self.n, dtype=jnp.result_type(z.dtype, float)), self.tail)
        out = self.fn(z[:self.n], z[self.n])
        return append_constants(out, self.tail) if self.tail else out

    def emit(self, z):
        """The expression at ``z``, when ``fn`` builds its own; else None."""
        if self.fn is None:
            return [0.0] * self.n + list(self.tail)
        if not graph_native(self.fn):
            return None
        out = self.fn.emit(z[:self.n], z[self.n])
        return list(out) + list(self.tail) if self.tail else out


def build_autonomous(system, joint_params=(), symmetry_fields=None):
    """The autonomous System on ``z = [x; t]`` of a parameter-free time-varying System.

    Args:
        system: a :class:`~uio_jax.System` with ``time`` set and no ``params`` (the joint
            System of a time-varying System with parameters), ``n`` states.
        joint_params: the coordinates of ``x`` that are parameters of the user's model (the
            joint System's :attr:`~uio_jax.System.joint_param_names`).
        symmetry_fields: the declared symmetries as fields of ``[x; t]``, or None.

    Returns:
        A System with ``n + 1`` states (``system.states`` then the time name), no params, no
        time argument: drift ``[f0(x, t); 1]`` (``[0; 1]`` without drift), fields
        ``[f_i(x, t); 0]``, outputs ``h(x, t)`` and ``t`` (named like the time variable),
        domain the state boxes then the time box; ``known_coordinates`` 1, ``time_name`` the
        time name. It validates itself (drawing ``t`` in the time box).
    """
    if system.time is None or system.params:
        raise ValueError("build_autonomous takes a time-varying System without params")
    n = system.n
    time = system.time
    outputs = {k: TimedFunction(fn, n) for k, fn in system.outputs.items()}
    outputs[time] = Coordinate(n)  # the time, measured
    return type(system)(  # System, without importing it back (no import cycle)
        system.states + (time,),
        outputs,
        known={k: TimedFunction(fn, n, (0.0,)) for k, fn in system.known.items()},
        unknown={k: TimedFunction(fn, n, (0.0,)) for k, fn in system.unknown.items()},
        drift=TimedFunction(system.drift, n, (1.0,)),
        domain={**{s: system.domain[s] for s in system.states}, time: system.time_box},
        angles=system.angles,
        name=system.name,
        notes=system.notes,
        derivation=Derivation(known_coordinates=1, time_name=time, joint_params=tuple(joint_params),
                              symmetry_fields=symmetry_fields),
    )


__all__ = ["TimedFunction", "build_autonomous"]
