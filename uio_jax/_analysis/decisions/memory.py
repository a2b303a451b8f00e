"""How many samples each phase of an analysis evaluates, and how much memory that takes,
refused before it is allocated.

Every analysis samples ``S`` states of its ``N`` coordinates (``N = n`` for the ORC, the
single-input analysis and the series test; ``N = n + K m_w`` for the EORC on
``Sigma^(K)``, ``K = k_max``) and works in two phases (:class:`~uio_jax._analysis.decisions.context.Context`):

* the **recursion** decides every candidate and membership on the first
  :func:`decision_count` samples (:data:`DECISION_SAMPLES` where the model is defined);
* the **certificate** re-decides the final span of ``r`` generators on the first
  :func:`certify_samples` (all ``S`` unless the span is very large).

The largest arrays (float64, 8 bytes per entry), at the span's full rank ``r = N``:

==============================  =============  ==================================================
array                           shape          where
==============================  =============  ==================================================
the sampled states              ``(S, N)``     :class:`~uio_jax._analysis.decisions.context.Context` ``xs_all``
the rank basis                  ``(N, S', N)`` :class:`~uio_jax._analysis.decisions.rank.Codistribution`
                                               ``basis`` (per sample, an orthonormal basis; rows
                                               allocated as the span grows)
the unit-covector test          4 x            :meth:`~uio_jax._analysis.decisions.rank.Codistribution.test_units`
                                ``(S', N, n)`` of ``e_1..e_n`` (covectors, the two residuals,
                                               the directions): the verdict per state (the
                                               EORC tests every coordinate: ``n = N``)
==============================  =============  ==================================================

with ``S'`` the larger of the two phases' sample counts (:func:`rank_samples`), so
:func:`analysis_bytes` = ``8 N (S + S' (N + 4 n))``. The kept gradients, the candidate
blocks of each step and JAX's own buffers come on top and depend on the run. A request
whose estimate exceeds the limit cannot fit and is refused (:func:`check_memory`) with a
one-line :class:`~uio_jax.OptionError` before the first array exists.

**The limit** (:func:`memory_limit`): ``$UIO_JAX_MEMORY_LIMIT`` if set (bytes, or a number
with a binary suffix: ``512M``, ``4G``, ``1.5T``; ``K`` = 1024), else half of the physical
memory (``0.5 x`` ``os.sysconf`` pages; 8 GiB where the platform does not tell).
"""

import math
import os
import re

import numpy as np

from ..._errors import OptionError

#: The environment variable that sets the limit, in bytes (suffixes K, M, G, T: powers of 1024).
ENV = "UIO_JAX_MEMORY_LIMIT"

#: Fraction of the physical memory an analysis may use when ``$UIO_JAX_MEMORY_LIMIT`` is unset.
PHYSICAL_FRACTION = 0.5

#: The limit where the physical memory is unknown (no ``os.sysconf``), bytes.
FALLBACK_LIMIT = 8 * 2**30

_FLOAT = 8  # bytes per float64 entry

#: The recursion decides on the first samples that hold this many states where the model
#: (its outputs and fields) is defined (:func:`decision_count`, never more than
#: :func:`certify_samples`); the final span is then certified on more
#: (:meth:`~uio_jax._analysis.decisions.context.Context.certify`). A weak vote is settled
#: beyond float64, so the rest of the samples add coverage of the domain, not correctness.
DECISION_SAMPLES = 128

#: The float64 screen of a model decided exactly keeps ``S N^2`` near this (a vote costs
#: ``S r N``): 128 samples up to 128 coordinates, 16 at 362 and beyond (:func:`screen_samples`).
SCREEN_BUDGET = 2**21

#: The fewest defined samples of a float64 screen.
SCREEN_MIN = 16

#: The final span is certified on all the samples while its per-sample arrays (at most
#: ``N x N`` float64 on ``N`` coordinates) fit: ``8 S N^2 <= CERTIFY_BYTES``. A larger span (a
#: deep EORC) is certified on the first samples that fit, never fewer than
#: :data:`DECISION_SAMPLES` (:attr:`uio_jax.Certificate.capped` says how many did not); the
#: exact verification of its kept generators certifies it already. The value keeps the default
#: 4096 samples for every analysis on up to 35 coordinates (every ORC of the zoo): 38 MiB.
CERTIFY_BYTES = 8 * 4096 * 35**2


def certify_samples(samples: int, coords: int) -> int:
    """How many of ``samples`` certify a final span on ``coords`` coordinates: all of them
    while ``8 S coords^2 <= CERTIFY_BYTES``, else as many as fit, never fewer than
    :data:`DECISION_SAMPLES` (nor more than ``samples``)."""
    fit = CERTIFY_BYTES // (_FLOAT * max(int(coords), 1) ** 2)
    return int(min(samples, max(DECISION_SAMPLES, fit)))


def screen_samples(coords: int) -> int:
    """The float64 screen's defined samples for a model whose every decision is made
    exactly: :data:`DECISION_SAMPLES`, fewer on a large model (a vote costs ``S r N`` per
    candidate: ``S N^2`` is kept near :data:`SCREEN_BUDGET`), never under :data:`SCREEN_MIN`.
    The votes only order the exact decisions; a wrong one is corrected modulo p."""
    return int(max(SCREEN_MIN, min(DECISION_SAMPLES, SCREEN_BUDGET // max(int(coords), 1) ** 2)))


def decision_count(defined, samples: int, coords: int, wanted: int = DECISION_SAMPLES) -> int:
    """How many of the first samples decide: the fewest holding ``wanted`` (default
    :data:`DECISION_SAMPLES`) states where the model is defined, at most
    :func:`certify_samples` (all of those when fewer are defined).

    Args:
        defined: ``(S,)`` booleans, the model defined at each sample (None: unknown, taken
            as defined everywhere).
        samples: ``S``.
        coords: the analysis' coordinates ``N``.
        wanted: defined samples wanted (:func:`screen_samples` where every decision is exact).
    """
    cap = certify_samples(samples, coords)
    if defined is None:
        return min(samples, wanted)
    at = np.flatnonzero(np.asarray(defined, dtype=bool)[:cap])
    return cap if len(at) < wanted else int(at[wanted - 1]) + 1


def rank_samples(samples: int, coords: int) -> int:
    """``S'``: the most samples a rank array of an analysis on ``coords`` coordinates spans
    (the recursion's or the certificate's)."""
    return max(min(int(samples), DECISION_SAMPLES), certify_samples(samples, coords))


_SUFFIX = {"": 1, "K": 2**10, "M": 2**20, "G": 2**30, "T": 2**40, "P": 2**50}


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
    """The largest arrays of an analysis (module docstring), bytes per array.

    Args:
        samples: S, sampled states.
        coords: N, coordinates of the codistribution (``n``, or ``n + K m_w`` for the EORC).
        states: n, original states whose unit covectors are tested (default ``N``).

    Returns:
        ``{"the sampled states": 8 S N, "the rank basis": 8 S' N^2,
        "the unit-covector test": 32 S' N n}`` with ``S'`` = :func:`rank_samples`
        (Python ints: no overflow).
    """
    S, N = int(samples), int(coords)
    n = N if states is None else int(states)
    Sr = rank_samples(S, N)
    return {
        "the sampled states": _FLOAT * S * N,
        "the rank basis": _FLOAT * Sr * N * N,
        "the unit-covector test": 4 * _FLOAT * Sr * N * n,
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


def resident_bytes() -> int | None:
    """The process's resident memory now (``/proc/self/statm``), else its peak
    (``getrusage``), else None."""
    try:
        with open("/proc/self/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError, AttributeError):
        pass
    try:
        import resource

        return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024
    except (ImportError, OSError, ValueError):
        return None


def check_resident(what: str) -> None:
    """Stop an analysis whose process has grown past :func:`memory_limit` (what the arrays'
    estimate before the run cannot see: the expression graph of deep derivatives and its
    evaluations grow with the model), with one line, instead of exhausting the machine.

    Raises:
        OptionError: the resident memory is over the limit; ``what`` says where the run was.
    """
    used = resident_bytes()
    if used is None:
        return
    limit, source = memory_limit()
    if used > limit:
        raise OptionError(f"the analysis grew to {format_bytes(used)} resident at {what}, past the limit "
                          f"{format_bytes(limit)} ({source}): a smaller model, a cap (max_order, k_max), "
                          "or a larger limit")


__all__ = ["resident_bytes", "check_resident", "ENV", "PHYSICAL_FRACTION", "FALLBACK_LIMIT", "DECISION_SAMPLES",
           "decision_count", "CERTIFY_BYTES", "certify_samples", "rank_samples", "parse_size",
           "physical_memory", "memory_limit", "analysis_bytes", "format_bytes", "check_memory"]
