"""Structural Jacobian patterns (``uio_jax._filter.sparsity``).

Oracle: the Jacobian by ``jax.jacfwd`` at random points (a pattern must cover every
non-zero it finds, and is exact for element-wise model code).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import zoo

from uio_jax._filter.ekf import make_model
from uio_jax._filter.sparsity import jacobian_pattern, structural_zeros
from uio_jax._io.loading import load_module


def _numeric_pattern(fn, q, points=6, seed=0):
    """Where the Jacobian is non-zero at any of ``points`` random points."""
    xs = jnp.asarray(np.random.default_rng(seed).normal(size=(points, q)))
    return np.any(np.asarray(jax.jit(jax.vmap(jax.jacfwd(fn)))(xs)) != 0, axis=0)


def test_pattern_of_element_wise_code_is_exact():
    def fn(x):
        v = jnp.stack([jnp.cos(x[2]) * x[3], jnp.sin(x[2]), 0.0 * x[1]])
        pad = jnp.concatenate([v, jnp.zeros(2)])
        return pad * x[4] + jnp.array([0.0, 0.0, 0.0, 1.0, 0.0]) * x[0]

    pat = jacobian_pattern(fn, np.zeros(5))
    expected = np.zeros((5, 5), bool)
    expected[0, [2, 3, 4]] = True
    expected[1, [2, 4]] = True
    expected[3, 0] = True         # the constant's 1.0 entry times x[0]; its zeros vanish
    np.testing.assert_array_equal(pat, expected)
    np.testing.assert_array_equal(pat, _numeric_pattern(fn, 5))
    # elements 2 (0 * x[1]) and 4 (a zero pad times x[4], plus a zero entry times x[0])
    # are zero whatever x; element 3 is not (the 1.0 entry), nor are 0 and 1
    np.testing.assert_array_equal(structural_zeros(fn, np.zeros(5)), [0, 0, 1, 0, 1])


def test_pattern_falls_back_to_dense_for_matrix_products():
    A = np.arange(9.0).reshape(3, 3)

    def fn(x):
        return jnp.concatenate([A @ x[:3], x[3:] ** 2])

    pat = jacobian_pattern(fn, np.zeros(5))
    assert pat[:3, :3].all()                      # dot_general: every operand element
    np.testing.assert_array_equal(pat[3:], np.eye(5, dtype=bool)[3:])
    assert np.all(pat >= _numeric_pattern(fn, 5))


def test_pattern_through_broadcasts_of_size_one_axes():
    def fn(x):
        b = jnp.broadcast_to(x[1:2], (3,))           # (1,) -> (3,)
        return b * jnp.stack([x[0], 1.0 + 0.0 * x[0], x[2]])

    pat = jacobian_pattern(fn, np.zeros(3))
    np.testing.assert_array_equal(pat, [[1, 1, 0], [0, 1, 0], [0, 1, 1]])
    np.testing.assert_array_equal(pat, _numeric_pattern(fn, 3))


def test_loops_are_not_read_as_calls():
    """A carry mixes the elements over the iterations: one pass through the body would miss
    dependences, so a loop depends on everything its operands depend on."""
    def fn(x):
        def body(c, _):
            return jnp.stack([c[1], c[2], c[0]]), None

        out, _ = jax.lax.scan(body, x, None, length=2)
        return out

    pat = jacobian_pattern(fn, np.zeros(3))
    assert np.all(pat >= _numeric_pattern(fn, 3))
    assert pat.all()


def test_an_unreadable_jaxpr_gives_the_dense_pattern(monkeypatch):
    from uio_jax._filter import sparsity as _sparsity

    def broken(*args):
        raise ValueError("a rule that fails")

    monkeypatch.setitem(_sparsity._RULES, "mul", broken)
    assert jacobian_pattern(lambda x: x * 2.0, np.zeros(3)).all()


def test_pattern_through_nested_jit_and_where():
    @jax.jit
    def inner(x):
        return jnp.where(x[0] > 0, x[1], -x[1])

    def fn(x):
        return jnp.stack([inner(x), x[2] * 0.0, jnp.tanh(x[0])])

    pat = jacobian_pattern(fn, np.zeros(3))
    assert pat[0, 1] and not pat[0, 2]
    assert not pat[1].any()
    np.testing.assert_array_equal(pat[2], [True, False, False])
    assert np.all(pat >= _numeric_pattern(fn, 3))


@pytest.mark.parametrize("path, name", [
    ("unicycle_disturbance.py", "range_gamma_known_experiment"),
    ("unicycle_disturbance.py", "range_gamma_unknown_experiment"),
    ("vehicle_wind.py", "wind_unknown_experiment"),
    ("vehicle_wind.py", "no_wind_experiment"),
])
def test_zoo_patterns_cover_the_jacobian(path, name):
    exp = getattr(load_module(zoo(path)), name)()
    model = make_model(exp)
    n, p, m = model.n, model.p, len(exp.system.known)
    flow = lambda z: model.dynamics(z[:n], z[n + p:], z[n:n + p])  # noqa: E731
    numeric = _numeric_pattern(flow, n + p + m)[:, :n + p]
    np.testing.assert_array_equal(model.pattern, numeric)   # exact on these models
    assert not model.pattern.all()                           # and the zeros are there
