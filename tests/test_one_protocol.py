"""One protocol for the two report types (issue 44 item 4): every question a user can ask of
a generic-state :class:`~uio_jax.Report` can be asked of an
:class:`~uio_jax.IdentifiabilityReport` at a known initial state, and the reverse, or is
refused in one line that says why."""

import jax.numpy as jnp
import pytest

import uio_jax as uj

#: The members both report types have (the user's questions).
PROTOCOL = ("question", "system_name", "states", "params", "notes", "observable", "identifiable", "verdicts",
            "undecided", "fully_determined", "exact", "answer", "answer_kind", "is_observable",
            "unobservable_directions", "direction_summary", "format_directions", "to_dict", "to_json")


def _sum_model():
    """``x' = -(a + b) x``, ``y = x``: only ``a + b`` is identifiable."""
    return uj.System(states=("x",), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0]]),
                     params={"a": (0.5, 1.5), "b": (0.5, 1.5)}, domain={"x": (0.5, 1.5)}, name="sum")


@pytest.fixture(scope="module")
def reports():
    system = _sum_model()
    return uj.analyze(system, samples=64), uj.analyze(system, initial={"x": 1.0})


def test_both_report_types_answer_the_protocol(reports):
    for rep in reports:
        missing = [m for m in PROTOCOL if not hasattr(type(rep), m) and m not in vars(rep)]
        assert not missing, (type(rep).__name__, missing)


def test_the_same_questions_get_the_same_answers(reports):
    generic, at_t0 = reports
    assert generic.verdicts["a"] is uj.Verdict.NOT_DETERMINED and generic.verdicts["x"] is uj.Verdict.DETERMINED
    assert not generic.fully_determined and generic.answer is uj.Answer.EXACT
    for rep in reports:  # a + b is determined, in both questions
        assert rep.is_observable(lambda z: z[1] + z[2]) is True
        assert rep.is_observable(lambda x, p: p[0] + p[1]) is True
    assert generic.is_observable(lambda z: z[1]) is False
    # at a specific initial state an order adding nothing proves nothing: undecided, said in one line
    with pytest.raises(uj.ModelError, match=r"^is_observable: undecided: not determined up to order \d+"):
        at_t0.is_observable(lambda z: z[1])


def test_what_one_type_cannot_answer_is_refused_in_one_line(reports):
    _, at_t0 = reports
    for ask in (at_t0.unobservable_directions, at_t0.direction_summary, at_t0.format_directions):
        with pytest.raises(uj.ModelError, match="no codistribution at generic states") as err:
            ask()
        assert "\n" not in str(err.value)
    for follow_up in (uj.observable_functions, uj.find_symmetries, uj.reparametrise):
        with pytest.raises(uj.ModelError, match="got IdentifiabilityReport") as err:
            follow_up(at_t0)
        assert "\n" not in str(err.value)


def test_is_observable_at_t0_of_a_closed_span_proves_not():
    """No known initial component: the span closes, so a function outside it is proved not
    determined (False), not undecided."""
    rep = uj.analyze([_sum_model()], initial=[None])
    assert rep.is_observable(lambda z: z[1] + z[2]) is True and rep.is_observable(lambda z: z[1]) is False
