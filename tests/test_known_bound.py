"""The EORC's early stop at the known-input bound (``uio_jax._analysis.recursions.known_bound``)."""

import jax.numpy as jnp
import pytest
from conftest import zoo

import uio_jax as uj
from uio_jax._analysis.recursions.driver import StopReason
from uio_jax._analysis.recursions.eorc import run_eorc
from uio_jax._analysis.recursions.known_bound import known_input_bound

SAMPLES = 256


def _chain():
    """``y = x1``, ``x1' = x1 x2``, ``x2' = w`` (unknown), ``x3' = x1 u`` (known, switchable).

    By hand: ``Omega-bar_0 = {dx1}``; ``L_F0 x1 = x1 x2`` gives ``dx2``; ``L_F0 (x1 x2) =
    x1 x2^2 + x1 w`` gives ``dw`` at order 2. With w measured the observation space is
    spanned by ``x1, x1 x2`` (``L_g (x1 x2) = x1``), so ``r = 2`` (the output series closes
    at order 2): ``x3`` appears in no output nor field,
    a translation symmetry. At k = 2 every unknown input is observable and ``dim_2 = 2 = r``:
    the EORC stops there; with ``k_max`` given it runs on, to the same verdicts, and each
    derivative ``w^(d)`` turns observable at order ``2 + d``."""
    return uj.System(
        states=("x1", "x2", "x3"), outputs={"y": lambda x: x[0]},
        drift=lambda x: jnp.array([x[0] * x[1], 0.0, 0.0]),
        unknown={"w": lambda x: jnp.array([0.0, 1.0, 0.0])},
        known={"u": lambda x: jnp.array([0.0, 0.0, x[0]])}, name="chain")


def test_the_eorc_stops_at_the_known_input_bound():
    rep = uj.analyze(_chain(), samples=SAMPLES)
    assert rep.method == "eorc"
    assert rep.dims == (1, 2, 2)
    assert StopReason.KNOWN_BOUND.matches(rep.stop_reason)
    assert StopReason.parse(rep.stop_reason).values == (("bound", 2), ("k", 2))
    assert rep.observable == {"x1": True, "x2": True, "x3": False}
    bound = rep.details["known_input_bound"]
    assert {k: bound[k] for k in ("dim", "series_order", "reached_at")} == \
        {"dim": 2, "series_order": 2, "reached_at": 2}
    assert bound["settled_beyond_float64"] >= 1  # the closing order's rejections, at least
    assert rep.details["inputs_observable_at"] == {"w": 2}
    # x3 is not observable even with w measured: the verdicts are exact
    assert rep.exact and rep.answer_kind().startswith("exact (EORC at the known-input bound")
    assert any("x3: not observable even with every input known" in n for n in rep.notes)
    assert not any("sufficient condition only" in n for n in rep.notes)


def test_a_given_k_max_runs_every_order_to_the_same_verdicts():
    stopped = uj.analyze(_chain(), samples=SAMPLES)
    full = uj.analyze(_chain(), samples=SAMPLES, k_max=6)
    assert StopReason.K_MAX.matches(full.stop_reason) and full.details["known_input_bound"] is None
    assert full.dims == (1, 2, 2, 2, 2, 2, 2)  # never above r = 2
    assert full.observable == stopped.observable and not full.exact
    # each derivative of the observable input at the next order (the module's lemma)
    assert full.details["inputs_observable_at"] == {"w": 2, "w^(1)": 3, "w^(2)": 4, "w^(3)": 5,
                                                   "w^(4)": 6}


def test_no_early_stop_while_an_unknown_input_is_unobservable():
    """``x1' = w1 + w2`` with ``y = x1``: only the sum ``w1 + w2`` is observable, never w1
    or w2: the bound is not even computed and the EORC runs to ``k_max = n + 2``."""
    system = uj.System(
        states=("x1", "x2"), outputs={"y": lambda x: x[0]},
        drift=lambda x: jnp.array([0.0, x[0]]),
        unknown={"w1": lambda x: jnp.array([1.0, 0.0]), "w2": lambda x: jnp.array([1.0, 0.0])},
        known={"u": lambda x: jnp.array([0.0, 1.0])})
    rep = uj.analyze(system, samples=SAMPLES)
    assert rep.method == "eorc" and StopReason.K_MAX.matches(rep.stop_reason)
    assert rep.details["known_input_bound"] is None
    assert "w1" not in rep.details["inputs_observable_at"]


def test_no_bound_with_known_coordinates():
    """Time in the model (a known coordinate): no sound bound is claimed (None)."""
    system = uj.System(
        states=("x1", "x2"), outputs={"y": lambda x, t: x[0]},
        drift=lambda x, t: jnp.array([x[1] * t, 0.0]),
        unknown={"w": lambda x, t: jnp.array([0.0, 1.0])}, time="t")
    auto = system.autonomous()
    assert known_input_bound(auto, samples=64, seed=0, rtol=1e-8) is None
    assert known_input_bound(_chain(), samples=64, seed=0, rtol=1e-8).dim == 2


@pytest.mark.slow
@pytest.mark.parametrize("spec", ["visual_inertial.py:gyro_z_unknown",
                                  "visual_inertial_partial.py:calibrated_one_acc"])
def test_the_early_stop_changes_no_verdict_of_a_deep_eorc(spec):
    """The full run to ``k_max = n + 2`` never exceeds the bound, reaches it at the order
    of the early stop, and gives the stopped run's verdicts (states and inputs)."""
    system = uj.load_system(zoo(spec))
    stopped = uj.analyze(system, samples=SAMPLES, method="eorc")
    assert StopReason.KNOWN_BOUND.matches(stopped.stop_reason)
    k, r = stopped.details["k"], stopped.details["known_input_bound"]["dim"]
    run, history, reason, _ = run_eorc(system, samples=SAMPLES, seed=0, rtol=1e-8, early_stop=False)
    assert reason.reason is StopReason.K_MAX
    assert all(st.dim <= r for st in history) and history[k].dim == history[-1].dim == r
    assert set(history[-1].extra["observable_states"]) == {s for s, v in stopped.observable.items() if v}
    seen = set(history[k].extra["observable_inputs"])
    assert seen == set(stopped.history[-1].extra["observable_inputs"])
    # each derivative w_j^(d) observable at order k + d (the module's lemma), to the end
    for d in range(len(history) - k):
        names = run.names[d * run.mw:(d + 1) * run.mw]
        assert set(names) <= set(history[k + d].extra["observable_inputs"])
