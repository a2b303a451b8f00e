"""Unknown constant parameters: identifiability as observability of ``[x; p]`` with ``p' = 0``."""

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj

S = 256


def two_compartment():
    """x1' = -(k1 + k2) x1 + k3 x2 + b u, x2' = k2 x1 - k3 x2, y = x1 (StrikePy's C2M).

    Transfer function Y/U = b (s + k3) / (s^2 + (k1 + k2 + k3) s + k1 k3): its four
    coefficients give b, k3, then k1 and k2, so every parameter is identifiable and, with
    them, both initial conditions are observable.
    """
    return uj.System(
        states=("x1", "x2"),
        outputs={"y": lambda x, p: x[0]},
        known={"u": lambda x, p: jnp.stack([p[3], 0.0 * p[3]])},
        drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0] + p[2] * x[1], p[1] * x[0] - p[2] * x[1]]),
        params={"k1": (0.5, 1.5), "k2": (0.5, 1.5), "k3": (0.5, 1.5), "b": (0.5, 1.5)},
        name="two_compartment",
    )


def sum_only():
    """x' = -(a + b) x, y = x: only a + b is identifiable (direction (0, 1, -1))."""
    return uj.System(states=("x",), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0]]), params=("a", "b"))


def test_two_compartment_fully_identifiable():
    rep = uj.analyze(two_compartment(), samples=S)
    assert rep.method == "orc"
    assert rep.states == ("x1", "x2") and rep.params == ("k1", "k2", "k3", "b")
    assert rep.n == 6 and rep.dim == 6
    assert dict(rep.observable) == {"x1": True, "x2": True}
    assert dict(rep.identifiable) == {"k1": True, "k2": True, "k3": True, "b": True}
    assert rep.fully_observable
    text = str(rep)
    assert "parameters:" in text and "k3  identifiable" in text


def test_sum_of_rates_not_identifiable():
    rep = uj.analyze(sum_only(), samples=S)
    assert rep.dim == 2 and rep.n == 3
    assert dict(rep.observable) == {"x": True}
    assert dict(rep.identifiable) == {"a": False, "b": False}
    assert not rep.fully_observable
    assert rep.is_observable(lambda z: z[1] + z[2])
    assert not rep.is_observable(lambda z: z[1])
    d = rep.unobservable_directions(np.array([1.0, 0.7, 1.2]))
    assert d.shape == (3, 1)
    np.testing.assert_allclose(np.abs(d[:, 0]), np.array([0.0, 1.0, 1.0]) / np.sqrt(2), atol=1e-10)
    out = rep.to_dict()
    assert out["params"] == ["a", "b"] and out["identifiable"] == {"a": False, "b": False}
    assert out["states"] == ["x"]


def _with_param(system, scale_field):
    """``system`` with a parameter c scaling the field ``scale_field``, two ways."""
    n = system.n
    fields = dict(system.unknown) | dict(system.known)

    def scaled(fn):
        return lambda x, p: p[0] * fn(x)

    def plain(fn):
        return lambda x, p: fn(x)

    def wrap(d):
        return {k: (scaled(f) if k == scale_field else plain(f)) for k, f in d.items()}

    with_params = uj.System(
        system.states, {k: plain(h) for k, h in system.outputs.items()},
        known=wrap(system.known), unknown=wrap(system.unknown),
        drift=None if system.drift is None else plain(system.drift),
        domain=dict(system.domain), angles=system.angles, params={"c": (0.5, 1.5)})

    def pad(fn, scale):
        return lambda z: jnp.concatenate([(z[n] if scale else 1.0) * fn(z[:n]), jnp.zeros(1)])

    by_hand = uj.System(
        system.states + ("c",), {k: (lambda z, h=h: h(z[:n])) for k, h in system.outputs.items()},
        known={k: pad(f, k == scale_field) for k, f in system.known.items()},
        unknown={k: pad(f, k == scale_field) for k, f in system.unknown.items()},
        drift=None if system.drift is None else pad(system.drift, False),
        domain={**system.domain, "c": (0.5, 1.5)}, angles=system.angles)
    assert scale_field in fields
    return with_params, by_hand


@pytest.mark.parametrize("spec, field, method", [
    pytest.param("unicycle_polar.py:range_v_unknown", "omega", "single_ui", marks=pytest.mark.slow),
    ("unicycle_polar.py:bearing_omega_unknown", "v", "single_ui"),
    ("counterexamples.py:drift_example", "w", "eorc"),
])
def test_params_equal_states_with_zero_derivative(spec, field, method):
    from conftest import zoo

    system = uj.load_system(zoo(spec))
    with_params, by_hand = _with_param(system, field)
    a = uj.analyze(with_params, samples=S, method=method, k_max=3)
    b = uj.analyze(by_hand, samples=S, method=method, k_max=3)
    assert a.method == b.method == method
    assert a.dims == b.dims and a.dim == b.dim
    assert dict(a.observable) == {s: b.observable[s] for s in system.states}
    assert dict(a.identifiable) == {"c": b.observable["c"]}


def test_sample_singular_values_show_the_gap():
    rep = uj.analyze(two_compartment(), samples=S)
    sv = rep.sample_singular_values()
    assert sv.shape == (rep.certificate.used, rep.dim)
    assert np.all(np.diff(sv, axis=1) <= 1e-12)
    np.testing.assert_allclose(sv[:, 0], 1.0)
    at_rank = (sv[:, -1] > rep.certificate.rtol).mean()
    assert at_rank == pytest.approx(rep.certificate.fraction)
    out = rep.to_dict()  # fully identifiable: the direction keys are there, empty
    assert out["unobservable_directions"] == [] and out["identifiable_combinations"] == []
    assert out["directions_at"]["point"] == {"x1": 1.0, "x2": 1.0, "k1": 1.0, "k2": 1.0, "k3": 1.0, "b": 1.0}


@pytest.mark.parametrize("kwargs, message", [
    ({"params": {"x": (0.0, 1.0)}}, "parameter 'x' has the name of a state"),
    ({"params": {"a": (1.0, 0.0)}}, "box of parameter 'a' is empty"),
    ({"params": {"a": "wide"}}, "must be a pair"),
    ({"params": {"a": (0.0, float("inf"))}}, "must be finite"),
])
def test_bad_params(kwargs, message):
    with pytest.raises(uj.ModelError, match=message):
        uj.System(states=("x",), outputs={"y": lambda x, p: x[0]}, **kwargs)


def test_callables_must_take_x_and_p():
    with pytest.raises(uj.ModelError, match=r"with params, every function takes \(x, p\)"):
        uj.System(states=("x",), outputs={"y": lambda x: x[0]}, params=("a",))
    with pytest.raises(uj.ModelError, match="indexes outside x"):
        uj.System(states=("x",), outputs={"y": lambda x, p: x[0] * p[3]}, params=("a",))


def test_monte_carlo_refuses_params_clearly():
    from uio_jax import Experiment

    with pytest.raises(uj.ModelError, match="does not take a System with params"):
        Experiment(name="e", system=sum_only(), dt=0.1, n_steps=10, x0=(1.0,), inputs=None,
                   istate0=(), n_input_normals=0, known_std=None, measurements=())


@pytest.fixture(scope="module")
def sum_rep():
    return uj.analyze(sum_only(), samples=64)


def test_is_observable_takes_fn_of_x_and_p(sum_rep):
    assert sum_rep.is_observable(lambda x, p: p[0] + p[1])
    assert sum_rep.is_observable(lambda x, p: x[0] * (p[0] + p[1]) ** 2)
    assert not sum_rep.is_observable(lambda x, p: p[0])
    assert sum_rep.is_observable(lambda z: z[1] + z[2])  # fn(z), z = [x; p], still works

    def scaled(z, scale=2.0):  # one required argument: a function of z
        return scale * z[0]

    assert sum_rep.is_observable(scaled)


@pytest.mark.parametrize("fn, message", [
    (lambda x, p, q: p[0], r"fn\(z\) with z = \[x; p\] \(3,\) or fn\(x, p\) with x \(1,\), p \(2,\).*3 required"),
    (lambda: 1.0, "0 required positional arguments"),
    (lambda x, p: x @ p, r"fn\(x, p\) with x \(1,\), p \(2,\) fails \(TypeError: .*\); expected fn\(z\)"),
    (lambda x, p: p[5], "indexes outside its arguments"),
    (lambda x, p: p, r"must return a scalar \(\), got shape \(2,\)"),
])
def test_is_observable_bad_functions_are_one_line(sum_rep, fn, message):
    with pytest.raises(uj.ModelError, match=message) as err:
        sum_rep.is_observable(fn)
    assert "\n" not in str(err.value) and not str(err.value).endswith(": TypeError")


def test_fn_of_x_and_p_needs_parameters():
    from conftest import zoo

    rep = uj.analyze(uj.load_system(zoo("unicycle_polar.py:range_known")), samples=64)
    with pytest.raises(uj.ModelError, match=r"fn\(x\) with x \(3,\) \(this model has no parameters\)"):
        rep.is_observable(lambda x, p: x[0])
    with pytest.raises(uj.ModelError, match="this model has no parameters"):
        rep.unobservable_directions(np.ones(3), np.ones(1))


def test_directions_labelled_with_the_identifiable_sum(sum_rep):
    np.testing.assert_allclose(sum_rep.domain_centre(), [1.0, 1.0, 1.0])
    summary = sum_rep.direction_summary()
    assert summary["point"] == {"x": 1.0, "a": 1.0, "b": 1.0}
    (d,) = summary["directions"]
    assert list(d) == ["x", "a", "b"] and d["x"] == 0.0
    np.testing.assert_allclose([d["a"], d["b"]], np.array([1.0, -1.0]) / np.sqrt(2), atol=1e-10)
    (c,) = summary["identifiable_combinations"]
    assert set(c) == {"a", "b"}
    np.testing.assert_allclose([c["a"], c["b"]], [1.0, 1.0], atol=1e-9)
    text = sum_rep.format_directions(summary)
    assert "+0.707 a  -0.707 b" in text and "da + db" in text
    # (x, p) and z give the same basis
    np.testing.assert_allclose(np.abs(sum_rep.unobservable_directions([1.0], [0.7, 1.2])),
                               np.abs(sum_rep.unobservable_directions([1.0, 0.7, 1.2])), atol=1e-12)
    out = sum_rep.to_dict()
    assert out["unobservable_directions"] == [d]
    assert out["identifiable_combinations"] == [c]
    assert out["directions_at"] == {"rule": "centre of the sampling box of every state and parameter",
                                    "point": {"x": 1.0, "a": 1.0, "b": 1.0}}


def test_weighted_combination_and_a_state_parameter_symmetry():
    weighted = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]},
                         drift=lambda x, p: jnp.stack([-(p[0] + 2.0 * p[1]) * x[0]]),
                         params={"a": (0.5, 1.5), "b": (0.5, 2.5)})
    rep = uj.analyze(weighted, samples=64)
    s = rep.direction_summary()
    assert s["point"] == {"x": 1.0, "a": 1.0, "b": 1.5}
    (d,) = s["directions"]
    np.testing.assert_allclose([d["x"], d["a"], d["b"]], np.array([0.0, 2.0, -1.0]) / np.sqrt(5), atol=1e-10)
    (c,) = s["identifiable_combinations"]
    np.testing.assert_allclose([c["a"], c["b"]], [0.5, 1.0], atol=1e-9)  # d(a + 2 b) / 2
    assert "0.5 da + db" in rep.format_directions(s)
    # y = a x, x' = 0: (x, a) -> (s x, a / s) is hidden, direction (x, -a) at the point
    scale = uj.System(states=("x",), outputs={"y": lambda x, p: p[0] * x[0]},
                      drift=lambda x, p: 0.0 * x, params={"a": (1.0, 3.0)})
    rep = uj.analyze(scale, samples=64)
    assert rep.dim == 1 and rep.n == 2
    s = rep.direction_summary()
    (d,) = s["directions"]
    np.testing.assert_allclose([d["x"], d["a"]], np.array([-1.0, 2.0]) / np.sqrt(5), atol=1e-10)
    assert s["identifiable_combinations"] == []  # one hidden parameter: no combination
    s = rep.direction_summary([0.5], [3.0])
    np.testing.assert_allclose(np.abs([s["directions"][0]["x"], s["directions"][0]["a"]]),
                               np.array([0.5, 3.0]) / np.hypot(0.5, 3.0), atol=1e-10)
