"""Weak rank decisions are settled again beyond float64, or reported undecided.

Every case is derived by hand. With ``y1 = x1`` and ``y2 = x1 + eps g(x2)``, the span of
``dy1, dy2`` is 2-dimensional for any ``eps != 0`` (``y2 - y1 = eps g(x2)`` with ``g`` not
constant), so both states are observable. With ``eps = 1e-9`` the second row's distance to
the first, after scaling to unit rows, is about ``1e-9 |g'|``: under ``rtol = 1e-8`` at
every sample, a unanimous but wrong float64 vote ("dependent"), whose median lies within
two decades of ``rtol``: weak, so it is settled again.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers import zoo_system

import uio_jax as uj
from uio_jax._analysis.decisions.settle import WEAK_ABOVE, WEAK_BELOW, Settler, is_weak
from uio_jax._analysis.results.evidence import Arithmetic
from uio_jax._analysis.results.kinds import Answer, Route
from uio_jax._engine import graph_exact
from uio_jax._engine.graph import Graph

EPS = 1e-9


def _two_outputs(second):
    return uj.System(states=("x1", "x2"), outputs={"y1": lambda x: x[0], "y2": second},
                     domain={"x1": (0.5, 1.5), "x2": (0.5, 1.5)})


def _bilirubin2():
    """Bilirubin model of Meshkat, Kuo and DiStefano (PLoS ONE 9, e110261, 2014) as in
    StructuralIdentifiability.jl's benchmarks (``Bilirubin2_io``): four compartments, seven
    rate constants, the input ``u`` into ``x1``, output ``y = x1``. Every parameter is
    locally identifiable (SI.jl's exact answer; the 11 x 11 Jacobian of the output's first
    11 Taylor coefficients is generically invertible)."""
    def drift(x, p):
        k01, k12, k13, k14, k21, k31, k41 = p
        x1, x2, x3, x4 = x
        return jnp.stack([-(k21 + k31 + k41 + k01) * x1 + k12 * x2 + k13 * x3 + k14 * x4,
                          k21 * x1 - k12 * x2, k31 * x1 - k13 * x3, k41 * x1 - k14 * x4])

    return uj.System(states=("x1", "x2", "x3", "x4"), outputs={"y": lambda x, p: x[0]},
                     known={"u": lambda x, p: jnp.array([1.0, 0.0, 0.0, 0.0])}, drift=drift,
                     params=("k01", "k12", "k13", "k14", "k21", "k31", "k41"), name="bilirubin2")


@pytest.mark.parametrize("method", ["series", "orc"])
def test_bilirubin2_last_direction_near_rtol_is_found(method):
    """A published case where float64 fails: the 11th direction of the series test (the
    order-10 coefficient) sits at the tolerance after scaling, and the float64 majority
    calls it dependent at seed 0 (SI.jl's issue: rank 10), independent by a split vote at
    others. Settled exactly, every parameter is identifiable, at every seed."""
    for seed in (0, 1, 2):
        rep = uj.analyze(_bilirubin2(), method=method, seed=seed)
        assert rep.dim == 11 and all(rep.identifiable.values()) and all(rep.observable.values())
        cert = rep.certificate
        assert cert.status == "escalated" and cert.undecided == 0
        if method == "series":
            last = [e for e in cert.escalations if e.what.startswith("y_10")]
            assert len(last) == 1  # weak: split, at the tolerance (dependent at seed 0)
            assert last[0].result == "independent" and last[0].how.startswith("exact mod p")
            if seed == 0:
                assert last[0].float64.startswith("dependent")


def test_a_tiny_rational_direction_is_settled_exactly():
    """Rational model: the escalation is exact (modulo p) and finds the second direction."""
    rep = uj.analyze(_two_outputs(lambda x: x[0] + EPS * x[1] ** 2), samples=256)
    assert rep.method == "orc" and rep.dim == 2
    assert rep.observable == {"x1": True, "x2": True}
    cert = rep.certificate
    assert cert.status == "escalated" and cert.undecided == 0
    esc = [e for e in cert.escalations if e.what.startswith("y2")]
    assert len(esc) == 1
    assert esc[0].float64.startswith("dependent") and esc[0].result == "independent"
    assert esc[0].how.startswith("exact mod p") and esc[0].bound == 0.0
    assert "escalated" in str(cert) and "UNDECIDED" not in str(rep)


def test_a_tiny_trigonometric_direction_is_settled_exactly():
    """``cos`` is made rational (a point of the circle per argument,
    ``uio_jax._engine.graph_elementary``): the escalation is exact modulo p."""
    rep = uj.analyze(_two_outputs(lambda x: x[0] + EPS * jnp.cos(x[1])), samples=256)
    assert rep.dim == 2 and all(rep.observable.values())
    esc = [e for e in rep.certificate.escalations if e.what.startswith("y2")]
    assert len(esc) == 1 and esc[0].result == "independent" and esc[0].how.startswith("exact mod p")


def test_a_tiny_direction_of_a_model_not_made_rational_is_settled_in_extended_precision():
    """``erf`` is not made rational: the escalation runs mpmath at two precisions."""
    rep = uj.analyze(_two_outputs(lambda x: x[0] + EPS * jax.scipy.special.erf(x[1])), samples=256)
    assert rep.dim == 2 and all(rep.observable.values())
    esc = [e for e in rep.certificate.escalations if e.what.startswith("y2")]
    assert len(esc) == 1 and esc[0].result == "independent" and esc[0].how.startswith("mpmath")


def test_an_exact_dependence_under_round_off_is_confirmed():
    """``y2 = y1 (1 + 1e-9)``: dependent; float64 agrees and is clear (rows equal after
    scaling, distance at round-off): nothing to settle, dim 1, x2 not observable."""
    rep = uj.analyze(_two_outputs(lambda x: x[0] * (1.0 + EPS)), samples=256)
    assert rep.dim == 1 and rep.observable == {"x1": True, "x2": False}
    assert rep.certificate.status == "ok"


def erf_part(x):
    """Not made rational (erf): a weak decision about it goes to extended precision."""
    return x[0] + EPS * jax.scipy.special.erf(x[1])


@pytest.fixture
def unsettled(monkeypatch):
    """Extended precision cannot decide (as when its two precisions disagree): the weak
    decisions of a model that is not rational stay undecided."""
    from uio_jax._analysis.decisions.settle import Settler
    from uio_jax._analysis.results.evidence import Escalation, Settlement

    monkeypatch.setattr(Settler, "_settle_extended",
                        lambda self, record, exprs: Escalation(**record, how=Settlement.NONE, detail="none: test",
                                                               result="undecided"))


def test_a_weak_decision_that_cannot_be_settled_is_reported_undecided(unsettled):
    rep = uj.analyze(_two_outputs(erf_part), samples=256)
    cert = rep.certificate
    assert cert.status == "undecided" and cert.undecided >= 1
    undecided = [e for e in cert.escalations if e.result == "undecided"]
    assert any(e.what.startswith("y2") and e.how_text.startswith("none") for e in undecided)
    assert any(n.startswith("UNDECIDED") for n in rep.notes)
    assert "UNDECIDED" in str(rep)
    d = rep.to_dict()["certificate"]
    assert d["status"] == "undecided" and d["escalations"][0]["result"] == "undecided"


def test_weakness_rule():
    """Median in the band around rtol, or a split vote: weak; clear votes are not."""
    valid = np.ones(100, dtype=bool)
    assert is_weak(np.full(100, 1e-9), valid, 1e-8, 1.0)
    assert is_weak(np.full(100, 1e-11), valid, 1e-8, 1.0)
    assert not is_weak(np.full(100, 1e-8 * 10 ** (WEAK_ABOVE + 0.5)), valid, 1e-8, 1.0)
    assert not is_weak(np.full(100, 1e-8 * 10 ** -(WEAK_BELOW + 0.5)), valid, 1e-8, 1.0)
    assert not is_weak(np.full(100, 1e-15), valid, 1e-8, 1.0)
    assert is_weak(np.full(100, 1e-3), valid, 1e-8, 0.7)


def test_modular_gradients_and_rank_by_hand():
    """f = x0^2 / x1 at (3, 5) modulo p: value 9/5, gradient (6/5, -9/25)."""
    p = graph_exact.PRIME
    g = Graph(2)
    f = g.div(g.ipow(g.x(0), 2), g.x(1))
    values, grads = graph_exact.gradients_mod_p(g, [f], [[3, 5]])
    inv5, inv25 = pow(5, -1, p), pow(25, -1, p)
    assert values[0, 0] == 9 * inv5 % p
    assert list(grads[0, 0]) == [6 * inv5 % p, (-9 * inv25) % p]
    assert graph_exact.rank_mod_p([[1, 2], [2, 4]]) == 1
    assert graph_exact.rank_mod_p([[1, 2], [2, 5]]) == 2
    with pytest.raises(graph_exact.Singular):
        graph_exact.gradients_mod_p(g, [f], [[3, 0]])


def test_settler_on_a_graph_by_hand():
    """span{d x0} and the candidate x0 + 1e-12 x1 (independent), x0 * (1 + 1e-12)
    (dependent): settled exactly whatever float64 said."""
    from uio_jax._calculus.generators import Node

    g = Graph(2)
    settler = Settler(g, [0.5, 0.5], [1.5, 1.5], seed=0)
    kept = [Node("x0", "scalar", expr=g.x(0))]
    tiny = g.add(g.x(0), g.mul(g.const(1e-12), g.x(1)))
    same = g.mul(g.x(0), g.const(1.0 + 1e-12))
    up = settler.settle(kept, Node("tiny", "scalar", expr=tiny), "dependent")
    flat = settler.settle(kept, Node("same", "scalar", expr=same), "independent")
    assert up.result == "independent" and up.bound == 0.0
    assert flat.result == "dependent" and 0.0 <= flat.bound < 1e-30


@pytest.mark.parametrize("seed", range(5))
def test_a_zero_gradient_under_round_off_is_dependent_in_extended_precision(seed):
    """``h c / d - h (c / d)`` with ``h = x1 + erf(x0)`` (not made rational): its gradient is
    zero, computed as rounding noise along ``d x0`` (about 1e-32 at 30 digits, 1e-62 or 0 at
    60). The noise's direction is not a row: against ``span{d x1}`` the candidate is
    dependent at every seed (a normalized noise row was "independent" at seeds 0 and 3)."""
    from uio_jax._calculus.generators import Node

    g = Graph(2)
    h = g.add(g.x(1), g.unary("erf", g.x(0)))
    c, d = g.const(0.7), g.const(1.3)
    noise = g.add(g.div(g.mul(h, c), d), g.neg(g.mul(h, g.div(c, d))))
    settler = Settler(g, [0.5, 0.5], [1.5, 1.5], seed=seed)
    found = settler.settle([Node("x1", "scalar", expr=g.x(1))], Node("noise", "scalar", expr=noise), "dependent")
    assert found.how == "mpmath" and found.result == "dependent"


def test_roots_with_no_common_point_modulo_p_are_decided_in_extended_precision():
    """``sqrt(x0)`` and ``sqrt(7 x0)``: their arguments are never squares together modulo
    ``p = 2^127 - 1`` (7 is no square there: ``p = 1 mod 7``, quadratic reciprocity), so the
    modular points of their variety do not exist. The symbolic route's decisions are in
    extended precision (they were left undecided, all three); the plan takes the Taylor
    route, exact with roots in ``F_p[i]``, at any size."""
    from uio_jax._calculus.generators import Node

    g = Graph(2)
    expr = g.add(g.unary("sqrt", g.x(0)), g.mul(g.x(1), g.unary("sqrt", g.mul(g.const(7), g.x(0)))))
    settler = Settler(g, [0.5, 0.5], [1.5, 1.5], seed=0)
    assert pow(7, (graph_exact.PRIME - 1) // 2, graph_exact.PRIME) == graph_exact.PRIME - 1
    assert settler.arithmetic([expr]) is Arithmetic.EXTENDED
    assert settler.arithmetic([expr], roots_in_extension=True) is Arithmetic.EXACT
    assert settler.arithmetic([g.mul(g.x(0), g.x(1))]) is Arithmetic.EXACT  # what needs no root
    system = uj.System(states=("x0", "x1"), outputs={"y": lambda x: jnp.sqrt(x[0]) + x[1] * jnp.sqrt(7 * x[0])},
                       drift=lambda x: jnp.array([x[1], -x[0]]))
    rep = uj.analyze(system)  # 2 coordinates, yet the Taylor route: it takes roots in F_p[i]
    assert rep.plan.route is Route.TAYLOR and rep.answer is Answer.EXACT and rep.dim == 2
    assert rep.plan.fallback.arithmetic is Arithmetic.EXTENDED and "no common point" in rep.plan.why
    found = settler.settle([], Node("y", "scalar", expr=expr), "independent")  # the symbolic route's decisions
    assert found.how == "mpmath" and found.result == "independent"


def test_undecided_verdicts_are_named_in_the_report_and_the_batch_table(unsettled):
    """The undecided vote rejected y2 (float64: dependent): the verdicts it could change are
    the 'not observable' ones: x2. The CLI text and the batch row say UNDECIDED."""
    weak = _two_outputs(erf_part)
    settled = _two_outputs(lambda x: x[0] + EPS * x[1] ** 2)
    rep = uj.analyze(weak, samples=256)
    assert rep.undecided == ("x2",) and rep.to_dict()["undecided"] == ["x2"]
    assert "x2  UNDECIDED (float64: not observable)" in str(rep)
    assert uj.analyze(settled, samples=256).undecided == ()
    result = uj.batch_analyze([weak, settled], samples=256)
    rows = result.rows
    assert [r.status for r in rows] == ["undecided", "escalated"]
    assert rows[0].undecided == ("x2",) and rows[0].to_dict()["status"] == "undecided"
    table = result.table()
    assert "UNDECIDED: x2" in table and "escalated" in table
    assert "UNDECIDED: x2" in result.to_markdown()


def test_is_observable_settles_or_refuses(unsettled):
    """``is_observable`` of ``x1 + 1e-9 x2^2`` on the span of dx1 alone (y1 = x1): float64
    says dependent, exact arithmetic says not (False, settled); a question that cannot be
    settled is an error, not an uncertified answer; a function outside the expression graph
    is refused in one line."""
    rep = uj.analyze(uj.System(states=("x1", "x2"), outputs={"y1": lambda x: x[0]}), samples=256)
    assert rep.dim == 1
    assert rep.is_observable(lambda x: x[0] + EPS * x[1] ** 2) is False
    assert rep.is_observable(lambda x: 2.0 * x[0]) is True
    with pytest.raises(uj.ModelError, match="undecided"):
        rep.is_observable(erf_part)
    with pytest.raises(uj.ModelError, match="no rule for the JAX primitive 'erf_inv'") as info:
        rep.is_observable(lambda x: jax.lax.erf_inv(0.5 * jnp.tanh(x[1])))
    assert "\n" not in str(info.value)


def test_a_step_that_keeps_nothing_is_settled_exactly(monkeypatch):
    """``y = x1``, ``x1' = x1 + eps x2``: ``d L_f y = (1, eps)`` lies ``eps`` (scaled) from
    ``span{dy}``, under float64's round-off band for ``eps = 1e-14``: the vote rejects it
    clearly, the step keeps nothing, and a step that keeps nothing would end the ORC with
    ``x2`` unobservable. It is settled exactly instead (a rational model: every clear
    rejection is verified modulo p): independent, kept, ``x2`` observable
    (``x2 = (y' - y) / eps``). Without the check the answer is dim 1."""

    def model(eps):
        return uj.System(("x1", "x2"), {"y": lambda x: x[0]},
                         drift=lambda x: jnp.array([x[0] + eps * x[1], 0.0]))

    rep = uj.analyze(model(1e-14), samples=256)
    assert rep.dims == (1, 2) and rep.observable == {"x1": True, "x2": True}
    found = [e for e in rep.certificate.escalations if e.what == "L_f0 y against rank 1"]
    assert len(found) == 1 and found[0].result == "independent" and found[0].float64.startswith("dependent")
    monkeypatch.setattr(Settler, "settle", lambda self, *args, **kw: None)  # float64 votes alone
    assert uj.analyze(model(1e-14), samples=256).dims == (1, 1)


def test_a_stopping_step_of_a_model_not_made_rational_is_settled_in_extended_precision():
    """The same model with ``erf`` (not made rational): the stopping step's rejection is
    settled in mpmath (independent): dim 2, decided in extended precision, not exact."""
    system = uj.System(("x1", "x2"), {"y": lambda x: x[0]},
                       drift=lambda x: jnp.array([x[0] + 1e-14 * jax.scipy.special.erf(x[1]), 0.0]))
    rep = uj.analyze(system, samples=256)
    assert rep.dims == (1, 2) and rep.certificate.arithmetic is Arithmetic.EXTENDED and not rep.exact


def test_the_stop_of_a_rational_orc_is_confirmed_exactly():
    """The vehicle without wind (quaternions: rational) stops on ``Omega_2 = Omega_1``; the
    rejections of step 2 are confirmed dependent modulo p and counted apart from the rank
    increases."""
    rep = uj.analyze(zoo_system("vehicle_wind", "no_wind"), samples=256)
    cert = rep.certificate
    assert rep.stop_reason.startswith("Omega_2 = Omega_1") and cert.rejections_verified > 0
    assert cert.float64_decisions == 0 and cert.arithmetic is Arithmetic.EXACT and rep.exact
    assert 0 < cert.error_bound < 1e-30 and cert.to_dict()["arithmetic"] == "exact"


def test_a_dependence_takes_more_points_while_its_degree_bound_needs_them(monkeypatch):
    """``d(x1^2)`` lies in ``span{d x1}``: modulo p the dependence holds at every point, with
    probability bound ``(D / p)^points``; where one point's bound exceeds ``MAX_BOUND``,
    points are added up to ``MAX_POINTS`` (else: undecided)."""
    from uio_jax._analysis.decisions import settle as _settle
    from uio_jax._calculus.generators import Node

    g = Graph(2)
    x1 = g.coords[0]
    kept, cand = [Node("x1", "scalar", expr=x1)], Node("x1^2", "scalar", expr=g.mul(x1, x1))
    one = Settler(g, np.zeros(2), np.ones(2), 0).settle(kept, cand, "dependent")
    assert one.result == "dependent" and one.how_text.endswith("at 1 point")
    monkeypatch.setattr(_settle, "MAX_BOUND", one.bound ** 1.5)  # two points needed
    two = Settler(g, np.zeros(2), np.ones(2), 0).settle(kept, cand, "dependent")
    assert two.result == "dependent" and two.how_text.endswith("at 2 points") and two.bound == one.bound ** 2
    monkeypatch.setattr(_settle, "MAX_POINTS", 1)
    assert Settler(g, np.zeros(2), np.ones(2), 0).settle(kept, cand, "dependent").result == "undecided"


def test_modular_gradients_with_long_sums_and_interleaved_coordinates():
    """Sums left unreduced (more than ``_UNREDUCED_DEPTH`` in a row) and sparse rows
    (operands on interleaved coordinates): values and gradients equal the exact rational
    ones, computed by sympy, reduced modulo p."""
    sympy = pytest.importorskip("sympy")
    p = graph_exact.PRIME
    n, terms = 6, 3 * graph_exact._UNREDUCED_DEPTH
    g = Graph(n)
    s = sympy.symbols(f"x0:{n}")
    node, expr = g.zero, sympy.Integer(0)
    for i in range(terms):
        a, b, c = i % n, (i + 2) % n, (i + 3) % n
        term = g.div(g.mul(g.x(a), g.x(b)), g.add(g.x(c), g.one))
        node = g.sub(node, term) if i % 3 == 0 else g.add(node, term)
        t = s[a] * s[b] / (s[c] + 1)
        expr = expr - t if i % 3 == 0 else expr + t
    point = [3, 5, 7, 11, 13, 17]
    values, grads = graph_exact.gradients_mod_p(g, [node], [point])

    def mod(q):
        q = sympy.Rational(q)
        return int(q.p) % p * pow(int(q.q), -1, p) % p

    at = dict(zip(s, point))
    assert values[0, 0] == mod(expr.subs(at))
    assert list(grads[0, 0]) == [mod(sympy.diff(expr, v).subs(at)) for v in s]


def test_clear_rejections_are_verified_exactly(monkeypatch):
    """ORC of ``y = (x1, x1 + 1e-10 x2, x3)``, ``x1' = x5``, ``x3' = x1 + 1e-15 x4``.

    Step 0: ``dy2`` lies 1e-10 (scaled) from ``span{dy1}``: a weak vote "dependent", settled
    exactly as independent: float64 has been contradicted. Step 1 keeps ``d L_f y1 = dx5``
    and meets ``d L_f y3 = dx1 + 1e-15 dx4``, a genuine direction 7 decades under ``rtol``:
    a clear float64 rejection, in a step that keeps something (no closure check). Every
    clear vote is verified exactly: independent, kept, every state observable
    (``x4 = (y3' - y1) / 1e-15``). With clear votes left to float64 the answer is dim 4, x4
    unobservable."""

    def drift(x):
        return jnp.array([x[4], 0.0, x[0] + 1e-15 * x[3], 0.0, 0.0])

    model = uj.System(("x1", "x2", "x3", "x4", "x5"),
                      {"y1": lambda x: x[0], "y2": lambda x: x[0] + 1e-10 * x[1], "y3": lambda x: x[2]},
                      drift=drift)
    rep = uj.analyze(model, samples=256, method="orc")
    assert rep.dims == (3, 5) and rep.fully_observable
    cert = rep.certificate
    weak = [e for e in cert.escalations if e.what == "y2 against rank 1"]
    assert len(weak) == 1 and weak[0].float64.startswith("dependent") and weak[0].result == "independent"
    # (asked against rank 3, then against rank 4 once d L_f y1 is kept)
    deep = [e for e in cert.escalations if e.what.startswith("L_f0 y3 against")]
    assert deep and all(e.result == "independent" for e in deep)
    assert all("median rho -7." in e.float64 for e in deep)  # clear votes, not weak ones
    assert cert.rejections_verified >= 1  # d L_f y2 = dx5: dependent, confirmed exactly
    assert f"{cert.rejections_verified} other rejections" in str(cert)

    # the same model with clear votes left to float64: the clear rejection stands
    real = Settler.settle

    def weak_only(self, kept, candidate, float64, exact_only=False, vote=None):
        return None if exact_only else real(self, kept, candidate, float64, vote=vote)

    monkeypatch.setattr(Settler, "settle", weak_only)
    assert uj.analyze(model, samples=256, method="orc").dims == (3, 4, 4)


def test_degree_bounds_hold_and_share_common_denominators():
    """``graph_exact.degrees`` bounds the numerator and denominator degrees of random
    rational graphs (checked against sympy's reduced forms), and a recurrence dividing
    every term by the same node (a Taylor quotient) keeps its denominator: ``c_k = (x1 -
    sum_{j<k} c_j x0) / q`` has denominator ``q^(k+1)`` (degree k + 1); bounding each sum by
    the product of its terms' denominators gave ``2^k``."""
    import random

    import sympy as sp

    from uio_jax._engine import graph_exact

    xs = sp.symbols("x0:3")
    rng = random.Random(3)
    for _ in range(30):
        g = Graph(3)
        pool = [(g.x(i), xs[i]) for i in range(3)] + [(g.const(2.0), sp.Integer(2))]
        for _ in range(8):
            (a, ea), (b, eb) = rng.choice(pool), rng.choice(pool)
            op = rng.choice(["add", "mul", "div", "neg", "ipow"])
            if op == "add":
                pool.append((g.add(a, b), ea + eb))
            elif op == "mul":
                pool.append((g.mul(a, b), ea * eb))
            elif op == "div" and eb != 0:
                pool.append((g.div(a, b), ea / eb))
            elif op == "neg":
                pool.append((g.neg(a), -ea))
            elif op == "ipow":
                k = rng.choice([-2, -1, 2, 3])
                if k > 0 or ea != 0:
                    pool.append((g.ipow(a, k), ea ** k))
        nodes = [nd for nd, _ in pool]
        for (num, den), (_, e) in zip(graph_exact.degrees(g, nodes), pool):
            p, q = sp.fraction(sp.cancel(sp.together(e)))
            assert sp.Poly(p, *xs).total_degree() <= num and sp.Poly(q, *xs).total_degree() <= den

    g = Graph(2)
    q = g.add(g.x(0), g.x(1))
    cs = [g.div(g.x(0), q)]
    for _ in range(30):
        total = g.x(1)
        for c in cs:
            total = g.add(total, g.neg(g.mul(c, g.x(0))))
        cs.append(g.div(total, q))
    (num, den), = graph_exact.degrees(g, [cs[-1]])
    assert den == 31 and num <= 2 * 31
