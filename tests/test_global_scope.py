"""``uj.analyze(system, scope="global")``, ``uio-jax analyze --global`` and ``batch --global``:
the global answer beside the local one, in the report, its text and its JSON (issue 46 item 1).
The engine's own answers are tested in ``tests/test_global.py``."""

import json

import jax.numpy as jnp
import pytest

import uio_jax as uj
from uio_jax import cli

MODEL = ('name = "square"\nstates = ["x"]\n[params]\na = [0.5, 1.5]\nb = [0.5, 1.5]\n[outputs]\ny = "x"\n'
         '[dynamics]\nx = "-(a**2 + 0*b)*x"\n')


def _square():
    """``x' = -a^2 x``, ``y = x``: ``a`` takes two values (``a -> -a``), ``x`` one."""
    return uj.System(states=("x",), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([-(p[0] ** 2) * x[0]]),
                     params={"a": (0.5, 1.5)}, domain={"x": (0.5, 1.5)}, name="square")


def test_the_report_carries_the_global_answer():
    rep = uj.analyze(_square(), samples=64, scope="global")
    assert rep.identifiable["a"] is True  # locally identifiable ...
    assert rep.global_identifiability["a"] is uj.GlobalVerdict.LOCAL and rep.value_counts["a"] == 2  # ... twice
    assert rep.global_identifiability["x"] is uj.GlobalVerdict.GLOBAL
    d = json.loads(rep.to_json())
    assert d["global"]["global_identifiability"] == {"x": "global", "a": "local"}
    assert "a  local  (2 values)" in str(rep) and "a -> -a" in str(rep)


def test_at_a_known_initial_state_too():
    rep = uj.analyze(_square(), initial={"x": 1.0}, scope="global")
    assert isinstance(rep, uj.IdentifiabilityReport) and rep.value_counts["a"] == 2
    assert "global" in rep.to_dict() and "a  local" in str(rep)


def test_not_asked_is_refused_in_one_line():
    rep = uj.analyze(_square(), samples=64)
    with pytest.raises(uj.ModelError, match="the global question was not asked") as err:
        rep.global_identifiability
    assert "\n" not in str(err.value) and "global" not in rep.to_dict()


@pytest.mark.parametrize("kwargs, match", [
    ({"scope": "everywhere"}, "unknown scope 'everywhere'"),
    ({"scope": "global", "global_timeout": -1}, "timeout must be a positive number"),
])
def test_bad_options(kwargs, match):
    with pytest.raises(uj.OptionError, match=match):
        uj.analyze(_square(), **kwargs)


def test_unknown_inputs_are_refused_before_any_work():
    system = uj.System(states=("x",), outputs={"y": lambda x: x[0]},
                       unknown={"w": lambda x: jnp.stack([1.0 + 0 * x[0]])}, drift=lambda x: jnp.stack([-x[0]]))
    with pytest.raises(uj.OptionError, match="unknown input"):
        uj.analyze(system, scope="global")


def test_cli_and_batch(tmp_path, capsys):
    model = tmp_path / "square.toml"
    model.write_text(MODEL)
    out_json = tmp_path / "r.json"
    assert cli.main(["analyze", str(model), "--global", "--samples", "64", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "observable codistribution" in out and "a  local  (2 values)" in out
    assert json.loads(out_json.read_text())["global"]["global_identifiability"]["b"] == "not"
    assert cli.main(["analyze", str(model), "--global-timeout", "5"]) == 2
    assert "--global-timeout applies with --global" in capsys.readouterr().err
    assert cli.main(["batch", str(model), "--global", "--samples", "64"]) == 0
    out = capsys.readouterr().out
    assert "global" in out.splitlines()[0] and "a: local (2 values)" in out and "b: not" in out


def test_named_functions_get_their_global_mark():
    """``x' = -a b x``: the named functions are ``x`` and ``a*b``, both global; with ``x' = -a^2 x``
    the parameter ``a`` itself is named and takes two values."""
    product = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]},
                        drift=lambda x, p: jnp.stack([-(p[0] * p[1]) * x[0]]),
                        params={"a": (0.5, 1.5), "b": (0.5, 1.5)}, domain={"x": (0.5, 1.5)}, name="ab")
    rep = uj.analyze(product, samples=64, scope="global")
    marks = {f.text: f.globally for f in uj.observable_functions(rep).functions}
    assert marks == {"x": "global", "a*b": "global"}
    assert "a*b   (globally: global)" in str(rep)
    rep = uj.analyze(_square(), samples=64, scope="global")
    assert {f.text: f.globally for f in uj.observable_functions(rep).functions} == {"x": "global", "a": "local"}
    plain = uj.analyze(product, samples=64)
    assert all(f.globally is None for f in uj.observable_functions(plain).functions)
