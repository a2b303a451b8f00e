"""Seeded random states of a System's domain box."""

import numpy as np


def sample_states(system, samples: int, seed: int = 0) -> np.ndarray:
    """Draw states uniformly in the system's sampling box.

    numpy's default generator (PCG64) seeded with ``seed``: the same seed gives the same
    states on every machine, and drawing them compiles nothing.

    Args:
        system: a :class:`~uio_jax.System`.
        samples: number of states S.
        seed: integer seed in ``[0, 2**64)``.

    Returns:
        numpy array of shape ``(S, n)``, float64.
    """
    lo, hi = system.box()
    u = np.random.default_rng(int(seed)).random((samples, system.n))
    return np.asarray(lo, dtype=np.float64) + u * np.asarray(hi - lo, dtype=np.float64)
