"""Time-varying Systems (``time="t"``): construction, validation, ``System.autonomous()``,
the loaders (model files, from_sympy, from_dynamics), save/load, the Experiment refusal."""

import json
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import zoo_system

import uio_jax as uj
from uio_jax._model.system import DEFAULT_TIME_BOX


def _at(fn, z):
    with jax.enable_x64(True):
        return np.asarray(fn(jnp.asarray(z, dtype=jnp.float64)))


def _one_line(exc) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    return msg


def oscillator(**kw):
    """x' = v, v' = -k t x + (1 + t) a, y = x cos(t): a time-varying spring."""
    return uj.System(
        states=("x", "v"),
        outputs={"y": lambda x, p, t: x[0] * jnp.cos(t)},
        known={"a": lambda x, p, t: jnp.stack([0.0 * t, 1.0 + t])},
        unknown={"w": lambda x, p, t: jnp.stack([jnp.sin(t) + 0.0 * x[0], x[0]])},
        drift=lambda x, p, t: jnp.stack([x[1], -p[0] * t * x[0]]),
        params={"k": (1.0, 2.0)}, time="t", **kw)


# ----------------------------------------------------------------------------- the model
def test_time_varying_system_has_its_time_box_and_repr():
    s = uj.System(states=("x",), outputs={"y": lambda x, t: x[0] * t},
                  drift=lambda x, t: -t * x, time="t")
    assert s.time == "t" and s.time_name == "t" and s.known_coordinates == 0
    assert s.time_box == DEFAULT_TIME_BOX == (0.0, 1.0)
    assert s.domain["t"] == (0.0, 1.0) and s.box()[0].shape == (1,)  # box(): the states only
    assert "time='t'" in repr(s)
    s2 = uj.System(states=("x",), outputs={"y": lambda x, t: x[0]}, domain={"t": (2.0, 5.0)}, time="t")
    assert s2.time_box == (2.0, 5.0)


def test_time_invariant_system_is_unchanged():
    s = uj.System(states=("x",), outputs={"y": lambda x: x[0]})
    assert s.time is None and s.time_name is None and s.time_box is None
    assert s.autonomous() is s and s.autonomous().known_coordinates == 0
    sp = uj.System(states=("x",), outputs={"y": lambda x, p: x[0] * p[0]}, params=["k"])
    assert sp.autonomous() is sp.joint() and sp.autonomous().known_coordinates == 0
    assert sp.autonomous().joint_param_names == ("k",)
    assert "time" not in repr(s) and "known_coordinates" not in repr(s)


def test_autonomous_values_match_hand_computed_ones():
    s = oscillator()
    a = s.autonomous()
    assert a.states == ("x", "v", "k", "t") and not a.params and a.time is None
    assert a.known_coordinates == 1 and a.time_name == "t" and a.joint_param_names == ("k",)
    assert tuple(a.outputs) == ("y", "t") and tuple(a.known) == ("a",) and tuple(a.unknown) == ("w",)
    assert a.domain == {"x": (0.5, 1.5), "v": (0.5, 1.5), "k": (1.0, 2.0), "t": (0.0, 1.0)}
    x, v, k, t = 0.7, 0.9, 1.6, 0.3
    z = [x, v, k, t]
    np.testing.assert_allclose(_at(a.drift, z), [v, -k * t * x, 0.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(_at(a.known["a"], z), [0.0, 1.0 + t, 0.0, 0.0], rtol=1e-15)
    np.testing.assert_allclose(_at(a.unknown["w"], z), [math.sin(t), x, 0.0, 0.0], rtol=1e-15)
    assert float(_at(a.outputs["y"], z)) == pytest.approx(x * math.cos(t), rel=1e-15)
    assert float(_at(a.outputs["t"], z)) == t
    assert "known_coordinates=1 ('t')" in repr(a)
    # the joint System keeps the time: callables (z, t) on z = [x; p]
    j = s.joint()
    assert j.states == ("x", "v", "k") and j.time == "t" and j.joint_param_names == ("k",)
    with jax.enable_x64(True):
        np.testing.assert_allclose(np.asarray(j.drift(jnp.array([x, v, k]), jnp.float64(t))),
                                   [v, -k * t * x, 0.0], rtol=1e-15)


def test_autonomous_creates_the_drift_when_there_is_none():
    s = uj.System(states=("r", "th"), outputs={"r": lambda x, t: x[0]},
                  unknown={"v": lambda x, t: jnp.stack([jnp.cos(x[1] - t), 0.0 * t])},
                  domain={"s": (1.0, 3.0)}, angles=("th",), time="s")
    a = s.autonomous()
    assert s.drift is None and a.drift is not None
    np.testing.assert_array_equal(_at(a.drift, [0.8, 0.1, 2.0]), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(_at(a.unknown["v"], [0.8, 0.1, 2.0]), [math.cos(0.1 - 2.0), 0.0, 0.0])
    assert a.domain["s"] == (1.0, 3.0) and a.angles == ("th",) and a.states[-1] == "s"


def test_with_known_keeps_the_time():
    s = oscillator()
    k = s.with_known(["w"])
    assert k.time == "t" and tuple(k.known) == ("a", "w") and k.autonomous().known_coordinates == 1


def test_finiteness_is_checked_at_times_drawn_in_the_time_box():
    # finite only for t > 0.95: about 5 % of the default time box (under the 12.5 % that asks
    # for a closer look whatever the draw of the 64 validation states)
    s = uj.System(states=("x",), outputs={"y": lambda x, t: x[0] * jnp.sqrt(t - 0.95)}, time="t")
    assert any("output 'y' is finite on only" in n for n in s.notes)
    assert s.notes == s.autonomous().notes
    sp = uj.System(states=("x",), outputs={"y": lambda x, p, t: x[0] * jnp.sqrt(t - 0.95)}, params=["k"],
                   time="t")
    assert any("output 'y' is finite on only" in n for n in sp.notes)
    assert sp.notes == sp.joint().notes == sp.autonomous().notes
    with pytest.raises(uj.ModelError) as exc:  # NaN for every t of the box [0, 1]
        uj.System(states=("x",), outputs={"y": lambda x, t: x[0] * jnp.sqrt(t - 2.0)}, time="t")
    assert "output 'y' returns NaN/inf at every one of" in _one_line(exc)
    ok = uj.System(states=("x",), outputs={"y": lambda x, t: x[0] * jnp.sqrt(t - 2.0)},
                   domain={"t": (2.5, 3.0)}, time="t")
    assert not ok.notes


@pytest.mark.parametrize("kw, message", [
    (dict(time="x"), "time 'x' has the name of a state"),
    (dict(time="k", params={"k": (0.5, 1.5)}), "time 'k' has the name of a parameter"),
    (dict(time="u", known={"u": lambda x, t: x}), "time 'u' has the name of a known input"),
    (dict(time="w", unknown={"w": lambda x, t: x}), "time 'w' has the name of an unknown input"),
    (dict(time="y"), "time 'y' has the name of an output"),
    (dict(time="2t"), "time must be the name of the time variable"),
    (dict(time="for"), "time must be the name of the time variable"),
    (dict(time=1.0), "time must be the name of the time variable"),
    (dict(time="t", domain={"t": (1.0, 0.0)}), "domain of 't' is empty"),
    (dict(time="t", domain={"s": (0.0, 1.0)}), "domain given for unknown state 's' (states: x, time: t)"),
])
def test_bad_time_declarations_are_one_line_model_errors(kw, message):
    out = {"y": (lambda x, p, t: x[0]) if "params" in kw else (lambda x, t: x[0])}
    with pytest.raises(uj.ModelError) as exc:
        uj.System(states=("x",), outputs=out, **kw)
    assert message in _one_line(exc)


def test_time_box_is_refused_without_time():
    with pytest.raises(uj.ModelError) as exc:
        uj.System(states=("x",), outputs={"y": lambda x: x[0]}, domain={"t": (0.0, 1.0)})
    assert "domain given for unknown state 't'" in _one_line(exc)


@pytest.mark.parametrize("kw, message", [
    (dict(outputs={"y": lambda x: x[0]}), "output 'y' fails on (x, t) of shapes (1,), (): TypeError"),
    (dict(outputs={"y": lambda x, p: x[0]}, params=["k"]), "every function takes (x, p, t)"),
    (dict(outputs={"y": lambda x, t: x[0]}, drift=lambda x, t: jnp.stack([x[0], t])),
     "drift returns shape (2,), expected shape (1,)"),
    (dict(outputs={"y": lambda x, t: x[1] * t}), "output 'y' indexes outside the state vector of length 1"),
    (dict(outputs={"y": lambda x, t: jnp.stack([x[0], t])}), "output 'y' returns shape (2,), expected a scalar"),
    (dict(outputs={"y": lambda x, t: x[0] + 1j * t}), "output 'y' returns a complex value"),
])
def test_bad_time_varying_callables_are_one_line_model_errors(kw, message):
    with pytest.raises(uj.ModelError) as exc:
        uj.System(states=("x",), time="t", **kw)
    msg = _one_line(exc)
    assert message in msg
    if "TypeError" in message:
        assert "(with time 't', every function takes (x, t))" in msg


def test_experiment_refuses_a_time_varying_system():
    from uio_jax._model.experiment import Measurement

    s = uj.System(("a", "b"), {"a": lambda x, t: x[0]}, known={"u": lambda x, t: jnp.array([1.0, t])},
                  unknown={"w": lambda x, t: jnp.array([0.0, 1.0])}, time="t")
    with pytest.raises(uj.ModelError) as exc:
        uj.Experiment("toy", s, 0.1, 12, (1.0, 2.0), lambda st, z: (st, z[:1], z[1:]), (), 2,
                      lambda u: 0.0 * u, (Measurement("a", lambda x: x[0], 0.1, 2),), w0=(0.0,),
                      w_white_std=(0.0,), order=1, q_aug=(0.0,), prior_std=(1.0, 1.0, 1.0))
    assert "time-varying systems are not simulated yet" in _one_line(exc)


# ----------------------------------------------------------------------------- model files
_AFFINE_TOML = """
name = "spring"
states = ["x", "v"]
time = "t"
params = ["k"]
[domain]
t = [0.0, 2.0]
[outputs]
y = "x*cos(t)"
[drift]
x = "v"
v = "-k*t*x"
[known.a]
v = "1 + t"
"""


def test_toml_model_file_with_time_matches_hand_computed_values(tmp_path):
    path = tmp_path / "spring.toml"
    path.write_text(_AFFINE_TOML)
    s = uj.load_system(str(path))
    assert s.time == "t" and s.time_box == (0.0, 2.0) and s.param_names == ("k",)
    a = s.autonomous()
    assert a.states == ("x", "v", "k", "t") and a.known_coordinates == 1
    x, v, k, t = 0.7, 0.9, 1.2, 1.3
    np.testing.assert_allclose(_at(a.drift, [x, v, k, t]), [v, -k * t * x, 0.0, 1.0], rtol=1e-15)
    np.testing.assert_allclose(_at(a.known["a"], [x, v, k, t]), [0.0, 1.0 + t, 0.0, 0.0], rtol=1e-15)
    assert float(_at(a.outputs["y"], [x, v, k, t])) == pytest.approx(x * math.cos(t), rel=1e-15)
    # the user's callables (x, p, t), on JAX and on numpy arguments alike
    np.testing.assert_allclose(np.asarray(s.drift(np.array([x, v]), np.array([k]), np.float64(t))),
                               [v, -k * t * x], rtol=1e-15)
    with jax.enable_x64(True):
        np.testing.assert_allclose(np.asarray(s.drift(jnp.array([x, v]), jnp.array([k]), jnp.float64(t))),
                                   [v, -k * t * x], rtol=1e-15)


def test_json_general_form_with_time_splits_and_promotes(tmp_path):
    path = tmp_path / "general.json"
    path.write_text(json.dumps({
        "states": ["x", "v"], "time": "t", "inputs": {"known": ["a"], "unknown": ["w"]},
        "domain": {"t": [1.0, 2.0]},
        "outputs": {"y": "x*t"}, "dynamics": {"x": "v + w*sin(t)", "v": "-t*x + a**2"}}))
    s = uj.load_system(str(path))
    assert s.time == "t" and s.states == ("x", "v", "a") and s.time_box == (1.0, 2.0)
    assert any("known input 'a' enters the dynamics non-affinely" in n for n in s.notes)
    a = s.autonomous()
    assert a.states == ("x", "v", "a", "t")
    z = [0.7, 0.9, 0.6, 1.3]
    np.testing.assert_allclose(_at(a.drift, z), [0.9, -1.3 * 0.7 + 0.36, 0.0, 1.0], rtol=1e-14)
    np.testing.assert_allclose(_at(a.unknown["w"], z), [math.sin(1.3), 0.0, 0.0, 0.0], rtol=1e-14)
    np.testing.assert_array_equal(_at(a.known["d_a"], z), [0.0, 0.0, 1.0, 0.0])
    assert {k: float(_at(f, z)) for k, f in a.outputs.items()} == pytest.approx({"y": 0.7 * 1.3, "a": 0.6, "t": 1.3})


def test_an_input_that_enters_only_with_time_stays_affine(tmp_path):
    """``u * t`` is affine in u: the time is not an input of the affinity test."""
    path = tmp_path / "m.toml"
    path.write_text('states = ["x"]\ntime = "t"\n[inputs]\nknown = ["u"]\n[outputs]\ny = "x"\n'
                    '[dynamics]\nx = "u*t**2"\n')
    s = uj.load_system(str(path))
    assert s.states == ("x",) and not s.notes and s.drift is None
    np.testing.assert_allclose(_at(s.autonomous().known["u"], [0.7, 0.5]), [0.25, 0.0])


@pytest.mark.parametrize("suffix", [".toml", ".json"])
def test_save_and_load_round_trip_keeps_the_time(tmp_path, suffix):
    src = tmp_path / "spring.toml"
    src.write_text(_AFFINE_TOML)
    s = uj.load_system(str(src))
    out = tmp_path / f"copy{suffix}"
    uj.save_model(s, str(out))
    text = out.read_text()
    assert ('time = "t"' in text) if suffix == ".toml" else (json.loads(text)["time"] == "t")
    s2 = uj.load_system(str(out))
    assert s2.time == "t" and s2.time_box == (0.0, 2.0) and s2.source == s.source
    z = [0.7, 0.9, 1.2, 1.3]
    for f, g in ((s.autonomous().drift, s2.autonomous().drift),
                 (s.autonomous().outputs["y"], s2.autonomous().outputs["y"])):
        np.testing.assert_array_equal(_at(f, z), _at(g, z))


@pytest.mark.parametrize("data, message", [
    ({"states": ["x"], "outputs": {"y": "x*t"}}, "name 't' is not allowed"),  # t is not reserved
    ({"states": ["x"], "time": "x", "outputs": {"y": "x"}}, "time variable 'x' has the name of a state"),
    ({"states": ["x"], "time": "t", "params": ["t"], "outputs": {"y": "x"}},
     "time variable 't' has the name of a parameter"),
    ({"states": ["x"], "time": "t", "constants": {"t": 1.0}, "outputs": {"y": "x"}},
     "time variable 't' has the name of a constant"),
    ({"states": ["x"], "time": "t", "outputs": {"y": "x"}, "known": {"t": {"x": "1"}}},
     "input 't' has the name of a time variable"),
    ({"states": ["x"], "time": "t", "outputs": {"t": "x"}}, "output 't' has the name of the time variable"),
    ({"states": ["x"], "time": "1t", "outputs": {"y": "x"}}, "'1t' is not a valid name"),
    ({"states": ["x"], "time": ["t"], "outputs": {"y": "x"}}, "time: must be a string"),
    ({"states": ["x"], "time": "t", "domain": {"t": [1, 0]}, "outputs": {"y": "x"}}, "empty box"),
    ({"states": ["x"], "time": "t", "domain": {"s": [0, 1]}, "outputs": {"y": "x"}},
     "'s' is not a state or the time"),
])
def test_bad_time_in_model_files_is_one_line(tmp_path, data, message):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(uj.UioJaxError) as exc:
        uj.load_system(str(path))
    msg = _one_line(exc)
    assert message in msg and str(path) in msg


def test_cli_reports_a_bad_time_in_one_line(tmp_path, capsys):
    from uio_jax.cli import main

    path = tmp_path / "bad.toml"
    path.write_text('states = ["x"]\ntime = "x"\n[outputs]\ny = "x"\n')
    assert main(["analyze", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("uio-jax: error: ") and "time variable 'x'" in err[0]


# ----------------------------------------------------------------------------- from_sympy
def test_from_sympy_with_time_matches_the_model_file(tmp_path):
    sympy = pytest.importorskip("sympy")
    x, v, t, k = sympy.symbols("x v t k")
    s = uj.System.from_sympy([x, v], {"y": x * sympy.cos(t)}, drift=[v, -k * t * x],
                             known={"a": [0, 1 + t]}, params=[k], time=t, domain={t: (0.0, 2.0)})
    assert s.time == "t" and s.time_box == (0.0, 2.0)
    path = tmp_path / "spring.toml"
    path.write_text(_AFFINE_TOML)
    f = uj.load_system(str(path))
    z = [0.7, 0.9, 1.2, 1.3]
    for name in ("drift",):
        np.testing.assert_allclose(_at(getattr(s.autonomous(), name), z), _at(getattr(f.autonomous(), name), z),
                                   rtol=1e-15)
    np.testing.assert_allclose(_at(s.autonomous().known["a"], z), _at(f.autonomous().known["a"], z), rtol=1e-15)
    out = tmp_path / "sympy.json"
    uj.save_model(s, str(out))
    assert uj.load_system(str(out)).time == "t"
    with pytest.raises(uj.ModelError) as exc:  # an undeclared t is an unknown name, as in files
        uj.System.from_sympy([x], {"y": x * t})
    assert "name 't' is not allowed" in _one_line(exc)


# ----------------------------------------------------------------------------- from_dynamics
def test_from_dynamics_with_time_takes_a_trailing_t():
    s = uj.System.from_dynamics(
        ("x", "v"), lambda x, u, w, t: jnp.stack([x[1] + w[0] * jnp.sin(t), -t * x[0] + u[0]]),
        {"y": lambda x, u, w, t: x[0] * t}, known=("a",), unknown=("w",), time="t", domain={"t": (0.0, 3.0)})
    assert s.time == "t" and s.time_box == (0.0, 3.0) and s.states == ("x", "v") and not s.notes
    a = s.autonomous()
    z = [0.7, 0.9, 0.3]
    np.testing.assert_allclose(_at(a.drift, z), [0.9, -0.21, 1.0], rtol=1e-15)
    np.testing.assert_allclose(_at(a.unknown["w"], z), [math.sin(0.3), 0.0, 0.0], rtol=1e-15)
    np.testing.assert_allclose(_at(a.known["a"], z), [0.0, 1.0, 0.0], rtol=1e-15)
    assert float(_at(a.outputs["y"], z)) == pytest.approx(0.21)


def test_from_dynamics_with_params_and_time():
    s = uj.System.from_dynamics(
        ("x",), lambda x, p, u, w, t: jnp.stack([p[0] * x[0] * t + u[0] ** 2]),
        {"y": lambda x, p, u, w, t: x[0]}, known=("a",), params={"k": (1.0, 2.0)}, time="t")
    assert s.time == "t" and s.param_names == ("k",) and s.states == ("x", "a")
    a = s.autonomous()
    assert a.states == ("x", "a", "k", "t") and a.joint_param_names == ("k",)
    np.testing.assert_allclose(_at(a.drift, [0.7, 0.5, 1.5, 0.3]), [1.5 * 0.7 * 0.3 + 0.25, 0.0, 0.0, 1.0],
                               rtol=1e-15)


@pytest.mark.parametrize("kw, message", [
    (dict(time="x"), "time variable 'x' has the name of a state"),
    (dict(time="9"), "time '9' is not a valid name"),
    (dict(time="t", domain={"s": (0.0, 1.0)}), "neither a state nor an input nor the time"),
])
def test_from_dynamics_bad_time_is_one_line(kw, message):
    with pytest.raises(uj.ModelError) as exc:
        uj.System.from_dynamics(("x",), lambda x, u, w, t: x, {"y": lambda x, u, w, t: x[0]}, **kw)
    assert message in _one_line(exc)


def test_from_dynamics_without_the_time_argument_is_one_line():
    with pytest.raises(uj.ModelError) as exc:
        uj.System.from_dynamics(("x",), lambda x, u, w: x, {"y": lambda x, u, w, t: x[0]}, time="t")
    assert "dynamics fails on (x, u, w, t)" in _one_line(exc)


def test_time_varying_directions_are_stated_at_a_time_the_user_can_choose():
    """``x1' = 1, x2' = w, y = x1 + t x2`` (TUIO6): the hidden direction at time t is
    ``(1, -1/t)``. The printed directions are at the centre of the t box (t = 1, said in the
    text), and ``unobservable_directions(x, t=...)`` takes another time; a model without time
    refuses one. The time's own output adds no note about idle outputs."""
    rep = uj.analyze(zoo_system("multi_ui", "time_varying"))
    text = rep.format_directions()
    assert "(x1=1, x2=1; t=1)" in text and "+0.707 x1  -0.707 x2" in text
    d = rep.unobservable_directions([1.0, 1.0], t=0.5)[:, 0]
    np.testing.assert_allclose(np.abs(d), np.array([1.0, 2.0]) / np.sqrt(5.0), atol=1e-12)
    assert not any("adds no direction" in note for note in rep.notes)
    plain = uj.analyze(uj.System(("x1",), {"y": lambda x: x[0]}), samples=64)
    with pytest.raises(uj.ModelError, match="does not depend on time"):
        plain.unobservable_directions([1.0], t=1.0)


def test_an_answer_for_switchable_known_inputs_says_so_and_what_to_run_for_smooth_ones():
    """The default meaning of a known input surprised robotics users (issue 40): a report with
    switchable known inputs says what it holds for and how to ask for smooth ones; smooth
    ones and Systems without known inputs get no such note."""
    def note(rep):
        return [n for n in rep.notes if "known_inputs='smooth'" in n and "may jump" in n]

    model = zoo_system("unicycle_polar", "range_v_unknown")
    assert len(note(uj.analyze(model, samples=64))) == 1
    assert not note(uj.analyze(model, samples=64, known_inputs="smooth"))
    assert not note(uj.analyze(uj.System(("x1",), {"y": lambda x: x[0]}), samples=64))
