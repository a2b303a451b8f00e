"""Declarative TOML/JSON model files: reading, errors, writing, round trips, general form."""

import functools
import json
import os

import jax.numpy as jnp
import numpy as np
import pytest
import tomllib
from helpers import ROOT, SAMPLES, published, zoo_report, zoo_system

import uio_jax as uj
from uio_jax._io.model_file import ModelSpec, build_system, load_model_file, read_model_file, spec_from_dict, to_toml

SYSTEMS = os.path.join(ROOT, "systems")
UNICYCLE = os.path.join(SYSTEMS, "unicycle_range_v_unknown.toml")
TWO_COMPARTMENT = os.path.join(SYSTEMS, "two_compartment.toml")


def summary(rep):
    """What must agree between two reports of the same model."""
    return (rep.method, rep.n, rep.dim, rep.dims, dict(rep.observable), dict(rep.identifiable), rep.params)


def analyze(system):
    return uj.analyze(system, samples=SAMPLES, seed=0)


@functools.cache
def file_report(path):
    """Report of a model file, computed once per session."""
    return analyze(uj.load_system(path))


def write(tmp_path, text, name="m.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


GENERAL = """
name = "general unicycle"
states = ["r", "phi", "theta"]
angles = ["phi", "theta"]
[domain]
r = [0.5, 2.0]
[outputs]
r = "r"
[inputs]
known = ["omega"]
unknown = ["v"]
[dynamics]
r = "v*cos(theta - phi)"
phi = "v*sin(theta - phi)/r"
theta = "omega"
"""

PROMOTED = """
states = ["x1", "x2"]
params = ["k"]
[outputs]
y = "x1"
[inputs]
known = ["u", "a"]
[dynamics]
x1 = "-k*x1 + x2 + u**2"
x2 = "-x2 + a*x1"
"""


# ----------------------------------------------------------------------------- examples
def test_unicycle_toml_matches_the_zoo_lambda_version():
    sys = uj.load_system(UNICYCLE)
    assert sys.name == "unicycle_range_v_unknown"
    assert isinstance(sys.source, ModelSpec)
    rep = file_report(UNICYCLE)
    zoo = zoo_report("unicycle_polar", "range_v_unknown")
    assert summary(rep) == summary(zoo)
    pub = published("unicycle_polar", "range_v_unknown")
    assert list(rep.dims) == pub["dims"] and rep.dim == pub["dim"]
    assert rep.details["m_prime"] == pub["m_prime"] and rep.details["m_star"] == pub["m_star"]


def test_general_form_gives_the_same_system_as_the_affine_form():
    g = build_system(spec_from_dict(tomllib.loads(GENERAL), "general"))
    a = uj.load_system(UNICYCLE)
    assert g.drift is None  # v*cos(.) at v = 0 vanishes exactly: no drift, single_ui applies
    x = np.array([1.2, 0.3, -0.4])
    for fields_g, fields_a in ((g.known, a.known), (g.unknown, a.unknown)):
        assert set(fields_g) == set(fields_a)
        for k in fields_g:
            want = np.asarray(fields_a[k](jnp.asarray(x)))
            np.testing.assert_allclose(fields_g[k](x), want, rtol=1e-15)  # numpy path
            np.testing.assert_allclose(np.asarray(fields_g[k](jnp.asarray(x))), want, rtol=1e-15)  # JAX path
    assert summary(analyze(g)) == summary(zoo_report("unicycle_polar", "range_v_unknown"))


def test_two_compartment_parameters_are_identifiable():
    sys = uj.load_system(TWO_COMPARTMENT)
    assert sys.params and tuple(sys.params) == ("k01", "k12", "k21")
    rep = file_report(TWO_COMPARTMENT)
    assert rep.method == "orc"
    assert rep.observable == {"x1": True, "x2": True}
    assert rep.identifiable == {"k01": True, "k12": True, "k21": True}


@pytest.mark.slow
def test_pendulum_damping_is_hidden_by_the_unknown_torque():
    rep = analyze(uj.load_system(os.path.join(SYSTEMS, "pendulum_torque_unknown.toml")))
    assert rep.method == "general_ui" and rep.exact  # auto: an unknown input and a drift
    assert rep.observable == {"theta": True, "omega": True} and rep.identifiable == {"c": False}


# ----------------------------------------------------------------------------- round trips
def _round_trip(system, tmp_path, suffix):
    path = str(tmp_path / f"model{suffix}")
    uj.save_model(system, path)
    back = uj.load_system(path)
    assert back.source == system.source or back.source.to_dict() == {
        **system.source.to_dict(), **({"name": system.name} if system.name else {})}
    return back


@pytest.mark.parametrize(
    "which, suffix",
    [("unicycle", ".toml"), ("unicycle", ".json"), ("two_compartment", ".toml"), ("promoted", ".toml"),
     pytest.param("two_compartment", ".json", marks=pytest.mark.slow),
     pytest.param("promoted", ".json", marks=pytest.mark.slow)],
)
def test_save_and_load_give_the_same_report(tmp_path_factory, suffix, which):
    """Unknown input (unicycle), parameters (two compartments), promoted input (promoted)."""
    if which == "promoted":
        path = str(tmp_path_factory.mktemp("promoted") / "promoted.toml")
        with open(path, "w") as fh:
            fh.write(PROMOTED)
    else:
        path = UNICYCLE if which == "unicycle" else TWO_COMPARTMENT
    sys = uj.load_system(path)
    back = _round_trip(sys, tmp_path_factory.mktemp("out"), suffix)
    assert back.states == sys.states and tuple(back.params) == tuple(sys.params)
    assert back.notes == sys.notes
    assert summary(analyze(back)) == summary(file_report(path))


def test_written_toml_is_the_same_spec_and_escapes_strings(tmp_path):
    text = """
name = "quotes \\" and \\\\ backslash, unicode θ, tab\\t"
description = "line1\\nline2"
notes = ["a note", "é"]
states = ["θ", "v"]
[params]
k = [0.25, 3]
[constants]
g = 9.81
[outputs]
"y 1" = "θ"
"y.2" = "v*g"
[drift]
"θ" = "v"
[known.a]
v = "1"
[unknown.wind]
v = "-k*cos(θ)"
"""
    spec = read_model_file(write(tmp_path, text))
    out = to_toml(spec.to_dict())
    assert spec_from_dict(tomllib.loads(out), "again") == spec
    assert spec_from_dict(json.loads(json.dumps(spec.to_dict())), "again") == spec
    sys = uj.load_system(write(tmp_path, text))
    back = _round_trip(sys, tmp_path, ".toml")
    assert back.source == spec


def test_python_systems_cannot_be_written(tmp_path):
    sys = zoo_system("unicycle_polar", "range_v_unknown")
    with pytest.raises(uj.ModelError, match="made of Python functions and cannot be written"):
        uj.save_model(sys, str(tmp_path / "m.toml"))
    with pytest.raises(uj.ModelError, match="must end in .toml or .json"):
        uj.save_model(uj.load_system(UNICYCLE), str(tmp_path / "m.yaml"))


# ----------------------------------------------------------------------------- promotion
def test_non_affine_inputs_are_promoted_with_notes(tmp_path):
    sys = uj.load_system(write(tmp_path, PROMOTED))
    # u**2: u becomes a measured state driven by d_u; w*x1 is affine in w
    assert sys.states == ("x1", "x2", "u")
    assert set(sys.known) == {"a", "d_u"} and not sys.unknown
    assert set(sys.outputs) == {"y", "u"}
    assert len(sys.notes) == 1 and "known input 'u'" in sys.notes[0] and "d_u" in sys.notes[0]
    x, p = np.array([0.7, 1.1, 0.9]), np.array([1.3])
    np.testing.assert_allclose(sys.drift(x, p), [-1.3 * 0.7 + 1.1 + 0.81, -1.1, 0.0])
    np.testing.assert_allclose(sys.known["a"](x, p), [0.0, 0.7, 0.0])
    np.testing.assert_allclose(sys.known["d_u"](x, p), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(sys.outputs["u"](jnp.asarray(x), jnp.asarray(p)), 0.9)
    assert any("promoted" in n for n in analyze(sys).notes)


def test_cross_terms_abs_outputs_and_unused_inputs(tmp_path):
    text = """
states = ["x"]
[outputs]
y = "x + c"
[inputs]
known = ["a", "c", "unused"]
unknown = ["w", "s"]
[dynamics]
x = "a*w - x + Abs(s)"
"""
    sys = uj.load_system(write(tmp_path, text))
    notes = " | ".join(sys.notes)
    assert "'unused' appears in no equation: dropped" in notes
    assert "known input 'c' appears in an output" in notes
    assert "unknown input 's' enters through abs/sign/min/max" in notes
    assert "unknown input 'w' multiplies input 'a'" in notes  # ties: the unknown input is promoted
    assert sys.states == ("x", "c", "w", "s")
    assert set(sys.known) == {"a", "d_c"} and set(sys.unknown) == {"d_w", "d_s"}
    x = np.array([0.7, 0.2, 1.4, -0.3])
    np.testing.assert_allclose(sys.known["a"](x), [1.4, 0, 0, 0])
    np.testing.assert_allclose(sys.drift(x), [-0.7 + 0.3, 0, 0, 0])


def test_drift_entries_that_are_zero_give_no_drift(tmp_path):
    text = 'states = ["x"]\n[outputs]\ny = "x"\n[drift]\nx = "0"\n[unknown.w]\nx = "1"\n'
    assert uj.load_system(write(tmp_path, text)).drift is None


# ----------------------------------------------------------------------------- errors
def _error(tmp_path, text, name="bad.toml"):
    path = write(tmp_path, text, name)
    with pytest.raises(uj.UioJaxError) as info:
        uj.load_system(path)
    msg = str(info.value)
    assert "\n" not in msg and path in msg
    return msg


@pytest.mark.parametrize(
    "text, fragment",
    [
        ('states = ["x"\n[outputs]\n', "TOML syntax error"),
        ('states = ["x"]\noutput = {y = "x"}\n', "unknown key 'output' (allowed: name,"),
        ('states = ["x"]\n', "missing 'outputs'"),
        ('[outputs]\ny = "x"\n', "missing 'states'"),
        ('states = "x"\n[outputs]\ny = "x"\n', "states: must be a list of names, got a string"),
        ('states = ["x", "x"]\n[outputs]\ny = "x"\n', "states: 'x' is listed twice"),
        ('states = ["x"]\nparams = ["x"]\n[outputs]\ny = "x"\n', "parameter 'x' has the name of a state"),
        ('states = ["x"]\n[constants]\nx = 1\n[outputs]\ny = "x"\n', "constant 'x' has the name of a state"),
        ('states = ["x"]\n[constants]\ng = "9.8"\n[outputs]\ny = "x"\n', "constants.g: must be a number"),
        ('states = ["x"]\n[outputs]\ny = "x +"\n', "outputs.y: expression 'x +' at column 4"),
        ('states = ["x"]\n[outputs]\ny = "__import__(\'os\')"\n', "function '__import__' is not allowed"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[drift]\nz = "1"\n', "drift.z: 'z' is not a state"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[known.u]\nx = "u"\n', "known.u.x: expression 'u' at column 1"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[domain]\nx = [2, 1]\n', "domain.x: empty box"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[domain]\nq = [0, 1]\n', "domain.q: 'q' is not a state"),
        ('states = ["x"]\nangles = ["a"]\n[outputs]\ny = "x"\n', "angles: 'a' is not a state"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[drift]\nx = "1"\n[dynamics]\nx = "1"\n', "not both"),
        ('states = ["x"]\n[inputs]\nknown = ["u"]\n[outputs]\ny = "x"\n', "only used with [dynamics]"),
        ('states = ["1x"]\n[outputs]\ny = "x"\n', "'1x' is not a valid name"),
        ('states = ["x"]\n[outputs]\n', "outputs: must define at least one output"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[unknown.w]\nx = "1/0*x"\n', "NaN/inf"),
        ('states = ["x"]\n[outputs]\ny = "x"\n[inputs]\nknown=["u"]\nunknown=["u"]\n[dynamics]\nx = "u"\n',
         "input 'u' has the name of an input"),
    ],
)
def test_broken_files_give_one_line_errors(tmp_path, text, fragment):
    assert fragment in _error(tmp_path, text)


def test_toml_syntax_error_names_the_line(tmp_path):
    msg = _error(tmp_path, 'states = ["x"]\n[outputs]\ny = \n')
    assert "line 3" in msg


def test_json_errors(tmp_path):
    msg = _error(tmp_path, '{"states": ["x"],\n "outputs": {"y": "x"\n', "bad.json")
    assert "JSON syntax error" in msg and "line" in msg
    msg = _error(tmp_path, '["x"]', "bad.json")
    assert "a model must be a table" in msg
    good = uj.load_system(write(tmp_path, '{"states": ["x"], "outputs": {"y": "x"}, "drift": {"x": "-x"}}',
                                "good.json"))
    assert good.states == ("x",) and good.name == "good.json"


def test_missing_and_unknown_files(tmp_path):
    with pytest.raises(uj.LoadError, match="model file not found"):
        uj.load_system(str(tmp_path / "nope.toml"))
    with pytest.raises(uj.LoadError, match="must end in .toml or .json"):
        load_model_file(str(tmp_path / "nope.yaml"))
    with pytest.raises(uj.LoadError, match="FILE.py:NAME, MODEL.toml, MODEL.json or a StrikePy MODEL.py"):
        uj.load_system(str(tmp_path / "nope.yaml"))
    (tmp_path / "bin.toml").write_bytes(b"\xff\xfe")
    with pytest.raises(uj.LoadError, match="not UTF-8"):
        uj.load_system(str(tmp_path / "bin.toml"))


def test_cli_analyzes_a_model_file(capsys):
    from uio_jax.cli import main

    assert main(["analyze", TWO_COMPARTMENT, "--samples", "256"]) == 0
    out = capsys.readouterr().out
    assert "k21" in out and "identifiable" in out


# ----------------------------------------------------------------------------- H4 small items
def test_a_number_past_pythons_digit_limit_is_one_line_naming_the_field_and_length(tmp_path):
    path = tmp_path / "big.toml"
    path.write_text('states = ["x"]\n[outputs]\ny = "x"\n[drift]\nx = "-x + ' + "1" * 5000 + '"\n')
    with pytest.raises(uj.ExpressionError) as err:
        uj.load_system(str(path))
    msg = str(err.value)
    assert "drift.x" in msg and "a number of 5000 digits is too large" in msg
    assert "\n" not in msg and "set_int_max_str_digits" not in msg


def test_a_zoo_file_without_name_lists_its_models(capsys):
    from uio_jax.cli import main

    spec = os.path.join(ROOT, "systems", "gps.py")
    with pytest.raises(uj.LoadError) as err:
        uj.load_system(spec)
    msg = str(err.value)
    assert msg.startswith(f"{spec} is a zoo file, not a StrikePy model module; name one model as FILE.py:NAME: ")
    for name in ("inputs_known", "inputs_unknown", "omega_unknown", "v_unknown"):
        assert f"{spec}:{name}" in msg
    assert "_system" not in msg and "\n" not in msg
    assert main(["analyze", spec]) == 2
    assert capsys.readouterr().err.startswith("uio-jax: error: ")


def test_model_functions_reads_public_top_level_defs_without_running(tmp_path):
    from uio_jax._io.loading import model_functions

    path = tmp_path / "m.py"
    path.write_text("raise SystemExit('never run')\n\ndef a():\n    pass\n\ndef _b():\n    pass\n\n"
                    "class C:\n    def d(self):\n        pass\n\ndef e(k=1):\n    pass\n")
    assert model_functions(str(path)) == ["a", "e"]
