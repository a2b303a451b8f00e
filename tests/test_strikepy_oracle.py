"""StrikePy model files: the project's importer + ``uj.analyze`` against an independent sympy oracle.

For each small known-input model in StrikePy's format (``tests/data/strikepy_models/``, re-typed
from the models shipped with StrikePy 1.0), the test

* reads the file with the project's importer (``uio_jax._io.strikepy_import.load_strikepy``) and
  analyses it (``uj.analyze``, ``method="auto"``, which is the ORC on ``z = [x; p]``);
* evaluates the same file independently with sympy (``runpy``; the file is trusted test data)
  and builds the Hermann-Krener codistribution of the joint system ``z = [x; p]``,
  ``z' = [f; 0]``: the gradients of ``h``, of its Lie derivatives along the drift ``f0 = f|_{u=0}``
  and the input fields ``f_i = df/du_i``, and so on, level after level, until a level adds no
  rank (then the codistribution is invariant). Ranks are taken in 50-digit arithmetic (mpmath
  SVD) at random rational points; a state or parameter ``z_j`` is observable / identifiable
  exactly when the unit covector ``e_j`` lies in that span;
* asserts both give the same verdict for every state and every parameter, and so does the
  generic-input series test (``method="series"``, the kind of test StrikePy runs).

StrikePy itself is not imported: it is not a dependency of the test suite. Where it is installed,
``test_data_files_match_the_shipped_models`` checks that the re-typed files define the same
models as the shipped ones (found with ``importlib.util.find_spec``, read with ``runpy``).
"""

import importlib.util
import random
import runpy
from pathlib import Path

import pytest

import uio_jax as uj

sp = pytest.importorskip("sympy", reason="the oracle needs sympy (dev extra)")
mpmath = pytest.importorskip("mpmath", reason="the oracle needs mpmath (installed with sympy)")
from sympy.polys.domains import QQ  # noqa: E402
from sympy.polys.matrices import DomainMatrix  # noqa: E402

DATA = Path(__file__).resolve().parent / "data" / "strikepy_models"
SAMPLES = 1024
_DPS = 50
_RTOL = mpmath.mpf(10) ** -30

# name -> marks; the slow ones (> 15 s on a shared 2-core machine) run with -m slow.
MODELS = {
    "1A_integral": (),
    "1B_prop_integral": (),
    "1C_nonlinear": (),
    "Bolie": (pytest.mark.slow,),  # 17-18 s
    "C2M": (),
    "C2M_2outputs": (),
    "CR": (),
    "BIG_known_input": (pytest.mark.slow,),
    "PK": (pytest.mark.slow,),
    "phos": (pytest.mark.slow,),
    "tumor": (pytest.mark.slow,),
    "HIV_1": (pytest.mark.slow,),
    "sirs": (pytest.mark.slow,),
    "SIWR": (pytest.mark.slow,),
}
# Not here: MAPK (the iterated Lie derivatives of n1**n1 / (n1**n1 + ps3**n1) grow too fast for
# sympy: no result in 10 minutes) and the larger models; scripts/compare_strikepy.py --oracle
# runs the same oracle on every known-input model under a time limit.


# --------------------------------------------------------------------------------------
# Reading a StrikePy model file with sympy
# --------------------------------------------------------------------------------------

def _flat(seq):
    """``[a, b]``, ``[[a], [b]]`` or a numpy column -> a flat list of sympy objects."""
    out = []
    for item in list(seq) if seq is not None else []:
        if isinstance(item, (list, tuple)) or (hasattr(item, "tolist") and not isinstance(item, sp.Basic)):
            out.extend(_flat(list(item)))
        else:
            out.append(sp.sympify(item))
    return out


def _unique(symbols):
    seen, out = set(), []
    for s in symbols:
        if s not in seen:
            seen.add(s)
            out.append(s)
    return out


def _read_model(path):
    """The model module evaluated with sympy: x, p (distinct), u, w, f, h and the known constants."""
    ns = runpy.run_path(str(path))
    x, p = _flat(ns["x"]), _unique(_flat(ns["p"]))
    u, w = _flat(ns.get("u", [])), _flat(ns.get("w", []))
    f, h = _flat(ns["f"]), _flat(ns["h"])
    assert len(f) == len(x), f"{path.name}: f has {len(f)} rows for {len(x)} states"
    named = set(x) | set(p) | set(u) | set(w)
    consts = sorted(set().union(*(e.free_symbols for e in f + h)) - named, key=str)
    return {"x": x, "p": p, "u": u, "w": w, "f": f, "h": h, "consts": consts}


# --------------------------------------------------------------------------------------
# The oracle: Hermann-Krener codistribution of [x; p], ranks in 50 digits
# --------------------------------------------------------------------------------------

def _rand_rational(rng):
    return sp.Rational(rng.randint(500, 1500), 1000)


def _rank_float(rows):
    """Numerical rank of mpmath rows (each normalised), 50 digits, relative threshold 1e-30."""
    rows = [r for r in rows if mpmath.norm(mpmath.matrix(r)) > 0]
    if not rows:
        return 0
    a = mpmath.matrix([[v / mpmath.norm(mpmath.matrix(r)) for v in r] for r in rows])
    s = mpmath.svd_r(a, compute_uv=False)
    s = [abs(s[i]) for i in range(len(s))]
    return sum(1 for v in s if v > _RTOL * max(s))


def _rank_exact(rows):
    """Exact rank of rows of rationals."""
    if not rows:
        return 0
    return DomainMatrix([[QQ.convert(v) for v in r] for r in rows], (len(rows), len(rows[0])), QQ).rank()


class _PolyArith:
    """Polynomial models: functions as ``Poly`` over QQ, exact gradients and exact ranks."""

    def __init__(self, z, points):
        self.z, self.points = z, points

    def function(self, expr):
        return sp.Poly(expr, *self.z, domain=QQ)

    def lie(self, phi, field):
        out = sp.Poly(0, *self.z, domain=QQ)
        for s, v in zip(self.z, field):
            if not v.is_zero:
                out += phi.diff(s) * v
        return out

    def grad_rows(self, phi):
        grads = [phi.diff(s) for s in self.z]
        return [[g.eval(tuple(pt[s] for s in self.z)) if not g.is_zero else QQ(0) for g in grads]
                for pt in self.points]

    rank = staticmethod(_rank_exact)

    def unit(self, j):
        return [QQ(int(i == j)) for i in range(len(self.z))]


class _SymbolicArith:
    """Other models: sympy expressions, gradients evaluated in 50 digits, SVD ranks."""

    def __init__(self, z, points):
        self.z, self.points = z, points

    def function(self, expr):
        return expr

    def lie(self, phi, field):
        return sum(sp.diff(phi, s) * v for s, v in zip(self.z, field) if v != 0)

    def grad_rows(self, phi):
        fn = sp.lambdify(self.z, [sp.diff(phi, s) for s in self.z], modules="mpmath")
        return [[mpmath.mpf(v) for v in fn(*[mpmath.mpf(pt[s].p) / pt[s].q for s in self.z])]
                for pt in self.points]

    rank = staticmethod(_rank_float)

    def unit(self, j):
        return [mpmath.mpf(int(i == j)) for i in range(len(self.z))]


def hk_oracle(model, n_points=2, seed=1):
    """Observable states, identifiable parameters (dicts name -> bool) and the rank of ``model``.

    Hermann-Krener on ``z = [x; p]`` with ``z' = [f0 + sum_i f_i u_i; 0]`` (every input known,
    entering affinely; known constants set to random rationals). Level 0 is ``h``; level k+1 the
    Lie derivatives of the functions kept at level k along every field; a function is kept when
    its gradient raises the rank at the random rational points (all of them must agree). Stops at
    the first level that keeps nothing: the span is then invariant under every field. Polynomial
    models are done exactly (``Poly`` over QQ, exact ranks), the others with symbolic Lie
    derivatives and 50-digit ranks.
    """
    rng = random.Random(seed)
    x, p, u = model["x"], model["p"], model["u"]
    assert not model["w"], "the oracle handles known inputs only"
    z = x + p
    consts = {c: _rand_rational(rng) for c in model["consts"]}
    f = [sp.nsimplify(e.xreplace(consts), rational=True) for e in model["f"]]
    h = [sp.nsimplify(e.xreplace(consts), rational=True) for e in model["h"]]
    zero_u = {ui: 0 for ui in u}
    fields = [[e.xreplace(zero_u) for e in f]]
    for ui in u:
        gi = [sp.diff(e, ui) for e in f]
        assert all(sp.diff(g, ui) == 0 for g in gi), f"input {ui} does not enter affinely"
        fields.append(gi)
    fields = [v + [sp.Integer(0)] * len(p) for v in fields]
    points = [{s: _rand_rational(rng) for s in z} for _ in range(n_points)]
    mpmath.mp.dps = _DPS
    polynomial = all(e.is_polynomial(*z) for e in h + [c for v in fields for c in v])
    ar = (_PolyArith if polynomial else _SymbolicArith)(z, points)
    fields = [[ar.function(c) for c in v] for v in fields] if polynomial else fields

    kept = [[] for _ in points]  # gradient rows per point
    frontier, level = [ar.function(e) for e in h], 0
    while frontier:
        new = []
        for phi in frontier:
            rows = ar.grad_rows(phi)
            grows = [ar.rank(k + [r]) > len(k) for k, r in zip(kept, rows)]
            assert len(set(grows)) == 1, f"random points disagree on a rank (level {level})"
            if grows[0]:
                for k, r in zip(kept, rows):
                    k.append(r)
                new.append(phi)
        if not new or len(kept[0]) == len(z):
            break
        frontier = [ar.lie(phi, v) for phi in new for v in fields]
        level += 1
    dim = len(kept[0])
    verdict = {}
    for j, s in enumerate(z):
        ins = [ar.rank(k + [ar.unit(j)]) == dim for k in kept]
        assert len(set(ins)) == 1, f"random points disagree on {s}"
        verdict[str(s)] = ins[0]
    return {str(s): verdict[str(s)] for s in x}, {str(s): verdict[str(s)] for s in p}, dim


# --------------------------------------------------------------------------------------
# Tests
# --------------------------------------------------------------------------------------

def _params():
    return [pytest.param(name, marks=marks) for name, marks in MODELS.items()]


@pytest.mark.parametrize("name", _params())
def test_importer_and_analysis_match_the_sympy_oracle(name):
    from uio_jax._io.strikepy_import import load_strikepy

    path = DATA / f"{name}.py"
    obs, ident, dim = hk_oracle(_read_model(path))
    system = load_strikepy(str(path))
    rep = uj.analyze(system, samples=SAMPLES)
    series = uj.analyze(system, samples=SAMPLES, method="series")  # StrikePy's own kind of test
    # auto: the ORC, or the series test on the Taylor route (BIG_known_input: its roots have
    # no common point modulo 2^127 - 1, the symbolic route would not be exact)
    assert rep.method == ("series" if rep.plan.route == "taylor" else "orc") and series.method == "series"
    for r in (rep, series):
        assert {s: bool(r.observable[s]) for s in obs} == obs
        assert {q: bool(r.identifiable[q]) for q in ident} == ident
        assert r.dim == dim


def test_oracle_on_a_hand_checked_model():
    """C2M_2outputs: both states measured, transfer functions give every parameter (rank 6);
    CR: x' = -2 k x^2 gives x(t) = x0 / (1 + 2 k x0 t), so y = s1 x / (1 + s2 x) =
    A / (B + C t) with A = s1 x0, B = 1 + s2 x0, C = 2 k x0: only A / B and C / B are
    identifiable, rank 2 of 4, no single state or parameter."""
    obs, ident, dim = hk_oracle(_read_model(DATA / "C2M_2outputs.py"))
    assert dim == 6 and all(obs.values()) and all(ident.values())
    obs, ident, dim = hk_oracle(_read_model(DATA / "CR.py"))
    assert dim == 2 and obs == {"x1": False} and ident == {"k": False, "s1": False, "s2": False}


def _shipped_dir():
    spec = importlib.util.find_spec("StrikePy")  # locates the package without importing it
    return None if spec is None or spec.origin is None else Path(spec.origin).parent / "models"


@pytest.mark.parametrize("name", list(MODELS))
def test_data_files_match_the_shipped_models(name):
    shipped = _shipped_dir()
    if shipped is None or not (shipped / f"{name}.py").exists():
        pytest.skip("StrikePy is not installed")
    ours, theirs = _read_model(DATA / f"{name}.py"), _read_model(shipped / f"{name}.py")
    for key in ("x", "p", "u", "w", "consts"):
        assert ours[key] == theirs[key], key
    for key in ("f", "h"):
        assert len(ours[key]) == len(theirs[key])
        for a, b in zip(ours[key], theirs[key]):
            assert sp.simplify(a - b) == 0, (key, a, b)
