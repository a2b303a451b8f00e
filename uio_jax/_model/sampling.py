"""Seeded random states of a System's domain box."""

import jax
import jax.numpy as jnp


def sample_states(system, samples: int, seed: int = 0) -> jax.Array:
    """Draw states uniformly in the system's sampling box.

    Args:
        system: a :class:`~uio_jax.System`.
        samples: number of states S.
        seed: integer seed; the same seed gives the same states.

    Returns:
        Array of shape ``(S, n)``, float64 (call under ``jax.enable_x64(True)``).
    """
    lo, hi = system.box()
    u = jax.random.uniform(jax.random.key(seed), (samples, system.n), dtype=jnp.float64)
    return jnp.asarray(lo) + u * jnp.asarray(hi - lo)
