"""Known initial values: one validation for every way a value arrives (issue 47 items 2-5).

A value arrives as a Python number, a Fraction, a numpy or JAX scalar, a string, a function of
the parameters, or an expression through ``--initial`` and a model file's ``[initial]`` table;
every kind goes through :func:`uio_jax._analysis.initial.initial_value`. Oracle for the
verdicts: the exact sympy Taylor oracle of ``tests/taylor_oracle.py``.
"""

import json
from fractions import Fraction

import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from conftest import ROOT
from taylor_oracle import oracle

import uio_jax as uj
from uio_jax import cli

X1, X2, A, B = sp.symbols("x1 x2 a b")


def model():
    """``x1' = -a x1 + b x2, x2' = -b x2``, ``y = x1``, states sampled in [0.5, 1.5]."""
    return uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([-p[0] * x[0] + p[1] * x[1], -p[1] * x[1]]),
                     params={"a": (0.5, 1.5), "b": (0.5, 1.5)}, domain={"x1": (0.5, 1.5), "x2": (0.5, 1.5)})


TOML = """name = "m"
states = ["x1", "x2"]
[params]
a = [0.5, 1.5]
b = [0.5, 1.5]
[domain]
x1 = [0.5, 1.5]
x2 = [0.5, 1.5]
[outputs]
y = "x1"
[drift]
x1 = "-a*x1 + b*x2"
x2 = "-b*x2"
"""


def _verdicts(rep):
    return {k: v.value for k, v in rep.verdicts.items()}


def _oracle(value, order):
    f = [-A * X1 + B * X2, -B * X2]
    return oracle([{"states": (X1, X2), "f": f, "h": [X1], "initial": {X2: value}}], (A, B), (A, B), order)[1]


@pytest.mark.parametrize("value", [0, 0.0, Fraction(0), "0", " 0 ", np.float64(0.0), np.int32(0), jnp.array(0.0),
                                   jnp.float32(0.0), lambda p: 0.0 * p[0], lambda p: 0 * p[1]])
def test_zero_through_every_kind_is_the_same_exact_zero(value):
    """Every kind of 0 is the exact 0 (a function that folds to a constant is that constant);
    the sampling box [0.5, 1.5] does not bound a known value; the verdicts are the oracle's."""
    rep = uj.analyze(model(), initial={"x2": value})
    assert rep.initial["x2"].endswith("0") and rep.arithmetic.name == "EXACT"
    determined = _oracle(0, rep.order)
    assert {k: v == "determined" for k, v in _verdicts(rep).items()} == determined


def test_values_outside_the_sampling_box_are_answered():
    """A known value is not a generic state: 5 (outside [0.5, 1.5]) and -2 are analysed and
    agree with the oracle."""
    for value in (5, -2.0, "5"):
        rep = uj.analyze(model(), initial={"x2": value})
        v = Fraction(str(value))
        assert {k: w == "determined" for k, w in _verdicts(rep).items()} == _oracle(v, rep.order)


NOT_REAL = ["1/0", "0/0", "log(0)", "sqrt(-1)", "acos(2)", "exp(1000)", "1e308*10", "nan", "inf", "-inf",
            "1e999", "a/0", "sqrt(-a)", "log(-b)"]


@pytest.mark.parametrize("text", NOT_REAL)
def test_values_that_are_not_real_are_refused_on_the_command_line(tmp_path, capsys, text):
    """Through ``--initial`` and through the model file's table: exit 2, one line."""
    path = tmp_path / "m.toml"
    path.write_text(TOML)
    assert cli.main(["analyze", str(path), "--initial", f"x2={text}"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err and "initial value of x2" in err, err
    assert any(w in err for w in ("not a real number", "float64 range")), err
    path.write_text(TOML + f'[initial]\nx2 = "{text}"\n')
    assert cli.main(["analyze", str(path)]) == 2
    err2 = capsys.readouterr().err.strip()
    assert len(err2.splitlines()) == 1 and ("initial value of x2" in err2 or "initial.x2" in err2), err2


@pytest.mark.parametrize("value, words", [
    (float("nan"), "not a real number"), (np.float64("inf"), "not a real number"),
    (jnp.array(jnp.nan), "not a real number"), (1 + 2j, "not a real number"), (np.complex128(1), "not a real number"),
    (jnp.array([1.0, 2.0]), "must be a scalar"), (True, "must be a number"), (None, "must be a number"),
    (lambda p: jnp.nan * p[0], "not a real number at any"), (lambda p: jnp.sqrt(-p[0]), "not a real number at any"),
    (lambda p: 1 / 0, "the function raised ZeroDivisionError"), (lambda p: p[7], "initial value of x2"),
    (Fraction(10**400), "float64 range"),
])
def test_values_that_are_not_real_are_refused_in_python(value, words):
    with pytest.raises(uj.OptionError, match=words) as info:
        uj.analyze(model(), initial={"x2": value})
    assert "\n" not in str(info.value)


def test_a_constant_known_in_float64_only_is_never_decided_exactly(tmp_path, capsys):
    """``sin(pi)`` is not the exact decimal 1.2246e-16: the answer is labelled not exact and a
    note says why; the same text with exact arithmetic (``1/3``, ``3*1``) stays exact."""
    path = tmp_path / "m.toml"
    path.write_text(TOML)
    assert cli.main(["analyze", str(path), "--initial", "x2=sin(pi)", "--json", str(tmp_path / "o.json")]) == 0
    out = capsys.readouterr().out
    d = json.loads((tmp_path / "o.json").read_text())
    assert "not exact" in out and "known in float64 only" in out and d["certificate"]["arithmetic"] != "exact"
    for text, exact in (("1/3", Fraction(1, 3)), ("3*1", Fraction(3)), ("2*pi/pi", None)):
        assert cli.main(["analyze", str(path), "--initial", f"x2={text}", "--json", str(tmp_path / "o.json")]) == 0
        out = capsys.readouterr().out
        d = json.loads((tmp_path / "o.json").read_text())
        if exact is not None:
            assert d["certificate"]["arithmetic"] == "exact", (text, out)
            determined = _oracle(exact, d["order"])
            assert {k: v == "determined" for k, v in {**d["observable"], **d["identifiable"]}.items()} == determined


def test_a_tiny_value_is_not_printed_as_zero(tmp_path, capsys):
    """``1e-400`` is an exact nonzero value: it prints as 1e-400, with the verdict of a
    nonzero value (the oracle's), never as 0."""
    rep = uj.analyze(model(), initial={"x2": Fraction(1, 10**400)})
    assert rep.initial["x2"] == "1e-400" and "x2 = 1e-400" in str(rep)
    assert {k: v == "determined" for k, v in _verdicts(rep).items()} == _oracle(Fraction(1, 10**400), rep.order)
    path = tmp_path / "m.toml"
    path.write_text(TOML)
    assert cli.main(["analyze", str(path), "--initial", "x2=1e-400"]) == 0
    out = capsys.readouterr().out
    assert "x2 = 1e-400" in out and "x2 = 0\n" not in out


@pytest.mark.parametrize("output", [lambda x, p: 1 / x[0], lambda x, p: jnp.log(x[0]), lambda x, p: jnp.sqrt(x[0]),
                                    lambda x, p: p[0] / (x[0] * x[0])])
def test_an_output_undefined_at_the_known_initial_state_is_refused(output):
    system = uj.System(states=("x",), outputs={"y": output}, drift=lambda x, p: jnp.stack([1.0 - p[0] * x[0]]),
                       params={"a": (0.5, 1.5)}, domain={"x": (0.5, 1.5)})
    with pytest.raises(uj.ModelError, match="not defined at the initial state") as info:
        uj.analyze(system, initial={"x": 0.0})
    assert "\n" not in str(info.value)


def test_the_readme_two_compartment_example_with_x2_zero(capsys):
    """``uio-jax analyze systems/two_compartment.toml --initial x2=0``: x2 = 0 lies outside the
    sampling box [0.5, 1.5] of the generic states, and is answered."""
    assert cli.main(["analyze", f"{ROOT}/systems/two_compartment.toml", "--initial", "x2=0"]) == 0
    out = capsys.readouterr().out
    assert "known initial state: x2 = 0" in out and "exact" in out


def test_an_sbml_species_may_start_at_zero(tmp_path):
    """SBML models declare no domain: a species known to start at 0 is analysed."""
    pytest.importorskip("libsbml")
    from test_sbml import Builder

    path = (Builder().compartment("c", 1).species("S", "c").species("P", "c").parameter("k", 0.3)
            .parameter("v", 0.5).reaction("feed", {}, {"S": 1}, "v").reaction("conv", {"S": 1}, {"P": 1}, "k*S")
            .write(tmp_path / "m.xml"))
    system = uj.load_system(path, outputs={"y": "P"})
    rep = uj.analyze(system, initial={"S": 0, "P": 0})
    assert dict(rep.identifiable) == {"k": uj.Verdict.DETERMINED, "v": uj.Verdict.DETERMINED}
    S, P, k, v = sp.symbols("S P k v")
    assert all(oracle([{"states": (S, P), "f": [v - k * S, k * S], "h": [P], "initial": {S: 0, P: 0}}],
                      (k, v), (k, v), rep.order)[1].values())
