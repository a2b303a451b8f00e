"""What the solutions say: how many values each unknown takes, and the simple symmetries.

msolve's parametrisation (:mod:`.msolve`) describes the solutions as the roots ``t`` of a
square-free ``w(t)`` over ``F_p``, each variable a polynomial ``a_i(t)`` modulo ``w``. The
algebra ``F_p[t] / (w)`` is a product of fields, one per orbit of roots, and the values of
``x_i`` on the solutions are the ``a_i(r)`` over the roots ``r``: ``x_i`` takes as many
distinct values as the degree of the minimal polynomial of ``a_i`` in that algebra (the
multiplication by ``a_i`` is diagonal over the closure, with the values on its diagonal).
It is found from the powers ``1, a_i, a_i^2, ..`` until the first linear dependence;
``a_i`` is one value exactly when it is a constant.

**The true point.** The point the outputs were computed at is a solution: the gcd of ``w``
and the ``a_i - x_i`` (over the unknowns) has positive degree. This checks the reading of
msolve's answer; if it fails the answer is undecided.

**Symmetries.** The solutions whose coordinates lie in ``F_p`` are the roots of ``w`` in
``F_p``. A discrete symmetry that permutes unknowns or changes their signs maps the true
point to such a solution; each one is compared with the true point coordinate by coordinate
(a coordinate equal to the true value of itself, of another unknown, or of its negative), and
described when every coordinate is one of those and the unknowns used form a permutation.
"""

import dataclasses

from .jets import flint_module
from .msolve import ADDED_VARIABLE


@dataclasses.dataclass(frozen=True)
class Symmetry:
    """A discrete symmetry read from one solution: unknown -> ``(source, sign)``: the
    unknown's value at that solution is ``sign`` times the true value of ``source``.

    Attributes:
        mapping: ``{unknown: (source, sign)}`` over the unknowns it moves.
        kind: ``"permutation"``, ``"sign change"`` or ``"permutation with sign change"``.
    """

    mapping: tuple
    kind: str

    @property
    def text(self) -> str:
        """``k21 <-> k31, x2 <-> x3`` (a permutation in cycles), ``y0 -> -y0``."""
        mapping = dict(self.mapping)
        seen, parts = set(), []
        for name in mapping:
            if name in seen:
                continue
            source, sign = mapping[name]
            if source == name:
                parts.append(f"{name} -> -{name}")
                seen.add(name)
                continue
            cycle, cur = [name], name
            while True:
                src, _ = mapping[cur]
                if src == name or src not in mapping:
                    break
                cycle.append(src)
                cur = src
            seen.update(cycle)
            if len(cycle) == 2 and all(mapping[c][1] == 1 for c in cycle):
                parts.append(f"{cycle[0]} <-> {cycle[1]}")
            else:
                parts.append(", ".join(f"{c} -> {'-' if mapping[c][1] < 0 else ''}{mapping[c][0]}" for c in cycle))
        return ", ".join(parts)


class SolutionSet:
    """The solutions of one parametrisation, read in the caller's variable names.

    Args:
        param: the :class:`~.msolve.Parametrisation`.
        names: msolve's variable name -> the caller's name (every variable of the system).
    """

    def __init__(self, param, names):
        flint = flint_module()
        p = param.p
        self.p = p

        def poly(coeffs):
            return flint.nmod_poly([int(c) % p for c in coeffs], p)

        self.w = poly(param.w)
        self.degree = self.w.degree()
        den_inv = _inverse_mod(poly(param.den), self.w)
        self.element = {}
        listed = param.variables
        for var, (coeffs, c) in zip(listed[:-1], param.params):
            value = (-poly(coeffs) * den_inv * pow(int(c), -1, p)) % self.w
            self.element[names.get(var, var)] = value
        if listed[-1] != ADDED_VARIABLE:
            self.element[names.get(listed[-1], listed[-1])] = poly([0, 1]) % self.w
        self.squarefree = self.w.gcd(self.w.derivative()).degree() == 0

    def contains(self, point: dict) -> bool:
        """Whether the point ``{name: residue}`` (every unknown named) is a solution."""
        g = self.w
        for name, value in point.items():
            g = g.gcd(self.element[name] - value)
            if g.degree() < 1:
                return False
        return True

    def count(self, name: str, cap: int | None = None) -> int | None:
        """The number of distinct values of ``name`` on the solutions (None past ``cap`` powers)."""
        flint = flint_module()
        a = self.element[name]
        if a.degree() <= 0:
            return 1
        d = self.degree
        rows, power = [], flint.nmod_poly([1], self.p)
        limit = d if cap is None else min(d, cap)
        for k in range(limit + 1):
            coeffs = [int(c) for c in power.coeffs()] + [0] * d
            rows.append(coeffs[:d])
            if flint.nmod_mat(rows, self.p).rank() < len(rows):
                return k
            power = (power * a) % self.w
        return None if limit < d else d

    def rational_solutions(self, unknowns) -> list[dict]:
        """The solutions whose coordinates lie in ``F_p``, as ``{unknown: residue}``."""
        return [{u: int(self.element[u](root)) for u in unknowns} for root, _ in self.w.roots()]


def _inverse_mod(a, w):
    g, s, _ = a.xgcd(w)
    if g.degree() != 0:
        raise ArithmeticError("the parametrisation's denominator is not invertible")
    return (s * pow(int(g[0]), -1, a.modulus())) % w


def symmetry(truth: dict, solution: dict, p: int) -> Symmetry | None:
    """The simple map (permutation and sign changes of the unknowns) sending ``truth`` to
    ``solution``, or None when some coordinate is not one of those."""
    by_value = {}
    for name, v in truth.items():
        by_value.setdefault(v, []).append((name, 1))
        by_value.setdefault((-v) % p, []).append((name, -1))
    mapping, used = {}, []
    for name, v in solution.items():
        if v == truth[name]:
            continue
        choices = [c for c in by_value.get(v, []) if c[0] != name or c[1] == -1]
        if len(choices) != 1:
            return None
        mapping[name] = choices[0]
        used.append(choices[0][0])
    if not mapping or sorted(used) != sorted(mapping):
        return None
    signs = any(s < 0 for _, s in mapping.values())
    moves = any(src != name for name, (src, _) in mapping.items())
    kind = ("permutation with sign change" if signs and moves else "sign change" if signs else "permutation")
    return Symmetry(tuple(mapping.items()), kind)


__all__ = ["Symmetry", "SolutionSet", "symmetry"]
