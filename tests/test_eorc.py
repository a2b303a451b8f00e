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
from uio_jax._analysis import memory
from uio_jax._analysis.eorc import extended_system
from uio_jax._analysis.rank import default_rtol
from uio_jax._calculus import blocks as _blocks
from uio_jax._calculus.powers import jet_power, lie_power, nested_power, power_mode
from uio_jax._engine.taylor import lie_powers

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


# ------------------------------------------------------------------ Taylor mode
def test_lie_power_matches_nested_jvp():
    sys_ = uj.load_system(zoo("unicycle_polar.py:range_v_unknown"))
    ext = extended_system(sys_, 4)
    h, F0 = ext.outputs["r"], ext.drift
    xs = jax.random.uniform(jax.random.key(1), (16, ext.n), minval=0.5, maxval=1.5)
    for j in (1, 2):
        b = jax.jit(jax.vmap(jax.grad(nested_power(h, F0, j))))(xs)
        for power in (jet_power, lie_power):  # jet, and the policy (Taylor here)
            a = jax.jit(jax.vmap(jax.grad(power(h, F0, j))))(xs)
            np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-11)  # round-off only


def test_taylor_rules_match_nested_jvp():
    """Stacked Taylor arithmetic (div, sin, cos, tan, exp, log, sqrt, powers, dot, where)
    against nested jvp, values and gradients of L_F^j psi for j <= 4 (oracle: autodiff)."""

    def F(x):
        return jnp.stack([jnp.sin(x[1]) * x[2], jnp.exp(-x[0]) + x[2] ** 2,
                          jnp.sqrt(x[0]) / (1.0 + x[1] ** 2)])

    def psi(x):
        a = jnp.array([[1.0, 2.0, -1.0], [0.5, 0.0, 3.0]]) @ x
        return jnp.log(x[0]) * jnp.cos(a[0]) + jnp.tan(0.3 * x[2]) / x[1] ** 3 + jnp.where(
            x[0] > 0, a[1] ** 2, 0.0)

    xs = jax.random.uniform(jax.random.key(2), (8, 3), minval=0.5, maxval=1.5)
    for j in (1, 3):
        a = jax.jit(jax.vmap(jax.jacfwd(lambda x: lie_powers(psi, F, j)(x)[j])))(xs)
        b = jax.jit(jax.vmap(jax.jacfwd(nested_power(psi, F, j))))(xs)
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * float(jnp.max(jnp.abs(b))))


def test_gradient_block_equals_dense_jacobian_of_the_children():
    """``ChildBlocks.block`` (Hessian-vector products, the fields pulled back once for every
    generator) against ``jacfwd`` of the children built by nested jvp, row for row: several
    generators (a power, a mixed word, an output), the drift and two known fields."""
    from uio_jax._analysis.eorc import _Eorc
    from uio_jax._calculus.lie import lie_derivative

    sys_ = uj.System(
        ("a", "b", "c"), {"y": lambda s: s[0] * s[1], "z": lambda s: jnp.sin(s[2])},
        known={"u1": lambda s: jnp.array([1.0, s[2], 0.0]),
               "u2": lambda s: jnp.array([0.0, jnp.cos(s[0]), s[1] ** 2])},
        unknown={"w": lambda s: jnp.array([0.0, 0.0, s[0]])},
        drift=lambda s: jnp.array([s[1], -s[0] * s[2], 0.5 * s[1]]))
    run = _Eorc(sys_, 2, 16, 0, default_rtol())
    y, z = run.ctx.output_nodes()
    up, mixed, _ = run.blocks.children(y)  # L_F0 y (a power) and L_u1 y (a mixed word)
    assert (up.label, mixed.label) == ("L_F0 y", "L_u1 y")
    frontier = [up, mixed, z]
    block = run.blocks.block(frontier)
    fields = [run.ext.drift] + list(run.ext.known.values())
    children = [lie_derivative(p.fn, v) for p in frontier for v in fields]
    with jax.enable_x64(True):
        xs = run.ctx.xs
        got = np.asarray(block(xs))
        want = np.asarray(jax.vmap(jax.jacfwd(lambda x: jnp.stack([c(x) for c in children])))(xs))
    assert got.shape == (16, 3 * 3, run.ext.n)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def _integrator_chain(known=True):
    """x1' = x2, x2' = x3, x3' = w (1 + x1^2), y = x1 x2 + sin x3, z = x1 x3, with or
    without a known field u = (x3, 0, x1^2): drift, an unknown input and a known field
    whose children are not zero, for the arithmetic of the chain program."""
    return uj.System(
        ("x1", "x2", "x3"), {"y": lambda s: s[0] * s[1] + jnp.sin(s[2]), "z": lambda s: s[0] * s[2]},
        known={"u": lambda s: jnp.array([s[2], 0.0, s[0] ** 2])} if known else {},
        unknown={"w": lambda s: jnp.array([0.0, 0.0, 1.0 + s[0] ** 2])},
        drift=lambda s: jnp.array([s[1], s[2], 0.0]))


@pytest.mark.parametrize("known", [True, False], ids=["known field", "drift only"])
def test_chain_block_equals_the_blocks_of_its_orders(known):
    """``ChildBlocks.chain_block`` (one Taylor pass per generator, the Jacobian of m powers,
    their Hessian-vector products) row for row against ``block`` of each order's frontier,
    for a frontier of two generators: ``(L_F0 y, z)``, then ``(L_F0^2 y, L_F0 z)``, ..."""
    from uio_jax._analysis.eorc import _Eorc

    run = _Eorc(_integrator_chain(known), 5, 16, 0, default_rtol())
    y, z = run.ctx.output_nodes()
    frontiers = [(run.blocks.children(y)[0], z)]
    for _ in range(2):
        frontiers.append(run.blocks.drift_children(frontiers[-1]))
    assert [p.label for p in frontiers[2]] == ["L_F0^3 y", "L_F0^2 z"]
    with jax.enable_x64(True):
        xs = run.ctx.xs
        got = np.asarray(run.blocks.chain_block(frontiers[0], 3)(xs))
        want = np.stack([np.asarray(run.blocks.block(f)(xs)) for f in frontiers], 1)
    assert got.shape == (16, 3, 2 * (2 if known else 1), run.ext.n)
    np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_chain_serves_later_orders_and_is_dropped_when_the_frontier_changes(monkeypatch):
    """(The compiled route, ``UIO_JAX_ENGINE=xla``: the gradient blocks are XLA programs.)
    The frontier of order 2 is the drift child of order 1's one generator: one chain
    program covers orders 2..5 (K = 6, at most CHAIN_ORDERS = 4 orders). Order 3 with its
    assumed frontier takes row 1; another frontier at order 3 drops the chain and gets a
    block of its own (same gradients as ``block``)."""
    from uio_jax._analysis.eorc import _Eorc

    monkeypatch.setenv("UIO_JAX_ENGINE", "xla")
    assert _blocks.CHAIN_ORDERS == 4
    run = _Eorc(_integrator_chain(), 6, 16, 0, default_rtol())
    y = run.ctx.output_nodes()[0]
    up = run.blocks.children(y)[0]
    assert run.dispatch([y], 1)[5] is None and run.stream.chain is None  # nothing repeated yet
    first = run.dispatch([up], 2)
    assert first[5] == 0 and run.stream.chain["m"] == 4
    up2, mixed = run.blocks.children(up)
    served = run.dispatch([up2], 3)
    assert served[5] == 1 and served[2] == 0.0  # no compile
    with jax.enable_x64(True):
        xs = run.ctx.xs
        np.testing.assert_allclose(np.asarray(served[4]), np.asarray(run.blocks.block([up2])(xs)),
                                   rtol=1e-10, atol=1e-12)
        own = run.dispatch([mixed], 3)
        assert own[5] is None and run.stream.chain is None
        np.testing.assert_allclose(np.asarray(own[4]), np.asarray(run.blocks.block([mixed])(xs)),
                                   rtol=1e-10, atol=1e-12)


def test_chain_gives_the_same_report_as_blocks_per_order(monkeypatch):
    """x1' = x2, x2' = x3, x3' = w (1 + x1^2), y = x1 + sin x2, a known field moving only the
    hidden x4: from order 1 on, the EORC keeps the drift child alone (every ``L_u phi`` is
    0), so one chain program serves orders 2..4. Same dims, ranks, observable states and
    inputs as with a block per order. (The compiled route, ``UIO_JAX_ENGINE=xla``.)"""
    monkeypatch.setenv("UIO_JAX_ENGINE", "xla")
    def hidden_chain():
        return uj.System(
            ("x1", "x2", "x3", "x4"), {"y": lambda s: s[0] + jnp.sin(s[1])},
            known={"u": lambda s: jnp.array([0.0, 0.0, 0.0, s[3]])},
            unknown={"w": lambda s: jnp.array([0.0, 0.0, 1.0 + s[0] ** 2, 0.0])},
            drift=lambda s: jnp.array([s[1], s[2], 0.0, 0.0]))

    chains = []
    real = _blocks.ChildBlocks.chain_block
    monkeypatch.setattr(_blocks.ChildBlocks, "chain_block",
                        lambda self, phis, m, batch=None:
                        chains.append((tuple(p.label for p in phis), m))
                        or real(self, phis, m, batch))
    with_chain = uj.analyze(hidden_chain(), method="eorc", samples=SAMPLES, k_max=4)
    assert chains == [(("L_F0 y",), 3)]
    monkeypatch.setattr(_blocks.Stream, "chain_length", lambda self, frontier, k: 0)
    per_order = uj.analyze(hidden_chain(), method="eorc", samples=SAMPLES, k_max=4)
    # By hand: every x1(t) is reachable (x1''' = (1 + x1^2) w), and y = x1 + sin(x1')
    # leaves x1(0) free (x1' = arcsin(y - x1) from any start), so only y and
    # L_F0 y = x2 + x3 cos x2 are observable functions: dim 2 from k = 1 on, no state alone.
    assert list(with_chain.dims) == list(per_order.dims) == [1] + [2] * 4
    assert with_chain.observable == per_order.observable == {s: False for s in ("x1", "x2", "x3", "x4")}
    for a, b in zip(with_chain.history, per_order.history):
        assert a.added == b.added and a.extra == b.extra


def test_fallback_without_jet_rule():
    """A primitive without a Taylor rule (erf_inv) falls back (jet, then nested jvp)."""
    sys_ = uj.System(("x", "a"), {"y": lambda s: jax.scipy.special.erfinv(0.3 * s[0])},
                     unknown={"w": lambda s: jnp.array([s[1], 0.0])})
    rep = uj.analyze(sys_, method="eorc", samples=64, k_max=2)
    assert rep.observable == {"x": True, "a": False}
    ext = extended_system(sys_, 2)
    with jax.enable_x64(True):
        like = jax.ShapeDtypeStruct((ext.n,), jnp.float64)
        assert power_mode(ext.outputs["y"], ext.drift, like) in ("jet", "nested")
        assert power_mode(lambda s: s[0] * s[1], ext.drift, like) == "taylor"


def test_power_policy_falls_back_only_for_a_missing_rule():
    """A bug in a model (here a shape error) is an error, not a slower way: the policy
    falls back only when a primitive has no rule."""

    def psi(x):
        return x[0] * jnp.ones(3) @ jnp.ones(2)  # (3,) @ (2,): a TypeError

    F = lambda x: x  # noqa: E731
    with jax.enable_x64(True), pytest.raises(TypeError):
        jax.eval_shape(lie_power(psi, F, 2), jax.ShapeDtypeStruct((2,), jnp.float64))
    with jax.enable_x64(True):  # below taylor_from: nested jvp, no choice to make
        fn = lie_power(lambda x: x[0] ** 3, F, 2, taylor_from=3)
        np.testing.assert_allclose(fn(jnp.array([2.0, 1.0])), 9.0 * 2.0 ** 3)  # L_F x0^3 = 3 x0^3


def test_streamed_blocks_give_the_same_report(monkeypatch):
    """Blocks over the samples in batches (after a block measured STREAM_ELEMENTS) answer
    as the blocks over all samples at once; here every block after order 1 is streamed.
    (The compiled route, ``UIO_JAX_ENGINE=xla``, every sample deciding.)"""
    monkeypatch.setenv("UIO_JAX_ENGINE", "xla")
    monkeypatch.setattr(memory, "DECISION_SAMPLES", 10**6)
    case = "unicycle_disturbance.py:gamma_known_range"
    plain = uj.analyze(uj.load_system(zoo(case)), method="eorc", samples=SAMPLES, k_max=3)
    batches = []

    def recording(fn, batch=None):
        batches.append(batch)
        return real_vmapped(fn, batch)

    real_vmapped = _blocks.vmapped
    monkeypatch.setattr(_blocks, "STREAM_ELEMENTS", 0.0)
    monkeypatch.setattr(_blocks, "vmapped", recording)
    streamed = uj.analyze(uj.load_system(zoo(case)), method="eorc", samples=SAMPLES, k_max=3)
    assert batches[0] is None and set(batches[1:]) == {_blocks.STREAM_BATCH}
    assert len(batches) == len(streamed.dims) - 1
    assert list(streamed.dims) == list(plain.dims)
    assert streamed.observable == plain.observable
    assert [s.extra["augmented_rank"] for s in streamed.history] == \
        [s.extra["augmented_rank"] for s in plain.history]


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
