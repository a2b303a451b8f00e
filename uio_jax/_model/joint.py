"""The parameter-free System on ``z = [x; p]`` of a System with parameters
(:meth:`uio_jax.System.joint`): every field padded with ``p' = 0``, every callable reading
``x = z[:n]``, ``p = z[n:]``."""

import jax.numpy as jnp


def build_joint(self):
    """The System on ``z = [x; p]`` of ``self`` (:meth:`uio_jax.System.joint`); it validates itself."""
    n, P = self.n, len(self.params)

    if self.time is None:
        def scalar(fn):
            return lambda z: fn(z[:n], z[n:])

        def vector(fn):
            return lambda z: jnp.concatenate([fn(z[:n], z[n:]), jnp.zeros(P, dtype=z.dtype)])
    else:  # a time-varying joint System: its callables take (z, t)
        def scalar(fn):
            return lambda z, t: fn(z[:n], z[n:], t)

        def vector(fn):
            return lambda z, t: jnp.concatenate([fn(z[:n], z[n:], t), jnp.zeros(P, dtype=z.dtype)])

    joint = type(self)(  # System, without importing it back (no import cycle)
        self.states + tuple(self.params),
        {k: scalar(fn) for k, fn in self.outputs.items()},
        known={k: vector(fn) for k, fn in self.known.items()},
        unknown={k: vector(fn) for k, fn in self.unknown.items()},
        drift=None if self.drift is None else vector(self.drift),
        domain={**self.domain, **self.params},
        angles=self.angles,
        name=self.name,
        notes=self.notes,
        time=self.time,
    )
    joint.mark_derived(joint_params=tuple(self.params))
    if self.time is not None:  # built before the joint knew its parameters: mark it too
        joint.autonomous().mark_derived(joint_params=tuple(self.params))
    object.__setattr__(self, "notes", joint.notes)  # with the notes of its finiteness check
    return joint


__all__ = ["build_joint"]
