"""The finite system: SIAN's truncation of the equations at the orders the local test proved enough.

The output of a model is determined by infinitely many Taylor coefficients; the question is
decided on finitely many. The local test (:mod:`uio_jax._analysis.at_t0.identifiability`, the
project's exact rank decisions on the Jacobian of the output coefficients) absorbs the
coefficients order by order and stops where the rank of ``d(y_0, .., y_K)`` is the rank of
all of them: ``beta_j = K + 1`` orders of every output (``y_j^(0..K)``) carry the whole rank.

SIAN's system ``E_t`` (Hong, Ovchinnikov, Pogudin, Yap 2019, Algorithm 1):

1. the output equations ``Y_j^(k)``, ``k < beta_j``;
2. for every state derivative ``x_i^(k)``, ``k >= 1``, occurring in them *or in the next
   output equations* ``Y_j^(beta_j)``, the state equation ``X_i^(k-1)`` that defines it, and so
   on for the derivatives these bring in (the closure looks one order ahead);
3. every later output equation ``Y_j^(k)``, ``k >= beta_j``, whose state derivatives are all
   defined already: it costs no new variable and removes the solutions that agree with the
   first orders only (``x' = a^2 + a x^3``, ``y = x``: ``y, y'`` leave ``a`` two values,
   ``y''`` fixes it);
4. a known initial state ``x_i(0) = c``: the equation ``x_i^(0) - c``.

Extra equations that hold on the true solution never change the answer, so taking the same
``beta`` for every output (the largest, where SIAN's own rank loop may stop some outputs
earlier) is safe; it only costs equations.
"""

import dataclasses


@dataclasses.dataclass
class Truncation:
    """The truncated system ``E_t`` (polynomials over the rationals in the jet ring).

    Attributes:
        polys: the equations.
        labels: what each is (``Y_y^(2)``, ``X_x1^(0)``, ``x2(0) = 0``).
        beta: per output, the orders taken in step 1.
        orders: per output, the highest order of its equations.
        max_state_order: per state, the highest jet order that occurs.
    """

    polys: list
    labels: list
    beta: dict
    orders: dict
    max_state_order: dict


def truncate(eqs, beta: dict, known_initial: dict) -> Truncation:
    """SIAN's ``E_t`` for ``eqs`` (:class:`~.jets.ModelEquations`) with ``beta[output]``
    orders per output and the known initial states ``{state: value}`` (values as
    :meth:`~.jets.ModelEquations.initial_equation` takes them)."""
    ring = eqs.ring
    polys, labels = [], []
    orders = {}
    for j, y in enumerate(eqs.outputs):
        for k in range(beta[y]):
            polys.append(eqs.y_equation(j, k))
            labels.append(f"Y_{y}^({k})")
        orders[y] = beta[y] - 1
    defined = {(s, 0) for s in eqs.states}
    state_index = {s: i for i, s in enumerate(eqs.states)}
    pending = list(polys) + [eqs.y_equation(j, beta[y]) for j, y in enumerate(eqs.outputs)]
    while pending:
        new = []
        for poly in pending:
            for v in ring.occurring(poly):
                if ring.kinds[v] != "state" or ring.base[v] in defined:
                    continue
                name, k = ring.base[v]
                defined.add((name, k))
                x = eqs.x_equation(state_index[name], k - 1)
                polys.append(x)
                labels.append(f"X_{name}^({k - 1})")
                new.append(x)
        pending = new
    for j, y in enumerate(eqs.outputs):
        k = beta[y]
        while k < ring.top:
            poly = eqs.y_equation(j, k)
            if any(ring.kinds[v] == "state" and ring.base[v] not in defined for v in ring.occurring(poly)):
                break
            polys.append(poly)
            labels.append(f"Y_{y}^({k})")
            orders[y] = k
            k += 1
    for state, value in known_initial.items():
        polys.append(eqs.initial_equation(state, value))
        labels.append(f"{state}(0) known")
    top = {}
    for name, k in defined:
        top[name] = max(top.get(name, 0), k)
    return Truncation(polys, labels, dict(beta), orders, top)


__all__ = ["Truncation", "truncate"]
