"""An independent EORC: ranks of the extended codistribution at random points, exactly
modulo a prime, by nilpotent jets (needs only numpy; nothing of ``uio_jax``).

The EORC of order k (004 sections 4-6) augments the state with the unknown inputs and their
derivatives, ``z = [x; w; w^(1); ..; w^(k-1)]``, drift ``F0 = [f0 + sum_j g_j w_j; w^(1); ..;
w^(k-1); 0]``, known fields ``F_i = [f_i; 0]``, and spans the gradients of every Lie
derivative ``L_{V_l} .. L_{V_1} h`` (``V`` in ``{F0, F_i}``, ``l <= k``) of every output.
Here every such word is kept (no pruning) and its gradient is computed at a point ``z0`` by
composition with nilpotent infinitesimals:

    L_{V_l} .. L_{V_1} h (z) = d/de_l .. d/de_1  h(z_1),
    z_{l+1} = z,   z_j = z_{j+1} + e_j V_j(z_{j+1})   (e_j^2 = 0, the e_j commuting),

and ``z = z0 + delta`` with a first-order ``delta`` in every coordinate (``delta_a delta_b =
0``): the coefficient of ``e_1 .. e_l`` is the Lie derivative, its ``delta`` part the
gradient. A :class:`Jet` holds one coefficient (value and gradient) per subset of the ``e``'s;
every number is an integer modulo the prime :data:`P`, so the model is written with ``+ - * /``
and integer (or rational) constants only. Ranks are exact modulo P; at a uniform random point
a rank is below the generic one with probability at most ``D / P`` (``D`` the degree of a
nonzero maximal minor: Schwartz-Zippel), and the dims are the largest over the points tried.

The dimension on the original state: ``rank(Omega) + n - rank([Omega; e_1..e_n])``; state
``x_i`` is observable when ``rank([Omega; e_i]) = rank(Omega)``.

Usage (the Vi-SfM models of ``systems/visual_inertial_no_offset.py``, transcribed below)::

    python scripts/eorc_jet_oracle.py --case one_acc --k 3
"""

import argparse
import random
import sys

import numpy as np

#: The prime: products of two residues fit in int64 with room for a sum of two.
P = 2**31 - 1


class Algebra:
    """Multiplication tables of the jets with ``m`` infinitesimals ``e`` and ``N`` gradient
    coordinates: pairs ``(T, S \\ T)`` for every subset ``S`` (bit masks)."""

    def __init__(self, m, N):
        self.m, self.N, self.size = m, N, 1 << m
        pairs = [(t, s ^ t, s) for s in range(self.size) for t in range(self.size) if t & s == t]
        self.I, self.J, self.K = (np.array(c, dtype=np.int64) for c in zip(*pairs))


class Jet:
    """``sum_S e^S (c_S + sum_a d_{S,a} delta_a)`` modulo P: ``c`` (2^m,), ``d`` (2^m, N)."""

    __slots__ = ("alg", "c", "d")

    def __init__(self, alg, c, d):
        self.alg, self.c, self.d = alg, c, d

    @classmethod
    def constant(cls, alg, value):
        c = np.zeros(alg.size, dtype=np.int64)
        c[0] = value % P
        return cls(alg, c, np.zeros((alg.size, alg.N), dtype=np.int64))

    def _lift(self, other):
        return other if isinstance(other, Jet) else Jet.constant(self.alg, as_residue(other))

    def __add__(self, other):
        o = self._lift(other)
        return Jet(self.alg, (self.c + o.c) % P, (self.d + o.d) % P)

    __radd__ = __add__

    def __neg__(self):
        return Jet(self.alg, (-self.c) % P, (-self.d) % P)

    def __sub__(self, other):
        return self + (-self._lift(other))

    def __rsub__(self, other):
        return self._lift(other) - self

    def __mul__(self, other):
        if not isinstance(other, Jet):
            k = as_residue(other)
            return Jet(self.alg, self.c * k % P, self.d * k % P)
        a = self.alg
        c = np.zeros(a.size, dtype=np.int64)
        d = np.zeros((a.size, a.N), dtype=np.int64)
        np.add.at(c, a.K, self.c[a.I] * other.c[a.J] % P)
        g = (self.c[a.I, None] * other.d[a.J] % P + other.c[a.J, None] * self.d[a.I] % P) % P
        np.add.at(d, a.K, g)
        return Jet(a, c % P, d % P)

    __rmul__ = __mul__

    def inverse(self):
        """``1 / self`` (its constant term nonzero): ``c^-1 sum_i (-N / c)^i``, ``N`` nilpotent
        of order ``m + 2``."""
        c0 = int(self.c[0])
        if c0 == 0:
            raise ZeroDivisionError("a jet with a zero constant term (draw another point)")
        inv = pow(c0, P - 2, P)
        nil = self * inv - 1  # N / c0
        term, total = Jet.constant(self.alg, 1), Jet.constant(self.alg, 1)
        for _ in range(self.alg.m + 1):
            term = term * (-nil)
            total = total + term
        return total * inv

    def __truediv__(self, other):
        return self * (other.inverse() if isinstance(other, Jet) else pow(as_residue(other), P - 2, P))

    def top(self, subset_mask):
        """The gradient (N,) of the coefficient of ``e^subset``."""
        return self.d[subset_mask]


def as_residue(value) -> int:
    """An int, or a rational written ``(num, den)``, modulo P."""
    if isinstance(value, tuple):
        num, den = value
        return num * pow(den, P - 2, P) % P
    return int(value) % P


def _eorc_fields(model, k):
    """The drift F0 and known fields of the k-th extension, as functions of a list ``z``."""
    n, mw = model["n"], len(model["unknown"])

    def f0(z):
        x = z[:n]
        out = list(model["drift"](x))
        for j, g in enumerate(model["unknown"]):
            out = [a + b * z[n + j] for a, b in zip(out, g(x))]
        return out + z[n + mw:] + [0] * mw

    def known(f):
        return lambda z: list(f(z[:n])) + [0] * (k * mw)

    return [f0] + [known(f) for f in model["known"]]


def gradients(model, k, point):
    """Rows: the gradient of every word of length <= k of every output at ``point`` (a list of
    residues of length ``n + k m_w``)."""
    N = len(point)
    alg = Algebra(k, N)
    fields = _eorc_fields(model, k)
    z = []
    for a, v in enumerate(point):
        jet = Jet.constant(alg, v)
        jet.d[0, a] = 1
        z.append(jet)
    rows = []

    def walk(z, depth, mask):  # depth fields applied (e_k, e_{k-1}, ...), mask: their e's
        rows.extend(h(z).top(mask) for h in model["outputs"])
        if depth == k:
            return
        e = Jet.constant(alg, 0)
        e.c[1 << (k - 1 - depth)] = 1  # the infinitesimal of this Lie derivative
        for V in fields:
            walk([a + e * b for a, b in zip(z, V(z))], depth + 1, mask | (1 << (k - 1 - depth)))

    walk(z, 0, 0)
    return rows


def rank_mod_p(rows) -> int:
    """Rank of integer rows modulo P (Gaussian elimination in Python integers)."""
    rows = [[int(v) % P for v in r] for r in rows]
    rank, ncol = 0, len(rows[0]) if rows else 0
    for col in range(ncol):
        piv = next((i for i in range(rank, len(rows)) if rows[i][col]), None)
        if piv is None:
            continue
        rows[rank], rows[piv] = rows[piv], rows[rank]
        inv = pow(rows[rank][col], P - 2, P)
        prow = [v * inv % P for v in rows[rank]]
        rows[rank] = prow
        for i in range(len(rows)):
            if i != rank and rows[i][col]:
                f = rows[i][col]
                rows[i] = [(a - f * b) % P for a, b in zip(rows[i], prow)]
        rank += 1
    return rank


def function_rank(fns, n, *, seed=0) -> int:
    """Rank of the Jacobian of the functions ``fns`` (each ``fn(x)`` on a list of ``n``
    coordinates, written with ``+ - * /`` and rational constants) at a random point modulo P:
    how many of them are independent (generic rank, with the probability of the module
    docstring)."""
    alg = Algebra(0, n)
    rng = random.Random(seed)
    x = []
    for a in range(n):
        jet = Jet.constant(alg, rng.randrange(1, P))
        jet.d[0, a] = 1
        x.append(jet)
    return rank_mod_p([(Jet.constant(alg, 0) + fn(x)).top(0) for fn in fns])


def eorc(model, k, *, points=2, seed=0):
    """``(dim, observable)`` of the EORC of order ``k``: the dimension on the original state
    and the set of observable state indices, the largest rank over ``points`` random points."""
    n, mw = model["n"], len(model["unknown"])
    rng = random.Random(seed)
    best = None
    for _ in range(points):
        point = [rng.randrange(1, P) for _ in range(n + k * mw)]
        rows = gradients(model, k, point)
        r = rank_mod_p(rows)
        unit = [[int(a == i) for a in range(n + k * mw)] for i in range(n)]
        dim = r + n - rank_mod_p(rows + unit)
        seen = frozenset(i for i in range(n) if rank_mod_p(rows + [unit[i]]) == r)
        if best is None or dim > best[0]:
            best = (dim, seen)
    return best


# ------------------------------------------------------------------ the Vi-SfM models
def _cols(q):
    qt, qx, qy, qz = q
    return ([qt * qt + qx * qx - qy * qy - qz * qz, 2 * (qx * qy + qt * qz), 2 * (qx * qz - qt * qy)],
            [2 * (qx * qy - qt * qz), qt * qt - qx * qx + qy * qy - qz * qz, 2 * (qy * qz + qt * qx)],
            [2 * (qx * qz + qt * qy), 2 * (qy * qz - qt * qx), qt * qt - qx * qx - qy * qy + qz * qz])


def _rt(q, w):
    return [c[0] * w[0] + c[1] * w[1] + c[2] * w[2] for c in _cols(q)]


def _q_times_pure(q, i):
    qt, qx, qy, qz = q
    return [[-qx, qt, qz, -qy], [-qy, -qz, qt, qx], [-qz, qy, -qx, qt]][i]


def vi_sfm_model(case, n_f=4):
    """Vi-SfM with the camera at the accelerometers, gravity known (``g = 981/100``),
    origin at feature 1: ``[r, v, q, q_c, F_2..F_nf]``, outputs the bearings and both
    quaternion norms. ``case``: ``"full_imu"``, ``"two_acc"`` (A_1, A_2 known) or
    ``"one_acc"`` (A_1 known); the other IMU readings are unknown inputs."""
    n = 14 + 3 * (n_f - 1)
    g = (981, 100)

    def drift(x):
        return [x[3], x[4], x[5], 0, 0, -as_residue(g)] + [0] * (n - 6)

    def acc(i):
        return lambda x: [0, 0, 0] + [c for c in _cols(x[6:10])[i]] + [0] * (n - 6)

    def gyro(i):
        return lambda x: [0] * 6 + [a * (1, 2) for a in _q_times_pure(x[6:10], i)] + [0] * (n - 10)

    def bearing(j, axis):
        def h(x):
            f = [0, 0, 0] if j == 0 else x[11 + 3 * j:14 + 3 * j]
            b = _rt(x[10:14], _rt(x[6:10], [f[a] - x[a] for a in range(3)]))
            return b[axis] / b[2]
        return h

    fields = [acc(i) for i in range(3)] + [gyro(i) for i in range(3)]
    n_known = {"full_imu": 6, "two_acc": 2, "one_acc": 1}[case]
    outputs = [bearing(j, a) for j in range(n_f) for a in (0, 1)]
    outputs += [lambda x: sum(a * a for a in x[6:10]), lambda x: sum(a * a for a in x[10:14])]
    return {"n": n, "drift": drift, "known": fields[:n_known], "unknown": fields[n_known:],
            "outputs": outputs}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="one_acc", choices=("full_imu", "two_acc", "one_acc"))
    ap.add_argument("--features", type=int, default=4)
    ap.add_argument("--k", type=int, nargs="+", default=[0, 1, 2, 3])
    args = ap.parse_args(argv)
    model = vi_sfm_model(args.case, args.features)
    for k in args.k:
        dim, seen = eorc(model, k)
        print(f"{args.case}, {args.features} features, k = {k}: dim {dim} of {model['n']}, "
              f"observable state indices {sorted(seen)}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
