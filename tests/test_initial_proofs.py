"""At a known initial state, "not determined" proved by a symmetry that keeps the known initial
values (issue 47 item 6; :mod:`uio_jax._analysis.at_t0.initial_proofs`).

Random models with a planted scaling: every state and parameter gets a weight ``w`` in
``{-1, 0, 1}`` (``z -> l^w z``), every term of ``x_i'`` has the weight of ``x_i``, the output
has weight 0, and the known initial values are 0 (kept by any scaling) or belong to a state of
weight 0. The scaling ``sum_i w_i z_i d/dz_i`` is then a symmetry that keeps the known values
(sympy checks it symbolically), so every unknown of nonzero weight is not determined.

Oracles: the exact sympy Taylor oracle (``tests/taylor_oracle.py``), which must agree with
every "determined" (to the order reached) and never determine an unknown called "not
determined" (at an order past the report's); and the planted field itself.
"""

import random

import jax.numpy as jnp
import pytest
import sympy as sp
from taylor_oracle import oracle

import uio_jax as uj

D, N, V = uj.Verdict.DETERMINED, uj.Verdict.NOT_DETERMINED, uj.Verdict.UNDECIDED


def _weighted_model(rng):
    """(states, params, drift, output, weights, initial) with a planted scaling."""
    xs = sp.symbols("x1:4")
    ps = sp.symbols("p1:4")
    var = list(xs) + list(ps)
    w = {v: rng.choice([-1, 0, 1]) for v in var}
    w[xs[0]] = 0  # the output x1 has weight 0
    if all(w[v] == 0 for v in var):
        w[ps[0]] = 1
    drift = []
    for x in xs:
        terms = []
        for _ in range(200):
            e = {v: rng.choice([0, 0, 1, 1, 2]) for v in rng.sample(var, 2)}
            if sum(k * w[v] for v, k in e.items()) == w[x] and any(e.values()):
                coefficient = sp.Rational(rng.randint(1, 9), rng.randint(1, 5))
                terms.append(coefficient * sp.Mul(*[v ** k for v, k in e.items()]))
                if len(terms) == 2:
                    break
        drift.append(sum(terms) if terms else sp.Integer(0))
    known = {xs[1]: 0}
    if w[xs[2]] == 0:
        known[xs[2]] = sp.Rational(rng.randint(1, 9), 4)
    else:
        known[xs[2]] = 0
    return xs, ps, drift, xs[0], w, known


def _is_symmetry(xs, ps, drift, h, w) -> bool:
    var = list(xs) + list(ps)
    xi = sp.Matrix([w[v] * v for v in var])
    F = sp.Matrix(list(drift) + [0] * len(ps))
    if sp.simplify(sum(sp.diff(h, v) * c for v, c in zip(var, xi))) != 0:
        return False
    bracket = F.jacobian(var) * xi - xi.jacobian(var) * F
    return all(sp.simplify(e) == 0 for e in bracket)


def _system(xs, ps, drift, h):
    var = list(xs) + list(ps)
    f = sp.lambdify(var, drift, modules=jnp)
    return uj.System(states=tuple(map(str, xs)), outputs={"y": lambda x, p: x[0]},
                     drift=lambda x, p: jnp.stack([jnp.asarray(e, dtype=float) + 0.0 * x[0] for e in f(*x, *p)]),
                     params={str(p): (0.5, 1.5) for p in ps}, domain={str(x): (0.5, 1.5) for x in xs})


def _check(seed):
    rng = random.Random(seed)
    xs, ps, drift, h, w, known = _weighted_model(rng)
    assert _is_symmetry(xs, ps, drift, h, w), (seed, drift, w)
    rep = uj.analyze(_system(xs, ps, drift, h), initial={str(k): v for k, v in known.items()}, max_order=6)
    unknown_states = [x for x in xs if x not in known]
    order = rep.order + 2
    _, determined = oracle([{"states": xs, "f": drift, "h": [h], "initial": known}], ps, ps, order)
    for name, verdict in rep.verdicts.items():
        if verdict is D:
            assert determined[name], (seed, name)
        elif verdict is N:
            assert not determined[name], (seed, name)  # never contradicted by a later order
    # every unknown the planted scaling moves is proved not determined
    for v in unknown_states + list(ps):
        if w[v] != 0:
            assert rep.verdicts[str(v)] is N, (seed, str(v), dict(rep.verdicts), rep.notes)
    return rep


def test_random_models_with_a_planted_scaling_are_proved_not_determined():
    reps = [_check(seed) for seed in range(4)]
    assert sum(v is N for r in reps for v in r.verdicts.values()) >= 4


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(4, 24))
def test_random_models_with_a_planted_scaling_more(seed):
    _check(seed)


def test_a_symmetry_that_moves_a_known_value_proves_nothing():
    """``x' = -a x``, ``y = c x``: the scaling ``(x, c) -> (l x, c / l)`` moves ``x``, so with
    ``x(0) = 1`` known it is no proof; the output at t = 0 is ``c``, and ``a``, ``c`` are
    determined (the oracle agrees)."""
    system = uj.System(states=("x",), outputs={"y": lambda x, p: p[1] * x[0]}, drift=lambda x, p: -p[0] * x,
                       params=("a", "c"))
    rep = uj.analyze(system, initial={"x": 1})
    assert dict(rep.identifiable) == {"a": D, "c": D}
    generic = uj.analyze(system, initial={})
    assert generic.identifiable["c"] is N and generic.observable["x"] is N  # closed: the generic span


def test_a_parameter_valued_initial_state_is_kept_by_the_proof():
    """``x1' = -(a + b) x1``, ``y = x1``, ``x1(0) = a``: the translation ``(a, b) -> (a + s,
    b - s)`` moves ``x1(0) = a``, so it proves nothing; the output ``a e^(-(a + b) t)`` determines
    both (oracle)."""
    system = uj.System(states=("x1",), outputs={"y": lambda x, p: x[0]},
                       drift=lambda x, p: jnp.stack([-(p[0] + p[1]) * x[0]]), params=("a", "b"))
    rep = uj.analyze(system, initial={"x1": "a"})
    a, b, x1 = sp.symbols("a b x1")
    _, determined = oracle([{"states": (x1,), "f": [-(a + b) * x1], "h": [x1], "initial": {x1: a}}], (a, b), (a, b),
                           rep.order)
    assert {k: v is D for k, v in rep.verdicts.items()} == determined == {"a": True, "b": True}
    rep = uj.analyze(system, initial={"x1": 2})  # a known number: the translation keeps it
    assert dict(rep.identifiable) == {"a": N, "b": N}
    assert any("moved by the verified symmetry" in n for n in rep.notes)


def test_the_proof_from_the_command_line(tmp_path, capsys):
    """``uio-jax analyze`` prints the proof with the field that gives it."""
    from uio_jax import cli

    path = tmp_path / "m.toml"
    path.write_text('states = ["x1", "x2"]\nparams = ["a", "b"]\n[outputs]\ny = "x1"\n'
                    '[drift]\nx1 = "a*x2"\nx2 = "b"\n[initial]\nx1 = 0\nx2 = 0\n')
    assert cli.main(["analyze", str(path), "--max-order", "5"]) == 0
    out = capsys.readouterr().out
    assert "a  not determined" in out and "b  not determined" in out and "moved by the verified symmetry" in out
