"""Identifiable combinations named completely (issue 47 item 8): ``named_functions.of_only(
report.params)`` is a basis of every observable function of the parameters alone.

Oracle (sympy, exact): the Lie derivatives ``L_f^k h`` (``k < N``) differentiated
symbolically, their Jacobian evaluated at a random rational point: the number of independent
observable functions of the parameters alone is ``rank J - rank J_x`` (``J_x`` the columns of
the states); every function of ``of_only`` must be observable (its gradient does not raise the
rank of ``J``), use only parameters, and they must be that many and independent.
"""

import random

import jax.numpy as jnp
import pytest
import sympy as sp

import uio_jax as uj

S = 128


def _model(rng):
    xs = sp.symbols("x1:3")
    ps = sp.symbols("a b c d")
    a, b, c, d = ps
    x1, x2 = xs
    terms = [a * b, a + b, c, c * d, a * c + d, b * d, (a + c) * b]
    f1 = -rng.choice(terms) * x1 + rng.choice(terms) * x2 + rng.choice([0, 1, c, d])
    f2 = rng.choice(terms) * x1 - rng.choice(terms) * x2
    h = rng.choice([x1, x1 + x2, x1 * rng.choice([1, d])])
    used = [p for p in ps if any(e.has(p) for e in (f1, f2, h))]
    return list(xs), used, [f1, f2], h


def _system(xs, ps, f, h):
    var = xs + ps
    fj = sp.lambdify(var, f, modules=jnp)
    hj = sp.lambdify(var, h, modules=jnp)
    return uj.System(states=tuple(map(str, xs)), outputs={"y": lambda x, p: hj(*x, *p) + 0.0 * x[0]},
                     drift=lambda x, p: jnp.stack([jnp.asarray(e, dtype=float) + 0.0 * x[0] for e in fj(*x, *p)]),
                     params=tuple(map(str, ps)), domain={str(x): (0.5, 1.5) for x in xs})


def _jacobian(xs, ps, f, h, point, extra=()):
    var = xs + ps
    rows, lie = [], h
    for _ in range(len(var)):
        rows.append([sp.diff(lie, v).subs(point) for v in var])
        lie = sum(sp.diff(lie, v) * e for v, e in zip(xs, f))
    return sp.Matrix(rows + [[sp.diff(e, v).subs(point) for v in var] for e in extra])


def _check(seed):
    rng = random.Random(seed)
    xs, ps, f, h = _model(rng)
    rep = uj.analyze(_system(xs, ps, f, h), samples=S)
    combos = rep.named_functions.of_only(rep.params)
    point = {v: sp.Rational(rng.randint(3, 29), rng.randint(3, 29)) for v in xs + ps}
    J = _jacobian(xs, ps, f, h, point)
    count = J.rank() - J[:, :len(xs)].rank()
    local = {str(v): v for v in xs + ps}
    exprs = [sp.sympify(c.text, locals=local) for c in combos]
    assert all(set(c.variables) <= set(rep.params) for c in combos)
    assert rep.named_functions.combinations_dim == count and len(combos) <= count
    if len(combos) < count:  # said, with the count
        assert f"identifiable combinations: {len(combos)} of {count} named" in rep.named_functions.summary()
    if exprs:
        assert _jacobian(xs, ps, f, h, point, exprs).rank() == J.rank()  # every one observable
        grads = sp.Matrix([[sp.diff(e, v).subs(point) for v in xs + ps] for e in exprs])
        assert grads.rank() == len(exprs)  # independent
    return len(combos), count


def test_of_only_lists_every_identifiable_combination_of_random_models():
    """Every combination named in most models (before: the named functions of the whole
    space that happened to use parameters only); never a wrong or dependent one; the count
    always right, and said where fewer could be named."""
    results = [_check(seed) for seed in range(1, 5)]
    assert sum(c for _, c in results) >= 4
    assert sum(named == count for named, count in results) >= 3


@pytest.mark.slow
def test_of_only_lists_every_identifiable_combination_more():
    results = [_check(seed) for seed in range(5, 37)]
    assert sum(named == count for named, count in results) >= 26


def test_three_compartment_combinations_are_named_and_counted():
    """The mammillary three-compartment model without input, ``y = x1 / v``: the three
    coefficients of the characteristic polynomial are its identifiable combinations."""
    s = uj.System(states=("x1", "x2", "x3"), outputs={"y": lambda x, p: x[0] / p[5]},
                  drift=lambda x, p: jnp.stack([-(p[0] + p[1] + p[2]) * x[0] + p[3] * x[1] + p[4] * x[2],
                                                p[1] * x[0] - p[3] * x[1], p[2] * x[0] - p[4] * x[2]]),
                  params=("k10", "k12", "k13", "k21", "k31", "v"))
    rep = uj.analyze(s, samples=S)
    nf = rep.named_functions
    combos = nf.of_only(rep.params)
    assert nf.combinations_dim == 3 and len(combos) == 3
    assert all(rep.is_observable(lambda x, p, t=c.text: _evaluate(t, rep.params, p)) for c in combos)
    assert "identifiable combinations: 3 of 3 named" in nf.summary()


def _evaluate(text, names, p):
    syms = sp.symbols(names)
    return sp.lambdify(syms, sp.sympify(text, locals=dict(zip(names, syms))), modules=jnp)(*p)
