"""Single unknown input (Algorithms 2-3 of 002, Definition 5 of 004) against the papers."""

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import SAMPLES, observable_set, published, zoo_module, zoo_report

import uio_jax as uj
from uio_jax._analysis.recursions.driver import StopReason

POLAR = ["range_v_unknown", "range_omega_unknown", "bearing_v_unknown",
         "bearing_omega_unknown", "phi_v_unknown", "phi_omega_unknown"]
DISTURBANCE = ["gamma_known_range", "gamma_known_bearing", "gamma_known_phi",
               "gamma_unknown_range", "gamma_unknown_bearing", "gamma_unknown_phi"]
CASES = ([("unicycle_polar", n) for n in POLAR] + [("unicycle_disturbance", n) for n in DISTURBANCE]
         + [("vehicle_wind", "wind_unknown")])


@pytest.mark.parametrize("module, name", CASES, ids=[f"{published(m, n)['source']}:{n}" for m, n in CASES])
def test_single_ui_matches_published_results(module, name):
    pub = published(module, name)
    rep = zoo_report(module, name)
    assert rep.method == "single_ui"
    assert rep.dim == pub["dim"]
    if "dims" in pub:
        k = len(pub["dims"])
        assert list(rep.dims[:k]) == pub["dims"]
        if len(rep.dims) > k:  # only the corrected stopping rule may compute further steps
            assert rep.details["m_star"] > rep.details["m_star_paper"]
            assert set(rep.dims[k:]) == {rep.dim}
    if "m_prime" in pub:
        assert rep.details["m_prime"] == pub["m_prime"]
    if "m_star" in pub:  # the papers' own stopping rule
        assert rep.details["m_star_paper"] == pub["m_star"]
    assert observable_set(rep) == set(pub["observable"])
    assert rep.certificate.fraction > 0.99
    assert rep.certificate.gap_decades > 1


def test_004_dims_per_case():
    """004 section 11.1: dimensions 2, 2, 1, 2, 2, 3 for the six cases."""
    dims = [zoo_report("unicycle_polar", n).dim for n in POLAR]
    assert dims == [2, 2, 1, 2, 2, 3]


def test_004_lg_zero_cases_use_a_new_output_with_the_paper_offset():
    """11.1.2 and 11.1.6: L_g h = 0, h~ = L_f h, Omega_1 = span{dh, dh~} (dim 2)."""
    for name in ("range_omega_unknown", "phi_omega_unknown"):
        rep = zoo_report("unicycle_polar", name)
        assert rep.details["relative_degree"] == 2
        assert rep.details["output"].startswith("L_v ")
        assert rep.history[1].m == 1 and rep.history[1].dim == 2
    assert zoo_report("unicycle_polar", "phi_omega_unknown").history[2].dim == 3


@pytest.mark.parametrize("module, name", [c for c in CASES if "symmetries" in published(*c)])
def test_published_symmetries_lie_in_the_unobservable_space(module, name):
    rep = zoo_report(module, name)
    mod = zoo_module(module)
    system = getattr(mod, name)()
    lo, hi = system.box()
    rng = np.random.default_rng(5)
    for sym_name in published(module, name)["symmetries"]:
        for _ in range(4):
            x = lo + (hi - lo) * rng.uniform(size=lo.shape)
            v = np.asarray(getattr(mod, sym_name)(x), dtype=float)
            N = rep.unobservable_directions(x)
            assert N.shape == (system.n, system.n - rep.dim)
            assert np.linalg.norm(v - N @ (N.T @ v)) < 1e-6 * np.linalg.norm(v)  # SVD null space: ~eps/s_min


def test_002_vehicle_in_wind():
    """002 section III-C: dims [3, 5, 6, 6], all phi_1 = 0, m' = 0, m* = 2, z observable,
    the published vector [-y, x, 0, -qz/2, -qy/2, qx/2, qt/2] spans the unobservable space."""
    rep = zoo_report("vehicle_wind", "wind_unknown")
    assert list(rep.dims) == [3, 5, 6, 6]
    assert rep.details["phi1_vanish"] is True
    assert rep.details["m_prime"] == 0 and rep.details["m_star"] == 2
    assert rep.dim == 6 and observable_set(rep) == {"z"}
    assert rep.details["output"] == "h_u"
    yaw = zoo_module("vehicle_wind").yaw_symmetry
    for X in ([1.0, 0.7, 1.2, 0.9, 0.1, -0.2, 0.25], [0.6, 1.3, 0.8, 1.1, -0.25, 0.05, 0.1]):
        X = np.array(X)
        N = rep.unobservable_directions(X)[:, 0]
        v = np.asarray(yaw(X))
        cos = abs(N @ v) / np.linalg.norm(v)
        assert cos == pytest.approx(1.0, abs=1e-9)


def test_003_table1():
    """003 Table 1: gamma known -> observable for r, beta, phi; unknown -> only phi."""
    for name in DISTURBANCE:
        rep = zoo_report("unicycle_disturbance", name)
        expected_full = name.startswith("gamma_known") or name.endswith("phi")
        assert rep.fully_observable == expected_full, name


# --------------------------------------------------------------- the stopping-rule correction
def counterexample():
    """x0' = u + x1 w, x1' = x0 x2 u, x2' = 0, y = x0 (tau = 0, m' = 0, Omega_1 = Omega_0)."""
    return zoo_module("counterexamples").single_ui_stop_rule()


def _sympy_eorc_dim(order):
    """Independent oracle: the EORC of 004 section 6 computed symbolically with sympy."""
    import sympy as sp

    x0, x1, x2, *ws = sp.symbols(f"x0 x1 x2 w0:{order}")
    z = [x0, x1, x2, *ws]
    F0 = [x1 * ws[0], 0, 0, *ws[1:], 0]  # g w plus the chain w -> w1 -> ...
    F1 = [1, x0 * x2, 0] + [0] * order
    gens = [x0]
    frontier = [x0]
    for _ in range(order):
        new = []
        for phi in frontier:
            for F in (F0, F1):
                new.append(sp.expand(sum(sp.diff(phi, zi) * Fi for zi, Fi in zip(z, F))))
        gens += new
        frontier = new
    J = sp.Matrix([[sp.diff(g, zi) for zi in z] for g in gens])
    rng = np.random.default_rng(0)
    point = {zi: sp.Float(v) for zi, v in zip(z, rng.uniform(0.5, 1.5, len(z)))}
    Jn = np.array(J.subs(point).evalf(), dtype=float)
    E = np.eye(len(z))[:3]
    rank = np.linalg.matrix_rank(Jn, tol=1e-9)
    rank_e = np.linalg.matrix_rank(np.vstack([Jn, E]), tol=1e-9)
    return rank + 3 - rank_e


def test_stopping_rule_correction_on_the_counterexample():
    rep = uj.analyze(counterexample(), samples=SAMPLES)
    assert rep.method == "single_ui"
    assert rep.details["m_prime"] == 0
    assert rep.details["m_star_paper"] == 0  # the literal rule stops at Omega_0 (dim 1)
    assert rep.details["m_star"] >= 1
    assert rep.dims[0] == 1 and rep.dims[1] == 1
    assert rep.dim == 2
    assert StopReason.parse(rep.stop_reason) == StopReason.CONVERGED_AFTER_M_PRIME.stop(m=3, prev=2)
    assert any("corrected rule" in note for note in rep.notes)
    # x0 x2 / x1 = L_{phi_1} h is observable; [0, x1, x2] is a symmetry
    assert rep.is_observable(lambda x: x[0] * x[2] / x[1])
    x = np.array([0.9, 1.3, 0.7])
    N = rep.unobservable_directions(x)
    v = np.array([0.0, x[1], x[2]])
    np.testing.assert_allclose(N[:, 0] * np.sign(N[:, 0] @ v), v / np.linalg.norm(v), atol=1e-9)


def test_counterexample_independently_by_symbolic_eorc():
    """Independent check: the symbolic EORC gives dim 2 on the original state at k = 2."""
    assert _sympy_eorc_dim(1) == 1
    assert _sympy_eorc_dim(2) == 2


# --------------------------------------------------------------- applicability and edge cases
def drift_example():
    return uj.System(states=("x1", "x2"), outputs={"y": lambda x: x[0]},
                     unknown={"w": lambda x: jnp.array([1.0, 0.0])},
                     drift=lambda x: jnp.stack([x[1], 0.0 * x[0]]))


def test_single_ui_refuses_drift_and_points_to_eorc():
    with pytest.raises(uj.OptionError, match="eorc"):
        uj.analyze(drift_example(), method="single_ui")


def test_single_ui_refuses_two_unknown_inputs():
    s = uj.System(states=("a", "b"), outputs={"y": lambda x: x[0]},
                  unknown={"w1": lambda x: jnp.array([1.0, 0.0]),
                           "w2": lambda x: jnp.array([0.0, 1.0])})
    with pytest.raises(uj.OptionError, match="exactly one unknown input"):
        uj.analyze(s, method="single_ui")


def test_unknown_input_that_never_reaches_the_outputs():
    """x1' = u x2, x2' = 0, x3' = w, y = x1: L_g vanishes on every Lie derivative, so w does
    not matter and the answer is the ORC of the known field: x1, x2 observable, x3 not."""
    s = uj.System(states=("x1", "x2", "x3"), outputs={"y": lambda x: x[0]},
                  known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0], 0.0 * x[0]])},
                  unknown={"w": lambda x: jnp.array([0.0, 0.0, 1.0])})
    rep = uj.analyze(s, samples=256)
    assert rep.details["unknown_input_affects_outputs"] is False
    assert rep.dim == 2 and observable_set(rep) == {"x1", "x2"}
    assert any("does not affect the outputs" in n for n in rep.notes)


def test_reports_state_the_semantics():
    rep = zoo_report("unicycle_polar", "range_v_unknown")
    assert "smooth (analytic) functions of time" in rep.semantics
    assert "jump" in rep.semantics
    assert rep.to_dict()["semantics"] == rep.semantics
