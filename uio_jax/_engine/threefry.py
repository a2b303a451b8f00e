"""JAX's default random numbers (threefry2x32), written as plain unrolled arithmetic.

The Monte Carlo filter draws all its noise with these functions. They give bit for bit
the numbers of ``jax.random.fold_in`` / ``split`` / ``bits`` / ``normal`` (float32) with
JAX's default ``threefry2x32`` keys and ``jax_threefry_partitionable=True`` (the default
since JAX 0.5), which ``tests/test_threefry.py`` checks. Keys are raw ``uint32`` arrays of
shape ``(2,)`` (what ``jax.random.key_data`` returns), so they vmap like any array.

Why not ``jax.random``: on a CPU, JAX lowers each threefry hash as a rolled ``while``
loop, which XLA compiles as separate kernels at a compile cost of a fraction of a CPU-second
per hash; the unrolled hash below (about 100 integer operations) fuses into the kernels that
use the numbers. The measurements are in ``docs/benchmarks/ekf.md`` (run 9).

Threefry-2x32 with 20 rounds (Salmon et al., "Parallel random numbers: as easy as 1, 2,
3", SC 2011): key ``(k0, k1)``, ``k2 = k0 ^ k1 ^ 0x1BD11BDA``; counter ``(x0, x1)``;
``x0 += k0, x1 += k1``; then 5 times: 4 rounds ``x0 += x1; x1 = rotl(x1, r) ^ x0`` with
rotations ``(13, 15, 26, 6)`` and ``(17, 29, 16, 24)`` alternately, and key injection
``x0 += k[(i+1) % 3], x1 += k[(i+2) % 3] + i + 1``.
"""

import jax.numpy as jnp
import numpy as np
from jax import lax

from .seeds import SEED_BOUND as SEED_BOUND  # the seed rule, imported from here too
from .seeds import check_seed as check_seed

_U32 = np.uint32
_ROTATIONS = ((13, 15, 26, 6), (17, 29, 16, 24))
_PARITY = 0x1BD11BDA


def _rotate_left(x, d: int):
    return lax.bitwise_or(lax.shift_left(x, _U32(d)), lax.shift_right_logical(x, _U32(32 - d)))


def threefry2x32(k0, k1, x0, x1):
    """The threefry-2x32 hash of counters ``(x0, x1)`` under key ``(k0, k1)``.

    Args:
        k0, k1: ``uint32`` key words (scalars, or arrays that broadcast with the counters).
        x0, x1: ``uint32`` counter words, any (broadcastable) shape.

    Returns:
        ``(y0, y1)``, two ``uint32`` arrays of the broadcast shape.
    """
    # lax, not jnp, operators: each jnp operator is a small jitted function, and the ~110
    # operators of an unrolled hash would cost their dispatch at every trace
    k0, k1, x0, x1 = (jnp.asarray(a, jnp.uint32) for a in (k0, k1, x0, x1))
    x0, x1 = jnp.broadcast_arrays(x0, x1)
    ks = (k0, k1, lax.bitwise_xor(lax.bitwise_xor(k0, k1), _U32(_PARITY)))
    x0 = lax.add(x0, ks[0])
    x1 = lax.add(x1, ks[1])
    for i in range(5):
        for r in _ROTATIONS[i % 2]:
            x0 = lax.add(x0, x1)
            x1 = lax.bitwise_xor(_rotate_left(x1, r), x0)
        x0 = lax.add(x0, ks[(i + 1) % 3])
        x1 = lax.add(x1, lax.add(ks[(i + 2) % 3], _U32(i + 1)))
    return x0, x1


def seed_key(seed: int) -> np.ndarray:
    """The key of an integer seed: ``jax.random.key_data(jax.random.key(seed))``.

    Args:
        seed: integer in ``[0, 2**64)``.

    Returns:
        ``uint32`` array ``[seed >> 32, seed & 0xFFFFFFFF]``, shape ``(2,)``.
    """
    seed = int(seed)
    if not 0 <= seed < 2**64:
        raise ValueError(f"seed must be in [0, 2**64), got {seed}")
    return np.array([seed >> 32, seed & 0xFFFFFFFF], np.uint32)


def fold_in(key, data):
    """``jax.random.fold_in`` for a ``uint32`` key ``(2,)`` and data in ``[0, 2**32)``.

    Args:
        key: ``uint32`` ``(2,)``.
        data: non-negative integer scalar (traced or not), below ``2**32``.

    Returns:
        The new key, ``uint32`` ``(2,)``.
    """
    y0, y1 = threefry2x32(key[0], key[1], _U32(0), jnp.asarray(data).astype(jnp.uint32))
    return jnp.stack([y0, y1])


def _hash_counters(key, n: int):
    """The hash of the counters ``(0, i)``, ``i < n``, as partitionable threefry counts."""
    return threefry2x32(key[0], key[1], jnp.zeros(n, jnp.uint32), jnp.arange(n, dtype=jnp.uint32))


def split(key, num: int = 2):
    """``jax.random.split``: ``num`` new keys, ``uint32`` ``(num, 2)``."""
    return jnp.stack(_hash_counters(key, num), axis=1)


def bits(key, n: int):
    """``jax.random.bits(key, (n,), uint32)``: ``n`` random 32-bit words, ``(n,)``."""
    return lax.bitwise_xor(*_hash_counters(key, n))


def normal(key, n: int):
    """``jax.random.normal(key, (n,), float32)``: ``n`` standard normals, float32 ``(n,)``.

    A uniform ``u`` in ``(-1, 1)`` from the 23 high bits of each word (mantissa trick),
    then ``sqrt(2) erfinv(u)``, exactly as JAX does.
    """
    mantissa = lax.bitwise_or(lax.shift_right_logical(bits(key, n), _U32(9)),
                              _U32(0x3F800000))  # the bits of a float in [1, 2)
    f = lax.bitcast_convert_type(mantissa, jnp.float32) - np.float32(1.0)
    lo = np.nextafter(np.float32(-1.0), np.float32(0.0))
    hi = np.float32(1.0)
    u = lax.max(lo, f * (hi - lo) + lo)
    return np.float32(np.sqrt(2.0)) * lax.erf_inv(u)
