"""Declared symmetries (``System(symmetries=...)``): verified exactly, then used as proofs of
unobservability and as the EORC's stopping bound (uio_jax._analysis.decisions.symmetry).

The examples are derived by hand in the docstrings: a point in the plane moved by two unknown
inputs along the axes and measured by its squared range is invariant under rotation about the
origin, ``xi = (-py, px)``: ``L_xi (px^2 + py^2) = 0``; with the radial known field
``f = (px, py)``, ``[xi, f] = Df xi - Dxi f = xi - xi = 0``; with ``g1 = e_x``, ``g2 = e_y``,
``Dxi = [[0, -1], [1, 0]]`` gives ``[xi, g1] = -Dxi e_x = -g2`` and ``[xi, g2] = g1``.
"""

import jax
import jax.numpy as jnp
import pytest

import uio_jax as uj
from uio_jax._analysis.recursions.driver import StopReason


def rotation(x):
    return jnp.array([-x[1], x[0]])


def plane(symmetries, known=True, output=None):
    return uj.System(
        ("px", "py"), {"r2": output or (lambda x: x[0] ** 2 + x[1] ** 2)},
        known={"u": lambda x: x} if known else {},
        unknown={"w1": lambda x: jnp.array([1.0, 0.0]), "w2": lambda x: jnp.array([0.0, 1.0])},
        symmetries=symmetries)


def test_rotation_is_verified_exactly_and_stops_the_eorc_at_its_bound():
    """dim <= n - 1 = 1 at every order; dh reaches it at k = 0 and both inputs are proved
    unobservable (B = [[0, -1], [1, 0]] has no zero column): the EORC stops at k = 0, exact."""
    system = plane({"rot": rotation})
    assert "symmetries=('rot',)" in repr(system)
    rep = uj.analyze(system, method="eorc", samples=64)
    sym = rep.details["symmetries"]
    assert rep.dim == 1 and not any(rep.observable.values()) and rep.details["k"] == 0
    assert StopReason.SYMMETRY_BOUND.matches(rep.stop_reason) and rep.exact
    assert sym["reached_at"] == 0 and sym["dim"] == 1 and sym["rank"] == 1
    assert sym["moved"] == ["px", "py"] and sym["unobservable_inputs"] == ["w1", "w2"]
    check = sym["checks"][0]
    assert check["verified"] and "exact mod p" in check["how"]
    assert check["mixing"] == {"w1": {"w2": "-1"}, "w2": {"w1": "1"}}
    assert 0.0 < sym["probability"] < 1e-30  # the Settler's zero tests, each D / p (p = 2^127 - 1)
    assert any("[rot, w1] = -w2; [rot, w2] = w1" in nt for nt in rep.notes)


def test_a_given_k_max_runs_on_and_is_still_exact_at_the_bound():
    rep = uj.analyze(plane({"rot": rotation}), method="eorc", samples=64, k_max=3)
    assert not StopReason.SYMMETRY_BOUND.matches(rep.stop_reason)
    assert rep.dim == 1 and rep.exact and rep.details["symmetries"]["reached_at"] == rep.details["k"]


def test_a_false_symmetry_is_reported_and_never_used():
    """A translation along x changes the range: L_xi h = 2 px != 0."""
    rep = uj.analyze(plane({"shift": lambda x: jnp.array([1.0, 0.0])}), method="eorc", samples=64)
    check = rep.details["symmetries"]["checks"][0]
    assert not check["verified"] and check["failure"] == "L_shift r2 is not zero"
    assert not StopReason.SYMMETRY_BOUND.matches(rep.stop_reason) and not rep.exact
    assert rep.details["symmetries"]["rank"] == 0 and rep.details["symmetries"]["moved"] == []
    assert any("shift: NOT verified" in nt for nt in rep.notes)


def test_a_nonconstant_input_mixing_is_not_a_symmetry_of_this_kind():
    """``xi = r^2 (-py, px)`` keeps the range but ``[xi, g1] = -r^2 g2 - 2 px xi``: a
    combination of g1, g2 with coefficients that vary, not a constant one."""
    def scaled(x):
        return (x[0] ** 2 + x[1] ** 2) * jnp.array([-x[1], x[0]])

    rep = uj.analyze(plane({"scaled": scaled}, known=False), method="eorc", samples=64)
    check = rep.details["symmetries"]["checks"][0]
    assert not check["verified"] and "not a CONSTANT combination" in check["failure"]


def test_a_trigonometric_model_is_verified_exactly():
    """``cos`` is made rational (a point of the circle per argument): exact modulo p."""
    rep = uj.analyze(plane({"rot": rotation}, output=lambda x: jnp.cos(x[0] ** 2 + x[1] ** 2)),
                     method="eorc", samples=64)
    check = rep.details["symmetries"]["checks"][0]
    assert check["verified"] and check["how"].startswith("exact mod p")
    assert rep.dim == 1 and rep.exact


def test_a_model_not_made_rational_is_verified_in_mpmath():
    """``erf`` is not made rational: the symmetry is verified in mpmath, and the analysis's
    own decisions are not exact either."""
    rep = uj.analyze(plane({"rot": rotation}, output=lambda x: jax.scipy.special.erf(x[0] ** 2 + x[1] ** 2)),
                     method="eorc", samples=64)
    check = rep.details["symmetries"]["checks"][0]
    assert check["verified"] and "mpmath" in check["how"] and rep.details["symmetries"]["probability"] is None
    assert rep.dim == 1 and not rep.exact


def test_a_scaling_of_a_state_against_a_parameter_proves_both_unidentifiable():
    """``x' = -a x``, ``y = c x``: ``xi = (x; 0, -c)`` on ``[x; a, c]`` keeps ``c x`` and
    commutes with ``f0 = (-a x; 0, 0)``. Every method reports it (here the series test)."""
    system = uj.System(("x",), {"y": lambda x, p: p[1] * x[0]}, drift=lambda x, p: -p[0] * x,
                       params=("a", "c"),
                       symmetries={"scale": lambda x, p: jnp.array([x[0], 0.0, -p[1]])})
    rep = uj.analyze(system, samples=64)
    sym = rep.details["symmetries"]
    assert sym["checks"][0]["verified"] and sym["moved"] == ["x", "c"]
    assert rep.identifiable == {"a": True, "c": False} and not rep.observable["x"]
    assert any("the final span: the states reach the bound 2" in nt and "x, c: not observable" in nt
               for nt in rep.notes)


def test_time_varying_symmetry_is_lifted_with_zero_time_component():
    system = uj.System(("px", "py"), {"r2": lambda x, t: (x[0] ** 2 + x[1] ** 2) * (1 + t)},
                       drift=lambda x, t: t * x, time="t",
                       symmetries={"rot": lambda x, t: jnp.array([-x[1], x[0]])})
    rep = uj.analyze(system, samples=64)
    sym = rep.details["symmetries"]
    assert sym["checks"][0]["verified"] and sym["moved"] == ["px", "py"] and rep.dim == 1


@pytest.mark.parametrize("symmetries, message", [
    ({"rot": lambda x: jnp.zeros(3)}, r"symmetry 'rot' returns shape \(3,\), expected \(2,\)"),
    ({"rot": 3}, "symmetries entry 'rot' is not callable"),
    ({"rot": lambda x: x[0] + 1j}, "symmetry 'rot' returns shape"),
    ({"rot": lambda x, y: x}, "symmetry 'rot' fails on the System's arguments"),
])
def test_bad_symmetries_are_one_line_errors(symmetries, message):
    with pytest.raises(uj.ModelError, match=message) as info:
        plane(symmetries)
    assert "\n" not in str(info.value)


def test_the_rank_of_several_symmetries_is_taken_at_one_point():
    """Two multiples of the same rotation: rank 1 (not 2, which rows evaluated at two
    different points would give, and with it a bound of 0 below the true 1)."""
    twice = {"rot": rotation, "rot2": lambda x: 2.0 * rotation(x)}
    rep = uj.analyze(plane(twice), method="eorc", samples=64)
    sym = rep.details["symmetries"]
    assert [c["verified"] for c in sym["checks"]] == [True, True]
    assert sym["rank"] == 1 and sym["dim"] == 1 and rep.dim == 1 and rep.exact


@pytest.mark.parametrize("field, how", [
    (lambda x: jnp.stack([0 * x[0], jnp.sqrt(x[1])]), "exact mod p"),
    (lambda x: jnp.stack([0 * x[0], jnp.cos(x[1]) + 2.0]), "exact mod p"),
    (lambda x: jnp.stack([0 * x[0], jax.scipy.special.erf(x[1]) + 2.0]), "mpmath"),
], ids=["sqrt", "cos", "erf"])
def test_a_declared_symmetry_of_a_model_that_is_not_rational(field, how):
    """``x1' = 0``, ``x2' = a(x2) w``, ``y = x2`` with the symmetry ``e_1`` (written ``(x2^2 +
    1) / (x2^2 + 1)`` so that the bracket is no zero the graph folds): verified exactly for
    ``sqrt`` and ``cos`` (made rational), in mpmath for ``erf``; before, ``sqrt`` crashed in
    mpmath's QR solve of the mixing matrix (a column with zeros under its pivot)."""
    system = uj.System(states=("x1", "x2"), outputs={"y": lambda x: x[1]}, unknown={"w": field},
                       symmetries={"e1": lambda x: jnp.stack([(x[1] ** 2 + 1) / (x[1] ** 2 + 1), 0 * x[0]])})
    rep = uj.analyze(system, samples=64)
    check = rep.details["symmetries"]["checks"][0]
    assert check["verified"] and check["how"].startswith(how)
    assert rep.observable == {"x1": False, "x2": True}


def test_a_symmetry_nan_everywhere_is_refused_up_front():
    """A declared field NaN at the centre of the box and at three other states is refused when
    the System is built, in one line (issue 40: it was accepted, then reported unverified)."""
    with pytest.raises(uj.ModelError, match="symmetry 's' is NaN/inf at every state tried"):
        uj.System(("x1", "x2"), {"y": lambda x: x[0]}, symmetries={"s": lambda x: jnp.nan * x})
