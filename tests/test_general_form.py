"""System.from_dynamics: the general form x' = f(x, u, w) for Python callables.

The split and the promotions must be those of the model files (same code, same notes):
each model here is also written as a TOML file and the two Systems are compared.
"""

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj


def toml(tmp_path, text, name="m.toml"):
    p = tmp_path / name
    p.write_text(text)
    return uj.load_system(str(p))


def same_report(a, b):
    ra, rb = uj.analyze(a, samples=128), uj.analyze(b, samples=128)
    assert ra.method == rb.method
    assert ra.dim == rb.dim
    assert ra.observable == rb.observable
    assert [s.dim for s in ra.history] == [s.dim for s in rb.history]
    return ra


def test_affine_model_gives_the_report_of_the_equivalent_system():
    gen = uj.System.from_dynamics(
        ("px", "py", "th"),
        lambda x, u, w: jnp.array([w[0] * jnp.cos(x[2]), w[0] * jnp.sin(x[2]), u[0]]),
        {"px": lambda x, u, w: x[0], "py": lambda x, u, w: x[1]},
        known=("om",), unknown=("v",), angles=("th",))
    ref = uj.System(
        ("px", "py", "th"), {"px": lambda x: x[0], "py": lambda x: x[1]},
        known={"om": lambda x: jnp.array([0.0, 0.0, 1.0])},
        unknown={"v": lambda x: jnp.array([jnp.cos(x[2]), jnp.sin(x[2]), 0.0])}, angles=("th",))
    assert gen.states == ref.states and tuple(gen.known) == ("om",) and tuple(gen.unknown) == ("v",)
    assert gen.drift is None and gen.notes == ()
    x = jnp.array([0.7, 1.1, 0.3])
    np.testing.assert_allclose(gen.unknown["v"](x), ref.unknown["v"](x), rtol=1e-15)
    rep = same_report(gen, ref)
    assert rep.method == "single_ui"


@pytest.mark.slow
def test_affine_model_with_params_and_drift_matches_the_system():
    gen = uj.System.from_dynamics(
        ("x1", "x2"),
        lambda x, p, u, w: jnp.array([-p[0] * x[0] + x[1], -x[1] + u[0] * x[0] + w[0]]),
        {"y": lambda x, p, u, w: x[0]}, known=("u",), unknown=("w",), params={"k": (1.0, 2.0)})
    ref = uj.System(
        ("x1", "x2"), {"y": lambda x, p: x[0]},
        known={"u": lambda x, p: jnp.array([0.0, x[0]])},
        unknown={"w": lambda x, p: jnp.array([0.0, 1.0])},
        drift=lambda x, p: jnp.array([-p[0] * x[0] + x[1], -x[1]]), params={"k": (1.0, 2.0)})
    assert gen.drift is not None and gen.param_names == ("k",)
    rep = same_report(gen, ref)
    assert rep.identifiable == {"k": True}


PROMOTE_TOML = """
states = ["x1", "x2"]
[outputs]
y = "x1 + w1"
[inputs]
known = ["u", "unused"]
unknown = ["w1", "w2"]
[dynamics]
x1 = "x2 + w2**2"
x2 = "-x1 + u*x2"
"""


def test_promotions_and_notes_are_those_of_the_toml_loader(tmp_path):
    gen = uj.System.from_dynamics(
        ("x1", "x2"),
        lambda x, u, w: jnp.array([x[1] + w[1] ** 2, -x[0] + u[0] * x[1]]),
        {"y": lambda x, u, w: x[0] + w[0]}, known=("u", "unused"), unknown=("w1", "w2"))
    ref = toml(tmp_path, PROMOTE_TOML)
    assert gen.notes == ref.notes
    assert any("'w1' appears in an output: promoted" in t for t in gen.notes)
    assert any("'w2' enters the dynamics non-affinely" in t for t in gen.notes)
    assert any("'unused' appears in no equation: dropped" in t for t in gen.notes)
    assert gen.states == ref.states == ("x1", "x2", "w1", "w2")
    assert tuple(gen.known) == tuple(ref.known) and tuple(gen.unknown) == tuple(ref.unknown)
    assert tuple(gen.outputs) == tuple(ref.outputs)
    z = jnp.array([0.7, 1.2, 0.9, 1.3])
    for k in ref.fields():
        np.testing.assert_allclose(gen.fields()[k](z), ref.fields()[k](z), rtol=1e-14)
    for k in ref.outputs:
        np.testing.assert_allclose(gen.outputs[k](z), ref.outputs[k](z), rtol=1e-14)


@pytest.mark.slow
def test_promoted_model_gives_the_report_of_the_toml_model(tmp_path):
    gen = uj.System.from_dynamics(
        ("x1", "x2"),
        lambda x, u, w: jnp.array([x[1] + w[1] ** 2, -x[0] + u[0] * x[1]]),
        {"y": lambda x, u, w: x[0] + w[0]}, known=("u", "unused"), unknown=("w1", "w2"))
    same_report(gen, toml(tmp_path, PROMOTE_TOML))


def test_cross_term_and_known_input_in_output_match_the_toml_loader(tmp_path):
    text = """
states = ["x"]
[outputs]
y = "x + c"
[inputs]
known = ["a", "c"]
unknown = ["w"]
[dynamics]
x = "a*w - x + c"
"""
    gen = uj.System.from_dynamics(
        ("x",), lambda x, u, w: jnp.array([u[0] * w[0] - x[0] + u[1]]),
        {"y": lambda x, u, w: x[0] + u[1]}, known=("a", "c"), unknown=("w",))
    ref = toml(tmp_path, text)
    assert gen.notes == ref.notes
    assert any("multiplies input 'a'" in t for t in gen.notes)
    assert gen.states == ref.states and tuple(gen.outputs) == tuple(ref.outputs)


def test_input_not_affine_between_zero_and_its_box_is_promoted():
    # |w| is affine on a box that excludes 0 (and its split there is exact); not on (-1, 1)
    def f(x, u, w):
        return jnp.array([-x[0] + jnp.abs(w[0])])

    pos = uj.System.from_dynamics(("x",), f, {"y": lambda x, u, w: x[0]}, unknown=("w",))
    assert pos.states == ("x",) and pos.notes == ()
    both = uj.System.from_dynamics(("x",), f, {"y": lambda x, u, w: x[0]}, unknown=("w",),
                                   domain={"w": (-1.0, 1.0)})
    assert both.states == ("x", "w")
    assert "'w' is not affine between 0 and its box" in both.notes[0]
    assert both.domain["w"] == (-1.0, 1.0)


@pytest.mark.parametrize("kw, message", [
    (dict(dynamics=lambda x, u, w: jnp.array([x[0] + 1j * w[0]])), "dynamics returns a complex value"),
    (dict(outputs={"y": lambda x, u, w: x[0] + 0j}), "output 'y' returns a complex value"),
    (dict(dynamics=lambda x, u, w: jnp.array([x[0], x[0]])), "dynamics returns shape (2,)"),
    (dict(dynamics=lambda x, u, w: jnp.array([w[3]])), "dynamics indexes outside"),
    (dict(dynamics=lambda x: x), "dynamics fails on (x, u, w)"),
    (dict(unknown=("x",)), "unknown input 'x' has the name of a state"),
    (dict(unknown=("w", "w")), "'w' is listed twice"),
    (dict(domain={"q": (0, 1)}), "neither a state nor an input"),
    (dict(dynamics=lambda x, u, w: jnp.array([jnp.log(-x[0] - w[0])])), "not finite at any of 32"),
])
def test_bad_general_models_are_refused_with_one_line(kw, message):
    args = dict(states=("x",), dynamics=lambda x, u, w: jnp.array([-x[0] + w[0]]),
                outputs={"y": lambda x, u, w: x[0]}, unknown=("w",))
    args.update(kw)
    with pytest.raises(uj.ModelError) as err:
        uj.System.from_dynamics(**args)
    assert message in str(err.value)
    assert "\n" not in str(err.value)
