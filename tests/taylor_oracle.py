"""An independent exact oracle for identifiability at t = 0 (plain sympy, no uio_jax).

For experiments ``e`` (each: states, drift ``f`` as sympy expressions in the states, the
parameters and the known inputs' jets; outputs ``h``; known initial values), the output's
time derivatives ``y^(k) = L_F^k h`` (``F`` the drift plus the chain ``u^(d)' = u^(d+1)`` of each
known input) are built symbolically, the known initial values substituted, the Jacobian with
respect to the unknowns (unknown initial states, shared parameters once, the others per
experiment) taken symbolically and evaluated at a random rational point (the known inputs'
jets random rationals too), and its rank found in exact rational arithmetic
(``sympy.Matrix.rank``). An unknown is determined at order ``K`` when its unit row does not
raise the rank.
"""

import random

import sympy as sp


def _rand(rng):
    return sp.Rational(rng.randint(1, 97), rng.randint(1, 13)) * rng.choice((1, -1))


def oracle(experiments, params, shared, order, seed=0):
    """``(rank, {unknown name: determined})`` at order ``order``.

    Args:
        experiments: list of dicts with ``states`` (sympy symbols), ``f`` (list of
            expressions), ``h`` (list), ``initial`` ({state symbol: value or expression in
            the parameters}), optional ``inputs`` ({name: (field list, jets symbols)}).
        params: the parameter symbols.
        shared: the shared parameter symbols (the others are renamed per experiment).
        order: the highest order K.
    """
    rng = random.Random(seed)
    many = len(experiments) > 1
    rows, unknowns, values = [], [], {}
    for e, ex in enumerate(experiments):
        tag = f"[{e + 1}]" if many else ""
        ren = {p: (p if p in shared else sp.Symbol(f"{p}{tag}")) for p in params}
        xs = list(ex["states"])
        jets = []
        F = [fi for fi in ex["f"]]
        for _name, (field, js) in ex.get("inputs", {}).items():
            F = [a + js[0] * b for a, b in zip(F, field)]
            jets += list(js)
        chain = []
        for _name, (_field, js) in ex.get("inputs", {}).items():
            chain += list(js[1:]) + [0]
        coords = xs + jets
        field = F + chain
        level = list(ex["h"])
        derivs = [level]
        for _ in range(order):
            level = [sum(sp.diff(g, c) * v for c, v in zip(coords, field)) for g in level]
            derivs.append(level)
        new_x = {x: sp.Symbol(f"{x}{tag}") for x in xs}
        subs = {}
        for x in xs:
            if x in ex["initial"]:
                subs[x] = sp.sympify(ex["initial"][x]).xreplace(ren)
            else:
                subs[x] = new_x[x]
                unknowns.append(new_x[x])
        subs.update({p: ren[p] for p in params})
        for p in params:
            if ren[p] not in unknowns:
                unknowns.append(ren[p])
        for j in jets:
            values[j] = _rand(rng)
        for level in derivs:
            rows += [g.xreplace(subs) for g in level]
    point = {u: _rand(rng) for u in unknowns}
    point.update(values)
    J = sp.Matrix([[sp.diff(r, u).xreplace(point) for u in unknowns] for r in rows])
    rank = J.rank()
    determined = {}
    for i, u in enumerate(unknowns):
        unit = sp.Matrix([[1 if j == i else 0 for j in range(len(unknowns))]])
        determined[str(u)] = J.col_join(unit).rank() == rank
    return rank, determined


__all__ = ["oracle"]
