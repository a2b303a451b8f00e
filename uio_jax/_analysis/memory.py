"""How much memory an analysis needs, refused before it is allocated.

Every analysis evaluates its codistribution at ``S`` sampled states of its ``N`` coordinates
(``N = n`` for the ORC, the single-input analysis and the series test; ``N = n + K m_w`` for
the EORC on ``Sigma^(K)``, ``K = k_max``). Those arrays are allocated whatever the run turns
out to be (float64, 8 bytes per entry):

==============================  =============  ==================================================
array                           shape          where
==============================  =============  ==================================================
the sampled states              ``(S, N)``     :class:`~uio_jax._analysis.context.Context` ``xs``
the rank basis                  ``(S, N, N)``  :class:`~uio_jax._analysis.rank.Codistribution`
                                               ``basis`` (per sample, an orthonormal basis)
the unit-covector test          4 x            :meth:`~uio_jax._analysis.rank.Codistribution.test_units`
                                ``(S, N, n)``  of ``e_1..e_n`` (covectors, the two residuals,
                                               the directions): the verdict per state
==============================  =============  ==================================================

so :func:`analysis_bytes` = ``8 S N (1 + N + 4 n)`` is a floor: the kept gradients
``(S, r, N)``, the candidate blocks ``(S, c, N)`` of each step and JAX's own buffers come on
top, and depend on the run. A request whose floor exceeds the limit cannot fit and is
refused (:func:`check_memory`) with a one-line :class:`~uio_jax.OptionError` before the
first array exists.

**The limit** (:func:`memory_limit`): ``$UIO_JAX_MEMORY_LIMIT`` if set (bytes, or a number
with a binary suffix: ``512M``, ``4G``, ``1.5T``; ``K`` = 1024), else half of the physical
memory (``0.5 x`` ``os.sysconf`` pages; 8 GiB where the platform does not tell).
"""

import math
import os
import re

from .._errors import OptionError

#: The environment variable that sets the limit, in bytes (suffixes K, M, G, T: powers of 1024).
ENV = "UIO_JAX_MEMORY_LIMIT"

#: Fraction of the physical memory an analysis may use when ``$UIO_JAX_MEMORY_LIMIT`` is unset.
PHYSICAL_FRACTION = 0.5

#: The limit where the physical memory is unknown (no ``os.sysconf``), bytes.
FALLBACK_LIMIT = 8 * 2**30

_SUFFIX = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40, "P": 2**50}
_FLOAT = 8  # bytes per float64 entry


def parse_size(text: str) -> int:
    """Bytes of a size written ``123``, ``512M``, ``4G``, ``1.5T`` (``K`` = 1024; an optional
    ``B`` or ``iB`` after the suffix, any case).

    Raises:
        OptionError: not such a size, or not positive.
    """
    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][+-]?[0-9]+)?)\s*([kKmMgGtTpP]?)(?:i?[bB])?\s*", str(text))
    value = float(m.group(1)) * _SUFFIX[m.group(2).upper()] if m else math.nan
    if not (math.isfinite(value) and value >= 1):
        raise OptionError(f"{ENV} must be a positive size in bytes such as 4G or 512M, got {text!r}")
    return int(value)


def physical_memory() -> int | None:
    """Bytes of physical memory (``SC_PAGE_SIZE x SC_PHYS_PAGES``), or None if unknown."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None
    return int(total) if total > 0 else None


def memory_limit() -> tuple[int, str]:
    """The memory an analysis may take: ``(bytes, where it comes from)``.

    ``$UIO_JAX_MEMORY_LIMIT`` (:func:`parse_size`) if set and non-empty, else
    :data:`PHYSICAL_FRACTION` of :func:`physical_memory`, else :data:`FALLBACK_LIMIT`.

    Raises:
        OptionError: ``$UIO_JAX_MEMORY_LIMIT`` is not a size.
    """
    env = os.environ.get(ENV, "").strip()
    if env:
        return parse_size(env), f"{ENV}={env}"
    phys = physical_memory()
    if phys is None:
        return FALLBACK_LIMIT, f"physical memory unknown; {ENV} overrides"
    return int(PHYSICAL_FRACTION * phys), f"{PHYSICAL_FRACTION:g} x physical memory; {ENV} overrides"


def analysis_bytes(samples: int, coords: int, states: int | None = None) -> dict[str, int]:
    """The arrays every analysis allocates (the floor of its memory), bytes per array.

    Args:
        samples: S, sampled states.
        coords: N, coordinates of the codistribution (``n``, or ``n + K m_w`` for the EORC).
        states: n, original states whose unit covectors are tested (default ``N``).

    Returns:
        ``{"the sampled states": 8 S N, "the rank basis": 8 S N^2,
        "the unit-covector test": 32 S N n}`` (Python ints: no overflow).
    """
    S, N = int(samples), int(coords)
    n = N if states is None else int(states)
    return {
        "the sampled states": _FLOAT * S * N,
        "the rank basis": _FLOAT * S * N * N,
        "the unit-covector test": 4 * _FLOAT * S * N * n,
    }


def format_bytes(b: float) -> str:
    """``b`` bytes in decimal units: ``48.0 GB``, ``131 GB``, ``32300 TB``."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if b >= size:
            v = b / size
            return f"{v:.0f} {unit}" if v >= 100 else f"{v:.1f} {unit}"
    return f"{int(b)} B"


def check_memory(samples: int, coords: int, states: int | None = None, *, what: str,
                 advice: str) -> int:
    """Refuse an analysis whose arrays cannot fit, before any is allocated.

    Args:
        samples, coords, states: as :func:`analysis_bytes`.
        what: the request in words, the start of the message (``"samples=10**9 x 6 states"``).
        advice: what to lower (``"lower samples"``).

    Returns:
        The estimated bytes (the sum of :func:`analysis_bytes`), when within the limit.

    Raises:
        OptionError: one line with the estimate, its largest array, the limit and its source.
    """
    parts = analysis_bytes(samples, coords, states)
    total = sum(parts.values())
    limit, source = memory_limit()
    if total > limit:
        name, size = max(parts.items(), key=lambda kv: kv[1])
        raise OptionError(
            f"{what} needs about {format_bytes(total)} ({name} alone: {format_bytes(size)}); "
            f"the limit is {format_bytes(limit)} ({source}); {advice}"
        )
    return total


__all__ = ["ENV", "PHYSICAL_FRACTION", "FALLBACK_LIMIT", "parse_size", "physical_memory",
           "memory_limit", "analysis_bytes", "format_bytes", "check_memory"]
