"""The generic-input series test (``method="series"``): the ORC's verdict from output Taylor
coefficients, and where its per-order dims differ from the ORC's steps."""

import functools

import jax.numpy as jnp
import pytest
from helpers import zoo_path, zoo_report

import uio_jax as uj
from uio_jax import cli
from uio_jax._analysis.recursions.driver import StopReason

SAMPLES = 512


def _verdict(rep):
    return rep.dim, dict(rep.observable), dict(rep.identifiable)


@pytest.mark.parametrize("module,name", [
    ("unicycle_polar", "range_known"),
    ("unicycle_polar", "bearing_known"),
    ("unicycle_polar", "phi_known"),
    ("gps", "inputs_known"),
    ("unicycle_disturbance", "no_disturbance_bearing"),
    pytest.param("vehicle_wind", "no_wind", marks=pytest.mark.slow),  # 24 s: compile of a 7-state series
])
def test_series_gives_the_orc_verdict_on_the_zoo(module, name):
    orc = zoo_report(module, name)
    assert orc.method == "orc"
    series = uj.analyze(uj.load_system(f"{zoo_path(module)}:{name}"), method="series", samples=SAMPLES)
    assert series.method == "series"
    assert _verdict(series) == _verdict(orc)
    assert series.certificate.fraction > 0.9


def test_model_file_with_parameters_and_a_known_input():
    system = uj.load_system(zoo_path("two_compartment").replace(".py", ".toml"))
    orc = uj.analyze(system, samples=SAMPLES)
    series = uj.analyze(system, method="series", samples=SAMPLES)
    assert _verdict(series) == _verdict(orc)


def _oscillator():
    """x1' = x2, x2' = -k x1 - c x2, y = x1, parameters k, c: drift only."""
    return uj.System(
        states=("x1", "x2"),
        outputs={"y": lambda x, p: x[0]},
        drift=lambda x, p: jnp.stack([x[1], -p[0] * x[0] - p[1] * x[1]]),
        params={"k": (0.5, 2.0), "c": (0.1, 1.0)},
    )


def test_drift_only_orders_equal_the_orc_steps():
    """One field: the span of dy_0..dy_K is the span of dh, dL_f h, .., dL_f^K h, so per-order
    dims equal the ORC's per-step dims (1, 2, 3, 4: x1, x2, k, c all recovered)."""
    orc = uj.analyze(_oscillator(), samples=SAMPLES)
    series = uj.analyze(_oscillator(), method="series", samples=SAMPLES)
    assert orc.dims == series.dims == (1, 2, 3, 4)
    assert series.fully_observable and orc.fully_observable


def test_input_derivatives_reach_later_than_the_orc_steps():
    """x1' = x2 + u x3, x2' = x3' = 0, y = x1. ORC step 1 holds L_f0 h = x2 and L_u h = x3
    apart (dim 3); the series at order 1 holds only y_1 = x2 + u(0) x3 (dim 2), and x3 comes
    with u'(0) at order 2. Same final span."""
    system = uj.System(
        states=("x1", "x2", "x3"),
        outputs={"y": lambda x: x[0]},
        drift=lambda x: jnp.stack([x[1], 0.0 * x[0], 0.0 * x[0]]),
        known={"u": lambda x: jnp.stack([x[2], 0.0 * x[0], 0.0 * x[0]])},
    )
    orc = uj.analyze(system, samples=SAMPLES)
    series = uj.analyze(system, method="series", samples=SAMPLES)
    assert orc.dims == (1, 3)
    assert series.dims == (1, 2, 3)
    assert _verdict(series) == _verdict(orc)


def test_unobservable_span_closes_and_stops():
    """CR-like scaling symmetry: the first order that adds nothing ends the test."""
    system = uj.System(
        states=("x",),
        outputs={"y": lambda x, p: p[0] * x[0]},
        drift=lambda x, p: -p[1] * x,
        params={"s": (0.5, 2.0), "k": (0.5, 2.0)},
    )
    rep = uj.analyze(system, method="series", samples=SAMPLES)
    assert rep.dim == 2 and not any(rep.observable.values()) and rep.identifiable == {"s": False, "k": True}
    assert StopReason.SPAN_CLOSED.matches(rep.stop_reason)
    assert rep.unobservable_directions([1.0, 1.0, 1.0]).shape == (3, 1)


def test_fast_uses_series_only_when_every_input_is_known():
    known = uj.load_system(f"{zoo_path('unicycle_polar')}:range_known")
    unknown = uj.load_system(f"{zoo_path('unicycle_polar')}:range_v_unknown")
    assert uj.analyze(known, method="fast", samples=64).method == "series"
    rep = uj.analyze(unknown, method="fast", samples=64)
    assert rep.method == "single_ui" and any(n.startswith("fast:") for n in rep.notes)


def test_series_refuses_unknown_inputs(capsys):
    unknown = uj.load_system(f"{zoo_path('unicycle_polar')}:range_v_unknown")
    with pytest.raises(uj.OptionError, match="needs every input known"):
        uj.analyze(unknown, method="series")
    assert cli.main(["analyze", f"{zoo_path('unicycle_polar')}:range_v_unknown", "--method", "series"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "needs every input known" in err[0]


def test_seed_reproducible_and_orders_capped():
    a = uj.analyze(_oscillator(), method="series", samples=64, seed=3)
    b = uj.analyze(_oscillator(), method="series", samples=64, seed=3)
    assert a.dims == b.dims and a.certificate == b.certificate
    capped = uj.analyze(_oscillator(), method="series", samples=64, max_order=1)
    assert capped.dims == (1, 2)
    assert capped.stop_reason == StopReason.MAX_ORDER.stop(max_order=1).message


@functools.cache
def _late_chain():
    """y1 = x1, y2 = x2 with x1' = x3 + u x2, x3' = x4, x4' = -x1, x2' = 0: rank 2, 3, 4 at
    orders 0, 1, 2, more than the ceil(n / p) = 2 orders that could reach rank 4. One System
    object, so the tests below share its compiled programs."""
    return uj.System(
        states=("x1", "x2", "x3", "x4"),
        outputs={"y1": lambda x: x[0], "y2": lambda x: x[1]},
        drift=lambda x: jnp.stack([x[2], 0.0 * x[0], x[3], -x[0]]),
        known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0], 0.0 * x[0], 0.0 * x[0]])},
    )

