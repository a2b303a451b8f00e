"""A plain sympy implementation of the ORC and of the single-unknown-input algorithm.

Independent of ``uio_jax`` (needs only sympy and numpy), so tests can use it as an oracle
on small systems, and ``scripts/bench_analysis.py`` uses it as the "sympy route" peer.

Method (the textbook way, no tricks):

* Lie derivatives are symbolic (``sympy.diff``), without simplification.
* Codistributions are kept as generating functions; a candidate is kept only if the
  gradient evaluated at ONE random point of the model's box raises the numeric rank
  (float64 SVD of the row-normalised matrix, relative tolerance ``rtol``). Pruning is sound:
  the Lie derivative of a combination of kept generators lies in the span of the kept
  generators and their Lie derivatives.
* ORC: Algorithm 1 of Martinelli 2017 (seed 002)::

      Omega_0 = span{dh},  Omega_m = Omega_{m-1} + sum_{v in {f0, f_i}} L_v Omega_{m-1}

  stopped at the first m with Omega_m = Omega_{m-1}, or at full rank.
* Single unknown input (no drift): Algorithms 2-3, Lemma 1, tau, m', m* (002 section II)::

      L_g^1 = L_g h,  phi^i_0 = f_i,  phi^i_m = [phi^i_{m-1}, g] / L_g^1
      Omega_0 = span{dh_all outputs}
      Omega_m = Omega_{m-1} + sum_i L_{f_i} Omega_{m-1} + L_{g/L_g^1} Omega_{m-1}
                + sum_i span{d L_{phi^i_{m-1}} h}

  with the project's correction (README, "A correction to the papers' stopping rule"): m* >= 1 unless every phi^i_1
  vanishes (``paper_stop=True`` gives the papers' rule instead). Lemma 1 is taken as met
  when every phi^i_1 vanishes (as 002 section III-C does). When L_g h vanishes for every
  output, 004 section 7: the first Lie derivative psi of the outputs along the known fields
  with L_g psi != 0 becomes the output (see :func:`single_ui`).

Usage::

    from _sympy_models import get
    from sympy_oracle import orc_dims, single_ui_dims
    orc_dims(get("systems/unicycle_polar.py:range_known"))          # [1, 2, 2]
    single_ui_dims(get("systems/vehicle_wind.py:wind_unknown"))     # [3, 5, 6, 6]

A single random point decides every rank: the answer is the generic rank with probability
one in exact arithmetic, but float64 round-off in high-order derivatives can in principle
fake or hide a rank; use ``seed`` to re-draw the point, and small systems.
"""

from __future__ import annotations

import numpy as np
import sympy as sp

__all__ = ["orc", "orc_dims", "single_ui", "single_ui_dims", "random_point", "Span"]

#: Relative tolerance on s_i / s_1 of the row-normalised matrix (same default as uio_jax).
RTOL = 1e-8
#: Decimal digits of the evaluation at the point. Gradients are evaluated in this precision
#: and entries below ``ZERO_TOL`` are set to 0 before the float64 SVD: a function that is
#: identically zero but written as a large cancelling expression evaluates to round-off,
#: which row normalisation would otherwise blow up into a fake rank.
DPS = 50
#: Absolute size under which a value evaluated at the point (in DPS digits) counts as zero.
ZERO_TOL = 1e-30


# --------------------------------------------------------------------------------------
# Numeric evaluation at one point
# --------------------------------------------------------------------------------------

def random_point(model, seed: int = 0) -> dict:
    """One random state of the model's box: ``{symbol: sympy.Float}``."""
    rng = np.random.default_rng(seed)
    point = {}
    for s in model.states:
        lo, hi = model.box(s)
        point[s] = sp.Float(float(rng.uniform(lo, hi)), DPS)
    return point


def _num(expr, point) -> float:
    """Evaluate a sympy expression at ``point`` (plain substitution, DPS digits) as a float;
    values below ``ZERO_TOL`` in absolute value are returned as exactly 0."""
    val = float(sp.N(sp.sympify(expr).xreplace(point), DPS))
    return 0.0 if abs(val) < ZERO_TOL else val


def _gradient(expr, states):
    return [sp.diff(expr, s) for s in states]


def _grad_at(expr, states, point) -> np.ndarray:
    return np.array([_num(d, point) for d in _gradient(expr, states)], dtype=float)


def lie(expr, vec, states, grad=None):
    """Lie derivative ``L_vec expr = d(expr) . vec`` (symbolic, unsimplified); ``grad``: the
    symbolic gradient of ``expr`` when already known."""
    grad = _gradient(expr, states) if grad is None else grad
    return sp.Add(*[grad[i] * vec[i] for i in range(len(states)) if vec[i] != 0])


def bracket(a, b, states):
    """Lie bracket ``[a, b] = (db/dx) a - (da/dx) b`` (column matrices)."""
    X = sp.Matrix(states)
    return b.jacobian(X) * a - a.jacobian(X) * b


class Span:
    """Rows (covectors at the point) and their numeric rank."""

    def __init__(self, n: int, rtol: float = RTOL):
        self.n = n
        self.rtol = rtol
        self.rows: list[np.ndarray] = []

    @staticmethod
    def rank_of(rows, rtol) -> int:
        if not rows:
            return 0
        M = np.array(rows, dtype=float)
        norms = np.linalg.norm(M, axis=1)
        M = M[norms > 0] / norms[norms > 0, None]
        if M.shape[0] == 0:
            return 0
        s = np.linalg.svd(M, compute_uv=False)
        return int(np.sum(s > rtol * s[0]))

    @property
    def dim(self) -> int:
        return self.rank_of(self.rows, self.rtol)

    def contains(self, row) -> bool:
        row = np.asarray(row, dtype=float)
        if not np.all(np.isfinite(row)):
            raise FloatingPointError("gradient is not finite at the point; use another seed")
        return self.rank_of(self.rows + [row], self.rtol) == self.dim

    def add(self, row) -> bool:
        """Append ``row`` if it raises the rank; return whether it did."""
        if self.contains(row):
            return False
        self.rows.append(np.asarray(row, dtype=float))
        return True


def _absorb(candidates, span, states, point):
    """Keep the candidates (scalar functions) whose gradients raise the rank.

    Returns ``[(function, symbolic gradient), ...]`` for the kept ones (the gradient is
    reused for their Lie derivatives at the next step).
    """
    kept = []
    for c in candidates:
        if c == 0:
            continue
        grad = _gradient(c, states)
        row = np.array([_num(d, point) for d in grad], dtype=float)
        if span.add(row):
            kept.append((c, grad))
    return kept


def _is_zero_vec(vec, point) -> bool:
    vals = np.array([_num(e, point) for e in vec], dtype=float)
    return bool(np.all(np.abs(vals) <= ZERO_TOL))


# --------------------------------------------------------------------------------------
# ORC (Algorithm 1)
# --------------------------------------------------------------------------------------

def orc(model, *, seed: int = 0, rtol: float = RTOL, max_steps: int | None = None,
        point: dict | None = None) -> dict:
    """ORC of a model with known inputs only (the unknown ones, if any, are ignored).

    Returns:
        ``{"dims": [dim Omega_0, ...], "dim": final dim, "generators": kept functions,
        "point": the point used}``. The list stops at the first repeat or at full rank.
    """
    states = list(model.states)
    n = len(states)
    point = random_point(model, seed) if point is None else point
    fields = ([model.drift] if model.drift is not None else []) + list(model.known.values())
    span = Span(n, rtol)
    frontier = _absorb(list(model.outputs.values()), span, states, point)
    generators = [k for k, _ in frontier]
    dims = [span.dim]
    m = 0
    while frontier and span.dim < n:  # converges by m = n - 1 (Isidori, Lemma 1.9.x)
        m += 1
        cands = [lie(k, v, states, dk) for k, dk in frontier for v in fields]
        frontier = _absorb(cands, span, states, point)
        generators += [k for k, _ in frontier]
        dims.append(span.dim)
        if max_steps is not None and m >= max_steps:
            break
    return {"dims": dims, "dim": dims[-1], "generators": generators, "point": point}


def orc_dims(model, *, seed: int = 0, rtol: float = RTOL, max_steps: int | None = None):
    """Dimensions of Omega_0, Omega_1, ... of the ORC (see :func:`orc`)."""
    return orc(model, seed=seed, rtol=rtol, max_steps=max_steps)["dims"]


# --------------------------------------------------------------------------------------
# Single unknown input (Algorithms 2-3 of 002)
# --------------------------------------------------------------------------------------

def _lemma1(phis, lg1, point, n):
    """Whether the assumptions of Lemma 1 of 002 hold, for every known input i.

    Lambda_j = span{phi^i_0, ..., phi^i_j} (vectors at the point); m = the smallest j with
    Lambda_{j+1} = Lambda_j (m <= n - 1); require L_{phi^i_j} L_g^1 = 0 for j = 0..m.
    """
    for i in range(len(phis.fields)):
        vecs = []
        for j in range(n):
            if _num(lie(lg1, phis(i, j), phis.states), point) != 0.0:
                return False
            vecs.append(np.array([_num(e, point) for e in phis(i, j)], dtype=float))
            nxt = np.array([_num(e, point) for e in phis(i, j + 1)], dtype=float)
            if Span.rank_of(vecs + [nxt], RTOL) == Span.rank_of(vecs, RTOL):
                break
    return True


class _Phis:
    """Lazy phi^i_j = [phi^i_{j-1}, g] / L_g^1 (Algorithm 3)."""

    def __init__(self, fields, g, lg1, states):
        self.fields = fields
        self.g = g
        self.lg1 = lg1
        self.states = states
        self.cache = {}

    def __call__(self, i, j):
        key = (i, j)
        if key not in self.cache:
            if j == 0:
                self.cache[key] = self.fields[i]
            else:
                self.cache[key] = bracket(self(i, j - 1), self.g, self.states) / self.lg1
        return self.cache[key]


def single_ui(model, *, seed: int = 0, rtol: float = RTOL, paper_stop: bool = False,
              output: str | None = None, point: dict | None = None) -> dict:
    """Observable codistribution with one unknown input and no drift (Algorithm 2 of 002).

    Args:
        model: a model with exactly one unknown input and no drift.
        seed: seed of the random point.
        rtol: relative rank tolerance.
        paper_stop: use the papers' stopping rule (m* may be 0) instead of the project's
            correction (m* >= 1 unless every phi^i_1 vanishes).
        output: name of the output defining L_g^1 (default: the first whose L_g h does not
            vanish at the point).
        point: the point (default: :func:`random_point`).

    Returns:
        ``{"dims", "dim", "m_prime", "m_star", "lemma1", "phi1_zero", "output", "offset",
        "unaffected", "generators", "point"}``; ``dims`` runs from Omega_0 to Omega_{m*+1}
        (or to Omega_{m*} at full rank).

    When L_g h vanishes for every output (004 section 7), the output is replaced by the
    first Lie derivative psi of the outputs along the known fields (order ``offset``) with
    L_g psi != 0; Omega_0 .. Omega_offset hold the outputs and their Lie derivatives up to
    that order (the paper's Omega_1 = span{dh, dL_f h} in 11.1.2 and 11.1.6), and the
    recursion goes on from m = offset + 1 with the phi term ``L_{phi^i_{m-1}} psi`` as printed
    there. If no such psi exists, the unknown input does not affect observability: the
    result is the ORC on the known fields, with ``unaffected = True``.
    """
    if len(model.unknown) != 1 or model.drift is not None:
        raise ValueError("single_ui needs exactly one unknown input and no drift")
    states = list(model.states)
    n = len(states)
    point = random_point(model, seed) if point is None else point
    (g,) = model.unknown.values()
    fields = list(model.known.values())

    # Step 1: L_g^1 for the chosen output; generators of Omega_0 (the outputs).
    span = Span(n, rtol)
    frontier = _absorb(list(model.outputs.values()), span, states, point)
    generators = [k for k, _ in frontier]
    dims = [span.dim]
    h_name, h, lg1 = None, None, None
    for name, expr in model.outputs.items():
        if output is not None and name != output:
            continue
        cand = lie(expr, g, states)
        if cand != 0 and _num(cand, point) != 0.0:
            h_name, h, lg1 = name, expr, cand
            break
    offset = 0
    if h is None:
        # 004 section 7 (worked cases 11.1.2, 11.1.6): L_g h = 0 for every output. Take the
        # Lie derivatives of the outputs along the known fields, order by order (pruned as
        # in the ORC), keeping them in Omega, until one, psi, has L_g psi != 0; psi is the
        # new output. Omega_offset (offset = the order of psi) then contains the outputs and
        # their Lie derivatives up to that order, as the paper's Omega_1 = span{dh, dL_f h}.
        while h is None and frontier and span.dim < n and offset < n:
            offset += 1
            cands = [lie(k, v, states, dk) for k, dk in frontier for v in fields]
            frontier = _absorb(cands, span, states, point)
            generators += [k for k, _ in frontier]
            dims.append(span.dim)
            for k, _ in frontier:
                cand = lie(k, g, states)
                if cand != 0 and _num(cand, point) != 0.0:
                    h_name, h, lg1 = f"psi (order {offset})", k, cand
                    break
        if h is None:
            # Every Lie derivative along the known fields has L_g = 0: the unknown input
            # does not affect observability; the result is the ORC on the known fields.
            res = orc(model, seed=seed, rtol=rtol, point=point)
            res.update(m_prime=None, m_star=None, lemma1=None, phi1_zero=None, output=None,
                       offset=None, unaffected=True)
            return res
    g_scaled = g / lg1
    phis = _Phis(fields, g, lg1, states)

    # Step 3: Lemma 1, and whether every phi^i_1 vanishes (the correction's exception).
    phi1_zero = all(_is_zero_vec(phis(i, 1), point) for i in range(len(fields)))
    # 002 section III-C: when every phi^i_1 vanishes "the assumptions of Lemma 1 are
    # trivially met" (the phi term only repeats L_{f_i} h at m = 1).
    lemma = phi1_zero or _lemma1(phis, lg1, point, n)
    # Step 4: tau = L_g^2 h / (L_g^1)^2.
    tau_grad = None if lemma else _grad_at(lie(lg1, g, states) / lg1**2, states, point)

    dh = _gradient(h, states)
    m_prime = offset if lemma or span.contains(tau_grad) else None
    m_star = None
    min_star = offset + (0 if (paper_stop or phi1_zero) else 1)
    m = offset
    while True:
        if span.dim >= n:
            m_star = m
            if m_prime is None:
                m_prime = m
            break
        if m >= n + 2:
            break  # no convergence within the bound of 002 (should not happen)
        m += 1
        cands = [lie(k, v, states, dk) for k, dk in frontier for v in fields + [g_scaled]]
        cands += [lie(h, phis(i, m - 1), states, dh) for i in range(len(fields))]
        frontier = _absorb(cands, span, states, point)
        generators += [k for k, _ in frontier]
        dims.append(span.dim)
        if m_prime is None and span.contains(tau_grad):
            m_prime = m
        prev = m - 1
        if (dims[-1] == dims[-2] and m_prime is not None and prev >= m_prime
                and prev >= min_star):
            m_star = prev
            break
    return {"dims": dims, "dim": span.dim, "m_prime": m_prime, "m_star": m_star,
            "lemma1": lemma, "phi1_zero": phi1_zero, "output": h_name, "offset": offset,
            "unaffected": False, "generators": generators, "point": point}


def single_ui_dims(model, *, seed: int = 0, rtol: float = RTOL, paper_stop: bool = False):
    """Dimensions of Omega_0 .. Omega_{m*+1} of Algorithm 2 (see :func:`single_ui`)."""
    return single_ui(model, seed=seed, rtol=rtol, paper_stop=paper_stop)["dims"]
