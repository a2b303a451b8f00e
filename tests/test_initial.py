"""Known initial conditions: identifiability at the given initial state (issue 39, item 1).

Every verdict is checked against a hand derivation and the independent sympy oracle
(``tests/taylor_oracle.py``: the Jacobian of the Taylor coefficients in exact rationals).

**The two-compartment model** ``x1' = -(k1 + k12) x1 + k21 x2``, ``x2' = k12 x1 - k21 x2``,
``y = x1``. The output solves ``y'' + a1 y' + a0 y = 0`` with ``a1 = k1 + k12 + k21`` and
``a0 = k1 k21``, so the output determines ``y(0) = x1(0)``, ``y'(0) = -(k1 + k12) x1(0) + k21
x2(0)``, ``a1`` and ``a0``: four functions of five unknowns. With ``x2(0)`` unknown it absorbs
``y'(0)``, and ``k1, k12, k21`` satisfy two equations only: none is identifiable, ``x2(0)``
neither (rank 4 of 5, the series closes at order 4). With ``x2(0) = 0`` known: ``y'(0) / y(0) =
-(k1 + k12) =: -s``, then ``k21 = a1 - s``, ``k1 = a0 / k21``, ``k12 = s - k1``: every
parameter is identifiable (rank 4 of 4 at order 3).
"""

import json
import random

import jax.numpy as jnp
import pytest
import sympy as sp
from taylor_oracle import oracle

import uio_jax as uj
from uio_jax import cli

X1, X2, K1, K12, K21 = sp.symbols("x1 x2 k1 k12 k21")
D, N, V = uj.Verdict.DETERMINED, uj.Verdict.NOT_DETERMINED, uj.Verdict.UNDECIDED


def two_compartment():
    return uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0] + p[2] * x[1], p[1] * x[0] - p[2] * x[1]]),
                     params=("k1", "k12", "k21"), domain={"x1": (0.0, 2.0), "x2": (0.0, 2.0)},
                     name="two_compartment")


def two_compartment_oracle(initial, order):
    f = [-(K1 + K12) * X1 + K21 * X2, K12 * X1 - K21 * X2]
    return oracle([{"states": (X1, X2), "f": f, "h": [X1], "initial": initial}], (K1, K12, K21), (K1, K12, K21),
                  order)


def test_x2_zero_makes_every_parameter_identifiable():
    rep = uj.analyze(two_compartment(), initial={"x2": 0.0})
    assert isinstance(rep, uj.IdentifiabilityReport)
    assert dict(rep.identifiable) == {"k1": D, "k12": D, "k21": D} and dict(rep.observable) == {"x1": D}
    assert rep.exact and rep.order == 3 and rep.ranks == (1, 2, 3, 4)
    rank, determined = two_compartment_oracle({X2: 0}, rep.order)
    assert rank == 4 and all(determined.values())
    # the order before: not yet (the oracle agrees that order 3 is needed)
    assert not all(two_compartment_oracle({X2: 0}, 2)[1].values())


def test_generic_initial_state_proves_the_parameters_not_identifiable():
    rep = uj.analyze(two_compartment(), initial={})
    assert dict(rep.identifiable) == {"k1": N, "k12": N, "k21": N}
    assert dict(rep.observable) == {"x1": D, "x2": N}
    assert rep.stop.name == "SPAN_CLOSED"
    rank, determined = two_compartment_oracle({}, rep.order + 3)  # later orders add nothing
    assert rank == 4 and determined == {"x1": True, "x2": False, "k1": False, "k12": False, "k21": False}


def test_the_report_names_the_question_and_the_verdict_change():
    generic = uj.analyze(two_compartment())  # the codistribution at generic states
    known = uj.analyze(two_compartment(), initial={"x2": 0})
    assert generic.question is uj.Question.GENERIC_STATES and not generic.identifiable["k1"]
    assert known.question is uj.Question.KNOWN_INITIAL_STATE and known.identifiable["k1"] is D
    assert "question: known_initial_state" in str(known) and "question: generic_states" in str(generic)
    d = json.loads(known.to_json())
    assert d["question"] == "known_initial_state" and d["identifiable"]["k1"] == "determined"
    assert d["initial"] == {"x2": "0"} and generic.to_dict()["question"] == "generic_states"


@pytest.mark.parametrize("value", ["k1", lambda p: p[0] / 2])
def test_initial_values_in_the_parameters(value):
    rep = uj.analyze(two_compartment(), initial={"x2": value})
    expr = K1 if isinstance(value, str) else K1 / 2
    _, determined = two_compartment_oracle({X2: expr}, rep.order)
    assert {k: v is D for k, v in rep.verdicts.items()} == determined


def test_a_specific_state_where_an_order_adds_nothing_is_proved_by_a_symmetry():
    """``x1' = a x2, x2' = b``, ``y = x1`` from ``x1 = x2 = 0``: ``y = a b t^2 / 2`` exactly, so
    only ``a b`` is determined; ``y_1 = 0`` adds nothing and ``y_2`` does, so no closure is
    claimed. The scaling ``(x2, a, b) -> (l x2, a / l, l b)`` keeps ``x2 = 0`` and the output:
    found and verified, it proves ``a`` and ``b`` not determined (issue 47 item 6); the oracle
    agrees that no order up to 5 determines them."""
    sys_ = uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([p[0] * x[1], p[1] + 0.0 * x[0]]), params=("a", "b"),
                     domain={"x1": (-1, 1), "x2": (-1, 1)})
    rep = uj.analyze(sys_, initial={"x1": 0, "x2": 0}, max_order=5)
    assert dict(rep.identifiable) == {"a": N, "b": N} and rep.order == 5 and rep.ranks == (0, 0, 1, 1, 1, 1)
    assert rep.exact and rep.undecided == () and any("moved by the verified symmetry" in n for n in rep.notes)
    a, b, x1, x2 = sp.symbols("a b x1 x2")
    rank, determined = oracle([{"states": (x1, x2), "f": [a * x2, b], "h": [x1], "initial": {x1: 0, x2: 0}}],
                              (a, b), (a, b), 5)
    assert rank == 1 and not any(determined.values())


def test_undecided_says_what_was_tried():
    """Capped before the order that determines them (two-compartment, x2 = 0, order 1): the
    rates are identifiable in truth, so no symmetry exists; they stay undecided and the note
    says that the symmetry search found nothing."""
    rep = uj.analyze(two_compartment(), initial={"x2": 0}, max_order=1)
    assert rep.undecided and not rep.exact
    note = next(n for n in rep.notes if n.startswith("undecided"))
    assert "a search for symmetries keeping the known initial values" in note and "found none" in note


def test_known_input_and_unknown_input():
    """``x' = -k x + u``, ``y = x``, ``x(0) = 0``: ``y_1 = u0``, ``y_2 = (-k u0 + u1) / 2``: ``k``
    is determined by a generic known input. With the input unknown, its jets are free unknowns:
    ``k`` is not determined at any order (each order brings a new jet), reported undecided under
    the sufficient-only question."""
    known = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]}, drift=lambda x, p: -p[0] * x,
                      known={"u": lambda x, p: jnp.ones(1)}, params=("k",), domain={"x": (-1, 1)})
    rep = uj.analyze(known, initial={"x": 0})
    assert rep.identifiable["k"] is D and rep.question is uj.Question.KNOWN_INITIAL_STATE and rep.exact
    x, k, u0, u1, u2 = sp.symbols("x k u0 u1 u2")
    _, determined = oracle([{"states": (x,), "f": [-k * x], "h": [x], "initial": {x: 0},
                             "inputs": {"u": ([1], (u0, u1, u2))}}], (k,), (k,), 2)
    assert determined == {"k": True}
    unknown = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]}, drift=lambda x, p: -p[0] * x,
                        unknown={"w": lambda x, p: jnp.ones(1)}, params=("k",), domain={"x": (-1, 1)})
    rep = uj.analyze(unknown, initial={"x": 0}, max_order=4)
    assert rep.question is uj.Question.KNOWN_INITIAL_STATE_FREE_INPUT_JETS and rep.question.sufficient_only
    assert rep.identifiable["k"] is V and not rep.exact and rep.answer_kind().startswith("sufficient only")


@pytest.mark.parametrize("initial, message", [
    ({"x9": 0.0}, "'x9' is not a state"),
    ({"k1": 0.0}, "'k1' is a parameter, not a state"),
    ({"x2": float("nan")}, "is nan: not a real number"),
    ({"x2": "q7"}, "'q7' is neither a number nor a parameter"),
    ({"x2": True}, "must be a number"),
    ([("x2", 0)], "must be a mapping"),
])
def test_bad_initial_values(initial, message):
    with pytest.raises(uj.OptionError, match=message.replace("[", r"\[").replace("]", r"\]")):
        uj.analyze(two_compartment(), initial=initial)


def test_model_undefined_at_the_initial_state_and_bad_options():
    sys_ = uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([p[0] / x[1], 0.0 * x[0]]), params=("a",),
                     domain={"x1": (0, 2), "x2": (0, 2)})
    with pytest.raises(uj.ModelError, match="not defined at the initial state"):
        uj.analyze(sys_, initial={"x2": 0})
    with pytest.raises(uj.OptionError, match="does not apply with initial="):
        uj.analyze(two_compartment(), initial={"x2": 0}, method="orc")
    with pytest.raises(uj.OptionError, match="shared= applies to several experiments"):
        uj.analyze(two_compartment(), initial={"x2": 0}, shared=("k1",))
    no_params = uj.System(states=("x",), outputs={"y": lambda x: x[0]}, drift=lambda x: -x)
    with pytest.raises(uj.OptionError, match="the System has none"):
        uj.analyze(no_params, initial={"x": lambda p: p[0]})


MODEL = """name = "two_compartment"
states = ["x1", "x2"]
params = ["k1", "k12", "k21"]
[domain]
x1 = [0, 2]
x2 = [0, 2]
[outputs]
y = "x1"
[drift]
x1 = "-(k1 + k12)*x1 + k21*x2"
x2 = "k12*x1 - k21*x2"
"""


def test_cli_initial_and_the_model_file_table(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text(MODEL)
    assert cli.main(["analyze", str(path), "--initial", "x2=k1/2", "--json", str(tmp_path / "o.json")]) == 0
    out = capsys.readouterr().out
    assert "question: known_initial_state" in out and "x2 = k1/2" in out
    d = json.loads((tmp_path / "o.json").read_text())
    _, determined = two_compartment_oracle({X2: K1 / 2}, d["order"])
    assert {k: v == "determined" for k, v in {**d["observable"], **d["identifiable"]}.items()} == determined
    path.write_text(MODEL + "[initial]\nx2 = 0\n")
    system = uj.load_system(str(path))
    uj.save_model(system, tmp_path / "again.toml")  # the table is written back
    assert "[initial]" in (tmp_path / "again.toml").read_text()
    assert cli.main(["analyze", str(tmp_path / "again.toml")]) == 0
    assert "known initial state: x2 = 0" in capsys.readouterr().out


@pytest.mark.parametrize("args, message", [
    (["--initial", "x9=0"], "'x9' is not a state"),
    (["--initial", "x2=nan"], "is nan"),
    (["--initial", "x2=q*2"], "name 'q' is not allowed"),
    (["--initial", "x2"], "needs STATE=VALUE"),
])
def test_cli_bad_initial_is_one_line_and_exit_2(tmp_path, capsys, args, message):
    path = tmp_path / "m.toml"
    path.write_text(MODEL)
    assert cli.main(["analyze", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_model_file_with_a_bad_initial_table(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text(MODEL + "[initial]\nx7 = 0\n")
    assert cli.main(["analyze", str(path)]) == 2
    assert "initial.x7: 'x7' is not a state" in capsys.readouterr().err


# ----------------------------------------------------------------------------- random models
def _random_model(seed):
    """A random polynomial system of 2 states and 2 parameters, a random output, and a random
    known initial state (a state at 0, at 1, or at a parameter; none, 30 % of the time)."""
    rng = random.Random(seed)
    x1, x2, a, b = sp.symbols("x1 x2 a b")
    monomials = [x1, x2, x1 * x2, x1**2, x2**2, sp.Integer(1)]

    def rhs():
        terms = rng.sample(monomials, 2)
        return rng.choice((a, b, 1)) * terms[0] + rng.choice((a, b, -1, 2)) * terms[1]

    f = [rhs(), rhs()]
    h = rng.choice([x1, x2, x1 + x2, x1 * x2])
    state = rng.choice((x1, x2))
    initial = {state: rng.choice((0, 1, a))}
    fn = sp.lambdify((sp.Matrix([x1, x2]), sp.Matrix([a, b])), f, "jax")
    hn = sp.lambdify((sp.Matrix([x1, x2]), sp.Matrix([a, b])), h, "jax")
    sys_ = uj.System(states=("x1", "x2"), outputs={"y": lambda x, p: hn(x, p) + 0.0 * x[0]},
                     drift=lambda x, p: jnp.stack([jnp.asarray(v, dtype=float) + 0.0 * x[0] for v in fn(x, p)]),
                     params=("a", "b"), domain={"x1": (-2, 2), "x2": (-2, 2)})
    value = "a" if initial[state] == a else int(initial[state])
    if rng.random() < 0.3:  # a generic initial state: closures are claimed and checked
        return sys_, {"states": (x1, x2), "f": f, "h": [h], "initial": {}}, (a, b), {}
    return sys_, {"states": (x1, x2), "f": f, "h": [h], "initial": initial}, (a, b), {str(state): value}


def _check_random(seed):
    sys_, ex, params, initial = _random_model(seed)
    try:
        rep = uj.analyze(sys_, initial=initial, max_order=5)
    except uj.ModelError:
        return  # undefined there (a singular initial state): refused, nothing to compare
    _, determined = oracle([ex], params, params, rep.order, seed=seed)
    for name, verdict in rep.verdicts.items():
        assert (verdict is D) == determined[name], (seed, name, verdict)
    if rep.stop.name == "SPAN_CLOSED":  # a closure claim: later orders add nothing
        assert oracle([ex], params, params, rep.order + 2, seed=seed)[1] == determined


@pytest.mark.parametrize("seed", range(5))
def test_random_polynomial_models_against_sympy(seed):
    _check_random(seed)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5, 40))
def test_random_polynomial_models_against_sympy_more(seed):
    _check_random(seed)
