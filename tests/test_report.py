"""Report API: JSON, text, symmetries, observability of user functions, library errors."""

import json
import re

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import zoo_report, zoo_system

import uio_jax as uj


def test_report_fields_and_json_round_trip():
    rep = zoo_report("unicycle_polar", "range_known")
    d = json.loads(rep.to_json())
    assert d == rep.to_dict()
    for key in ("method", "dim", "observable", "fully_observable", "history", "certificate",
                "generators", "notes", "semantics"):
        assert key in d
    cert = d["certificate"]
    assert cert["used"] + cert["dropped"] + cert["capped"] == cert["samples"]
    text = str(rep)
    assert "dim 2 of 3" in text
    assert re.search(r"^  r +observable$", text, re.M)
    assert re.search(r"^  phi +not observable$", text, re.M)
    assert rep.fully_observable is False
    assert rep.dims == tuple(s.dim for s in rep.history)


def test_is_observable_of_user_functions():
    rep = zoo_report("unicycle_polar", "range_known")
    assert rep.is_observable(lambda x: x[0] ** 2)
    assert rep.is_observable(lambda x: jnp.cos(x[2] - x[1]))  # rotation invariant
    assert not rep.is_observable(lambda x: x[1])
    with pytest.raises(uj.ModelError, match="scalar"):
        rep.is_observable(lambda x: x)
    with pytest.raises(uj.ModelError, match="callable"):
        rep.is_observable(3)


def test_unobservable_directions_checks_its_input():
    rep = zoo_report("unicycle_polar", "range_known")
    with pytest.raises(uj.ModelError, match=r"shape \(3,\)"):
        rep.unobservable_directions(np.zeros(2))
    with pytest.raises(uj.ModelError, match="NaN"):
        rep.unobservable_directions(np.array([1.0, np.nan, 0.0]))
    N = rep.unobservable_directions(np.array([1.0, 0.2, 0.4]))
    assert N.shape == (3, 1)
    np.testing.assert_allclose(N.T @ N, np.eye(1), atol=1e-12)


@pytest.mark.parametrize(
    "kw, message",
    [
        (dict(method="quick"), "unknown method 'quick'"),
        (dict(samples=4), "samples must be an integer >= 8"),
        (dict(samples=10.5), "samples must be an integer"),
        (dict(seed=-2), "seed must be a non-negative integer"),
        (dict(rtol=0), "rtol must be a number in (0, 1)"),
        (dict(max_order=-1), "max_order"),
        (dict(k_max=0), "k_max"),
    ],
)
def test_analyze_option_errors(kw, message):
    with pytest.raises(uj.OptionError) as err:
        uj.analyze(zoo_system("unicycle_polar", "range_known"), **kw)
    assert message in str(err.value)


def test_analyze_needs_a_system():
    with pytest.raises(uj.OptionError, match="needs a uio_jax.System"):
        uj.analyze("systems/vehicle_wind.py:no_wind")


def test_auto_never_drops_unknown_inputs():
    rep = zoo_report("unicycle_polar", "range_v_unknown")
    assert rep.method == "single_ui"
    assert any("auto" in n for n in rep.notes)


def test_load_system_errors(tmp_path):
    with pytest.raises(uj.LoadError, match="not found"):
        uj.load_system(str(tmp_path / "x.py") + ":f")
    with pytest.raises(uj.LoadError, match="FILE.py:NAME"):
        uj.load_system("x.py")


def test_max_order_caps_the_recursion():
    rep = uj.analyze(zoo_system("vehicle_wind", "no_wind"), samples=64, max_order=0)
    assert rep.dims == (3,)
    assert "max_order" in rep.stop_reason


def test_the_first_lines_say_which_question_is_answered():
    import dataclasses

    rep = zoo_report("unicycle_polar", "range_known")
    lines = str(rep).splitlines()
    assert lines[2].startswith("answer: exact (observability rank condition")
    from uio_jax._analysis.decisions.answer import decide_answer
    from uio_jax._analysis.recursions.driver import StopReason

    def as_if(**changes):  # the report another analysis would have made: its answer decided again
        other = dataclasses.replace(rep, **changes)
        answer = decide_answer(other.method, other.stop, other.details, other.certificate.arithmetic)
        return dataclasses.replace(other, answer=answer)

    eorc = as_if(method="eorc")
    assert str(eorc).splitlines()[2].startswith("answer: sufficient only (EORC)")
    capped = as_if(stop=StopReason.MAX_ORDER.stop(max_order=1))
    assert "sufficient only (the recursion was capped" in capped.answer_kind()
    single = as_if(method="single_ui")
    assert single.answer_kind().startswith("exact (Martinelli")


def test_directions_at_a_regular_point_and_json_without_parameters():
    rep = zoo_report("unicycle_polar", "range_known")
    np.testing.assert_allclose(rep.domain_centre(), [1.25, 0.0, 0.0])
    # phi = theta = 0 is a singular point of this codistribution: the centre is refused ...
    with pytest.raises(uj.ModelError, match=r"drops rank at \(r=1.25, phi=0, theta=0\)"):
        rep.direction_summary(rep.domain_centre())
    # ... and the report's representative point moves off it, saying so
    z, rule = rep.representative_point()
    assert "off the centre" in rule and np.all(np.isfinite(z))
    (d,) = rep.direction_summary()["directions"]
    np.testing.assert_allclose([d["r"], d["phi"], d["theta"]], np.array([0.0, 1.0, 1.0]) / np.sqrt(2),
                               atol=1e-9)  # the rotation about the origin
    text = rep.format_directions()
    assert "the rank drops there" in text and "+0.707 phi  +0.707 theta" in text
    # without parameters the JSON keeps its keys (the zoo snapshot compares them)
    assert not {"unobservable_directions", "directions_at", "identifiable_combinations"} & set(rep.to_dict())
