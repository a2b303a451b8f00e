"""The recursion driver (uio_jax._analysis.recursions.driver) and the single_ui stopping rule as a
function of integer sequences."""

import pytest

from uio_jax._analysis.recursions.driver import Cap, Recursion, Stop, StopReason, iterate
from uio_jax._analysis.recursions.single_ui import stopping_rule
from uio_jax._analysis.results.evidence import Step
from uio_jax._progress import step_listener

R = StopReason


# --------------------------------------------------------------- the enumeration
TEXTS = [  # the texts reports carry (compared bit for bit with older reports)
    (R.FULL_RANK.stop(n=3, m=2), "full rank 3 at m=2"),
    (R.FULL_RANK_ORDER.stop(n=4, k=1), "full rank 4 at order 1"),
    (R.CONVERGED.stop(m=2, prev=1), "Omega_2 = Omega_1"),
    (R.CONVERGED_AFTER_M_PRIME.stop(m=3, prev=2), "Omega_3 = Omega_2 with m >= m'"),
    (R.SPAN_CLOSED.stop(k=2), "order 2 adds nothing: span closed"),
    (R.MAX_ORDER.stop(max_order=4), "max_order=4 reached before convergence"),
    (R.STEP_CAP.stop(cap=9), "no convergence certified within 9 steps"),
    (R.KNOWN_FIELDS_ORC.stop(), "ORC of the known fields converged"),
    (R.ALL_STATES.stop(k=1), "every state component observable at k=1"),
    (R.K_MAX.stop(k_max=4), "k_max=4 reached"),
    (R.KNOWN_BOUND.stop(bound=12, k=2),
     "every unknown input observable and the states at the known-input bound 12 at k=2: no higher "
     "order changes a verdict"),
    (R.SYMMETRY_BOUND.stop(bound=22, k=10),
     "the states at the bound 22 of the verified symmetries at k=10, every unknown input observable "
     "or proved unobservable: no higher order changes a verdict"),
    (R.EXTENSION_CLOSED.stop(k=10, prev=9),
     "Omega-bar_10 = Omega-bar_9: no higher order (in any extension) adds a generator"),
    (R.CLOSURE_CONVERGED.stop(m=0), "closure along the drift converged at iteration 0"),
    (R.CANONIC_CLOSURE.stop(m=1),
     "canonic at iteration 1: the closure under the rescaled fields converged"),
    (R.REMAINING_UIS_VANISH.stop(m=0),
     "iteration 0: every unreconstructed unknown-input field vanishes; the closure under the "
     "rescaled fields converged"),
    (R.GUARD_PASSED.stop(m=2),
     "iteration 2: the guarded closure converged without meeting an unreconstructed input"),
    (R.GENERAL_STALLED.stop(m=3),
     "iteration 3: no progress (m = 0 and nothing new); no convergence certified"),
    (R.GENERAL_CAP.stop(cap=30), "no convergence within 30 iterations"),
]


@pytest.mark.parametrize("stop, text", TEXTS, ids=[s.reason.name for s, _ in TEXTS])
def test_each_reason_formats_the_report_text_and_parses_back(stop, text):
    assert stop.message == str(stop) == text
    assert stop.reason.matches(text)
    assert StopReason.parse(text) == stop
    assert [r for r in StopReason if r.matches(text)] == [stop.reason]  # no ambiguity


def test_every_reason_is_covered_and_caps_are_not_convergence():
    assert {s.reason for s, _ in TEXTS} == set(StopReason)
    assert {r for r in StopReason if not r.converged} == {R.MAX_ORDER, R.STEP_CAP, R.K_MAX,
                                                          R.GENERAL_STALLED, R.GENERAL_CAP}


def test_a_missing_value_fails_when_the_stop_is_made():
    with pytest.raises(KeyError):
        R.FULL_RANK.stop(n=3)
    with pytest.raises(ValueError, match="not a stop reason"):
        StopReason.parse("it stopped")


# --------------------------------------------------------------- the driver
class Counting(Recursion):
    """dim_m = min(m + 1, top); stops when a step adds nothing (the driver caps it)."""

    def __init__(self, top):
        self.top, self.finished = top, None

    def init(self):
        return Step(0, 1, ("a0",), 1.0, {})

    def step(self, m):
        dim = min(m + 1, self.top)
        return Step(m, dim, () if dim == self.top and m >= self.top else (f"a{m}",), 1.0, {})

    def terminate(self, m, history):
        if m > 0 and not history[-1].added:
            return R.CONVERGED.stop(m=m, prev=m - 1)
        return None

    def postprocess(self, history, stop):
        return [st.dim for st in history]


def cap(steps):
    return Cap(steps, R.MAX_ORDER.stop(max_order=steps))


def test_iterate_records_announces_and_postprocesses():
    seen = []
    with step_listener(seen.append):
        out = iterate(Counting(top=3), cap=cap(10))
    assert out.stop == R.CONVERGED.stop(m=3, prev=2)
    assert out.m == 3 and [st.m for st in out.history] == [0, 1, 2, 3]
    assert out.result == [1, 2, 3, 3]
    assert seen == out.history  # every step announced once, in order


def test_iterate_stops_at_the_cap_and_can_stop_at_init():
    out = iterate(Counting(top=9), cap=cap(2))
    assert out.stop.reason is R.MAX_ORDER and out.m == 2 and len(out.history) == 3
    out = iterate(Counting(top=9), cap=cap(0))
    assert out.m == 0 and len(out.history) == 1


def test_iterate_continues_a_given_history_without_announcing_it():
    class FromHistory(Counting):
        def init(self):
            return None

    before = [Step(0, 1, ("h",), 1.0, {})]
    seen = []
    with step_listener(seen.append):
        out = iterate(FromHistory(top=2), before, cap=cap(5))
    assert out.history[0] is before[0] and seen == out.history[1:]
    with pytest.raises(ValueError):
        iterate(FromHistory(top=2), cap=cap(5))


def test_stop_is_a_value():
    assert R.FULL_RANK.stop(m=1, n=2) == Stop(R.FULL_RANK, (("m", 1), ("n", 2)))


# --------------------------------------------------------------- the single_ui stopping rule
def rule(dims, m_prime, n=3, phi1_vanish=False, cap=9, max_order=None, offset=0):
    v = stopping_rule(dims, m_prime, n=n, phi1_vanish=phi1_vanish, cap=cap,
                      max_order=max_order, offset=offset)
    return (None if v.stop is None else v.stop.message), v.m_star, v.m_star_paper


def test_rule_goes_on_while_the_span_grows():
    assert rule([1], 0) == (None, None, None)
    assert rule([1, 2], 0) == (None, None, None)


def test_corrected_rule_does_not_stop_at_m_star_zero():
    """The counterexample: dims 1, 1, 2, 2 with m' = 0. The papers stop at m* = 0
    (Omega_1 = Omega_0); the correction goes on to m* = 2."""
    assert rule([1, 1], 0) == (None, None, 0)
    assert rule([1, 1, 2], 0) == (None, None, 0)
    assert rule([1, 1, 2, 2], 0) == ("Omega_3 = Omega_2 with m >= m'", 2, 0)


def test_m_star_zero_is_accepted_when_every_phi1_vanishes():
    assert rule([1, 1], 0, phi1_vanish=True) == ("Omega_1 = Omega_0 with m >= m'", 0, 0)


def test_the_vehicle_in_wind():
    """002 III-C: dims 3, 5, 6, 6 in R^7, all phi_1 = 0, m' = 0: m* = 2."""
    assert rule([3, 5, 6, 6], 0, n=7, phi1_vanish=True) == (
        "Omega_3 = Omega_2 with m >= m'", 2, 2)


def test_equal_dims_before_m_prime_do_not_stop():
    assert rule([1, 1, 1], None) == (None, None, None)
    assert rule([1, 1, 1, 2], 3) == (None, None, None)  # d_1 = d_0, d_2 = d_1, but m - 1 < m'
    assert rule([1, 1, 1, 2, 2], 3) == ("Omega_4 = Omega_3 with m >= m'", 3, 3)


def test_full_rank_stops_once_m_prime_is_known():
    assert rule([2, 3], None) == (None, None, None)  # full rank, but d tau not yet in Omega
    assert rule([2, 3, 3], 2) == ("full rank 3 at m=2", 2, 2)
    assert rule([2, 3], 1) == ("full rank 3 at m=1", 1, 1)
    # the papers' m* was found earlier (at 0); the corrected one is the full-rank step
    assert rule([2, 2, 3], 0) == ("full rank 3 at m=2", 2, 0)


def test_offset_numbers_the_messages_and_max_order():
    assert rule([1, 1, 2, 2], 0, offset=1) == ("Omega_4 = Omega_3 with m >= m'", 2, 0)
    assert rule([1, 2], 0, max_order=2, offset=1) == (
        "max_order=2 reached before convergence", None, None)
    assert rule([1, 2], 0, max_order=2) == (None, None, None)


def test_cap_without_m_prime():
    assert rule([1, 1, 1], None, cap=2) == ("no convergence certified within 2 steps", None, None)
    assert rule([1, 1, 1], 0, cap=2) == ("Omega_2 = Omega_1 with m >= m'", 1, 0)
    assert rule([1, 1], 0, cap=1) == ("no convergence certified within 1 steps", None, 0)


# --------------------------------------------------------------- the rank rule of Lemma 1
def test_vector_rank_uses_the_codistributions_rank_rule():
    """Sampled vector fields ``(S, k, n)``: parallel fields have rank 1, independent ones 2,
    a zero field counts nothing, invalid samples are ignored, and ``rtol`` is the threshold
    on ``s_i / s_1`` as in :func:`decide_rank`."""
    import numpy as np

    from uio_jax._analysis.recursions.single_ui import _vector_rank

    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 8, 3))
    valid = np.ones(8, bool)
    assert _vector_rank(np.stack([a, 2 * a], axis=1), valid, 1e-8) == 1
    assert _vector_rank(np.stack([a, b], axis=1), valid, 1e-8) == 2
    assert _vector_rank(np.stack([a, 0 * a], axis=1), valid, 1e-8) == 1
    near = a + 1e-6 * b  # s_2 / s_1 ~ 1e-6: independent at rtol 1e-8, not at 1e-4
    assert _vector_rank(np.stack([a, near], axis=1), valid, 1e-8) == 2
    assert _vector_rank(np.stack([a, near], axis=1), valid, 1e-4) == 1
    mixed = np.stack([a, np.where(np.arange(8)[:, None] < 3, b, a)], axis=1)
    assert _vector_rank(mixed, valid, 1e-8) == 1  # majority of the samples
    assert _vector_rank(mixed, np.arange(8) < 3, 1e-8) == 2  # only the valid ones count
