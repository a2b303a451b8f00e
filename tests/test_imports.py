"""Imports: System.from_sympy and StrikePy model modules (read with ast, never executed)."""

import functools
import glob
import importlib.util
import os
import sys

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import SAMPLES, zoo_path, zoo_report

import uio_jax as uj
from uio_jax._io.strikepy_import import generic_value, is_strikepy_module, load_strikepy, read_strikepy

sp = pytest.importorskip("sympy")

_spec = importlib.util.find_spec("StrikePy")
MODELS_DIR = os.path.join(os.path.dirname(_spec.origin), "models") if _spec and _spec.origin else None
#: StrikePy 1.0's shipped models (files named uj_* were written by our benchmark: ignored).
SHIPPED = sorted(
    os.path.basename(p)[:-3]
    for p in glob.glob(os.path.join(MODELS_DIR or "/nonexistent", "*.py"))
    if not os.path.basename(p).startswith(("uj_", "__"))
)
needs_strikepy = pytest.mark.skipif(not SHIPPED, reason="StrikePy is not installed")


def summary(rep):
    return (rep.method, rep.n, rep.dim, rep.dims, dict(rep.observable), dict(rep.identifiable), rep.params)


def model_path(name):
    return os.path.join(MODELS_DIR, f"{name}.py")


# ----------------------------------------------------------------------------- from_sympy
def test_from_sympy_affine_form_gives_the_zoo_report():
    r, phi, th = sp.symbols("r phi theta")
    sys_ = uj.System.from_sympy([r, phi, th], {"r": r}, known={"omega": [0, 0, 1]},
                                unknown={"v": [sp.cos(th - phi), sp.sin(th - phi) / r, 0]},
                                domain={r: (0.5, 2.0)}, angles=[phi, th], name="sympy unicycle")
    assert sys_.name == "sympy unicycle" and sys_.drift is None
    rep = uj.analyze(sys_, samples=SAMPLES, seed=0)
    assert summary(rep) == summary(zoo_report("unicycle_polar", "range_v_unknown"))


def test_from_sympy_general_form_gives_the_zoo_report():
    x1, x2, w = sp.symbols("x1 x2 w")
    sys_ = uj.System.from_sympy([x1, x2], {"y": x1}, dynamics=[x2 + w, 0], unknown=[w])
    assert sys_.drift is not None and set(sys_.unknown) == {"w"}
    rep = uj.analyze(sys_, samples=SAMPLES, seed=0)
    assert summary(rep) == summary(zoo_report("counterexamples", "drift_example"))


def test_from_sympy_with_params_matches_the_model_file(tmp_path):
    x1, x2, u, k01, k12, k21 = sp.symbols("x1 x2 u k01 k12 k21")
    s = uj.System.from_sympy([x1, x2], [x1], dynamics=sp.Matrix([-(k01 + k21) * x1 + k12 * x2 + u,
                                                                 k21 * x1 - k12 * x2]),
                             known=[u], params=[k01, k12, k21], name="two_compartment")
    f = uj.load_system(os.path.join(os.path.dirname(zoo_path("gps")), "two_compartment.toml"))
    assert tuple(s.params) == tuple(f.params) and set(s.outputs) == {"x1"}
    rng = np.random.default_rng(0)
    for _ in range(5):
        x, p = jnp.asarray(rng.random(2) + 0.5), jnp.asarray(rng.random(3) + 0.5)
        np.testing.assert_allclose(s.drift(x, p), f.drift(x, p), rtol=1e-14)
        np.testing.assert_allclose(s.known["u"](x, p), f.known["u"](x, p), rtol=1e-14)
    path = str(tmp_path / "s.toml")
    uj.save_model(s, path)
    assert uj.load_system(path).source == s.source


def test_from_sympy_errors(monkeypatch):
    x, y = sp.symbols("x y")
    with pytest.raises(uj.ModelError, match="is complex"):
        uj.System.from_sympy([x], [x], drift=[sp.I * x])
    with pytest.raises(uj.ExpressionError, match="function 'Piecewise' is not allowed"):
        uj.System.from_sympy([x], [x], drift=[sp.Piecewise((x, x > 0), (0, True))])
    with pytest.raises(uj.ModelError, match=r"symbol name 'x_\{1\}'"):
        uj.System.from_sympy([sp.Symbol("x_{1}")], [x])
    with pytest.raises(uj.ModelError, match="drift has 2 entries for 1 states"):
        uj.System.from_sympy([x], [x], drift=[x, x])
    with pytest.raises(uj.ExpressionError, match="name 'y' is not allowed"):
        uj.System.from_sympy([x], [x], drift=[y])
    with pytest.raises(uj.ModelError, match="either dynamics="):
        uj.System.from_sympy([x], [x], drift=[x], dynamics=[x])
    monkeypatch.setitem(sys.modules, "sympy", None)
    with pytest.raises(uj.ModelError, match="pip install sympy"):
        uj.System.from_sympy([x], [x])


# ----------------------------------------------------------------------------- StrikePy
@functools.cache
def _imported(name):
    """The shipped module executed by Python (trusted package code): the oracle."""
    spec = importlib.util.spec_from_file_location(f"strikepy_oracle_{name}", model_path(name))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _flat(v):
    out = []
    for e in (v if isinstance(v, (list, tuple)) else [v]):
        out.extend(_flat(e) if isinstance(e, (list, tuple)) else [e])
    return out


@needs_strikepy
def test_every_shipped_model_is_listed():
    assert len(SHIPPED) >= 23 and "p53" in SHIPPED and "TS_unknown_inputs_reparameterized" in SHIPPED


@needs_strikepy
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_model_loads_and_matches_sympy(name):
    """Every shipped model loads; drift + fields reproduce StrikePy's f at random points."""
    path = model_path(name)
    assert is_strikepy_module(path)
    system = uj.load_system(path)
    spec = system.source
    mod = _imported(name)
    names = lambda lst: list(dict.fromkeys(s.name for s in _flat(lst)))  # noqa: E731
    xs, ps = names(mod.x), names(getattr(mod, "p", []))
    us, ws = names(getattr(mod, "u", [])), names(getattr(mod, "w", []))
    assert list(spec.states) == xs and list(spec.params) == ps
    assert list(spec.inputs_known) == us and list(spec.inputs_unknown) == ws
    promoted = system.states[len(xs):]
    # StrikePy's f through sympy, with our values of the known constants
    syms = {s.name: s for e in _flat(mod.f) for s in sp.sympify(e).free_symbols}
    f_exprs = [sp.sympify(e).subs({syms[c]: v for c, v in spec.constants.items() if c in syms}) for e in _flat(mod.f)]
    args = [sp.Symbol(n) for n in xs + ps + us + ws]
    f_num = sp.lambdify(args, f_exprs, "numpy")
    rng = np.random.default_rng(1)
    rest = [v for v in us + ws if v not in promoted and (v in system.known or v in system.unknown)]
    for v in set(us + ws) - set(rest) - set(promoted):  # in no equation: dropped, with a note
        assert any(f"{v!r} appears in no equation: dropped" in n for n in system.notes)
    for _ in range(3):
        vals = {n: 0.5 + rng.random() for n in xs + ps + us + ws}
        want = np.array(f_num(*(vals[n] for n in xs + ps + us + ws)), dtype=float).ravel()
        z = jnp.asarray([vals[n] for n in system.states])
        p = [jnp.asarray([vals[n] for n in ps])] if ps else []
        got = np.zeros(len(system.states))
        if system.drift is not None:
            got += np.asarray(system.drift(z, *p))
        for v in rest:
            fld = system.known.get(v) or system.unknown.get(v)
            got += vals[v] * np.asarray(fld(z, *p))
        np.testing.assert_allclose(got[: len(xs)], want, rtol=1e-10, atol=1e-12)
    if spec.constants:
        assert any("StrikePy known constants" in n for n in system.notes)


@needs_strikepy
def test_non_affine_inputs_of_p53_and_ts_are_promoted():
    p53 = load_strikepy(model_path("p53"))
    assert p53.states[-1] == "u1" and set(p53.known) == {"d_u1"} and "u1" in p53.outputs
    assert any("known input 'u1' enters the dynamics non-affinely" in n for n in p53.notes)
    ts = load_strikepy(model_path("TS_unknown_inputs_reparameterized"))
    assert ts.states[-2:] == ("w1", "w2") and set(ts.unknown) == {"d_w1", "d_w2"} and not ts.known
    assert sum("promoted to a state" in n for n in ts.notes) == 2


@needs_strikepy
def test_known_constants_and_aliases():
    spec = read_strikepy(model_path("1A_integral"))
    assert dict(spec.constants) == {"u0": generic_value("u0"), "x10": generic_value("x10")}
    assert generic_value("u0") == generic_value("u0") and 0.5 <= generic_value("x10") < 1.5
    assert len({generic_value(n) for n in ("a", "b", "d", "u0", "x10", "x6")}) == 6
    tumor = read_strikepy(model_path("tumor"))
    assert set(tumor.constants) == {"a", "b", "d"}
    mapk = read_strikepy(model_path("MAPK"))  # KK1, KK2 = sym.symbols('n1 n2'): the same symbols as n1, n2
    assert list(mapk.params).count("n1") == 1 and any("twice" in n for n in mapk.notes)
    big = read_strikepy(model_path("1D_BIG"))  # numeric constants and auxiliary expressions are inlined
    assert "0.021/(24*60)" in big.dynamics["x2"] and "p5" in big.dynamics["x3"]


@needs_strikepy
@pytest.mark.parametrize("name", ["1A_integral", "p53", "TS_unknown_inputs_reparameterized"])
def test_strikepy_model_converts_to_toml(tmp_path, name):
    system = load_strikepy(model_path(name))
    path = str(tmp_path / f"{name}.toml")
    uj.save_model(system, path)
    back = uj.load_system(path)
    assert back.source == system.source
    assert back.states == system.states and back.notes == system.notes


@pytest.mark.slow  # 9-12 s; CR and C2M are also in the default sympy-oracle tests
@needs_strikepy
def test_cr_scaling_symmetry_and_c2m_identifiability():
    """CR: x' = -2 k x^2 gives y = s1 x/(1 + s2 x) = s1 x0 / (1 + s2 x0 + 2 k x0 t): only the
    ratios (s1 x0)/(1 + s2 x0) and (2 k x0)/(1 + s2 x0) are seen (rank 2 of 4), nothing is
    identifiable or observable. C2M (y = x1, input gain b unknown): the transfer function
    b (s + k21) / (s^2 + (k1e + k12 + k21) s + k1e k21) gives all four parameters."""
    cr = uj.analyze(load_strikepy(model_path("CR")), samples=256)
    assert cr.dim == 2 and not any(cr.observable.values()) and not any(cr.identifiable.values())
    c2m = uj.analyze(load_strikepy(model_path("C2M")), samples=256)
    assert c2m.fully_observable and all(c2m.identifiable.values()) and len(c2m.identifiable) == 4


#: Arabidopsis (7 states + 28 parameters, 2 outputs): our ORC did not finish within 20 min at
#: 256 samples on the 2-core machine (nested Lie words of depth ~9 along the known input), so it
#: is left out of this analysis test; it is still loaded and checked against sympy's f by
#: ``test_shipped_model_loads_and_matches_sympy``. Open performance limit (BENCHMARKS.md).
TOO_BIG_TO_ANALYZE = {"Arabidopsis"}


@needs_strikepy
@pytest.mark.slow
@pytest.mark.parametrize("name", [m for m in SHIPPED if m not in TOO_BIG_TO_ANALYZE])
def test_shipped_model_analyzes(name):
    rep = uj.analyze(load_strikepy(model_path(name)), samples=256)
    assert rep.dim >= 1 and rep.certificate.used > 0


# ----------------------------------------------------------------------------- StrikePy errors
GOOD = """import sympy as sym
x1, x2 = sym.symbols('x1 x2')
k = sym.Symbol('k')
x = [[x1], [x2]]
p = [k]
h = [x1]
f = [[-k*x1 + x2], [sym.exp(-x1) - x2]]
variables_locales = locals().copy()
"""


def _write(tmp_path, text):
    path = tmp_path / "model.py"
    path.write_text(text)
    return str(path)


def test_a_minimal_module_loads(tmp_path):
    system = uj.load_system(_write(tmp_path, GOOD))
    assert system.states == ("x1", "x2") and tuple(system.params) == ("k",)
    x, p = np.array([0.7, 1.2]), np.array([0.9])
    np.testing.assert_allclose(system.drift(x, p), [-0.9 * 0.7 + 1.2, np.exp(-0.7) - 1.2])


@pytest.mark.parametrize(
    "change, fragment",
    [
        (("x = [[x1], [x2]]", "x = [[x1], [x2]"), "line 4: Python syntax error"),
        (("h = [x1]", "h = [x1]\nimport os\nos.system('true')"), "line 8: statement Expr is not supported"),
        (("h = [x1]", "h = [x1]\ndef g():\n    pass"), "line 7: statement FunctionDef is not supported"),
        (("h = [x1]", "h = [x1]\nfor i in x:\n    pass"), "line 7: statement For is not supported"),
        (("h = [x1]", "h = [__import__('os').system('true')]"),
         "line 6: call of '__import__('os').system' is not allowed"),
        (("h = [x1]", "h = [x1.__class__]"), "line 6: attribute access '.__class__' is not allowed"),
        (("h = [x1]", "h = [os.getcwd()]"), "call of 'os.getcwd' is not allowed"),
        (("h = [x1]", "h = [sym.Piecewise(x1)]"), "function 'Piecewise' is not allowed"),
        (("h = [x1]", "h = [x3]"), "line 6: name 'x3' is not defined"),
        (("h = [x1]", "h = [x1 ^ 2]"), "use '**'"),
        (("h = [x1]", "h = ['x1']"), "string constant"),
        (("f = [[-k*x1 + x2], [sym.exp(-x1) - x2]]", "f = [-k*x1]"), "f has 1 entries for 2 states"),
        (("h = [x1]\n", ""), "missing h"),
        (("p = [k]", "p = [k*2]"), "p must list symbols"),
        (("x1, x2 = sym.symbols('x1 x2')", "x1, x2 = sym.symbols('x1 x2 x3')"), "2 names but 3 values"),
    ],
)
def test_broken_strikepy_modules(tmp_path, change, fragment):
    old, new = change
    assert old in GOOD
    text = GOOD.replace(old, new)
    path = _write(tmp_path, text)
    with pytest.raises(uj.UioJaxError) as info:
        load_strikepy(path)
    msg = str(info.value)
    assert "\n" not in msg and path in msg and fragment in msg


def test_inlining_cannot_blow_up(tmp_path):
    text = GOOD.replace("h = [x1]", "a = x1*x1\n" + "a = a*a\n" * 60 + "h = [a]")
    with pytest.raises(uj.LoadError, match=r"line \d+: too large"):
        load_strikepy(_write(tmp_path, text))
    text = GOOD.replace("h = [x1]", "a = x1\n" + "a = a + x1\n" * 500 + "h = [a]")
    with pytest.raises(uj.LoadError, match="nested too deeply"):
        load_strikepy(_write(tmp_path, text))


def test_load_system_dispatch(tmp_path):
    assert not is_strikepy_module(zoo_path("gps"))
    assert not is_strikepy_module(str(tmp_path / "none.py"))
    with pytest.raises(uj.LoadError, match="not a StrikePy model module.*FILE.py:NAME"):
        uj.load_system(zoo_path("gps"))
    assert uj.load_system(f"{zoo_path('gps')}:inputs_known").states == ("xv", "yv", "theta")
