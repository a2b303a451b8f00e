"""The machine-word Taylor kernel (int64 lanes modulo random primes below 2^26) against the
reference arithmetic and against independent evaluations.

* its coefficients and gradients equal the object-integer arithmetic modulo the same prime
  at the same point, and ``k!`` times them equal the symbolic Lie derivatives evaluated modulo
  that prime (:class:`~uio_jax._engine.graph_exact.ModularEvaluator`), on random models
  (rational, and with sin, exp, log: the generators' values shared);
* its echelon form decides ranks and memberships as the Python-integer one does;
* its roots (``F_p[i]``, random branches) satisfy ``w^b = u^a`` as series, gradients included;
* the degree and height bounds stay polynomial where the old bounds grew exponentially;
* a prime that divides a minor (a fault of one lane) is caught: the row rises in another
  lane, the faulty lane is dropped, and the verdict equals the symbolic route's; a lane that
  cannot certify its dependence alone never reports it;
* the primes are drawn from the range and the classes they should, and the count of those
  primes the bound uses is the sieve's.
"""

import math
from fractions import Fraction

import jax.numpy as jnp
import numpy as np
import pytest

import uio_jax as uj
from uio_jax._analysis.recursions import taylor_route
from uio_jax._engine import graph_elementary, graph_exact, primes, taylor_rank
from uio_jax._engine.graph import Graph
from uio_jax._engine.taylor import Modular, TaylorSeries
from uio_jax._engine.taylor_degrees import TaylorDegrees
from uio_jax._engine.taylor_program import program
from uio_jax._engine.taylor_word import Word, WordSquare
from uio_jax._engine.word_echelon import WordEchelon


def _random_model(seed, kinds, n_states=4, n_params=2):
    """A random model on a bare graph: ``(graph, drift entries, output)``."""
    rng = np.random.default_rng(seed)
    n = n_states + n_params
    g = Graph(n)
    xs = [g.x(i) for i in range(n)]

    def pick():
        return xs[int(rng.integers(n))]

    def term():
        kind = kinds[int(rng.integers(len(kinds)))]
        a, b = pick(), pick()
        c = g.const(float(rng.integers(1, 9)) / 4)
        return {"mul": lambda: g.mul(c, g.mul(a, b)), "lin": lambda: g.mul(c, a),
                "div": lambda: g.div(a, g.add(g.const(1.0), g.ipow(b, 2))), "sin": lambda: g.unary("sin", a),
                "exp": lambda: g.mul(c, g.unary("exp", g.neg(a))),
                "log": lambda: g.unary("log", g.add(c, g.ipow(a, 2))),
                "sqrt": lambda: g.unary("sqrt", g.add(g.ipow(g.sub(a, b), 2), c)),
                "pow": lambda: g.binary("pow", g.add(c, g.ipow(a, 2)), g.const(0.75))}[kind]()

    f0 = [g.add(term(), g.mul(g.x(n_states + i % n_params), g.x(i))) for i in range(n_states)] + [None] * n_params
    h = g.add(term(), g.x(0))
    return g, f0, h


def _keys(ins):
    """The generator keys of a program's instructions."""
    for op, _, param in ins:
        if op == "sin":
            yield ("circle", param[1])
        elif op == "exp":
            yield ("exp", param)
        elif op == "free":
            yield param[0]


@pytest.mark.parametrize("seed, kinds", [(1, ("mul", "lin")), (2, ("mul", "div")), (3, ("div", "lin")),
                                         (4, ("sin", "mul")), (5, ("exp", "div")), (6, ("log", "mul", "sin"))])
def test_word_coefficients_equal_the_reference_and_the_lie_derivatives(seed, kinds):
    g, f0, h = _random_model(seed, kinds)
    rng = np.random.default_rng(seed)
    ins = program(g, [h] + [v for v in f0 if v is not None])[0]
    K = 6
    for lane in range(2):
        p = primes.random_prime(rng)
        point = rng.integers(0, p, size=g.n)
        draws = graph_elementary.Draws(p, 1, [lane, seed])
        word = Word([p], [point], np.random.default_rng(0))
        for key in _keys(ins):  # the same generator values in every arithmetic
            found = draws.get(key)
            word.values[key] = tuple(np.array([int(v[0])], dtype=np.int64) for v in found) \
                if isinstance(found, tuple) else np.array([int(found[0])], dtype=np.int64)
        fast = TaylorSeries(g, [f0], [], [h], word, K)
        reference = TaylorSeries(g, [f0], [], [h], Modular([point], draws, p), K)
        evaluator = graph_exact.ModularEvaluator(g, [point], p)
        evaluator.draws = draws
        L = h
        for k in range(K + 1):
            got = [int(v) for v in fast.coefficient(h, k)[0]]
            assert got == [int(v) % p for v in reference.coefficient(h, k)[0]]
            values, grads = evaluator.gradients([L])
            scale = math.factorial(k) % p
            assert got[0] * scale % p == int(values[0][0]) % p
            assert [v * scale % p for v in got[1:]] == [int(v) % p for v in grads[0][0]]
            L = g.jvp([L], [g.zero if v is None else v for v in f0])[0]


def test_word_lanes_equal_single_lanes():
    g, f0, h = _random_model(7, ("mul", "div", "lin"))
    rng = np.random.default_rng(7)
    lanes = [primes.random_prime(rng) for _ in range(3)]
    points = [rng.integers(0, p, size=g.n) for p in lanes]
    together = TaylorSeries(g, [f0], [], [h], Word(lanes, points, np.random.default_rng(1)), 5)
    for lane, p in enumerate(lanes):
        alone = TaylorSeries(g, [f0], [], [h], Word([p], [points[lane]], np.random.default_rng(1)), 5)
        for k in range(6):
            np.testing.assert_array_equal(together.coefficient(h, k)[lane], alone.coefficient(h, k)[0])


@pytest.mark.parametrize("seed", range(4))
def test_word_echelon_equals_the_python_echelon(seed):
    rng = np.random.default_rng(seed)
    p = primes.random_prime(rng)
    n, r = 9, 6
    basis = rng.integers(0, p, size=(r, n))
    rows = [(rng.integers(0, 3, size=r) @ basis) % p if rng.random() < 0.5 else rng.integers(0, p, size=n)
            for _ in range(14)]
    fast, slow = WordEchelon(p, n), graph_exact.Echelon(p)
    for row in rows:
        assert fast.add(row) == slow.add([int(v) for v in row])
        probe = (rng.integers(0, 2, size=len(slow.rows)) @ np.array(slow.rows, dtype=np.int64)) % p \
            if slow.rows else np.zeros(n, dtype=np.int64)
        assert not fast.reduce(probe).any() and not any(slow.reduce([int(v) for v in probe]))
    assert fast.rank == slow.rank


@pytest.mark.parametrize("node, power", [("sqrt", Fraction(1, 2)), ("pow", Fraction(3, 4))])
def test_roots_of_the_extension_satisfy_their_equation_as_series(node, power):
    """``w = u^(a/b)`` in ``F_p[i]`` with random branches: ``w^b = u^a`` coefficient by
    coefficient (values and gradients) up to order 6, for an argument that is not a square
    modulo p at the point half of the time."""
    g = Graph(3)
    x, y, a = g.x(0), g.x(1), g.x(2)
    u = g.add(g.ipow(g.sub(x, y), 2), g.mul(a, x))
    w = g.unary("sqrt", u) if node == "sqrt" else g.binary("pow", u, g.const(float(power)))
    f0 = [g.mul(a, y), g.add(w, g.neg(x)), None]
    rng = np.random.default_rng(3)
    conditions = primes.root_conditions([power.denominator])
    lanes = [primes.random_prime(rng, conditions) for _ in range(4)]
    ar = WordSquare(lanes, [rng.integers(0, p, size=3) for p in lanes], np.random.default_rng(0))
    series = TaylorSeries(g, [f0], [], [u, w], ar, 6)
    U = [series.coefficient(u, k) for k in range(7)]
    Wc = [series.coefficient(w, k) for k in range(7)]

    def product(A, B):  # dual Cauchy products of two series of (rows, N + 1)
        out = []
        for k in range(len(A)):
            total = 0
            for j in range(k + 1):
                t = ar.mul(A[j], B[k - j][:, :1])
                t[:, 1:] = t[:, 1:] + ar.mul(A[j][:, :1], B[k - j][:, 1:])
                total = ar.reduce(total + t)
            out.append(total)
        return out

    def power_of(S, m):
        out = S
        for _ in range(m - 1):
            out = product(out, S)
        return out

    lhs, rhs = power_of(Wc, power.denominator), power_of(U, power.numerator)
    for k in range(7):
        np.testing.assert_array_equal(lhs[k], rhs[k])
    assert len({int(v) for v in Wc[0][len(lanes):, 0]}) > 1  # some roots are imaginary


def _chain(n_states, coupling):
    def drift(x, a):
        nxt = jnp.concatenate([x[1:], jnp.zeros(1)])
        prev = jnp.concatenate([jnp.zeros(1), x[:-1]])
        other = x / (1.0 + x ** 2) if coupling == "div" else x
        return -a * x + nxt + 0.5 * prev * other

    return uj.System(states=tuple(f"x{i}" for i in range(n_states)), outputs={"y": lambda x, a: x[0]},
                     drift=drift, params={f"a{i}": (0.5, 1.5) for i in range(n_states)})


def test_the_bounds_of_a_rational_chain_stay_polynomial():
    """The degree bound of ``y_24`` of a 12-state chain with ``x / (1 + x^2)`` couplings (the
    bound that doubled the atoms at every product reached 1.2e12) and its height bound."""
    from uio_jax._analysis.decisions.context import Context

    ctx = Context(_chain(12, "div").autonomous(), 16, 0, 1e-8)
    g = ctx.builder.graph
    f0 = list(ctx.field_node("f0").expr)
    h = ctx.output_nodes()[0].expr
    ins, slot, lagged = program(g, [h] + [v for v in f0 if v is not None])
    bounds = TaylorDegrees(ins, [[None if v is None else slot[v] for v in f0]], [], 24, lagged)
    degrees = [bounds.degree(slot[h], k) for k in range(25)]
    bits = [bounds.row_bits(slot[h], k) for k in range(25)]
    assert degrees[24] < 5000 and bits[24] < 5000
    assert all(b - a < 200 for a, b in zip(degrees[12:], degrees[13:]))  # linear growth


def _faulty_chain(q):
    """A 12-state chain whose parameter ``b`` enters as ``q b``: modulo ``q`` it vanishes, so
    every minor with ``b``'s column has content divisible by ``q``."""
    base = _chain(12, "mul")

    def drift(x, a):
        return base.drift(x, a[:12]) + jnp.zeros(12).at[3].set(q * a[12] * x[4])

    params = dict(base.params)
    params["b"] = (0.5, 1.5)
    return uj.System(states=base.states, outputs=base.outputs, drift=drift, params=params, name="faulty")


FAULTY_PRIME = 33554467  # a prime = 3 mod 4 in [2^25, 2^26)


def test_a_prime_dividing_a_minor_is_caught(monkeypatch):
    """The first lane's prime is forced to ``q``: ``b``'s row is dependent there, the bound of
    one lane does not certify it, lanes are added, the row rises in them (certain) and the
    faulty lane is dropped; the verdicts equal the symbolic route's."""
    assert primes.is_prime(FAULTY_PRIME) and FAULTY_PRIME % 4 == 3
    system = _faulty_chain(FAULTY_PRIME)
    draw = primes.random_prime
    forced = [FAULTY_PRIME]

    def random_prime(rng, conditions=(2, ())):
        return forced.pop() if forced else draw(rng, conditions)

    created = []

    class Spy(taylor_rank.TaylorRank):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            created.append(self)

    with monkeypatch.context() as m:
        m.setattr(taylor_rank, "random_prime", random_prime)
        m.setattr(taylor_route, "TaylorRank", Spy)
        fast = uj.analyze(system)
    assert any("Taylor series" in note for note in fast.notes) and fast.exact
    rank = created[0]
    assert len(rank.arith.primes) > 1  # the first lane's dependence was not certified alone
    assert FAULTY_PRIME not in rank.primes and rank.decisions
    with monkeypatch.context() as m:
        m.setattr(taylor_route, "TAYLOR_MIN_VARIABLES", 10**9)
        slow = uj.analyze(system)
    assert fast.dim == slow.dim and dict(fast.identifiable) == dict(slow.identifiable)
    assert fast.identifiable["b"]


def test_a_dependence_one_lane_cannot_certify_is_not_reported(monkeypatch):
    """Every lane's prime forced to ``q`` and one lane allowed: the dependence of ``b``'s row is
    never certified (the route refuses; the symbolic route decides), so no wrong verdict."""
    system = _faulty_chain(FAULTY_PRIME)
    with monkeypatch.context() as m:
        m.setattr(taylor_rank, "random_prime", lambda rng, conditions=(2, ()): FAULTY_PRIME)
        m.setattr(taylor_rank, "MAX_LANES", 1)
        report = uj.analyze(system)
    assert not any("Taylor series" in note for note in report.notes)
    assert report.identifiable["b"] and report.dim == system.n + len(system.params)


def _root_system(seed):
    """A random model of 12 states and 12 parameters with square roots of non-coordinate
    arguments, rational powers and a parameter as an exponent (24 variables: the Taylor
    route)."""
    rng = np.random.default_rng(seed)
    n = 12
    plan = [[(str(rng.choice(["mono", "dist", "pow", "expo", "quad"])), int(rng.integers(n)), int(rng.integers(n)),
              int(rng.integers(n)), float(np.round(rng.uniform(0.3, 2.0), 1))) for _ in range(int(rng.integers(2, 4)))]
            for _ in range(n)]
    outs = [int(v) for v in rng.choice(n, size=int(rng.integers(1, 3)), replace=False)]

    def term(kind, q, j, m, c, x, p):
        if kind == "mono":
            return p[q] * x[j]
        if kind == "quad":
            return c * p[q] * x[j] * x[m]
        if kind == "dist":  # a range: the root of a sum of squares
            return p[q] * jnp.sqrt((x[j] - x[m]) ** 2 + c)
        if kind == "pow":
            return p[q] * (1.0 + x[j] ** 2) ** 0.75
        return c * (1.0 + x[j] ** 2) ** p[q]  # a parameter as the exponent

    def drift(x, p):
        return jnp.stack([sum(term(*t, x, p) for t in plan[i]) for i in range(n)])

    outputs = {f"y{k}": (lambda x, p, i=i: x[i]) for k, i in enumerate(outs)}
    return uj.System(states=tuple(f"x{i}" for i in range(n)), params={f"p{i}": (0.5, 1.5) for i in range(n)},
                     drift=drift, outputs=outputs, name=f"roots{seed}")


def _root_case(monkeypatch, seed):
    system = _root_system(seed)
    fast = uj.analyze(system)
    assert any("Taylor series" in note for note in fast.notes) and fast.exact
    with monkeypatch.context() as m:
        m.setattr(taylor_route, "TAYLOR_MIN_VARIABLES", 10**9)
        slow = uj.analyze(system)
    assert not any("Taylor series" in note for note in slow.notes)
    assert fast.dim == slow.dim and fast.dims == slow.dims
    assert dict(fast.observable) == dict(slow.observable)
    assert dict(fast.identifiable) == dict(slow.identifiable)
    assert fast.generators == slow.generators and fast.stop_reason == slow.stop_reason


@pytest.mark.parametrize("seed", [1, 2])
def test_models_with_roots_and_powers_equal_the_symbolic_route(monkeypatch, seed):
    _root_case(monkeypatch, seed)


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(3, 12))
def test_models_with_roots_and_powers_equal_the_symbolic_route_more(monkeypatch, seed):
    _root_case(monkeypatch, seed)


def test_primes_are_drawn_from_their_class_and_counted():
    rng = np.random.default_rng(0)
    for conditions in [(2, ()), (3, (3,)), primes.root_conditions([4, 15])]:
        for _ in range(20):
            p = primes.random_prime(rng, conditions)
            m, coprime = conditions
            assert primes.LOW <= p < primes.HIGH and primes.is_prime(p)
            assert (p + 1) % 2 ** m == 0 and all((p - 1) % q for q in coprime)
    assert primes._count(2, ()) == primes.DEFAULT_COUNT
    assert primes.LAZY_TERMS * (primes.HIGH - 1) ** 2 < 2**63
