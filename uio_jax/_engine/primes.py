"""Random primes of machine-word size for the modular Taylor kernel (:mod:`.taylor_word`).

A prime is drawn uniformly from the primes of the half-open range ``[LOW, HIGH)`` that
satisfy the congruences the model needs (``p = 3 mod 4`` always, so that ``-1`` is not a
square and ``F_p[i] = F_{p^2}`` holds every square root of ``F_p``; more for roots of higher
order, :func:`root_conditions`): an integer is drawn uniformly from the range until one is
prime and satisfies them, which is uniform over those primes.

``HIGH = 2^26``: a product of two residues is below ``2^52``, so a sum of ``2^11`` products
fits a signed 64-bit integer unreduced (:data:`LAZY_TERMS`): the Cauchy sums of the Taylor
recurrences are matrix products of int64 arrays, reduced once.

Counting the primes the draw can return (:func:`prime_count`) bounds the probability that it
returns one of the few primes dividing a given nonzero integer (``graph_exact``'s content
bound, :mod:`.taylor_heights`).
"""

import functools
import math

#: the range of the primes: ``[LOW, HIGH)``
LOW = 2**25
HIGH = 2**26

#: products of two residues that a signed 64-bit sum holds unreduced
LAZY_TERMS = (2**63 - 1) // (HIGH - 1) ** 2

#: deterministic Miller-Rabin bases for every n < 3.3e24
_BASES = (2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41)


def is_prime(n: int) -> bool:
    """Whether ``n`` is prime (deterministic Miller-Rabin, exact for ``n < 3.3e24``)."""
    if n < 2:
        return False
    for b in _BASES:
        if n % b == 0:
            return n == b
    d, s = n - 1, 0
    while d % 2 == 0:
        d, s = d // 2, s + 1
    for b in _BASES:
        x = pow(b, d, n)
        if x in (1, n - 1):
            continue
        for _ in range(s - 1):
            x = x * x % n
            if x == n - 1:
                break
        else:
            return False
    return True


def root_conditions(orders) -> tuple[int, tuple[int, ...]]:
    """The congruences of a prime serving roots of the given orders ``b`` (``u^(1/b)``):
    ``(m, coprime)`` with ``p = -1 mod 2^m`` (every ``2^(m-1)``-th root of ``F_p`` lies in
    ``F_{p^2}``; ``m >= 2``) and ``gcd(p - 1, q) = 1`` for every ``q`` in ``coprime`` (the odd
    primes of the orders: ``q``-th roots are unique in ``F_p``)."""
    m, odd = 2, set()
    for b in orders:
        b = int(b)
        e = (b & -b).bit_length() - 1
        m = max(m, e + 1)
        b >>= e
        q = 3
        while b > 1:
            while b % q == 0:
                odd.add(q)
                b //= q
            q += 2
    return m, tuple(sorted(odd))


def _fits(p, m, coprime) -> bool:
    return (p + 1) % (1 << m) == 0 and all((p - 1) % q for q in coprime)


def random_prime(rng, conditions=(2, ())) -> int:
    """A prime drawn uniformly from those of ``[LOW, HIGH)`` that satisfy ``conditions``
    (:func:`root_conditions`), with the numpy Generator ``rng``."""
    m, coprime = conditions
    step = 1 << m
    while True:  # p = step * j - 1 runs over the residue class p = -1 mod 2^m
        p = step * int(rng.integers(LOW // step + 1, HIGH // step + 1)) - 1
        if LOW <= p < HIGH and _fits(p, m, coprime) and is_prime(p):
            return p


#: the number of primes ``p = 3 mod 4`` in ``[LOW, HIGH)`` (counted by :func:`_count`, checked
#: by the tests)
DEFAULT_COUNT = 947272


def prime_count(conditions=(2, ())) -> int:
    """The number of primes :func:`random_prime` draws from under ``conditions`` (counted
    once per process by a sieve, except the default's :data:`DEFAULT_COUNT`)."""
    if tuple(conditions[:1]) == (2,) and not conditions[1]:
        return DEFAULT_COUNT
    return _count(int(conditions[0]), tuple(conditions[1]))


@functools.lru_cache(maxsize=8)
def _count(m: int, coprime: tuple) -> int:
    """The primes of ``[LOW, HIGH)`` with the congruences (a sieve of Eratosthenes)."""
    import numpy as np

    sieve = np.ones(HIGH, dtype=bool)
    sieve[:2] = False
    for i in range(2, math.isqrt(HIGH) + 1):
        if sieve[i]:
            sieve[i * i::i] = False
    p = np.nonzero(sieve[LOW:])[0] + LOW
    keep = (p + 1) % (1 << m) == 0
    for q in coprime:
        keep &= (p - 1) % q != 0
    return int(keep.sum())


__all__ = ["LOW", "HIGH", "LAZY_TERMS", "is_prime", "random_prime", "prime_count", "root_conditions", "DEFAULT_COUNT"]
