"""Global identifiability (issue 46): SIAN's route solved by msolve.

Published answers reproduced: StructuralIdentifiability.jl's test models and its benchmark
Bilirubin2_io, SIAN's test models (``tests/global_models.py``). Hand-derived:

* ``x' = -a b x``, ``y = x``: ``y = x0 exp(-a b t)`` gives ``x0`` and ``a b``; ``a`` and ``b``
  alone are not identifiable (``(a s, b / s)`` gives the same output).
* ``x' = -a^2 x``: ``a^2`` is identified, ``a`` up to its sign: 2 values, the sign change.
* two compartments draining separately, ``y = x1 + x2``: ``y = x1 e^(-k1 t) + x2 e^(-k2 t)``
  determines the two exponentials as a set: swapping ``(x1, k1)`` with ``(x2, k2)`` gives the
  same output: every unknown 2 values, the permutation ``x1 <-> x2, k1 <-> k2``.
* the mirror beacon: a robot at ``(px, py)`` drives along the x axis with known speed ``u``
  and measures its squared range to a beacon at the origin, ``y = px^2 + py^2``: ``y' = 2 px u``
  gives ``px``, then ``py^2 = y - px^2``: ``py`` up to its sign, the mirror image across the
  path (``py -> -py``).
* a wheel seen through its kinetic energy: ``w' = -a w + b u`` (known voltage ``u``),
  ``y = w^2``: ``(w, b) -> (-w, -b)`` gives the same output: ``a`` global, ``w`` and ``b`` two values
  each, one sign change of both.
"""

import json

import pytest
from global_models import SI_JL_TESTS, SIAN_TESTS, build

import uio_jax as uj
from uio_jax import cli

G, L, N, U = (uj.GlobalVerdict.GLOBAL, uj.GlobalVerdict.LOCAL, uj.GlobalVerdict.NOT, uj.GlobalVerdict.UNDECIDED)
CODE = {"G": G, "L": L, "N": N}


def verdicts(result, names):
    return {k: result.global_identifiability[k] for k in names}


@pytest.mark.parametrize("table,name", [("si", k) for k in SI_JL_TESTS if k not in ("siwr", "rational_four_states")]
                         + [("sian", k) for k in SIAN_TESTS])
def test_published_answers(tmp_path, table, name):
    spec = dict((SI_JL_TESTS if table == "si" else SIAN_TESTS)[name])
    answer = {k: CODE[v] for k, v in spec.pop("answer").items()}
    functions = spec.pop("functions", None)
    result = uj.global_identifiability(build(tmp_path, name, **spec), functions=functions)
    assert verdicts(result, answer) == answer
    for k, v in result.global_identifiability.items():  # counts agree with the verdicts
        if v is G:
            assert result.value_counts[k] == 1
        if v is L:
            assert result.value_counts[k] >= 2
    assert result.error_bound <= 1 - result.prob_threshold


def test_bilirubin_permutations():
    """SI.jl's benchmark Bilirubin2_io: x1 and k01 global, the rest 3 values each; the 6
    solutions are the permutations of compartments 2, 3, 4 (its identifiable functions are
    the symmetric functions of their rates and initial amounts)."""
    result = uj.global_identifiability(uj.load_system("tests/data/global/bilirubin2_io.toml"))
    assert result.names(G) == ["x1", "k01"]
    assert set(result.names(L)) == {"x2", "x3", "x4", "k12", "k13", "k14", "k21", "k31", "k41"}
    assert all(result.value_counts[k] == 3 for k in result.names(L))
    assert result.solution_count == 6
    assert "x2 <-> x3, k12 <-> k13, k21 <-> k31" in result.symmetries
    assert len(result.symmetries) == 5 and set(result.symmetry_kinds) == {"permutation"}


def test_product_of_parameters(tmp_path):
    s = build(tmp_path, "ab", ["x"], ["a", "b"], {"y": "x"}, {"x": "-a*b*x"})
    result = uj.global_identifiability(s, functions={"ab": lambda x, p: p[0] * p[1],
                                                     "a_plus_b": lambda x, p: p[0] + p[1]})
    assert verdicts(result, ["x", "a", "b", "ab", "a_plus_b"]) == {"x": G, "a": N, "b": N, "ab": G, "a_plus_b": N}
    assert result.functions == ("ab", "a_plus_b") and result.value_counts["ab"] == 1
    assert len(result.specialised) == 1 and result.specialised[0] in ("a", "b")


def test_square_of_a_parameter(tmp_path):
    s = build(tmp_path, "a2", ["x"], ["a"], {"y": "x"}, {"x": "-a**2*x"})
    result = uj.global_identifiability(s)
    assert verdicts(result, ["x", "a"]) == {"x": G, "a": L} and result.value_counts["a"] == 2
    assert result.symmetries == ("a -> -a",) and result.symmetry_kinds == ("sign change",)


def test_two_compartment_permutation(tmp_path):
    s = build(tmp_path, "two_exp", ["x1", "x2"], ["k1", "k2"], {"y": "x1 + x2"}, {"x1": "-k1*x1", "x2": "-k2*x2"})
    result = uj.global_identifiability(s)
    assert all(v is L for v in result.global_identifiability.values())
    assert all(c == 2 for c in result.value_counts.values()) and result.solution_count == 2
    assert result.symmetries == ("x1 <-> x2, k1 <-> k2",)


def test_mirror_beacon(tmp_path):
    s = build(tmp_path, "beacon", ["px", "py"], [], {"r2": "px**2 + py**2"}, {"px": "u", "py": "0"}, known=["u"])
    result = uj.global_identifiability(s)
    assert verdicts(result, ["px", "py"]) == {"px": G, "py": L} and result.value_counts["py"] == 2
    assert result.symmetries == ("py -> -py",)
    assert any("known inputs" in n for n in result.notes)


def test_wheel_sign_ambiguity(tmp_path):
    s = build(tmp_path, "wheel", ["w"], ["a", "b"], {"energy": "w**2"}, {"w": "-a*w + b*u"}, known=["u"])
    result = uj.global_identifiability(s)
    assert verdicts(result, ["w", "a", "b"]) == {"w": L, "a": G, "b": L}
    assert result.symmetries == ("w -> -w, b -> -b",)


def test_known_initial_state_enters_the_equations(tmp_path):
    """With x2(0) = 0 known the leaky two-compartment model is identifiable (test_initial's
    hand derivation): every parameter takes one value, or a finite set; x1 is global."""
    s = build(tmp_path, "two_c", ["x1", "x2"], ["k1", "k12", "k21"], {"y": "x1"},
              {"x1": "-(k1 + k12)*x1 + k21*x2", "x2": "k12*x1 - k21*x2"}, domain={"x2": (0, 2)})
    result = uj.global_identifiability(s, initial={"x2": 0})
    assert "x2" not in result.global_identifiability
    assert verdicts(result, ["x1", "k1", "k12", "k21"]) == {"x1": G, "k1": G, "k12": G, "k21": G}
    assert dict(result.initial) == {"x2": "0"} and any("generic values" in n for n in result.notes)
    free = uj.global_identifiability(s)
    assert verdicts(free, ["k1", "k12", "k21"]) == {"k1": N, "k12": N, "k21": N}


def test_result_embeds_as_json(tmp_path):
    s = build(tmp_path, "a2", ["x"], ["a"], {"y": "x"}, {"x": "-a**2*x"})
    result = uj.global_identifiability(s)
    d = json.loads(result.to_json())
    assert d["global_identifiability"] == {"x": "global", "a": "local"} and d["value_counts"] == {"x": 1, "a": 2}
    assert d["symmetries"] == ["a -> -a"] and d["prime"] == result.prime
    text = str(result)
    assert "a  local  (2 values)" in text and "discrete symmetry (sign change): a -> -a" in text


def test_time_limit_answers_undecided(tmp_path):
    """SI.jl's rational four-state model takes msolve minutes here: with 1 s it is stopped
    and the locally identifiable unknowns are undecided with the reason; the others keep
    their local verdict."""
    spec = dict(SI_JL_TESTS["rational_four_states"])
    spec.pop("answer")
    spec.pop("functions")
    result = uj.global_identifiability(build(tmp_path, "r4", **spec), timeout=1.0)
    assert result.global_identifiability["alpha"] is N and result.global_identifiability["b"] is U
    assert "time limit of 1 s" in result.undecided_reason


@pytest.mark.parametrize("bad,message", [
    (dict(initial={"zz": 0}), "not a state"),
    (dict(initial={"x": float("nan")}), "not a real number"),
    (dict(initial={"a": 1.0}), "a parameter, not a state"),
    (dict(timeout=-1), "timeout"),
    (dict(prob_threshold=1.5), "prob_threshold"),
    (dict(functions={"x": lambda x, p: p[0]}), "new identifier"),
    (dict(functions={"f": 3}), "not callable"),
])
def test_bad_options_one_line(tmp_path, bad, message):
    s = build(tmp_path, "a2", ["x"], ["a"], {"y": "x"}, {"x": "-a**2*x"})
    with pytest.raises(uj.OptionError, match=message) as info:
        uj.global_identifiability(s, **bad)
    assert "\n" not in str(info.value)


def test_unknown_inputs_refused(tmp_path):
    path = tmp_path / "w.toml"
    path.write_text('name = "w"\nstates = ["x"]\n[outputs]\ny = "x"\n[inputs]\nunknown = ["w"]\n'
                    '[dynamics]\nx = "-x + w"\n')
    with pytest.raises(uj.OptionError, match="unknown inputs"):
        uj.global_identifiability(uj.load_system(str(path)))


def test_non_rational_refused(tmp_path):
    s = build(tmp_path, "pend", ["th", "om"], ["g"], {"y": "th"}, {"th": "om", "om": "-g*sin(th)"})
    with pytest.raises(uj.ModelError, match="rational model: .*sin\\(th\\)") as info:
        uj.global_identifiability(s)
    assert "\n" not in str(info.value)


def test_cli_global(tmp_path, capsys):
    s = tmp_path / "a2.toml"
    s.write_text('name = "a2"\nstates = ["x"]\n[params]\na = [0.5, 1.5]\n[outputs]\ny = "x"\n[dynamics]\n'
                 'x = "-a**2*x"\n')
    out_json = tmp_path / "g.json"
    assert cli.main(["analyze", str(s), "--global", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "a  local  (2 values)" in out
    assert json.loads(out_json.read_text())["global"]["global_identifiability"]["a"] == "local"


@pytest.mark.parametrize("model,extra,message", [
    ('[inputs]\nunknown = ["w"]\n[dynamics]\nx = "-a*x + w"\n', [], "unknown inputs"),
    ('[dynamics]\nx = "-a*sin(x)"\n', [], "rational model"),
    ('[dynamics]\nx = "-a*x"\n', ["--initial", "zz=1"], "not a state"),
])
def test_cli_bad_input_exit_2(tmp_path, capsys, model, extra, message):
    s = tmp_path / "m.toml"
    s.write_text('name = "m"\nstates = ["x"]\n[params]\na = [0.5, 1.5]\n[outputs]\ny = "x"\n' + model)
    assert cli.main(["analyze", str(s), "--global", *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1


def test_memory_limit_answers_undecided():
    result = uj.global_identifiability(uj.load_system("tests/data/global/bilirubin2_io.toml"), memory_gb=0.02)
    assert all(v is U for v in result.global_identifiability.values())
    assert "memory limit of 0.02 GiB" in result.undecided_reason


def test_ctrl_c_stops_msolve_and_keeps_going():
    """A dense random system of 10 quadrics (1024 solutions, about 20 s here): a Ctrl-C while
    msolve runs kills it at once and answers INTERRUPTED (the caller keeps the local verdicts)."""
    import random
    import time

    from uio_jax._analysis.globally.msolve import SolveStatus, input_text, run_msolve

    rng, p, names = random.Random(1), 65521, [f"x{i}" for i in range(10)]

    def quadric():
        terms = [f"{rng.randrange(1, p)}*{a}*{b}" for i, a in enumerate(names) for b in names[i:]]
        return "+".join(terms + [f"{rng.randrange(1, p)}*{a}" for a in names] + ["1"])

    def interrupt(elapsed):
        raise KeyboardInterrupt

    t0 = time.perf_counter()
    solved = run_msolve(input_text(names, p, [quadric() for _ in names]), timeout=120, on_wait=interrupt)
    assert solved.outcome is SolveStatus.INTERRUPTED and "Ctrl-C" in solved.reason
    assert time.perf_counter() - t0 < 10


def test_a_state_named_z(tmp_path):
    """The saturating variable z of SIAN's system is no name of the model's: a state called z
    is a state (HIV's model has one)."""
    s = build(tmp_path, "z", ["z"], ["a"], {"y": "z"}, {"z": "-a**2*z"})
    result = uj.global_identifiability(s)
    assert verdicts(result, ["z", "a"]) == {"z": G, "a": L}
