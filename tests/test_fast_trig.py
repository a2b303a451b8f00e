"""Vectorizable float64 sin / cos (``uio_jax._filter.fast_trig``) against mpmath at 40 digits."""

import jax
import jax.numpy as jnp
import mpmath
import numpy as np
import pytest

from uio_jax._filter.fast_trig import ACCURATE_BELOW, cos, sin, with_vectorized_trig


def _ulps(got, exact):
    """Error in units of the last place of the exact value."""
    return np.abs(got - exact) / np.spacing(np.abs(exact))


@pytest.mark.parametrize("span, ulps", [(1.0, 1), (8.0, 1), (1e3, 1), (0.999 * ACCURATE_BELOW, 2)])
def test_within_one_or_two_ulp_of_the_exact_values(span, ulps):
    """1 ulp up to 1e3 rad (as libm), 2 ulp up to 2^19 pi."""
    rng = np.random.default_rng(3)
    x = rng.uniform(-span, span, 400)
    # quadrant boundaries and multiples of pi/2 are the hard cases of the reduction
    x = np.concatenate([x, np.arange(-40, 41) * (np.pi / 2), np.arange(-40, 41) * (np.pi / 4),
                        [0.0, 1e-300, -1e-12, 5e-9]])
    x = x[np.abs(x) <= span]
    with mpmath.workdps(40):
        want_s = np.array([float(mpmath.sin(mpmath.mpf(float(v)))) for v in x])
        want_c = np.array([float(mpmath.cos(mpmath.mpf(float(v)))) for v in x])
    with jax.enable_x64(True):
        got_s = np.asarray(jax.jit(sin)(jnp.asarray(x)))
        got_c = np.asarray(jax.jit(cos)(jnp.asarray(x)))
    nz_s, nz_c = want_s != 0, want_c != 0
    assert _ulps(got_s[nz_s], want_s[nz_s]).max() <= ulps
    assert _ulps(got_c[nz_c], want_c[nz_c]).max() <= ulps


def test_derivatives_are_the_functions_own():
    with jax.enable_x64(True):
        x = jnp.linspace(-7.0, 7.0, 101)
        t = jnp.ones_like(x)
        _, ds = jax.jvp(sin, (x,), (t,))
        _, dc = jax.jvp(cos, (x,), (t,))
        np.testing.assert_allclose(ds, np.cos(np.asarray(x)), rtol=0, atol=2e-16)
        np.testing.assert_allclose(dc, -np.sin(np.asarray(x)), rtol=0, atol=2e-16)
        np.testing.assert_allclose(jax.vmap(jax.grad(jax.grad(sin)))(x), -np.sin(np.asarray(x)), atol=2e-16)


def test_beyond_the_accurate_range_the_values_stay_bounded():
    with jax.enable_x64(True):
        x = jnp.array([1e7, -3e12, 1e300, -1e308])
        for f in (sin, cos):
            y = np.asarray(f(x))
            assert np.isfinite(y).all() and np.abs(y).max() <= 1.0 + 1e-3


def test_a_model_function_gets_the_fast_kernels_and_the_same_values():
    @jax.jit
    def heading(x):  # inside a jit sub-function, next to other operations
        return jnp.stack([jnp.cos(x[2]), jnp.sin(x[2])])

    def field(x):
        return jnp.concatenate([x[0] * heading(x), jnp.tanh(x[1:2]) + jnp.sin(x[0] * x[1])])

    fast = with_vectorized_trig(field)
    with jax.enable_x64(True):
        xs = jax.random.uniform(jax.random.key(0), (64, 3), minval=-4.0, maxval=4.0)
        np.testing.assert_allclose(jax.vmap(fast)(xs), jax.vmap(field)(xs), rtol=3e-16, atol=3e-16)
        np.testing.assert_allclose(jax.vmap(jax.jacfwd(fast))(xs), jax.vmap(jax.jacfwd(field))(xs),
                                   rtol=1e-15, atol=1e-15)
        text = str(jax.make_jaxpr(fast)(xs[0]))
    assert " sin " not in text and " cos " not in text and "tanh" in text


def test_float32_operands_keep_the_library_functions():
    fast = with_vectorized_trig(lambda x: jnp.sin(x))
    text = str(jax.make_jaxpr(fast)(jnp.ones(3, jnp.float32)))
    assert " sin " in text


def _count(jaxpr, name):
    """Equations of primitive ``name`` in a jaxpr and its sub-jaxprs."""
    total = 0
    for eqn in jaxpr.eqns:
        total += eqn.primitive.name == name
        for value in eqn.params.values():
            sub = getattr(value, "jaxpr", value)
            if hasattr(sub, "eqns"):
                total += _count(sub, name)
    return total


def test_sin_and_cos_of_one_angle_share_one_reduction():
    """``cos(x[2])`` and ``sin(x[2])`` slice ``x`` twice: the repeated slice is recognised,
    so the angle is reduced once (one ``round``), and the values are unchanged."""
    def field(x):
        return jnp.stack([jnp.cos(x[2]), jnp.sin(x[2]), jnp.cos(x[0]), x[2] * x[2], x[2] * x[2]])

    fast = with_vectorized_trig(field)
    with jax.enable_x64(True):
        x = jnp.array([0.3, -1.0, 2.5])
        jaxpr = jax.make_jaxpr(fast)(x).jaxpr
        np.testing.assert_allclose(fast(x), field(x), rtol=3e-16, atol=0)
    assert _count(jaxpr, "round") == 2  # x[2] and x[0]
    assert _count(jaxpr, "integer_pow") + _count(jaxpr, "mul") > 0
    assert _count(jaxpr, "slice") == 2


def test_trig_of_constants_is_evaluated_once_on_the_host():
    """``cos(gamma)`` of a constant angle stages no reduction, and keeps its value."""
    def field(x):
        g = 0.7 * np.pi
        return jnp.stack([jnp.cos(g) * x[0], jnp.sin(g) * x[1]])

    fast = with_vectorized_trig(field)
    with jax.enable_x64(True):
        x = jnp.array([2.0, 3.0])
        jaxpr = jax.make_jaxpr(fast)(x).jaxpr
        np.testing.assert_array_equal(fast(x), [np.cos(0.7 * np.pi) * 2.0, np.sin(0.7 * np.pi) * 3.0])
    assert _count(jaxpr, "round") == 0
