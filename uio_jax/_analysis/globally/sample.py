"""The random point, SIAN's probability bound, and the system specialised at the point modulo p.

**The point.** The unknowns (parameters, unknown initial states) and the known inputs'
derivatives at ``t = 0`` take integer values drawn uniformly in ``[0, D]``; the output
coefficients ``y_j^(k)`` are what the model gives there. The system ``E_t`` with these
output values (and the input values) substituted has the true point among its solutions;
an unknown is globally identifiable exactly when it takes one value on all of them, for
every point off a hypersurface (SIAN's theorem).

**The bound** (SIAN, step 3 of Algorithm 1): the bad points lie on a hypersurface of degree at
most ``6 |theta_l| deg(E_t) (1 + 2 d0 max beta)``, ``theta_l`` the unknowns asked about,
``deg(E_t)`` the product of the degrees of the equations (Bezout), ``d0`` the model's degree
(:mod:`.jets`); by Schwartz-Zippel a point drawn in ``[0, D]`` is bad with probability at most
that degree over ``D + 1``. ``D`` is chosen so that this is under the share of ``1 -
prob_threshold`` given to it: an integer of any size (Python's), reduced modulo the prime.

**Modulo p.** The specialised system is solved over ``F_p``, a prime drawn in
``[2^29, 2^30)`` (msolve's fast linear algebra needs ``p < 2^30``): the reduction of the
rational system. The coefficients ``y_j^(k)`` are computed modulo ``p`` from the same
equations, triangularly (``X_i^(k)`` is linear in ``x_i^(k+1)`` with coefficient ``Q_i``,
``Y_j^(k)`` in ``y_j^(k)`` with ``Q_j``). A point where ``Q`` vanishes modulo ``p`` is drawn
again. The answer over ``F_p`` is the answer over the rationals for all but finitely many
primes; that set is not bounded a priori (as for SIAN's ``p_mod``): the report says so.
"""

import math
import random
from fractions import Fraction

from ..._engine.primes import is_prime
from .jets import SATURATION, flint_module

#: The primes are drawn in ``[2^29, 2^30)``.
PRIME_RANGE = (2**29, 2**30)

#: Points drawn before giving up on a point where ``Q`` does not vanish.
MAX_DRAWS = 20


def draw_prime(rng: random.Random) -> int:
    """A random prime in :data:`PRIME_RANGE` (:func:`uio_jax._engine.primes.is_prime`)."""
    while True:
        p = rng.randrange(*PRIME_RANGE) | 1
        if is_prime(p):
            return p


def sian_degree(truncation, eqs, asked: int) -> int:
    """SIAN's degree of the bad hypersurface: ``6 |theta_l| deg(E_t) (1 + 2 d0 max beta)``."""
    deg = math.prod(max(int(poly.total_degree()), 1) for poly in truncation.polys)
    beta = max(truncation.beta.values())
    return 6 * max(asked, 1) * deg * (1 + 2 * int(eqs.d0) * beta)


def sample_range(degree: int, eps: float) -> int:
    """The ``D`` with ``degree / (D + 1) <= eps``."""
    return max(math.ceil(Fraction(int(degree)) / Fraction(eps)), 2)


def to_mod(poly, ctx_p, p: int):
    """An ``fmpq_mpoly`` reduced modulo ``p`` into ``ctx_p`` (same variables), or None when
    ``p`` divides a denominator."""
    terms = {}
    for exps, c in poly.to_dict().items():
        num, den = int(c.p), int(c.q)
        if den % p == 0:
            return None
        terms[exps] = num * pow(den, -1, p) % p
    return ctx_p.from_dict(terms)


class Point:
    """The values of every jet variable modulo ``p`` at a random point.

    Args:
        eqs: the :class:`~.jets.ModelEquations`.
        p: the prime.
        known_initial: ``{state: value}`` as the truncation takes them.
        upto: per output the highest order needed; per state likewise (``{name: order}``).
        rng: a :class:`random.Random`.
        D: the range of the draws.

    Attributes:
        values: one residue per variable of the ring (``None`` where not computed).
        drawn: ``{name: the integer drawn}`` for the unknowns.
    """

    def __init__(self, eqs, p, known_initial, upto, rng, D):
        self.eqs, self.p = eqs, p
        ring = eqs.ring
        flint = flint_module()
        self.ctx_p = flint.nmod_mpoly_ctx.get(tuple(f"v{i}" for i in range(len(ring.labels))),
                                              ordering="degrevlex", modulus=p)
        self._mod = {}
        for _ in range(MAX_DRAWS):
            if self._draw(known_initial, upto, rng, D):
                return
        raise ArithmeticError("the saturating polynomial vanished at every point drawn")

    def mod(self, poly):
        """``poly`` modulo ``p`` (memoized per polynomial)."""
        key = id(poly)
        if key not in self._mod:
            self._mod[key] = (poly, to_mod(poly, self.ctx_p, self.p))
        out = self._mod[key][1]
        if out is None:
            raise ArithmeticError("the prime divides a coefficient's denominator")
        return out

    def _draw(self, known_initial, upto, rng, D) -> bool:
        eqs, ring, p = self.eqs, self.eqs.ring, self.p
        values = [0] * len(ring.labels)
        self.drawn = {}
        for name in list(eqs.params) + [s for s in eqs.states if s not in known_initial]:
            v = rng.randint(0, D)
            self.drawn[name] = v
            values[ring.index[(name, 0)]] = v % p
        for u in eqs.inputs:
            for k in range(ring.top + 1):
                values[ring.index[(u, k)]] = rng.randint(0, D) % p
        for state, value in known_initial.items():
            values[ring.index[(state, 0)]] = self._known_value(value, values)
        if self.mod(eqs.Q)(*values) == 0:
            return False
        top_state = max(upto.values(), default=0)
        for k in range(top_state + 1):
            for j, y in enumerate(eqs.outputs):
                if k <= upto.get(y, -1):
                    values[ring.index[(y, k)]] = self._leader(eqs.y_equation(j, k), ring.index[(y, k)], values)
            for i, s in enumerate(eqs.states):
                if k + 1 <= upto.get(s, 0):
                    values[ring.index[(s, k + 1)]] = self._leader(eqs.x_equation(i, k), ring.index[(s, k + 1)],
                                                                  values)
        values[ring.index[(SATURATION, 0)]] = pow(int(self.mod(eqs.Q)(*values)), -1, p)
        for name, (num, den) in zip(eqs.functions, eqs.function_fractions):
            d = int(self.mod(den)(*values))
            if d == 0:
                return False
            values[ring.index[(name, 0)]] = int(self.mod(num)(*values)) * pow(d, -1, p) % p
        self.values = values
        return True

    def _known_value(self, value, values):
        p, ring = self.p, self.eqs.ring
        if isinstance(value, str):
            return values[ring.index[(value, 0)]]
        if isinstance(value, tuple):
            num, den = (int(self.mod(f)(*values)) for f in value)
            return num * pow(den, -1, p) % p
        return value.numerator % p * pow(value.denominator % p, -1, p) % p

    def _leader(self, poly, leader, values) -> int:
        """The value of the variable ``leader`` in which ``poly`` is linear, from the others."""
        m = self.mod(poly)
        saved, values[leader] = values[leader], 0
        rest = int(m(*values))
        slope = int(m.derivative(leader)(*values))
        values[leader] = saved
        if slope % self.p == 0:
            raise ArithmeticError("a separant vanished at the point")
        return (-rest) * pow(slope, -1, self.p) % self.p

    def specialise(self, poly):
        """``poly`` modulo ``p`` with the outputs' and inputs' jets replaced by their values."""
        ring = self.eqs.ring
        m = self.mod(poly)
        subs = {f"v{i}": self.values[i] for i in ring.occurring(poly) if ring.kinds[i] in ("output", "input")}
        return m.subs(subs) if subs else m


__all__ = ["Point", "draw_prime", "sian_degree", "sample_range", "to_mod", "PRIME_RANGE"]
