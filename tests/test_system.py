"""System validation: every malformed model gets a one-line ModelError naming the problem."""

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj

STATES = ("a", "b")


def good(**kw):
    args = dict(states=STATES, outputs={"y": lambda x: x[0]},
                known={"u": lambda x: jnp.array([x[1], 0.0])})
    args.update(kw)
    return uj.System(**args)


def test_a_valid_system_builds_with_default_domain():
    s = good(angles=("b",))
    assert s.n == 2
    lo, hi = s.box()
    np.testing.assert_allclose(lo, [0.5, -np.pi])
    np.testing.assert_allclose(hi, [1.5, np.pi])
    assert "System(" in repr(s)


@pytest.mark.parametrize(
    "kw, message",
    [
        (dict(known={"u": lambda x: jnp.array([1.0, 0.0, 0.0])}),
         "known field 'u' returns shape (3,), expected shape (2,)"),
        (dict(unknown={"w": lambda x: jnp.array([1.0])}), "unknown field 'w' returns shape (1,)"),
        (dict(drift=lambda x: x[0]), "drift returns shape ()"),
        (dict(outputs={"y": lambda x: x}), "output 'y' returns shape (2,), expected a scalar"),
        (dict(outputs={"y": lambda x: x[:1]}), "output 'y' returns shape (1,)"),
        (dict(outputs={}), "at least one output"),
        (dict(states=("a", "a")), "duplicate name 'a' in states"),
        (dict(states="ab"), "sequence of names"),
        (dict(outputs={"y": 3.0}), "outputs entry 'y' is not callable"),
        (dict(known={"u": None}), "known entry 'u' is not callable"),
        (dict(unknown={"u": lambda x: x}), "'u' is declared both known and unknown"),
        (dict(domain={"c": (0, 1)}), "domain given for unknown state 'c'"),
        (dict(domain={"a": (1, 1)}), "domain of 'a' is empty"),
        (dict(domain={"a": (2, 1)}), "domain of 'a' is empty"),
        (dict(domain={"a": (0, np.inf)}), "domain of 'a' must be finite"),
        (dict(domain={"a": 3}), "domain of 'a' must be a pair"),
        (dict(angles=("z",)), "angle 'z' is not a state"),
        (dict(outputs={"y": lambda x: x[5]}), "output 'y' indexes outside the state vector of length 2"),
        (dict(known={"u": lambda x: jnp.array([x[2], 0.0])}), "known field 'u' indexes outside"),
        (dict(outputs={"y": lambda x: x @ jnp.ones(3)}), "output 'y' fails on a state vector"),
        (dict(outputs={"y": lambda x: jnp.log(-x[0] - 1.0)}), "output 'y' returns NaN/inf at every"),
        (dict(known={"u": lambda x: jnp.array([jnp.nan, 0.0])}), "known field 'u' returns NaN/inf"),
        (dict(outputs={"y": lambda x: x[0] + 1j * x[1]}),
         "output 'y' returns a complex value (complex128); outputs and fields must be real"),
        (dict(known={"u": lambda x: jnp.array([x[1], 0.0]) * (1 + 0j)}), "known field 'u' returns a complex value"),
        (dict(drift=lambda x: jnp.array([0j, 1.0])), "drift returns a complex value"),
        (dict(outputs={"y": lambda x, p: x[0] + 1j * p[0]}, known={"u": lambda x, p: jnp.array([x[1], 0.0])},
              params=("k",)), "output 'y' returns a complex value"),
        (dict(known={"a": lambda x: jnp.array([x[1], 0.0])}), "known input 'a' has the name of a state"),
        (dict(unknown={"b": lambda x: jnp.array([1.0, 0.0])}), "unknown input 'b' has the name of a state"),
        (dict(outputs={"y": lambda x, p: x[0]}, known={"k": lambda x, p: jnp.array([x[1], 0.0])},
              params=("k",)), "known input 'k' has the name of a parameter"),
    ],
)
def test_bad_models_are_refused_with_one_line(kw, message):
    with pytest.raises(uj.ModelError) as err:
        good(**kw)
    text = str(err.value)
    assert message in text
    assert "\n" not in text


def test_integer_and_boolean_results_are_promoted_to_float():
    s = good(outputs={"y": lambda x: x[0], "flag": lambda x: x[0] > 1.0},
             drift=lambda x: jnp.array([1, 0]))
    x = jnp.array([1.2, 0.7])
    assert s.drift(x).dtype == jnp.result_type(float) and s.outputs["flag"](x) == 1.0
    rep = uj.analyze(s, samples=64)
    assert rep.observable == {"a": True, "b": True}


def test_model_error_is_a_value_error():
    assert issubclass(uj.ModelError, ValueError)
    assert issubclass(uj.OptionError, uj.UioJaxError)


def test_with_known_moves_an_unknown_input():
    s = good(unknown={"w": lambda x: jnp.array([1.0, 0.0])})
    k = s.with_known(["w"])
    assert set(k.known) == {"u", "w"} and not k.unknown
    with pytest.raises(uj.ModelError, match="not an unknown input"):
        s.with_known(["u"])


def test_system_is_read_only():
    s = good()
    with pytest.raises(Exception):
        s.outputs["z"] = lambda x: x[0]
    with pytest.raises(Exception):
        s.states = ("q",)


def test_a_domain_too_wide_for_float64_is_refused_by_the_api_too():
    """The file loaders refused ``[-1e308, 1e308]``; the Python API sampled inf and blamed the
    model (issue 40): one line naming the box, as the loaders say."""
    with pytest.raises(uj.ModelError, match=r"domain of 'x' \[-1e\+308, 1e\+308\] is too wide"):
        uj.System(states=("x",), outputs={"y": lambda x: x[0]}, domain={"x": (-1e308, 1e308)})


@pytest.mark.parametrize("kwargs, words", [
    (dict(states=("1x",), outputs={"y": lambda x: x[0]}), "state name '1x' is not a valid name"),
    (dict(states=("x y",), outputs={"y": lambda x: x[0]}), "state name 'x y' is not a valid name"),
    (dict(states=("x",), params=("2k",), outputs={"y": lambda x, p: x[0]}), "parameter name '2k' is not a valid"),
])
def test_the_api_refuses_the_names_model_files_refuse(kwargs, words):
    """State and parameter names the file loaders refuse are refused by ``System`` too (issue
    40); a keyword such as the HIV model's ``lambda`` stays a name, an output any key."""
    with pytest.raises(uj.ModelError, match=words):
        uj.System(**kwargs)
    uj.System(states=("lambda",), outputs={"y": lambda x: x[0]})


def test_a_renamed_system_is_a_new_system_built_with_the_same_parts():
    """``with_name`` (what the loaders use for an unnamed model) builds a new System: the
    original keeps its name; the translations of its functions, its parameters' joint System
    and its time's autonomous System come along renamed, nothing traced or validated again."""
    s = uj.System(states=("x", "v"), outputs={"y": lambda x, p, t: x[0] + t * p[0]},
                  drift=lambda x, p, t: jnp.array([x[1], -p[0] * x[0]]), params=("k",), time="t",
                  symmetries={"none": lambda x, p, t: jnp.zeros(3)})
    r = s.with_name("spring")
    assert (s.name, r.name) == ("", "spring") and r is not s and s.with_name("") is s
    for a, b in ((s.joint(), r.joint()), (s.autonomous(), r.autonomous())):
        assert b.name == "spring" and b is not a
        assert b.expression_graph is a.expression_graph  # the translations, not redone
        assert (b.known_coordinates, b.time_name, b.joint_param_names, b.known_outputs) == (
            a.known_coordinates, a.time_name, a.joint_param_names, a.known_outputs)
        assert b.symmetry_fields.keys() == a.symmetry_fields.keys()
    assert r.autonomous().known_coordinates == 1 and r.autonomous().joint_param_names == ("k",)
    assert r.autonomous().symmetry_fields.keys() == {"none"} and not r.joint().symmetry_fields
    assert r.derivation.same_functions_as is None  # not kept once built
    with pytest.raises(uj.ModelError, match="name must be a string"):
        s.with_name(3)
    with pytest.raises(uj.ModelError, match="derivation must be a Derivation"):
        uj.System(states=("x",), outputs={"y": lambda x: x[0]}, derivation={"known_coordinates": 1})
