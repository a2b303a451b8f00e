"""The small models of the new-user tests (issue 40) and their fixtures (a pytest plugin of
``tests/conftest.py``: shared by ``test_new_user.py`` and ``test_new_user_more.py``)."""

import textwrap

import pytest

TOY = """
import jax.numpy as jnp
import uio_jax as uj

def _system():
    return uj.System(("x",), {"y": lambda x: x[0]}, drift=lambda x: -2.0 * x)

def toy_experiment():
    return uj.Experiment(name="toy", system=_system(), dt=0.05, n_steps=20, x0=(1.0,),
                         inputs=lambda s, z: (s, jnp.zeros(0), jnp.zeros(0)), istate0=(),
                         n_input_normals=0, known_std=lambda u: jnp.zeros(0),
                         measurements=(uj.Measurement("y", lambda x: x[0], 0.1, 1),),
                         prior_std=(5.0,), units={"x": "m"})
"""

TOML = """
name = "two states"
states = ["a", "b"]
[outputs]
y = "a"
[drift]
a = "b"
b = "0"
"""


@pytest.fixture
def toy(tmp_path):
    """``FILE.py:toy``: a one-state Monte Carlo experiment written to a temporary file."""
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY))
    return f"{path}:toy"


@pytest.fixture
def toml_model(tmp_path):
    """A two-state TOML model written to a temporary file (its path)."""
    path = tmp_path / "m.toml"
    path.write_text(textwrap.dedent(TOML))
    return str(path)
