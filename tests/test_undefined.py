"""Models defined on part of their sampling box only (NaN/inf elsewhere).

A System is refused only when none of thousands of sampled states is finite; a sparse
finite set gives a note in System.notes, and a report whose analysis dropped more than
``DROPPED_NOTE_FRACTION`` of its samples says so.
"""

import re

import jax.numpy as jnp
import pytest

import uio_jax as uj
from uio_jax._analysis.decisions.context import DROPPED_NOTE_FRACTION


def chain(output, **kw):
    """x1' = x2, x2' = 0, y = output(x): both states observable where y is defined."""
    return uj.System(("x1", "x2"), {"y": output}, drift=lambda x: jnp.array([x[1], 0.0]), **kw)


def finite_note(system):
    notes = [t for t in system.notes if "is finite on only" in t]
    assert len(notes) == 1, system.notes
    return float(re.search(r"finite on only ([0-9.]+) %", notes[0]).group(1)), notes[0]


def test_model_finite_on_five_percent_of_its_box_is_accepted_with_a_note_and_analysed():
    sys = chain(lambda x: jnp.sqrt(x[0] - 1.45))  # finite for x1 in [1.45, 1.5): 5 % of (0.5, 1.5)
    pct, note = finite_note(sys)
    assert 3.5 < pct < 6.5
    assert note.startswith("output 'y' is finite on only") and "narrow `domain`" in note
    rep = uj.analyze(sys, samples=1024)
    assert rep.observable == {"x1": True, "x2": True}
    assert 0.9 * 1024 < rep.certificate.dropped < 0.99 * 1024
    assert any("were dropped: the model is NaN/inf there" in t for t in rep.notes)


def test_sparse_finite_set_with_params_notes_the_users_system():
    sys = uj.System(("x1",), {"y": lambda x, p: jnp.log(x[0] - 1.46) + p[0] * x[0]},
                    drift=lambda x, p: jnp.array([p[0]]), params={"k": (0.5, 1.5)})
    pct, _ = finite_note(sys)
    assert 2.0 < pct < 6.0
    assert sys.joint().notes == sys.notes


def test_model_nan_on_sixty_percent_gets_the_report_note():
    sys = chain(lambda x: jnp.sqrt(x[0] - 1.1))  # NaN for x1 < 1.1: 60 % of the box
    assert not any("finite on only" in t for t in sys.notes)  # 40 % is not sparse
    rep = uj.analyze(sys, samples=512)
    dropped = rep.certificate.dropped
    screened = rep.certificate.used + dropped  # the screen's samples (every decision exact)
    assert 0.5 * screened < dropped < 0.7 * screened
    note = (f"{dropped} of {screened} sampled states ({100 * dropped / screened:.0f} %) were dropped: "
            "the model is NaN/inf there")
    assert note in rep.notes
    assert rep.observable == {"x1": True, "x2": True}


def test_few_dropped_samples_give_no_note():
    sys = chain(lambda x: jnp.sqrt(x[0] - 0.53))  # 3 % of the box dropped
    rep = uj.analyze(sys, samples=512)
    assert 0 < rep.certificate.dropped < DROPPED_NOTE_FRACTION * 512
    assert not any("were dropped" in t for t in rep.notes)


@pytest.mark.parametrize("what, kw", [
    ("output 'y'", dict(output=lambda x: jnp.log(-x[0] - 1.0))),
    ("drift", dict(output=lambda x: x[0], drift=lambda x: jnp.array([jnp.sqrt(-x[1]), 0.0]))),
])
def test_model_nan_everywhere_is_refused_with_a_true_message(what, kw):
    drift = kw.pop("drift", lambda x: jnp.array([x[1], 0.0]))
    with pytest.raises(uj.ModelError) as err:
        uj.System(("x1", "x2"), {"y": kw["output"]}, drift=drift)
    msg = str(err.value)
    assert msg.startswith(f"{what} returns NaN/inf at every one of 4160 states drawn in the sampling box")
    assert "(64 at validation, 4096 more" in msg and "\n" not in msg


def test_the_recursion_decides_on_as_many_defined_states_on_a_partly_undefined_model():
    """The decision samples are the first ones holding ``DECISION_SAMPLES`` states where the
    outputs and fields are finite: that many where the model is defined on its whole box,
    about twice as many where on half of it, all that the certificate may use where fewer
    are defined."""
    from uio_jax._analysis.decisions import memory
    from uio_jax._analysis.decisions.context import Context

    D, S = memory.DECISION_SAMPLES, 1024
    for cut in (0.4, 1.0, 1.45):  # NaN for x1 < cut: none, half, 95 % of (0.5, 1.5)
        ctx = Context(chain(lambda x, cut=cut: jnp.sqrt(x[0] - cut)), S, 0, 1e-8)
        defined = ctx.xs_all[:, 0] >= cut
        assert len(ctx.xs) == ctx.decisions
        if cut < 0.5:
            assert ctx.decisions == D
        elif cut == 1.0:
            assert defined[: ctx.decisions].sum() == D and defined[ctx.decisions - 1]
            assert 1.6 * D < ctx.decisions < 2.4 * D
        else:
            assert defined.sum() < D and ctx.decisions == memory.certify_samples(S, 2) == S
    assert memory.decision_count(None, S, 2) == D  # a model outside the graph: not screened


def test_an_output_nan_through_a_where_is_noticed():
    """``y = where(x1 > 1, nan, x1 + x2^2)``: NaN on half the box while its gradient is finite
    there (the chosen branch is a constant): the samples are dropped and the report says so
    (issue 40: it was not noticed)."""
    system = uj.System(("x1", "x2"), {"y": lambda x: jnp.where(x[0] > 1.0, jnp.nan, x[0] + x[1] ** 2)},
                       drift=lambda x: jnp.array([x[1], -x[0]]))
    rep = uj.analyze(system, samples=512)
    cert = rep.certificate
    assert 0.4 < cert.dropped / (cert.used + cert.dropped) < 0.6
    assert any("were dropped: the model is NaN/inf there" in note for note in rep.notes)
    assert rep.dim == 2
