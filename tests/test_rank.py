"""Certified generic rank: the decision rule, round-off that could fake a rank, thin sets."""

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj
from uio_jax._analysis.decisions.rank import decide_increase, decide_rank, default_rtol


def _spectra(ranks, m=5, seed=0):
    """Synthetic s_i/s_1 rows with the given numerical ranks (noise floor ~1e-14)."""
    rng = np.random.default_rng(seed)
    rows = []
    for r in ranks:
        s = np.sort(rng.uniform(1e-3, 1.0, m))[::-1]
        s[0] = 1.0
        s[r:] = rng.uniform(1e-15, 1e-13, m - r)
        rows.append(np.sort(s)[::-1])
    return np.array(rows)


def test_decide_rank_resists_drops_and_fakes():
    ranks = [3] * 90 + [2] * 5 + [4] * 5  # 5% near the singular set, 5% faked by round-off
    d = decide_rank(_spectra(ranks), np.ones(100, bool), 1e-8)
    assert d.rank == 3
    assert d.fraction == pytest.approx(0.9)
    assert d.sigma_r_min >= 1e-3 and d.sigma_next_max <= 1e-13
    assert d.samples == 100


def test_decide_rank_ignores_invalid_samples():
    ranks = [2] * 10 + [4] * 30
    valid = np.array([True] * 10 + [False] * 30)
    assert decide_rank(_spectra(ranks), valid, 1e-8).rank == 2


def test_decide_increase_majority_and_margins():
    rho = np.array([1e-3] * 8 + [1e-14] * 2)
    d = decide_increase(rho, np.ones(10, bool), 1e-8, base_rank=2)
    assert d.rank == 3 and d.fraction == pytest.approx(0.8) and d.sigma_r_min == 1e-3
    d = decide_increase(rho[::-1][:3], np.ones(3, bool), 1e-8, base_rank=2)
    assert d.rank == 2 and d.sigma_next_max == 1e-14


def _chain_unicycle(scale_r=1.0, scale_a=1.0):
    """Polar unicycle whose heading rate hides behind a chain of three more states:
    theta' = a1 w, a1' = a2 w, a2' = a3 w, a3' = 0. y = r. The rotation about the origin
    (phi and theta shifted together) is an exact symmetry; every other direction is
    observable, but only through Lie derivatives of order up to 5 of cos/sin terms."""

    def v_field(x):
        r, phi, th = x[0], x[1], x[2]
        z = 0.0 * r
        return jnp.stack([jnp.cos(th - phi), jnp.sin(th - phi) / r, z, z, z, z])

    def w_field(x):
        z = 0.0 * x[0]
        return jnp.stack([z, z, x[3], x[4], x[5], z])

    return uj.System(
        states=("r", "phi", "theta", "a1", "a2", "a3"),
        outputs={"r": lambda x: x[0]},
        known={"v": v_field, "w": w_field},
        domain={"r": (scale_r, 2 * scale_r), "a1": (scale_a, 2 * scale_a),
                "a2": (scale_a, 2 * scale_a), "a3": (scale_a, 2 * scale_a)},
        angles=("phi", "theta"),
    )


@pytest.mark.parametrize("scale_r, scale_a", [(1.0, 1.0), (1e4, 1e-3)])
def test_high_order_derivatives_do_not_fake_rank(scale_r, scale_a):
    """Derivatives up to order 5 on states scaled by 1e4 and 1e-3: round-off must not fill
    in the rotation symmetry, and the genuine directions must not be lost."""
    rep = uj.analyze(_chain_unicycle(scale_r, scale_a), samples=1024)
    assert rep.dim == 5
    assert {s for s, ok in rep.observable.items() if ok} == {"r", "a1", "a2", "a3"}
    assert len(rep.history) >= 5  # needs Lie derivatives of high order
    cert = rep.certificate
    assert cert.sigma_next_max < cert.rtol < cert.sigma_r_min
    x = np.array([1.5 * scale_r, 0.3, -1.0, 1.2 * scale_a, 1.7 * scale_a, 1.1 * scale_a])
    N = rep.unobservable_directions(x)
    np.testing.assert_allclose(np.abs(N[:, 0]), np.array([0, 1, 1, 0, 0, 0]) / np.sqrt(2), atol=1e-8)


def test_rank_drop_on_a_thin_set_does_not_lower_the_generic_rank():
    """y2 = x1 + x2^9: dy2 is numerically parallel to dy1 wherever |x2| < ~0.13 (a thick
    numerical neighbourhood of the singular set x2 = 0, ~20% of this domain)."""
    s = uj.System(states=("x1", "x2"),
                  outputs={"y1": lambda x: x[0], "y2": lambda x: x[0] + x[1] ** 9},
                  domain={"x1": (-1.0, 1.0), "x2": (-0.3, 1.0)})
    rep = uj.analyze(s, samples=2048)
    assert rep.dim == 2 and rep.fully_observable
    cert = rep.certificate
    assert 0.6 < cert.fraction < 0.95  # the drop is visible in the evidence
    # the vote on y2 (split, or clear on the decision samples) is settled exactly: a
    # rational model, every decision modulo p
    assert cert.arithmetic.name == "EXACT" and cert.float64_decisions == 0 and rep.exact


def test_samples_where_the_model_is_undefined_are_dropped_and_counted():
    s = uj.System(states=("x1", "x2"),
                  outputs={"y": lambda x: jnp.sqrt(x[0]) + x[1]},
                  known={"u": lambda x: jnp.stack([1.0 + 0.0 * x[0], x[0]])},
                  domain={"x1": (-1.0, 1.0)})
    rep = uj.analyze(s, samples=1000)
    cert = rep.certificate  # every decision exact: the screen stopped at the decision samples
    screened = cert.used + cert.dropped
    assert 0.3 < cert.dropped / screened < 0.7 and screened + cert.capped == 1000
    assert rep.dim == 2


def test_unit_covectors_tested_in_one_product_equal_the_generic_test():
    """``test_units`` (residuals of every e_j from ``I - B^T B``) equals ``test`` of the
    unit covectors; ``contains`` and ``absorb`` accept either without re-testing."""
    from uio_jax._analysis.decisions.rank import Codistribution
    from uio_jax._calculus.generators import Node

    rng = np.random.default_rng(1)
    S, n = 300, 6
    codist = Codistribution(n, S, rng.uniform(0.5, 2.0, n), default_rtol())
    g = rng.normal(size=(S, 3, n))
    g[:, 0, 3:] = g[:, 1, 3:] = 0.0  # the span lies in span{e_1, e_2, e_3}
    g[:, 2] = g[:, 0] + 2.0 * g[:, 1]  # dependent: rank 2
    codist.absorb([Node(f"g{i}", "scalar") for i in range(3)], g)
    assert codist.rank == 2
    units = np.zeros((n, S, n))
    units[np.arange(n), :, np.arange(n)] = 1.0
    generic, fast = codist.test(units), codist.test_units(n)
    for field in ("cands", "rho", "dirs"):
        np.testing.assert_allclose(getattr(fast, field), getattr(generic, field), atol=1e-13)
    member = [m for m, _ in codist.contains(None, fast)]
    assert member == [m for m, _ in codist.contains(units)] == [False] * n
    # absorbing e_1..e_3 from the one test raises the rank by exactly 1 (span is 2 of 3)
    added = codist.absorb([Node(f"e{i}", "scalar") for i in range(3)], None, fast.first(3))
    assert len(added) == 1 and codist.rank == 3


def test_copy_is_independent_and_starts_without_decisions():
    """``Codistribution.copy``: the same span, absorbing into the copy leaves the original
    unchanged, and the copy's decision lists hold only its own decisions."""
    from uio_jax._analysis.decisions.rank import Codistribution
    from uio_jax._calculus.generators import Node

    rng = np.random.default_rng(2)
    S, n = 200, 4
    codist = Codistribution(n, S, np.ones(n), default_rtol())
    codist.absorb([Node(f"g{i}", "scalar") for i in range(2)], rng.normal(size=(S, 2, n)))
    before = (codist.grads.copy(), codist.kept_basis().copy(), list(codist.nodes), len(codist.acceptances))
    new = rng.normal(size=(S, 1, n))
    for trial in (False, True):  # a trial copy shares the storage, the span is unchanged too
        fork = codist.copy(trial=trial)
        assert fork.rank == 2 and fork.acceptances == [] and fork.rejections == []
        np.testing.assert_array_equal(fork.kept_basis(), codist.kept_basis())
        fork.absorb([Node("e", "scalar")], new)
        assert fork.rank == 3 and len(fork.acceptances) == 1
        np.testing.assert_array_equal(codist.grads, before[0])
        np.testing.assert_array_equal(codist.kept_basis(), before[1])
        assert codist.nodes == before[2] and len(codist.acceptances) == before[3]
        assert (fork._rows is codist._rows) == (trial and len(codist._rows) >= 3)
