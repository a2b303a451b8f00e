"""EORC (004 sections 4-6, 001 Algorithm 1): published numbers, hand-derived cases, and the
cross-check against the single-unknown-input analysis (Theorem 1 of 004: ``dim`` on the
original state at order k equals ``dim Omega_k``)."""

import importlib.util
import json
import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import ROOT, zoo
from helpers import zoo_report

import uio_jax as uj
from uio_jax._analysis.decisions.rank import default_rtol

SAMPLES = 512  # compile time dominates; the rank decisions have gaps of > 6 decades


def _module(name):
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "systems", f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _observable(rep):
    return sorted(s for s, v in rep.observable.items() if v)


# ------------------------------------------------------------------ GPS (004 section 11.2.1)
def test_gps_both_inputs_unknown_full_at_k1():
    pub = _module("gps").PUBLISHED["inputs_unknown"]
    rep = uj.analyze(uj.load_system(zoo("gps.py:inputs_unknown")), samples=SAMPLES, method="eorc")
    assert rep.method == "eorc" and not rep.exact  # sufficient only, even when it shows all
    assert rep.fully_observable and rep.dim == pub["dim"] == 3
    assert list(rep.dims) == pub["dims"]
    assert rep.details["k"] == pub["k"] == 1
    assert rep.details["augmented_ranks"] == pub["augmented_ranks"]  # 4 generators at k = 1
    assert len(rep.generators) == 4
    # Omega-bar_1^perp = span{e_omega}: v is observable, omega is not (004 section 11.2.1)
    assert rep.history[1].extra["observable_inputs"] == ("v",)
    assert rep.details["inputs_observable_at"] == {"v": 1}
    assert rep.unobservable_directions(np.array([0.1, 0.2, 0.3])).shape == (3, 0)
    assert not any("sufficient" in n for n in rep.notes)


def test_gps_both_inputs_known_orc():
    pub = _module("gps").PUBLISHED["inputs_known"]
    rep = uj.analyze(uj.load_system(zoo("gps.py:inputs_known")), samples=SAMPLES)
    assert rep.method == "orc"
    assert list(rep.dims) == pub["dims"] and rep.fully_observable


# ------------------------------------------------------------------ drift and counterexample
def test_drift_example_x2_unobservable():
    sys_ = uj.load_system(zoo("counterexamples.py:drift_example"))
    rep = uj.analyze(sys_, samples=SAMPLES, k_max=4, method="eorc")
    assert rep.method == "eorc"
    assert rep.observable == {"x1": True, "x2": False}
    assert rep.dims == (1, 1, 1, 1, 1) and rep.details["k"] == 4
    # Omega-bar_k = span{dx1, d(x2 + w), dw^(1), .., dw^(k-1)} (hand derivation)
    assert rep.details["augmented_ranks"] == [1, 2, 3, 4, 5]
    assert rep.details["observable_inputs"][4] == ["w^(1)", "w^(2)", "w^(3)"]
    assert any("sufficient condition only" in n and "k=4" in n for n in rep.notes)
    d = rep.unobservable_directions(np.array([0.3, -0.7]))
    assert d.shape == (2, 1)
    np.testing.assert_allclose(np.abs(d[:, 0]), [0.0, 1.0], atol=1e-12)
    assert rep.is_observable(lambda x: x[0] ** 2)
    assert not rep.is_observable(lambda x: x[1])
    json.dumps(rep.to_dict())
    assert "k=4" in str(rep)


def test_single_ui_stop_rule_counterexample_dim2_at_k2():
    pub = _module("counterexamples").PUBLISHED["single_ui_stop_rule"]
    rep = uj.analyze(uj.load_system(zoo("counterexamples.py:single_ui_stop_rule")),
                     method="eorc", samples=SAMPLES, k_max=2)
    assert list(rep.dims) == pub["dims"] == [1, 1, 2]
    assert _observable(rep) == pub["observable"]
    assert rep.history[2].extra["augmented_rank"] == 4


def test_default_k_max_is_n_plus_2():
    rep = uj.analyze(uj.load_system(zoo("counterexamples.py:drift_example")), samples=64,
                     method="eorc")
    assert rep.details["k_max"] == 2 + 2 and rep.details["k"] == 4


# ------------------------------------------------------------------ children in the graph
def test_children_gradients_equal_dense_jacobian_of_the_children():
    """The gradients of an order's children (``L_F0`` powers and ``L_{F_i}`` words, in the
    expression graph) against ``jacfwd`` of the children built by nested jvp, row for row:
    several generators (a power, a mixed word, an output), the drift and two known fields."""
    from uio_jax._analysis.recursions.eorc import _Eorc

    y_, z_ = (lambda s: s[0] * s[1]), (lambda s: jnp.sin(s[2]))
    u1 = lambda s: jnp.array([1.0, s[2], 0.0])  # noqa: E731
    u2 = lambda s: jnp.array([0.0, jnp.cos(s[0]), s[1] ** 2])  # noqa: E731
    gw = lambda s: jnp.array([0.0, 0.0, s[0]])  # noqa: E731
    f0 = lambda s: jnp.array([s[1], -s[0] * s[2], 0.5 * s[1]])  # noqa: E731
    sys_ = uj.System(("a", "b", "c"), {"y": y_, "z": z_}, known={"u1": u1, "u2": u2}, unknown={"w": gw}, drift=f0)
    run = _Eorc(sys_, 2, 16, 0, default_rtol())
    y, z = run.ctx.output_nodes()
    up, mixed, _ = run.children(y)  # L_F0 y (a power) and L_u1 y (a mixed word)
    assert (up.label, mixed.label) == ("L_F0 y", "L_u1 y")
    frontier = [up, mixed, z]
    _, _, got = run.dispatch(frontier, 2)
    ext = run.ext  # X = [a, b, c, w, w']: F0 = [f0 + g w; w'; 0], the known fields padded
    lie = lambda p, v: lambda x: jax.jvp(p, (x,), (v(x),))[1]  # noqa: E731
    F0 = lambda X: jnp.concatenate([f0(X[:3]) + gw(X[:3]) * X[3], X[4:5], jnp.zeros(1)])  # noqa: E731
    fields = [F0] + [lambda X, f=f: jnp.concatenate([f(X[:3]), jnp.zeros(2)]) for f in (u1, u2)]
    Y, Zo = (lambda X: y_(X[:3])), (lambda X: z_(X[:3]))
    base = [lie(Y, F0), lie(Y, fields[1]), Zo]
    children = [lie(p, v) for p in base for v in fields]
    with jax.enable_x64(True):
        xs = jnp.asarray(run.ctx.xs)
        # compiled once: the nested jvp's of the oracle dispatched op by op took most of the time
        want = np.asarray(jax.jit(jax.vmap(jax.jacfwd(lambda x: jnp.stack([c(x) for c in children]))))(xs))
    assert got.shape == (16, 3 * 3, ext.n)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


# ------------------------------------------------------------------ single_ui cross-check
_SINGLE = [(f, name) for f in ("unicycle_polar", "unicycle_disturbance", "vehicle_wind")
           for name, pub in _module(f).PUBLISHED.items() if pub["method"] == "single_ui"]
_FAST = {("unicycle_polar", n) for n in ("range_omega_unknown", "bearing_omega_unknown",
                                         "phi_omega_unknown", "range_v_unknown")}
_FAST |= {("unicycle_disturbance", "gamma_known_range"), ("unicycle_disturbance", "gamma_unknown_phi")}
#: L_g h = 0: the paper's Omega_1 = span{dh, dL_f h} (11.1.2, 11.1.6) -> compare final dims.
_OFFSET = {"range_omega_unknown", "phi_omega_unknown"}


@pytest.mark.parametrize(
    "case", [pytest.param(c, id=f"{c[0]}:{c[1]}",
                          marks=() if c in _FAST else pytest.mark.slow) for c in _SINGLE])
def test_eorc_agrees_with_single_ui(case):
    fname, name = case
    pub = _module(fname).PUBLISHED[name]
    sys_ = uj.load_system(zoo(f"{fname}.py:{name}"))
    rep = uj.analyze(sys_, method="eorc", samples=SAMPLES, k_max=4)
    assert _observable(rep) == sorted(pub["observable"])
    assert rep.dim == pub["dim"]
    if "dims" in pub and name not in _OFFSET:
        want = list(pub["dims"]) + [pub["dims"][-1]] * 8
        assert list(rep.dims) == want[: len(rep.dims)]
    single = zoo_report(fname, name)  # the report test_single_ui checks (cached, 1024 samples)
    assert single.method == "single_ui"
    assert _observable(rep) == _observable(single)
    assert rep.dim == single.dim
    if name not in _OFFSET:
        want = list(single.dims) + [single.dims[-1]] * 8
        assert list(rep.dims) == want[: len(rep.dims)]


# ------------------------------------------------------------------ vehicle in wind (slow)
@pytest.mark.slow
def test_vehicle_wind_eorc_yaw_symmetry():
    mod = _module("vehicle_wind")
    rep = uj.analyze(mod.wind_unknown(), method="eorc", samples=1024, k_max=4)
    assert list(rep.dims) == [3, 5, 6, 6, 6]
    assert _observable(rep) == ["z"]
    x = np.array([0.9, 1.1, 0.8, 1.0, 0.2, -0.1, 0.3])
    d = rep.unobservable_directions(x)[:, 0]
    yaw = np.asarray(mod.yaw_symmetry(x))
    assert abs(d @ yaw) / np.linalg.norm(yaw) == pytest.approx(1.0, abs=1e-8)


# ------------------------------------------------------------------ visual-inertial (slow)
@pytest.mark.slow
def test_visual_inertial_standard_and_gyro_missing():
    mod = _module("visual_inertial")
    pub = mod.PUBLISHED["full_imu"]
    full = uj.analyze(mod.full_imu(), samples=512)
    assert full.method == "orc" and full.dim == pub["dim"] == 12
    assert _observable(full) == sorted(pub["observable"])
    x = np.array([0.1, 0.2, 0.3, 0.2, -0.1, 0.3, 1.0, 0.1, -0.2, 0.2, 0.3, -0.2, 3.0,
                  -0.4, 0.5, 2.5])
    d = full.unobservable_directions(x)
    yaw = np.asarray(mod.yaw_symmetry(x))
    assert np.linalg.norm(d @ (d.T @ yaw)) / np.linalg.norm(yaw) == pytest.approx(1.0, abs=1e-8)
    rep = uj.analyze(mod.gyro_z_unknown(), samples=512, k_max=2)
    assert rep.method == "eorc"  # auto: a drift
    assert rep.dim == 12 and _observable(rep) == _observable(full)
