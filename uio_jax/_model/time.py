"""Time-varying Systems made autonomous: time as a known state with ``t' = 1``.

A time-varying :class:`~uio_jax.System` (``time="t"``) has callables of ``(x, t)``
(``(x, p, t)`` with parameters). Its parameters are first made states by
:meth:`System.joint` (``[x; p]``, ``p' = 0``; the joint System is still time-varying), then
:func:`build_autonomous` appends the time coordinate::

    z = [x; p; t],   z' = [f0(x, p, t); 0; 1] + sum_i [f_i(x, p, t); 0; 0] u_i
                           + sum_j [g_j(x, p, t); 0; 0] w_j,
    y = (h(x, p, t), t).

Time is measured (the extra output named like the time variable reads ``z[-1]``), so an
analysis of this System has ``dt`` in its codistribution from the start; the System is
marked with ``known_coordinates = 1`` and ``time_name`` so that the analyses leave ``t``
out of their verdicts. This is exact: along any trajectory of the time-varying system,
``t(s) = t0 + s`` is the solution of ``t' = 1`` and ``t0`` is known.
"""

import jax.numpy as jnp


def build_autonomous(system):
    """The autonomous System on ``z = [x; t]`` of a parameter-free time-varying System.

    Args:
        system: a :class:`~uio_jax.System` with ``time`` set and no ``params`` (the joint
            System of a time-varying System with parameters), ``n`` states.

    Returns:
        A System with ``n + 1`` states (``system.states`` then the time name), no params, no
        time argument: drift ``[f0(x, t); 1]`` (``[0; 1]`` without drift), fields
        ``[f_i(x, t); 0]``, outputs ``h(x, t)`` and ``t`` (named like the time variable),
        domain the state boxes then the time box, the same angles, name and notes. Its
        ``known_coordinates`` is 1 and ``time_name`` the time name. It validates itself (its
        finiteness check draws ``t`` in the time box); ``system.notes`` receives the notes of
        that check.
    """
    if system.time is None or system.params:
        raise ValueError("build_autonomous takes a time-varying System without params")
    n = system.n
    time = system.time

    def scalar(fn):
        return lambda z: fn(z[:n], z[n])

    def vector(fn):
        def f(z):
            v = jnp.asarray(fn(z[:n], z[n]))
            return jnp.concatenate([v, jnp.zeros(1, dtype=v.dtype)])

        return f

    f0 = system.drift

    def drift(z):
        if f0 is None:
            return jnp.zeros(n + 1, dtype=jnp.result_type(z.dtype, float)).at[n].set(1.0)
        v = jnp.asarray(f0(z[:n], z[n]))
        return jnp.concatenate([v, jnp.ones(1, dtype=v.dtype)])

    def clock(z):
        return jnp.asarray(z[n])

    outputs = {k: scalar(fn) for k, fn in system.outputs.items()}
    outputs[time] = clock
    auto = type(system)(  # System, without importing it back (no import cycle)
        system.states + (time,),
        outputs,
        known={k: vector(fn) for k, fn in system.known.items()},
        unknown={k: vector(fn) for k, fn in system.unknown.items()},
        drift=drift,
        domain={**{s: system.domain[s] for s in system.states}, time: system.time_box},
        angles=system.angles,
        name=system.name,
        notes=system.notes,
    )
    auto.mark_derived(known_coordinates=1, time_name=time)
    object.__setattr__(system, "notes", auto.notes)  # with the notes of its finiteness check
    return auto
