"""The coefficient-recurrence flow (``uio_jax._engine.taylor_flow``) against the stacked passes and autodiff."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from uio_jax._engine.interpreter import NoTaylorRule
from uio_jax._engine.taylor import flow_series
from uio_jax._engine.taylor_flow import flow_coefficients


def _field(x):
    """Every kind of rule: mul, div, sin, cos, tan, exp, log, sqrt, rsqrt, integer and real
    powers, negative powers, dot products with and without constants, where, abs, max, the
    recipes of ELEMENTARY (atan2, tanh), clamp, reduce_max, rem."""
    A = jnp.array([[1.0, 2.0, -1.0], [0.5, 0.0, 3.0]])
    a = A @ x
    return jnp.stack([
        jnp.sin(x[1]) * x[2] + jnp.cos(a[0]) - jnp.tan(0.3 * x[0]),
        jnp.exp(-x[0]) + x[2] ** 2 + jnp.log(x[2]) * x[0] ** -2 + jnp.dot(x, x),
        jnp.sqrt(x[0]) / (1.0 + x[1] ** 3) + x[1] ** 1.7 + jax.lax.rsqrt(x[2])
        + jnp.where(x[0] > 0, x[1] * x[0], 0.0) + jnp.abs(x[2]) + jnp.maximum(x[0], 0.2) + x[0] ** x[1]
        + jnp.arctan2(x[1], x[0]) * jnp.tanh(x[2]) + jnp.clip(x[1], 0.0, 2.0) + jnp.max(x) + jnp.mod(x[0], 0.5),
    ])


@pytest.mark.parametrize("K", [1, 2, pytest.param(3, marks=pytest.mark.slow)])
def test_recurrence_equals_stacked_passes(K):
    """Values and Jacobians equal flow_series (K full stacked passes) to round-off."""
    x = jnp.array([0.7, 1.1, 0.9])

    @jax.jit
    def both(z):
        def f(fn):
            return fn(_field, z, K), jax.jacfwd(lambda y: fn(_field, y, K))(z)
        return f(flow_series), f(flow_coefficients)

    (a, ja), (b, jb) = both(x)
    np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-13 * float(jnp.max(jnp.abs(a))))
    np.testing.assert_allclose(jb, ja, rtol=1e-11, atol=1e-12 * float(jnp.max(jnp.abs(ja))))


def test_recurrence_equals_nested_derivatives():
    """x^(k)(0) / k! from the recurrence = nested jvp of the flow's Lie derivatives (oracle)."""
    x = jnp.array([0.8, 1.3, 0.6])
    K = 4
    got = jax.jit(lambda z: flow_coefficients(_field, z, K))(x)

    @jax.jit
    def nested(z):  # x^(k) = L_F^(k-1) F: d/dt of g(x(t)) is jvp(g, x, F(x))
        g, want = _field, []
        for k in range(1, K + 1):
            want.append(g(z) / math.factorial(k))
            g = (lambda g: lambda y: jax.jvp(g, (y,), (_field(y),))[1])(g)
        return jnp.stack(want)

    np.testing.assert_allclose(got, nested(x), rtol=1e-10)


def test_known_series_enters_as_given_coefficients():
    """A known input u(t) = sum a_k t^k given as a stack equals the time-augmented field."""
    u = jnp.array([[0.3], [1.2], [-0.5], [0.8], [0.1], [0.2]])
    K = 5

    def G(x, u):
        return jnp.stack([x[1] * u[0], -jnp.sin(x[0]) + u[0] * u[0] / (1.0 + x[1] ** 2)])

    def G_time(z):  # z = [x; t], u by Horner in t
        t, uu = z[2], u[K, 0]
        for j in range(K - 1, -1, -1):
            uu = uu * t + u[j, 0]
        return jnp.concatenate([G(z[:2], jnp.array([uu])), jnp.ones(1)])

    got = jax.jit(lambda x: flow_coefficients(G, x, K, known=(u,)))(jnp.array([1.0, 0.5]))
    want = jax.jit(lambda z: flow_series(G_time, z, K))(jnp.array([1.0, 0.5, 0.0]))[:, :2]
    np.testing.assert_allclose(got, want, rtol=1e-13, atol=1e-15)


def test_operation_without_a_rule_is_named():
    lgamma = jax.scipy.special.gammaln
    with pytest.raises(NoTaylorRule, match="lgamma"):
        flow_coefficients(lambda x: lgamma(2.0 + x), jnp.array([0.3, 0.4]), 3)
    with pytest.raises(NoTaylorRule, match="lgamma"):  # inside a call too
        flow_coefficients(jax.jit(lambda x: lgamma(2.0 + x)), jnp.array([0.3, 0.4]), 3)


def _field_with_parameters(z):
    """States z[0:3] move, z[3:6] are parameters (derivative padded with zeros, as
    System.joint does); parameters enter through slices, a gather, a concatenation, a
    real power (constant exponent, and constant base too), products and a quotient."""
    x, p = z[:3], z[3:]
    v = jnp.concatenate([x, p])  # the model-file parser rebuilds one vector like this
    gathered = p[jnp.array([2, 0])]
    dx = jnp.stack([
        p[0] * x[1] - v[4] * x[0] / (p[1] + x[0]),
        v[3] * x[0] ** p[2] / (p[2] ** p[0] + x[2] ** p[2]) - gathered[0] * x[1] * x[2],
        jnp.sin(p[1] * x[0]) + gathered[1] * x[2] ** 2 - p[2] * p[0],
    ])
    return jnp.concatenate([dx, jnp.zeros(3)])


def test_parameters_are_constants_of_the_recurrence():
    """States with a structurally zero derivative are found, and treating them as constants
    (fewer carried stacks: products with them are linear) gives the same values and
    Jacobians as the recurrence without that knowledge and as the stacked passes."""
    from uio_jax._engine.taylor_flow import constant_states

    z = jnp.array([0.7, 1.1, 0.9, 1.3, 0.6, 1.7])
    np.testing.assert_array_equal(constant_states(_field_with_parameters, z), [0, 0, 0, 1, 1, 1])
    K = 3

    def run(constants):
        fn = lambda y: flow_coefficients(_field_with_parameters, y, K, constants=constants)  # noqa: E731
        return jax.jit(lambda y: (fn(y), jax.jacfwd(fn)(y)))(z), jax.make_jaxpr(fn)(z)

    (a, ja), full = run(False)
    (b, jb), lean = run(True)
    c = jax.jit(lambda y: flow_series(_field_with_parameters, y, K))(z)
    np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-14)
    np.testing.assert_allclose(jb, ja, rtol=1e-12, atol=1e-13 * float(jnp.max(jnp.abs(ja))))
    np.testing.assert_allclose(b, c, rtol=1e-12, atol=1e-13)
    assert np.all(np.asarray(b)[:, 3:] == 0)
    # the loop carries one stack per nonlinear result of a moving quantity only
    carried = [e.params["num_carry"] for j in (full, lean)
               for e in j.jaxpr.eqns if e.primitive.name == "scan"]  # fori_loop, static bounds
    assert carried[1] < carried[0], carried
