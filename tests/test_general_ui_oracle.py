"""The exact oracle of the general unknown-input solution (``scripts/general_ui_oracle.py``).

The oracle is plain sympy (no ``uio_jax``): exact rational arithmetic at 3 random points for
rational models, 60 digits otherwise. These tests check it against verdicts derived by hand
(``systems/multi_ui.py`` docstrings), against the semantics table of
``docs/general_ui.md`` section 6 (polar unicycle of 004 section 11.1, EORC under both
meanings of known inputs), against the published GPS case (004 section 11.2.1), and against the
exact EORC on random two-UI systems (the EORC is a lower bound of the general solution's answer,
equal to it where the EORC has stabilised). They also check that the zoo's JAX transcriptions of
``systems/multi_ui.py`` equal their sympy twins (``scripts/_sympy_models.py``).
"""

import os
import sys

import jax.numpy as jnp
import numpy as np
import pytest
import sympy as sp
from helpers import ROOT, zoo_module, zoo_system

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import _sympy_models  # noqa: E402
import general_ui_oracle as oracle  # noqa: E402

X1, X2, X3, X4, X5 = sp.symbols("x1 x2 x3 x4 x5", real=True)


def _multi(name):
    return _sympy_models.get(f"systems/multi_ui.py:{name}")


def _names(model, indices):
    return [str(model.states[i]) for i in indices]


# --------------------------------------------------------------------------------------
# The semantics table (note section 6): EORC S1 / S2 per order k = 1..4, general solution (S1)
# --------------------------------------------------------------------------------------

UNICYCLE_TABLE = [
    # case, EORC smooth (S1) k=1..4, EORC switchable (S2) k=1..4, general solution dim
    ("range_v_unknown", [1, 1, 1, 1], [1, 2, 2, 2], 1),        # 11.1.1
    ("range_omega_unknown", [2, 2, 2, 2], [2, 2, 2, 2], 2),    # 11.1.2
    ("bearing_v_unknown", [1, 1, 1, 1], [1, 1, 1, 1], 1),      # 11.1.3
    ("bearing_omega_unknown", [1, 1, 1, 1], [2, 2, 2, 2], 1),  # 11.1.4
    ("phi_v_unknown", [1, 1, 1, 1], [1, 2, 2, 2], 1),          # 11.1.5
    ("phi_omega_unknown", [2, 2, 2, 2], [2, 3, 3, 3], 2),      # 11.1.6
]


@pytest.mark.parametrize("case, smooth, switchable, general", UNICYCLE_TABLE,
                         ids=[c[0] for c in UNICYCLE_TABLE])
def test_unicycle_semantics_table(case, smooth, switchable, general):
    """The polar unicycle (004 section 11.1): the switchable EORC reproduces the seed's
    single-UI answers (2, 2, 1, 2, 2, 3 of 004), the smooth EORC and the general solution
    (smooth known inputs) give the smaller S1 answers of the note's table."""
    model = _sympy_models.get(f"systems/unicycle_polar.py:{case}")
    e1 = oracle.eorc_model(model, k_max=4, known_inputs="smooth")
    e2 = oracle.eorc_model(model, k_max=4, known_inputs="switchable")
    assert e1["dims"][1:] == smooth
    assert e2["dims"][1:] == switchable
    res = oracle.general_ui_model(model)
    assert res["dim"] == general
    assert res["canonic"] and not res["ui_extension"] and not res["exact"]  # trigonometric: 60 digits


def test_known_gain_semantics():
    """``x1' = x2 u, x2' = w, y = x1 + x2``: switchable u shows both states (a jump of u reveals x2
    in y' = u x2 + w), smooth u only x1 + x2 (module docstring of ``systems/multi_ui.py``)."""
    args = ([X1, X2], None, {"u": [X2, 0]}, {"w": [0, 1]}, [X1 + X2])
    assert oracle.eorc(*args, k_max=4, known_inputs="switchable")["dims"] == [1, 2, 2, 2, 2]
    assert oracle.eorc(*args, k_max=4, known_inputs="switchable")["observable"][-1] == [0, 1]
    assert oracle.eorc(*args, k_max=4, known_inputs="smooth")["dims"] == [1, 1, 1, 1, 1]
    res = oracle.general_ui(*args)
    assert (res["dim"], res["observable"], res["exact"]) == (1, [], True)
    assert res["ui_observable"] == [False]


# --------------------------------------------------------------------------------------
# Published and hand-derived verdicts
# --------------------------------------------------------------------------------------

def test_gps_two_unknown_inputs_is_observable():
    """004 section 11.2.1 (published): v and omega unknown, GPS position measured: the whole state
    is observable. Only the v column is reconstructable at first (m = 1), one extension makes
    the system canonic."""
    model = _sympy_models.get("systems/gps.py:inputs_unknown")
    res = oracle.general_ui_model(model)
    assert res["dim"] == 3 and res["observable"] == [0, 1, 2] and res["state_observable"]
    assert not res["initially_canonic"] and res["canonic"] and res["ui_extension"]
    assert res["trace"][0]["m"] == 1 and res["ui_degree"] == 2
    assert res["ui_reconstructable"] == [0, 1] and res["extension_states_observable"]


def test_extension_keeps_the_chain_when_theta_v_depends_on_v():
    """``systems/multi_ui.py:extension_kept`` (derived by hand there): x4 = y1'' / y2', all observable.
    The guarded closure aborts at x4 (root x1, ord 2); theta_v = D^2 x1 = x4 v depends on v^(0):
    v^(0) is kept, v^(1), v^(2) deleted, and m rises from 1 to 2."""
    res = oracle.general_ui_model(_multi("extension_kept"))
    assert res["dim"] == 4 and res["observable"] == [0, 1, 2, 3]
    ext = [s for s in res["trace"] if s["step"] == "ui extension"]
    assert len(ext) == 1
    assert (ext[0]["ord"], ext[0]["root"], ext[0]["chains"], ext[0]["m_raised"]) == (2, X1, {0: 0}, True)
    assert sp.expand(ext[0]["theta_v"] - X4 * ext[0]["states_added"][0]) == 0
    assert len(res["extension_states"]) == 1 and res["extension_states_observable"]
    assert res["ui_observable"] == [True, True]


def test_extension_deletes_the_chain_when_theta_v_has_no_v():
    """``extension_dropped`` (by hand: w2 = y1'' - x4 y2' hides x4): dim 3, x4 unobservable.
    theta_v = x3 has no v, so the chain is deleted and the rescaled w1 field stays a UI."""
    res = oracle.general_ui_model(_multi("extension_dropped"))
    assert res["dim"] == 3 and res["observable"] == [0, 1, 2]
    ext = [s for s in res["trace"] if s["step"] == "ui extension"]
    assert (ext[0]["ord"], ext[0]["theta_v"], ext[0]["chains"], ext[0]["states_added"]) == (1, X3, {0: -1}, [])
    assert res["extension_states"] == [] and res["canonic"] and res["ui_degree"] == 2
    # w1 = y2' is observable, w2 = y1'' - x4 y2' is not (x4 is not)
    assert res["ui_observable"] == [True, False]


def test_extension_keeps_a_longer_chain_and_may_end_non_canonic():
    """``extension_two_kept`` (by hand: x4 = y1'' / y2', x5 = x4', x6 hidden by w2): dim 5 of 6.
    theta_v = D^3 x1 = v x5 + v' x4 keeps v^(0) and v^(1); the guarded closure then ends without
    abort while w3 is still not reconstructable (final m = 2 < 3)."""
    res = oracle.general_ui_model(_multi("extension_two_kept"))
    assert res["dim"] == 5 and res["observable"] == [0, 1, 2, 3, 4]
    ext = [s for s in res["trace"] if s["step"] == "ui extension"]
    assert len(ext) == 1 and (ext[0]["ord"], ext[0]["chains"]) == (3, {0: 1}) and len(ext[0]["states_added"]) == 2
    assert res["trace"][-1]["step"] == "guarded closure, no abort"
    assert not res["canonic"] and res["ui_degree"] == 2 and res["ui_reconstructable"] == [0, 1]
    assert res["extension_states_observable"]
    assert oracle.eorc_model(_multi("extension_two_kept"), k_max=4, known_inputs="smooth")["dims"] == [2, 3, 4, 5, 5]


@pytest.mark.parametrize("name, dim, observable", [
    ("tac2025", 4, ["x1", "x2", "x3"]),
    ("guarded_full_rank", 3, ["x2", "x3"]),
])
def test_full_rank_inside_the_guarded_closure_is_no_certificate(name, dim, observable):
    """Note section 7.1: the guarded closure reaches rank n, its guard still triggers a UI
    extension, and the true answer (derived by hand in ``systems/multi_ui.py``) is smaller."""
    model = _multi(name)
    res = oracle.general_ui_model(model)
    assert res["dim"] == dim and _names(model, res["observable"]) == observable
    abort = [s for s in res["trace"] if s["step"] == "guarded closure, abort"]
    assert len(abort) == 1 and abort[0]["rank_reached"] == model.n
    assert res["ui_extension"] and res["canonic"] and not res["initially_canonic"]
    # the exact EORC (a lower bound) reaches the same dimension
    assert oracle.eorc_model(model, k_max=4, known_inputs="smooth")["dims"][-1] == dim


def test_hiv_reconstructable_but_not_observable_ui():
    """HIV (TUIO6): dim 7 (one free constant, derived in ``systems/multi_ui.py``); V, lambda, rho, c
    observable; eta reconstructable after the m = 0 branch but not observable."""
    model = _multi("hiv")
    res = oracle.general_ui_model(model)
    assert res["dim"] == 7 and _names(model, res["observable"]) == ["V", "lambda", "rho", "c"]
    assert [s["step"] for s in res["trace"]][:3] == ["reconstructability", "guarded closure, abort",
                                                     "filtered closure (m = 0)"]
    assert not res["initially_canonic"] and res["canonic"] and not res["ui_extension"]
    assert res["ui_reconstructable"] == [0] and res["ui_observable"] == [False]


def test_trivial_drift_takes_the_m0_branch():
    """TUIO6 TRIVIAL ``x1' = x2, x2' = w, y = x1``: x2 = y', observable; m = 0 at the start."""
    res = oracle.general_ui_model(_multi("trivial_drift"))
    assert res["dim"] == 2 and res["observable"] == [0, 1] and res["ui_observable"] == [True]
    assert res["trace"][0]["m"] == 0 and "filtered closure (m = 0)" in [s["step"] for s in res["trace"]]


def test_time_varying_examples():
    """TUIO6's two time-varying examples: ``y = x1 + t x2`` (rational, exact) and
    ``y = cos(x1 + t x2)`` (60 digits), x2 driven by w: only the combination x1 + t x2 is
    observable (dim 1), with d/dt terms in every total derivative."""
    t = sp.Symbol("t", real=True)
    res = oracle.general_ui_model(_multi("time_varying"))
    assert (res["dim"], res["observable"], res["exact"]) == (1, [], True)
    res = oracle.general_ui([X1, X2], [sp.cos(t), 1], {}, {"w": [0, t]}, [sp.cos(X1 + t * X2)], t=t)
    assert (res["dim"], res["observable"], res["exact"]) == (1, [], False)
    # without the time derivative the drift would be read differently: t is a known symbol, not a state
    assert oracle.eorc([X1, X2], [1, 0], {}, {"w": [0, 1]}, [X1 + t * X2], t=t, k_max=3)["dims"] == [1, 1, 1, 1]


def test_exact_and_float_routes_agree():
    """The same rational model in exact rational arithmetic and in 60-digit arithmetic."""
    model = _multi("tac2025")
    a = oracle.general_ui_model(model)
    b = oracle.general_ui_model(model, arithmetic="float")
    assert a["exact"] and not b["exact"]
    assert (a["dim"], a["observable"], a["ui_observable"]) == (b["dim"], b["observable"], b["ui_observable"])


def test_a_pole_restarts_with_new_points():
    """Seed 16 puts a = b at one point (found by search), a pole of a / (a - b): the analysis restarts."""
    a, b = sp.symbols("a b", real=True)
    res = oracle.general_ui([a, b], [0, b], {}, {"w": [0, 1]}, [a / (a - b)], seed=16)
    assert res["seed"] != 16 and res["dim"] == 1


def test_bad_arguments_raise():
    with pytest.raises(ValueError, match="components"):
        oracle.general_ui([X1, X2], [X2], {}, {"w": [0, 1]}, [X1])
    with pytest.raises(ValueError, match="clashes"):
        oracle.general_ui([X1, X2], None, {"x1": [1, 0]}, {"w": [0, 1]}, [X1])
    with pytest.raises(ValueError, match="known_inputs"):
        oracle.eorc([X1], None, {}, {}, [X1], k_max=1, known_inputs="both")
    with pytest.raises(ValueError, match="rational"):
        oracle.general_ui([X1], None, {}, {"w": [1]}, [sp.sin(X1)], arithmetic="exact")


# --------------------------------------------------------------------------------------
# Random two-UI systems against the exact EORC
# --------------------------------------------------------------------------------------

def _random_system(seed):
    """4 states, y = (x1, x2), a sparse polynomial drift and two sparse UI fields (the oracle's
    :func:`random_two_ui_system`, also usable by the JAX route's tests)."""
    return oracle.random_two_ui_system(seed)


RANDOM_SEEDS = list(range(40))


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_random_two_ui_systems_against_the_eorc(seed):
    """dim(general) >= dim(EORC, smooth) at every order k, and equal once the EORC has stabilised
    (its last three orders equal)."""
    args = _random_system(seed)
    res = oracle.general_ui(*args)
    e = oracle.eorc(*args, k_max=4, known_inputs="smooth")
    assert all(d <= res["dim"] for d in e["dims"]), (e["dims"], res["dim"])
    if e["dims"][-1] == e["dims"][-2] == e["dims"][-3]:
        assert e["dims"][-1] == res["dim"]
        assert e["observable"][-1] == res["observable"]


def test_the_random_family_exercises_every_branch():
    """The random family above is not trivial: it contains non-canonic systems that need a UI
    extension, initially canonic ones, and partially observable answers above the outputs."""
    kinds = set()
    for seed in RANDOM_SEEDS[:24]:
        res = oracle.general_ui(*_random_system(seed))
        kinds.add("extension" if res["ui_extension"] else ("canonic" if res["initially_canonic"] else "other"))
        if 2 < res["dim"] < 4:
            kinds.add("partial")
    assert {"extension", "canonic", "partial"} <= kinds


# --------------------------------------------------------------------------------------
# The zoo file systems/multi_ui.py: verdicts and transcriptions
# --------------------------------------------------------------------------------------

MULTI = list(zoo_module("multi_ui").PUBLISHED)


@pytest.mark.parametrize("name", MULTI)
def test_multi_ui_zoo_verdicts_equal_the_oracle(name):
    """Every PUBLISHED verdict of ``systems/multi_ui.py`` equals the oracle on the sympy twin
    (general_ui entries) or the exact switchable EORC (eorc entries)."""
    pub = zoo_module("multi_ui").PUBLISHED[name]
    model = _multi(name)
    if pub["method"] == "general_ui":
        res = oracle.general_ui_model(model)
        assert res["dim"] == pub["dim"]
        assert _names(model, res["observable"]) == pub["observable"]
        assert (res["ui_extension"], res["canonic"]) == (pub["ui_extension"], pub["canonic"])
    else:
        e = oracle.eorc_model(model, k_max=3, known_inputs=pub["known_inputs"])
        assert e["dims"][-1] == pub["dim"] and _names(model, e["observable"][-1]) == pub["observable"]


@pytest.mark.parametrize("name", MULTI)
def test_multi_ui_zoo_transcription_equals_the_sympy_twin(name):
    """The JAX System of each entry and its sympy twin give the same drift, fields and outputs at
    random points (so the oracle's verdict is about the zoo's model)."""
    system = zoo_system("multi_ui", name)
    model = _multi(name)
    assert tuple(system.states) == tuple(str(s) for s in model.states)
    assert tuple(system.unknown) == tuple(model.unknown) and tuple(system.known) == tuple(model.known)
    t = getattr(model, "time", None)
    rng = np.random.default_rng(0)
    for _ in range(3):
        xv = rng.uniform(0.5, 1.5, size=len(model.states))
        tv = float(rng.uniform(0.5, 1.5))
        sub = dict(zip(model.states, xv.tolist()))
        if t is not None:
            sub[t] = tv
        extra = (tv,) if t is not None else ()

        def same(fn, expr_vec):
            got = np.asarray(fn(jnp.asarray(xv), *extra), dtype=float).reshape(-1)
            want = np.array([float(sp.sympify(e).xreplace(sub)) for e in expr_vec], dtype=float)
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)

        drift = model.drift if model.drift is not None else [0] * len(model.states)
        if system.drift is not None or model.drift is not None:
            same(system.drift, drift)
        for k, field in model.unknown.items():
            same(system.unknown[k], field)
        for k, field in model.known.items():
            same(system.known[k], field)
        assert tuple(system.outputs) == tuple(model.outputs)
        for k, expr in model.outputs.items():
            same(system.outputs[k], [expr])
