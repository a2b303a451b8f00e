"""The one check of every seed (the analyses' samples, the Monte Carlo trials, the command
line), without JAX: a seed is an integer in ``[0, 2**64)``, the 64 bits of a key of
:mod:`uio_jax._engine.threefry`."""

import numbers

from .._errors import OptionError

#: Seeds are integers in ``[0, SEED_BOUND)``: a key holds 64 bits.
SEED_BOUND = 2**64


def check_seed(seed, what: str = "seed") -> int:
    """``seed`` as a Python int, checked to be an integer in ``[0, 2**64)``: the one check
    of every seed (the analyses' samples, the Monte Carlo trials, the command line).

    Args:
        seed: an integer (numpy integers too; not a bool).
        what: its name in the message (``"--seed"`` on the command line).

    Raises:
        OptionError: not an integer, negative, or ``>= 2**64``.
    """
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or not 0 <= seed < SEED_BOUND:
        raise OptionError(f"{what} must be a non-negative integer below 2**64, got {seed!r}")
    return int(seed)


__all__ = ["SEED_BOUND", "check_seed"]
