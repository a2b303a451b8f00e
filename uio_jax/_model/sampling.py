"""Seeded random states of a System's domain box."""

import jax
import jax.numpy as jnp
import numpy as np


def sample_states(system, samples: int, seed: int = 0) -> jax.Array:
    """Draw states uniformly in the system's sampling box.

    Args:
        system: a :class:`~uio_jax.System`.
        samples: number of states S.
        seed: integer seed in ``[0, 2**64)``; the same seed gives the same states (a seed
            from 2**63 up is passed to ``jax.random.key`` as a uint64, which gives the key
            of a smaller seed unchanged).

    Returns:
        Array of shape ``(S, n)``, float64 (call under ``jax.enable_x64(True)``).
    """
    lo, hi = system.box()
    key = jax.random.key(int(seed) if seed < 2**63 else np.uint64(seed))
    u = jax.random.uniform(key, (samples, system.n), dtype=jnp.float64)
    return jnp.asarray(lo) + u * jnp.asarray(hi - lo)
