"""An exact, independent oracle of Martinelli's general unknown-input solution, and of the EORC.

Plain sympy + numpy + mpmath; it does not import ``uio_jax``. It implements the algorithm of
``docs/general_ui.md`` (A. Martinelli's TUIO6 toolbox, arXiv 2201.07610
Algorithm 5.1/6.1) as stated there, for systems ::

    x' = f0(x, t) + sum_i u_i(t) f_i(x, t) + sum_j w_j(t) g_j(x, t),     y = h(x, t)

with unknown inputs (UIs) ``w_j`` and known inputs ``u_i``.

**Known inputs.** :func:`general_ui` takes every known input to be a *generic smooth* function
of time (meaning S1 of the note): ``u_i`` enters the drift ``g0 = f0 + sum_i u_i f_i`` through
its jet, the free symbols ``u_i, u_i_1, u_i_2, ...`` (``u_i^(r)``), and the **total derivative**
along a field ``F`` of a function ``theta(x, t, jets)`` is ::

    D_F theta = sum_k d theta/d x_k F_k + d theta/d t + sum_{i,r} u_i^(r+1) d theta/d u_i^(r).

The plain Lie derivative is ``L_F theta = sum_k d theta/d x_k F_k``. Both are expanded
(``sympy.expand``, an exact rewriting that keeps the expressions small). Gradients and ranks are
taken with respect to the state only (t and the jets are known quantities).

:func:`eorc` computes the extended observability rank criterion (004 sections 4-6) under both
meanings: ``known_inputs="switchable"`` (S2, the classical EORC: close under the extended drift
``F0`` and each raw known field ``F_i`` separately) and ``known_inputs="smooth"`` (S1: the
known inputs as jets in ``F0``, no separate known fields).

**Generic ranks** (note section 2). Every symbol (state, known constant, t, jet, extension
state) gets an independent random rational ``p/q`` (``1 <= p <= 97``, ``1 <= q <= 13``) at each
of ``K = 3`` points. For rational models (every expression a rational function with rational
coefficients) values are exact rationals and ranks come from exact Gaussian elimination; for
other models values have 60 significant digits, a gradient entry below ``1e-30`` is round-off,
and a row counts as zero when what is left of it after elimination is below ``1e-30`` of its norm.
The generic rank of a list of functions is the maximum over the points of the rank of their state
gradients; a function is generically zero when it vanishes at every point. A point that hits a
pole restarts the whole analysis with new points (seed + 1000, up to 5 tries; the result's
``seed`` says which).

Usage::

    import sympy as sp
    from general_ui_oracle import general_ui, eorc
    x1, x2, u, w = sp.symbols("x1 x2 u w")
    general_ui([x1, x2], f0=None, known={"u": [x2, 0]}, unknown={"w": [0, 1]},
               outputs=[x1 + x2])["dim"]                                     # 1
    eorc([x1, x2], None, {"u": [x2, 0]}, {"w": [0, 1]}, [x1 + x2], k_max=3,
         known_inputs="switchable")["dims"]                                  # [1, 1, 2, 2]

Both functions also accept a ``SympyModel`` of ``scripts/_sympy_models.py`` through
:func:`general_ui_model` and :func:`eorc_model`.
"""

from __future__ import annotations

import random
from fractions import Fraction

import mpmath
import sympy as sp

__all__ = ["general_ui", "general_ui_model", "eorc", "eorc_model", "random_two_ui_system", "Pole", "DPS",
           "ZERO_REL"]

#: Number of random points of every generic-rank decision.
POINTS = 3
#: Significant digits of the evaluation of non-rational models.
DPS = 60
#: Non-rational models: what is left of a row after elimination counts as zero below this size
#: relative to the row, and a value counts as zero below it relative to its largest term.
ZERO_REL = mpmath.mpf("1e-30")
#: Non-rational models: a gradient entry below this absolute size is round-off (the values at the
#: points are of order 1e-3 .. 1e3; a cancelling sum that is identically zero leaves ~1e-60).
ZERO_ABS = mpmath.mpf("1e-30")
#: Safety bound of the main loop (note section 5, step 2).
MAX_ITER = 30
#: Restarts with new points after a pole.
MAX_RESTARTS = 5


class Pole(ArithmeticError):
    """A random point hit a pole of some expression (division by zero)."""


# --------------------------------------------------------------------------------------
# Points, evaluation and generic ranks
# --------------------------------------------------------------------------------------

def _is_rational_expr(e) -> bool:
    e = sp.sympify(e)
    if e.atoms(sp.Float) or e.atoms(sp.NumberSymbol) or e.has(sp.I):
        return False
    return bool(e.is_rational_function())


class _Ctx:
    """Points, the exact/float mode, the jets of the known inputs, the time symbol."""

    def __init__(self, exact: bool, seed: int, t=None, jets=None):
        self.exact = exact
        self.seed = seed
        self.t = t
        # jet symbol -> next jet symbol (u_i^(r) -> u_i^(r+1)); grown on demand
        self.jets = dict(jets or {})
        self._jet_name = {}
        self._vals = [dict() for _ in range(POINTS)]

    # ---- jets -------------------------------------------------------------------------
    def add_jet_root(self, name: str, taken: set) -> sp.Symbol:
        """The order-0 symbol of a known input ``name`` (its jet grows on demand)."""
        s = sp.Symbol(name, real=True)
        if s in taken:
            raise ValueError(f"known input {name!r} clashes with another symbol")
        self._jet_name[s] = (name, 0)
        self.jets[s] = None
        return s

    def next_jet(self, s):
        nxt = self.jets.get(s)
        if nxt is None:
            name, r = self._jet_name[s]
            nxt = sp.Symbol(f"{name}_{r + 1}", real=True)
            self._jet_name[nxt] = (name, r + 1)
            self.jets[s] = nxt
            self.jets.setdefault(nxt, None)
        return nxt

    def is_jet(self, s) -> bool:
        return s in self._jet_name

    # ---- points -----------------------------------------------------------------------
    def value(self, s, k):
        v = self._vals[k].get(s)
        if v is None:
            rng = random.Random(f"{self.seed}:{k}:{s.name}")
            v = sp.Rational(rng.randint(1, 97), rng.randint(1, 13))
            self._vals[k][s] = v
        return v

    def evaluate(self, e, k):
        """``e`` at point ``k``: a ``Fraction`` (exact mode) or an ``mpmath.mpf``."""
        e = sp.sympify(e)
        if e.is_Number:
            r = e
        else:
            sub = {s: self.value(s, k) for s in e.free_symbols}
            if self.exact:
                r = e.xreplace(sub)
            else:
                sub = {s: sp.Float(v, DPS) for s, v in sub.items()}
                r = sp.N(e.xreplace(sub), DPS)
        if r.has(sp.zoo, sp.nan, sp.oo, -sp.oo):
            raise Pole(str(e)[:80])
        if self.exact:
            if not r.is_Rational:
                raise Pole(f"not a rational value: {str(r)[:80]}")
            return Fraction(int(r.p), int(r.q))
        if not r.is_real and r.is_real is not None:
            raise Pole(f"complex value: {str(r)[:80]}")
        with mpmath.workdps(DPS):
            try:
                return mpmath.mpf(sp.Float(r, DPS)._mpf_)
            except (TypeError, AttributeError):
                raise Pole(f"not a number: {str(r)[:80]}") from None

    def is_zero(self, e) -> bool:
        """Generic zero test: ``e`` vanishes at every point (1e-30 relative to its terms)."""
        e = sp.sympify(e)
        if e == 0:
            return True
        for k in range(POINTS):
            v = self.evaluate(e, k)
            if self.exact:
                if v != 0:
                    return False
            else:
                scale = self._scale(e, k)
                if abs(v) > ZERO_REL * scale:
                    return False
        return True

    def _scale(self, e, k):
        """Size of the top-level terms of ``e`` at point k (the reference of the zero test)."""
        s = mpmath.mpf(1)
        for a in sp.Add.make_args(e):
            try:
                s = max(s, abs(self.evaluate(a, k)))
            except Pole:
                continue
        return s

    # ---- derivatives ------------------------------------------------------------------
    def grad(self, e, states):
        return [sp.diff(e, s) for s in states]

    def lie(self, e, field, states, grad=None):
        """``L_F e = sum_k de/dx_k F_k``."""
        grad = self.grad(e, states) if grad is None else grad
        return sp.expand(sp.Add(*[gk * fk for gk, fk in zip(grad, field) if gk != 0 and fk != 0]))

    def total(self, e, field, states, grad=None):
        """``D_F e = L_F e + de/dt + sum u^(r+1) de/du^(r)`` (note section 1)."""
        out = self.lie(e, field, states, grad)
        e = sp.sympify(e)
        extra = []
        if self.t is not None and e.has(self.t):
            extra.append(sp.diff(e, self.t))
        for s in sorted((s for s in e.free_symbols if self.is_jet(s)), key=lambda s: s.name):
            extra.append(sp.diff(e, s) * self.next_jet(s))
        return sp.expand(sp.Add(out, *extra))

    def row(self, e, states, k, grad=None):
        """The gradient of ``e`` at point ``k``; in 60-digit mode an entry below ``ZERO_ABS`` is set
        to 0 (round-off of an identically zero derivative written as a cancelling sum)."""
        grad = self.grad(e, states) if grad is None else grad
        vals = [self.evaluate(d, k) for d in grad]
        if not self.exact:
            vals = [mpmath.mpf(0) if abs(v) < ZERO_ABS else v for v in vals]
        return vals


class _Span:
    """Generators whose state gradients are generically independent (note section 2).

    One echelon basis per point; the generic rank is the maximum of the per-point ranks, and
    :meth:`add` keeps a function only if it raises that maximum.
    """

    def __init__(self, ctx: _Ctx, states):
        self.ctx = ctx
        self.states = list(states)
        self.bases = [[] for _ in range(POINTS)]

    @property
    def rank(self) -> int:
        return max(len(b) for b in self.bases)

    @staticmethod
    def _reduce(ctx, basis, row):
        """What is left of ``row`` after elimination against ``basis`` (None if dependent)."""
        if ctx.exact:
            row = list(row)
            for piv, b in basis:
                c = row[piv]
                if c:
                    row = [ri - c * bi for ri, bi in zip(row, b)]
            for j, v in enumerate(row):
                if v:
                    return (j, [ri / v for ri in row])
            return None
        with mpmath.workdps(DPS):
            row = [mpmath.mpf(v) for v in row]
            norm0 = mpmath.sqrt(sum(v * v for v in row))
            if norm0 == 0:
                return None
            for _ in range(2):  # Gram-Schmidt twice
                for b in basis:
                    c = sum(ri * bi for ri, bi in zip(row, b))
                    row = [ri - c * bi for ri, bi in zip(row, b)]
            norm = mpmath.sqrt(sum(v * v for v in row))
            if norm <= ZERO_REL * norm0:
                return None
            return [ri / norm for ri in row]

    @classmethod
    def rank_of_rows(cls, ctx, rows) -> int:
        """Rank of a list of numeric rows (one point)."""
        basis = []
        for r in rows:
            red = cls._reduce(ctx, basis, r)
            if red is not None:
                basis.append(red)
        return len(basis)

    def add_rows(self, rows) -> bool:
        """Add a function given by its rows at the points; True if the generic rank rose."""
        reds = [self._reduce(self.ctx, b, r) for b, r in zip(self.bases, rows)]
        new = max(len(b) + (red is not None) for b, red in zip(self.bases, reds))
        if new <= self.rank:
            return False
        for b, red in zip(self.bases, reds):
            if red is not None:
                b.append(red)
        return True

    def add(self, e, grad=None) -> bool:
        e = sp.sympify(e)
        if e == 0 or not (e.free_symbols & set(self.states)):
            return False
        grad = self.ctx.grad(e, self.states) if grad is None else grad
        return self.add_rows([self.ctx.row(e, self.states, k, grad) for k in range(POINTS)])


def _generic_rank(ctx, exprs, states) -> int:
    span = _Span(ctx, states)
    for e in exprs:
        span.add(e)
    return span.rank


def _matrix_rank(ctx, M) -> tuple[int, int]:
    """Generic rank of a matrix of expressions and the first point where it is reached."""
    best, kbest = -1, 0
    for k in range(POINTS):
        rows = [[ctx.evaluate(e, k) for e in r] for r in M]
        r = _Span.rank_of_rows(ctx, rows) if rows and rows[0] else 0
        if r > best:
            best, kbest = r, k
    return best, kbest


# --------------------------------------------------------------------------------------
# Close (note section 3)
# --------------------------------------------------------------------------------------

def _close(ctx, theta0, fields, states, *, guard=None, filt=None):
    """``Close(Theta0, [F0, F1, ..]; guard, filter)`` of the note, section 3.

    ``fields[0]`` gets the total derivative D, the others plain Lie derivatives. Returns
    ``{"gens": [(theta, root)], "rank", "abort": None | (root_index, ord), "passes"}``.
    Without a guard it stops at full rank; with a guard, full rank does not stop it: every
    remaining generator must still pass the guard (TUIO6 ``Algorithm2``).
    """
    n = len(states)
    span = _Span(ctx, states)
    gens = []
    for i, th in enumerate(theta0):
        if guard is None and span.rank == n:
            break
        if span.add(th):
            gens.append((sp.sympify(th), i))
    frontier = list(gens)
    r = 0
    while frontier:
        if guard is None and span.rank == n:
            break
        new = []
        for th, root in frontier:
            if guard is not None and guard(th):
                return {"gens": gens, "rank": span.rank, "abort": (root, r), "passes": r}
            if filt is not None and not filt(th):
                continue
            if span.rank == n:
                continue  # full rank: nothing can be added, but the guard must still be checked
            grad = ctx.grad(th, states)
            for a, F in enumerate(fields):
                c = ctx.total(th, F, states, grad) if a == 0 else ctx.lie(th, F, states, grad)
                if span.add(c):
                    new.append((c, root))
                    gens.append((c, root))
                    if guard is None and span.rank == n:
                        break
            if guard is None and span.rank == n:
                break
        frontier = new
        r += 1
    return {"gens": gens, "rank": span.rank, "abort": None, "passes": r}


# --------------------------------------------------------------------------------------
# Reconstructability and rescaled fields (note section 4)
# --------------------------------------------------------------------------------------

def _greedy(ctx, rows_num, count):
    """Indices of the first ``count`` independent rows (in order) of a numeric matrix."""
    chosen, basis = [], []
    for i, r in enumerate(rows_num):
        red = _Span._reduce(ctx, basis, r)
        if red is not None:
            basis.append(red)
            chosen.append(i)
            if len(chosen) == count:
                break
    return chosen


def _reconstructability(ctx, theta, g, states):
    """Degree m, identifiers (indices into theta) and the chosen UI columns (note section 4)."""
    mw = len(g)
    if mw == 0 or not theta:
        return 0, [], []
    R = [[ctx.lie(th, gj, states) for gj in g] for th in theta]
    m, k = _matrix_rank(ctx, R)
    if m == 0:
        return 0, [], []
    num = [[ctx.evaluate(e, k) for e in r] for r in R]
    rows = _greedy(ctx, num, m)
    sub_t = [[num[i][j] for i in rows] for j in range(mw)]  # columns of the chosen rows
    cols = _greedy(ctx, sub_t, m)
    return m, rows, cols


def _rescaled(ctx, g0, g, idents, m, states):
    """``ghat0, [ghat_1..ghat_m], [Ghat_{m+1}..Ghat_mw]`` (note section 4)."""
    n = len(states)
    if m == 0:
        return list(g0), [], [list(gk) for gk in g]
    B = sp.Matrix(m, m, lambda i, j: ctx.lie(idents[i], g[j], states))
    a = sp.Matrix(m, 1, lambda i, _: ctx.total(idents[i], g0, states))
    Binv = B.inv(method="LU") if m > 1 else sp.Matrix([[1 / B[0, 0]]])
    c = Binv * a
    ghat0 = [g0[r] - sp.Add(*[c[j] * g[j][r] for j in range(m)]) for r in range(n)]
    ghat = [[sp.Add(*[Binv[j, k] * g[j][r] for j in range(m)]) for r in range(n)] for k in range(m)]
    Ghat = []
    for kk in range(m, len(g)):
        lk = [ctx.lie(idents[j], g[kk], states) for j in range(m)]
        Ghat.append([g[kk][r] - sp.Add(*[ghat[j][r] * lk[j] for j in range(m)]) for r in range(n)])
    return ghat0, ghat, Ghat


# --------------------------------------------------------------------------------------
# Input normalisation
# --------------------------------------------------------------------------------------

def _vec(field, n, what):
    v = [sp.sympify(e) for e in (list(field) if field is not None else [0] * n)]
    if len(v) != n:
        raise ValueError(f"{what} has {len(v)} components, the state has {n}")
    return v


def _prepare(states, f0, known, unknown, outputs, t, seed, arithmetic="auto"):
    states = [sp.sympify(s) for s in states]
    n = len(states)
    f0 = _vec(f0, n, "f0")
    known = {k: _vec(v, n, f"known field {k!r}") for k, v in (known or {}).items()}
    unknown = {k: _vec(v, n, f"unknown field {k!r}") for k, v in (unknown or {}).items()}
    outputs = [sp.sympify(h) for h in (outputs.values() if isinstance(outputs, dict) else outputs)]
    exprs = f0 + [e for v in known.values() for e in v] + [e for v in unknown.values() for e in v] + outputs
    if arithmetic not in ("auto", "exact", "float"):
        raise ValueError(f"arithmetic must be 'auto', 'exact' or 'float', not {arithmetic!r}")
    rational = all(_is_rational_expr(e) for e in exprs)
    if arithmetic == "exact" and not rational:
        raise ValueError("arithmetic='exact' needs rational expressions with rational coefficients")
    exact = rational and arithmetic != "float"
    ctx = _Ctx(exact, seed, t=t)
    taken = set(states) | ({t} if t is not None else set())
    for e in exprs:
        taken |= e.free_symbols
    jets = {name: ctx.add_jet_root(name, taken) for name in known}
    g0 = [f0[r] + sp.Add(*[jets[k] * known[k][r] for k in known]) for r in range(n)]
    return ctx, states, f0, known, unknown, outputs, g0, jets


def _restarting(fn, seed):
    last = None
    for attempt in range(MAX_RESTARTS):
        try:
            return fn(seed + 1000 * attempt)
        except Pole as exc:  # note section 2: restart with new points
            last = exc
    raise Pole(f"every point set hit a pole ({last})")


# --------------------------------------------------------------------------------------
# The general solution (note section 5)
# --------------------------------------------------------------------------------------

def general_ui(states, f0, known: dict, unknown: dict, outputs, *, t=None, seed: int = 0,
               arithmetic: str = "auto") -> dict:
    """Martinelli's general analytic solution of unknown-input observability (note section 5).

    Args:
        states: state symbols ``x_1..x_n`` (unknown constant parameters are states with zero
            dynamics).
        f0: drift, ``n`` sympy expressions (or None for no drift).
        known: known input name -> field ``f_i`` (``n`` expressions). Each known input is a generic
            smooth function of time (meaning S1), entered through its jet ``name, name_1, ..``.
        unknown: unknown input name -> field ``g_j`` (``n`` expressions), in order.
        outputs: output expressions (list, or dict name -> expression).
        t: optional time symbol appearing explicitly in the fields/outputs.
        seed: seed of the random points.
        arithmetic: ``"auto"`` (exact for rational models, 60 digits otherwise), ``"exact"`` or
            ``"float"`` (60 digits even for a rational model: a cross-check of the two routes).

    Returns:
        dict with ``dim`` (dimension of the observable codistribution on the original state,
        ``rank Omega - rank(Omega projected on the extension coordinates)``), ``observable``
        (indices i with ``dx_i`` in Omega), ``state_observable`` (dim == n), ``initially_canonic``,
        ``canonic``, ``ui_extension``, ``ui_degree`` (final m), ``ui_reconstructable`` (original UI
        indices behind the final degree), ``final_uis`` (original index behind each final UI),
        ``ui_observable`` (one bool per final UI: ``dw_k`` in the span of ``dtheta`` and of the
        differentials of the full time derivatives of theta in Omega, in (state, w) coordinates),
        ``extension_states``, ``extension_states_observable``, ``exact`` (rational arithmetic),
        ``generators`` (Omega), ``final_states`` and ``trace`` (one dict per step).
    """
    return _restarting(lambda s: _general_ui(states, f0, known, unknown, outputs, t, s, arithmetic), seed)


def _general_ui(states, f0, known, unknown, outputs, t, seed, arithmetic):
    ctx, X, _f0, _known, unknown, h, g0, _jets = _prepare(states, f0, known, unknown, outputs, t, seed,
                                                          arithmetic)
    n = len(X)
    X = list(X)
    g = [list(v) for v in unknown.values()]
    labels = list(range(len(g)))  # original UI index behind each current UI
    mw = len(g)
    trace = []
    E = []  # extension states
    extended = False

    def finish(omega_gens, m, stop):
        return _outputs(ctx, X, n, E, omega_gens, g0, g, labels, m, mw, extended, initially_canonic,
                        stop, trace)

    if mw == 0:
        res = _close(ctx, h, [g0], X)
        trace.append({"step": "orc", "rank": res["rank"]})
        initially_canonic = True
        return finish([e for e, _ in res["gens"]], 0, "no unknown input")

    theta = list(h)
    m, rows, cols = _reconstructability(ctx, theta, g, X)
    order = cols + [j for j in range(mw) if j not in cols]
    g, labels = [g[j] for j in order], [labels[j] for j in order]
    idents = [theta[i] for i in rows]
    initially_canonic = m == mw
    trace.append({"step": "reconstructability", "m": m, "identifiers": list(idents), "ui_order": list(labels)})
    n_ext = 0
    for it in range(MAX_ITER):
        theta = [e for e, _ in _close(ctx, theta, [], X)["gens"]]
        # identifiers must stay in Theta (they do: Close keeps the first independent ones)
        if m == mw:
            break
        ghat0, ghat, Ghat = _rescaled(ctx, g0, g, idents, m, X)
        if all(ctx.is_zero(e) for G in Ghat for e in G):
            res = _close(ctx, theta, [ghat0] + ghat, X)
            trace.append({"step": "Ghat vanish", "m": m, "rank": res["rank"]})
            return finish([e for e, _ in res["gens"]], m, "every Ghat_k vanishes")

        def guard(th, Ghat=Ghat):
            grad = ctx.grad(th, X)
            return any(not ctx.is_zero(ctx.lie(th, G, X, grad)) for G in Ghat)

        res = _close(ctx, theta, [ghat0] + ghat, X, guard=guard)
        if res["abort"] is None:
            trace.append({"step": "guarded closure, no abort", "m": m, "rank": res["rank"]})
            return finish([e for e, _ in res["gens"]], m, "guarded closure without abort")
        root, ordr = res["abort"]
        theta_star = theta[root]
        trace.append({"step": "guarded closure, abort", "m": m, "root": theta_star, "ord": ordr,
                      "rank_reached": res["rank"]})
        if m == 0:
            def filt(th):
                grad = ctx.grad(th, X)
                return all(ctx.is_zero(ctx.lie(th, gj, X, grad)) for gj in g)

            theta = [e for e, _ in _close(ctx, theta, [g0], X, filt=filt)["gens"]]
            trace.append({"step": "filtered closure (m = 0)", "generators": len(theta)})
        else:
            extended = True
            n_ext += 1
            theta, X, E, g0, g = _extend(ctx, X, E, theta, ghat0, ghat, Ghat, theta_star, ordr, m, n_ext,
                                         trace)
        m_old = m
        m, rows, cols = _reconstructability(ctx, theta, g, X)
        order = cols + [j for j in range(mw) if j not in cols]
        g, labels = [g[j] for j in order], [labels[j] for j in order]
        idents = [theta[i] for i in rows]
        trace.append({"step": "reconstructability", "m": m, "identifiers": list(idents), "ui_order": list(labels)})
        if m_old >= 1 and trace[-2].get("step") == "ui extension":
            # each extension is expected to raise m; TUIO6 does not check it (note, stopping rule)
            trace[-2]["m_raised"] = m > m_old
    else:
        raise RuntimeError(f"no convergence in {MAX_ITER} iterations")
    # canonic closure (step 3)
    ghat0, ghat, _ = _rescaled(ctx, g0, g, idents, m, X)
    res = _close(ctx, theta, [ghat0] + ghat, X)
    trace.append({"step": "canonic closure", "m": m, "rank": res["rank"]})
    return finish([e for e, _ in res["gens"]], m, "canonic")


def _extend(ctx, X, E, theta, ghat0, ghat, Ghat, theta_star, ordr, m, n_ext, trace):
    """UI extension (state augmentation), note section 5 step 2.7."""
    N = len(X)
    taken = {s.name for s in X}
    V = {}  # (j, i) -> symbol
    for i in range(ordr + 1):
        for j in range(m):
            nm = f"v{n_ext}_{j + 1}" + (f"_{i}" if i else "")
            while nm in taken:
                nm += "'"
            taken.add(nm)
            V[(j, i)] = sp.Symbol(nm, real=True)
    newX = X + [V[(j, i)] for i in range(ordr + 1) for j in range(m)]
    xdrift = [ghat0[r] + sp.Add(*[V[(j, 0)] * ghat[j][r] for j in range(m)]) for r in range(N)]
    vdrift = {V[(j, i)]: (V[(j, i + 1)] if i < ordr else sp.Integer(0)) for j in range(m) for i in range(ordr + 1)}
    drift = xdrift + [vdrift[s] for s in newX[N:]]
    theta_v = theta_star
    for _ in range(ordr):
        theta_v = ctx.total(theta_v, drift, newX)
    delete = set()
    new_ui = []
    chain_kept = {}
    for j in range(m):
        top = None
        for i in range(ordr, -1, -1):
            if not ctx.is_zero(sp.diff(theta_v, V[(j, i)])):
                top = i
                break
        if top is None:
            delete |= {V[(j, i)] for i in range(ordr + 1)}
            xdrift = [xdrift[r] - V[(j, 0)] * ghat[j][r] for r in range(N)]
            new_ui.append(("field", ghat[j]))
            chain_kept[j] = -1
        else:
            delete |= {V[(j, i)] for i in range(top + 1, ordr + 1)}
            vdrift[V[(j, top)]] = sp.Integer(0)
            new_ui.append(("unit", V[(j, top)]))
            chain_kept[j] = top
    if delete:
        theta_v = theta_v.xreplace({s: sp.Integer(1) for s in delete})
    kept = [s for s in newX[N:] if s not in delete]
    X2 = X + kept
    g0_new = xdrift + [vdrift[s] for s in kept]
    g_new = []
    for kind, val in new_ui:
        if kind == "unit":
            g_new.append([sp.Integer(0)] * N + [sp.Integer(1) if s == val else sp.Integer(0) for s in kept])
        else:
            g_new.append(list(val) + [sp.Integer(0)] * len(kept))
    for G in Ghat:
        g_new.append(list(G) + [sp.Integer(0)] * len(kept))
    theta2 = list(theta) + list(kept) + [theta_v]
    trace.append({"step": "ui extension", "ord": ordr, "root": theta_star, "theta_v": theta_v,
                  "states_added": list(kept), "chains": chain_kept})
    return theta2, X2, E + kept, g0_new, g_new


def _outputs(ctx, X, n, E, omega, g0, g, labels, m, mw, extended, initially_canonic, stop, trace):
    """The outputs of the note (section "Outputs")."""
    N = len(X)
    best = None
    for k in range(POINTS):
        rows = [ctx.row(e, X, k) for e in omega]
        rO = _Span.rank_of_rows(ctx, rows)
        rE = _Span.rank_of_rows(ctx, [r[n:] for r in rows]) if N > n else 0
        obs = []
        for i in range(N):
            unit = [Fraction(int(i == c)) if ctx.exact else mpmath.mpf(int(i == c)) for c in range(N)]
            obs.append(_Span.rank_of_rows(ctx, rows + [unit]) == rO)
        cand = (rO, rE, obs)
        if best is None or (rO, rE) > best[:2]:
            best = cand
    rO, rE, obs = best
    dim = rO - rE
    # final-UI observability: dw_k in span{dtheta, d(D_g0 theta + sum_j w_j L_gj theta)}
    W = []
    taken = {s.name for s in X}
    for k in range(len(g)):
        nm = f"wbar_{k + 1}"
        while nm in taken:
            nm += "'"
        W.append(sp.Symbol(nm, real=True))
    XW = X + W
    ui_obs = []
    if g:
        span = _Span(ctx, XW)
        for th in omega:
            span.add(th)
        for th in omega:
            grad = ctx.grad(th, X)
            dth = ctx.total(th, g0, X, grad) + sp.Add(*[W[j] * ctx.lie(th, g[j], X, grad) for j in range(len(g))])
            span.add(dth)
        for k in range(len(g)):
            unit = [Fraction(int(i == N + k)) if ctx.exact else mpmath.mpf(int(i == N + k)) for i in range(len(XW))]
            probe = _Span(ctx, XW)
            probe.bases = [list(b) for b in span.bases]
            ui_obs.append(not probe.add_rows([unit] * POINTS))
    reconstructable = sorted(labels) if m == mw else sorted(labels[:m])
    return {
        "dim": dim, "n": n, "observable": [i for i in range(n) if obs[i]],
        "state_observable": dim == n, "initially_canonic": initially_canonic, "canonic": m == mw,
        "ui_extension": extended, "ui_degree": m, "ui_reconstructable": reconstructable,
        "final_uis": list(labels), "ui_observable": ui_obs,
        "extension_states": list(E), "extension_states_observable": all(obs[n:]),
        "exact": ctx.exact, "generators": list(omega), "final_states": list(X), "stop": stop,
        "trace": trace, "seed": ctx.seed,
    }


# --------------------------------------------------------------------------------------
# EORC under both meanings of known inputs
# --------------------------------------------------------------------------------------

def eorc(states, f0, known: dict, unknown: dict, outputs, *, k_max: int, known_inputs: str = "switchable",
         t=None, seed: int = 0, arithmetic: str = "auto") -> dict:
    """Extended observability rank criterion per order k = 0..k_max (004 sections 4-6).

    Extended state ``x^(K) = [x; w; w^(1); ..; w^(K-1)]`` with ``K = k_max`` and extended drift
    ``F0 = [f0 + sum_j g_j w_j (+ sum_i u_i f_i if smooth); w^(1); ..; w^(K-1); 0]``::

        Omega-bar_0 = span{dh},   Omega-bar_k = Omega-bar_{k-1} + sum_{v} L_v Omega-bar_{k-1},

    with ``v`` in ``{D_F0, L_F1, .., L_Fmu}`` (``known_inputs="switchable"``, meaning S2: each raw
    known field ``F_i = [f_i; 0]`` separately) or ``v = D_F0`` only (``"smooth"``, meaning S1:
    ``F0`` holds ``u_i f_i`` with the jets of ``u_i`` as free known symbols). D adds ``d/dt`` and
    the jet terms (module docstring). Gradients are taken on the extended state. ``t``, ``seed``
    and ``arithmetic`` as in :func:`general_ui`.

    Returns:
        ``{"dims": [dim_k on the original state], "ranks": [rank of Omega-bar_k], "observable":
        [indices with dx_i in Omega-bar_k, per k], "closed_at": the first k whose pass added
        nothing (then every higher order gives the same), or None, "exact": bool}``, with
        ``dim_k = rank Omega-bar_k - rank(Omega-bar_k restricted to the w-coordinates)``.
    """
    if known_inputs not in ("switchable", "smooth"):
        raise ValueError(f"known_inputs must be 'switchable' or 'smooth', not {known_inputs!r}")
    if k_max < 0:
        raise ValueError("k_max must be >= 0")
    return _restarting(lambda s: _eorc(states, f0, known, unknown, outputs, k_max, known_inputs, t, s,
                                       arithmetic), seed)


def _eorc(states, f0, known, unknown, outputs, k_max, mode, t, seed, arithmetic):
    ctx, X, f0v, known, unknown, h, g0, _ = _prepare(states, f0, known, unknown, outputs, t, seed, arithmetic)
    n = len(X)
    mw = len(unknown)
    K = max(k_max, 1)
    taken = {s.name for s in X}
    Wsym = []
    for d in range(K):
        for name in unknown:
            nm = name if d == 0 else f"{name}_d{d}"
            while nm in taken:
                nm += "'"
            taken.add(nm)
            Wsym.append(sp.Symbol(nm, real=True))
    XE = X + Wsym
    base = g0 if mode == "smooth" else f0v
    gs = list(unknown.values())
    F0 = [base[r] + sp.Add(*[Wsym[j] * gs[j][r] for j in range(mw)]) for r in range(n)]
    F0 += [Wsym[i + mw] if i + mw < len(Wsym) else sp.Integer(0) for i in range(len(Wsym))]
    fields = [F0]
    if mode == "switchable":
        fields += [list(f) + [sp.Integer(0)] * len(Wsym) for f in known.values()]
    span = _Span(ctx, XE)
    frontier = []
    for e in h:
        if span.add(e):
            frontier.append(e)
    gens = list(frontier)
    dims, ranks, observ = [], [], []
    closed_at = None

    def record():
        best = None
        for k in range(POINTS):
            rows = [ctx.row(e, XE, k) for e in gens]
            rO = _Span.rank_of_rows(ctx, rows)
            rW = _Span.rank_of_rows(ctx, [r[n:] for r in rows])
            obs = []
            for i in range(n):
                unit = [Fraction(int(i == c)) if ctx.exact else mpmath.mpf(int(i == c)) for c in range(len(XE))]
                obs.append(_Span.rank_of_rows(ctx, rows + [unit]) == rO)
            if best is None or (rO, rW) > best[:2]:
                best = (rO, rW, obs)
        dims.append(best[0] - best[1])
        ranks.append(best[0])
        observ.append([i for i in range(n) if best[2][i]])

    record()
    for k in range(1, k_max + 1):
        new = []
        for th in frontier:
            grad = ctx.grad(th, XE)
            for a, F in enumerate(fields):
                c = ctx.total(th, F, XE, grad) if a == 0 else ctx.lie(th, F, XE, grad)
                if span.add(c):
                    new.append(c)
        gens += new
        frontier = new
        record()
        if not new and closed_at is None:
            closed_at = k
    return {"dims": dims, "ranks": ranks, "observable": observ, "closed_at": closed_at, "exact": ctx.exact}


# --------------------------------------------------------------------------------------
# Random test systems
# --------------------------------------------------------------------------------------

def random_two_ui_system(seed: int):
    """A random rational test system: 4 states ``x1..x4``, outputs ``(x1, x2)``, a sparse polynomial
    drift (each component 0 with probability 0.4, else +-1 or 2 times a monomial of degree <= 2) and
    two unknown inputs whose fields have 1 or 2 nonzero components of degree <= 1.

    Returns the positional arguments of :func:`general_ui` / :func:`eorc`:
    ``(states, f0, known={}, unknown={"w1": g1, "w2": g2}, outputs)``. Deterministic in ``seed``.
    """
    rng = random.Random(seed)
    X = list(sp.symbols("x1:5"))

    def mono(p0, degrees):
        if rng.random() < p0:
            return sp.Integer(0)
        e = sp.Integer(rng.choice([1, 2, -1]))
        for _ in range(rng.choice(degrees)):
            e *= rng.choice(X)
        return e

    f0 = [mono(0.4, (0, 1, 1, 2)) for _ in X]
    g = []
    for _ in range(2):
        v = [sp.Integer(0)] * 4
        for i in rng.sample(range(4), rng.choice([1, 2])):
            v[i] = mono(0.0, (0, 1))
        g.append(v)
    return X, f0, {}, {"w1": g[0], "w2": g[1]}, [X[0], X[1]]


# --------------------------------------------------------------------------------------
# SympyModel adapters (scripts/_sympy_models.py)
# --------------------------------------------------------------------------------------

def _model_args(model):
    return (list(model.states), (list(model.drift) if model.drift is not None else None),
            {k: list(v) for k, v in model.known.items()}, {k: list(v) for k, v in model.unknown.items()},
            list(model.outputs.values()))


def general_ui_model(model, **kw) -> dict:
    """:func:`general_ui` of a ``SympyModel`` (``scripts/_sympy_models.py``)."""
    return general_ui(*_model_args(model), t=getattr(model, "time", None), **kw)


def eorc_model(model, **kw) -> dict:
    """:func:`eorc` of a ``SympyModel`` (``scripts/_sympy_models.py``)."""
    return eorc(*_model_args(model), t=getattr(model, "time", None), **kw)
