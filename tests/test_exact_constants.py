"""Constants in a model are exact rationals, and constants derived from them stay exact.

A literal means its decimal value (``1.3`` is ``13/10``); a quotient of two constants folded by
the expression graph (the derivative of ``x1 / 7`` is ``1/7``) is ``Fraction(1, 7)``, not the
float64 nearest to it. Before, the general solution rescaled a field by a constant folded in
float64 and read back as a dyadic rational: the cancellation ``L_{g^0} y = 0`` failed modulo p
and a spurious direction was "verified" exactly (``x1/7`` gave dim 2 where the truth is 1).

The truth of each case: derived by hand in its docstring, or the independent exact sympy
oracle (``scripts/general_ui_oracle.py``: rational arithmetic, constants as sympy Rationals).
"""

import random
from fractions import Fraction

import jax.numpy as jnp
import pytest
import sympy as sp
from helpers import script_module

import uio_jax as uj
from uio_jax._engine.graph import Graph, exact_literal

# ------------------------------------------------------------------ the graph's constants


def test_a_literal_is_its_decimal_and_folds_are_exact():
    g = Graph(1)
    assert exact_literal(1.3) == Fraction(13, 10)
    assert exact_literal(0.1 + 0.2) == Fraction("0.30000000000000004")
    seven = g.const(7.0)
    assert g.exact_value(g.div(g.one, seven)) == Fraction(1, 7)
    assert g.exact_value(g.mul(g.const(1.7), g.const(0.15))) == Fraction(255, 1000)
    assert g.exact_value(g.ipow(g.const(1.3), -2)) == Fraction(100, 169)
    # x / 7 differentiated: the slope is the exact 1/7, and x * (1/7) written in Python is
    # the decimal 0.14285714285714285, another constant
    slope = g.jvp([g.div(g.x(0), seven)], [g.one])[0]
    assert g.exact_value(slope) == Fraction(1, 7)
    assert g.const(1 / 7) != slope


def test_a_non_rational_fold_is_known_in_float64_only():
    """``sin(0.3)`` folded is a float64 constant: no exact decision may use it."""
    g = Graph(1)
    s = g.unary("sin", g.const(0.3))
    assert g.exact_value(s) is None and g.value_of(s) == pytest.approx(0.29552020666133955)
    assert not g.is_rational([g.mul(s, g.x(0))])
    assert g.is_rational([g.mul(g.const(0.3), g.x(0))])


# ------------------------------------------------------------------ the cases


def _one_ui(output, g1=1.0, g2=0.0, drift=None):
    drift = drift or (lambda x: jnp.stack([x[1], 0 * x[0]]))
    return uj.System(states=("x1", "x2"), outputs={"y": output}, drift=drift,
                     unknown={"w": lambda x: jnp.array([g1, g2]) + 0 * x[0]})


@pytest.mark.parametrize("output", [lambda x: x[0] / 7, lambda x: x[0] * (1 / 7), lambda x: x[0] / 1.3,
                                    lambda x: 0.15 * x[0], lambda x: x[0] / 3 / 1.7],
                         ids=["div7", "times_one_seventh", "div1.3", "times0.15", "two_divisions"])
def test_a_constant_in_the_output_does_not_reveal_a_hidden_state(output):
    """``x1' = x2 + w, x2' = 0, y = c x1``: ``w`` hides ``x2`` for every constant ``c != 0``:
    ``Omega = span{dx1}`` (dim 1)."""
    rep = uj.analyze(_one_ui(output), method="general_ui")
    assert (rep.dim, rep.observable) == (1, {"x1": True, "x2": False})


C_H = [1.0, 2.0, 0.5, 7.0, 1.3, 0.15, 3.0, 0.1, 1 / 3, 2.7, 10.0]
C_G = [1.0, 1.7, 0.3, 7.0, 1 / 7, 0.25, 5.0]


@pytest.mark.parametrize("c_h", C_H)
def test_the_constant_sweep(c_h):
    """``x1' = 0, x2' = x1 + c_g w, y = c_h x2`` over 77 pairs: ``w`` hides ``x1`` (dim 1, x2
    observable) whatever the constants (37 of the 77 pairs were wrong, "exact")."""
    for c_g in C_G:
        system = uj.System(states=("x1", "x2"), outputs={"y": lambda x: c_h * x[1]},
                           drift=lambda x: jnp.stack([0 * x[0], x[0]]),
                           unknown={"w": lambda x: jnp.stack([0 * x[0], c_g + 0 * x[0]])})
        rep = uj.analyze(system)
        assert (rep.dim, rep.observable) == (1, {"x1": False, "x2": True}), (c_h, c_g, rep.method)


# ------------------------------------------------------------------ against the exact oracle

DECIMALS = ("1.3", "0.15", "2.5", "0.7", "1.7", "3", "-1.1", "0.2", "1/7", "2/3")
FUNCTIONS = ("sin({})", "cos({})", "exp({}/4)", "sqrt(1 + ({})**2)", "atan({})", "log(1 + ({})**2)",
             "tanh({})", "cosh({}/2)", "atan2({}, 2)")


def _random_model(seed: int, functions: bool):
    """A random system with decimal constants in every role: 3 states (the last one a
    parameter, zero dynamics, in half of the systems), a sparse drift, one or two unknown
    inputs, one or two outputs. Expressions are strings read by sympy (``rational=True``: the
    decimals exact) and by JAX (the same text, evaluated on the state)."""
    rng = random.Random(seed)
    n, param = 3, rng.random() < 0.5
    names = [f"x{i + 1}" for i in range(n)]

    def monomial(degree):
        return "*".join(rng.choice(names) for _ in range(degree)) or "1"

    def term(degree_choices, p_function=0.0):
        body = f"{rng.choice(DECIMALS)}*{monomial(rng.choice(degree_choices))}"
        if functions and rng.random() < p_function:
            body = f"{rng.choice(DECIMALS)}*" + rng.choice(FUNCTIONS).format(monomial(1))
        return f"({body})"

    def component(p_zero, degrees, p_function=0.3):
        return "0" if rng.random() < p_zero else " + ".join(term(degrees, p_function)
                                                          for _ in range(rng.choice((1, 2))))

    drift = [component(0.35, (0, 1, 2)) for _ in range(n)]
    if param:
        drift[-1] = "0"
    unknown = {}
    for j in range(rng.choice((1, 2))):
        field = ["0"] * n
        for i in rng.sample(range(n - param), rng.choice((1, 2))):
            field[i] = component(0.0, (0, 1), 0.15)
        unknown[f"w{j + 1}"] = field
    outputs = [component(0.0, (1,), 0.2) if k else f"{rng.choice(DECIMALS)}*x1/{rng.choice((3, 7, 1.3))}"
               for k in range(rng.choice((1, 2)))]
    return names, drift, unknown, outputs


_JAX = {"sin": jnp.sin, "cos": jnp.cos, "exp": jnp.exp, "sqrt": jnp.sqrt, "atan": jnp.arctan, "log": jnp.log,
        "tanh": jnp.tanh, "asin": jnp.arcsin, "cosh": jnp.cosh, "atan2": jnp.arctan2}


def _jax_function(names, texts):
    code = [compile(t, "<model>", "eval") for t in texts]

    def fn(x):
        env = dict(_JAX, **{name: x[i] for i, name in enumerate(names)})
        values = [eval(c, {"__builtins__": {}}, env) for c in code]  # noqa: S307 (test's own text)
        return jnp.stack([v + 0 * x[0] for v in values]) if len(values) > 1 else values[0] + 0 * x[0]

    return fn


def _check_against_oracle(seed, functions):
    names, drift, unknown, outputs = _random_model(seed, functions)
    symbols = sp.symbols(names, real=True)
    local = dict(zip(names, symbols))

    def sym(text):
        return sp.sympify(text, rational=True, locals=local)

    oracle = script_module("general_ui_oracle")
    exact = oracle.general_ui(list(symbols), [sym(e) for e in drift], {},
                              {k: [sym(e) for e in v] for k, v in unknown.items()}, [sym(e) for e in outputs])
    system = uj.System(states=tuple(names), outputs={f"y{k}": _jax_function(names, [t])
                                                     for k, t in enumerate(outputs)},
                       drift=_jax_function(names, drift),
                       unknown={k: _jax_function(names, v) for k, v in unknown.items()})
    rep = uj.analyze(system, method="general_ui")
    got = (rep.dim, {s for s, ok in rep.observable.items() if ok})
    want = (exact["dim"], {names[i] for i in exact["observable"]})
    assert got == want, (seed, drift, unknown, outputs)


@pytest.mark.parametrize("seed", range(12))
def test_random_rational_systems_with_decimal_constants_equal_the_exact_oracle(seed):
    _check_against_oracle(seed, functions=False)


@pytest.mark.parametrize("seed", range(8))
def test_random_systems_with_elementary_functions_equal_the_oracle(seed):
    _check_against_oracle(100 + seed, functions=True)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(12, 60))
def test_more_random_systems_equal_the_oracle(seed):
    _check_against_oracle(seed, functions=seed % 3 == 0)
