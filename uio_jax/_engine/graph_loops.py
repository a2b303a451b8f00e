"""Loops with a static trip count, unrolled into the expression graph.

``lax.fori_loop`` with Python bounds and ``lax.scan`` of a static length (the ``scan``
primitive), and a ``while`` loop whose condition stays a constant along the loop (a
``fori_loop`` with bounds computed from constants): the body's jaxpr is walked once per
iteration by the same rule table (:func:`uio_jax._engine.interpreter.interpret`), so a
loop of ``L`` iterations adds what ``L`` copies of its body add. A condition that depends
on the state, or more than :data:`MAX_ITERATIONS` iterations, is refused (the graph has
no loops of its own).
"""

import numpy as np

from .graph_values import Untranslatable, as_nodes, is_symbolic
from .interpreter import interpret

#: Most iterations a loop is unrolled to (its body walked this many times at most).
MAX_ITERATIONS = 10_000


def loop_rules(rules):
    """``{"scan": rule, "while": rule}`` for the rule table ``rules`` (:class:`Rules`, which
    walks the bodies: the table these rules are added to)."""

    def stack(graph, values):
        if any(is_symbolic(v) for v in values):
            values = [as_nodes(graph, v) for v in values]
        return np.stack([np.asarray(v) for v in values])

    def scan(graph, i, eqn, ins):
        p = eqn.params
        length, n_consts, n_carry = int(p["length"]), p["num_consts"], p["num_carry"]
        if length > MAX_ITERATIONS:
            raise Untranslatable("scan", f"{length} iterations (at most {MAX_ITERATIONS} are unrolled)")
        body = p["jaxpr"]
        consts, carry, xs = ins[:n_consts], list(ins[n_consts:n_consts + n_carry]), ins[n_consts + n_carry:]
        xs = [np.asarray(x) if not is_symbolic(x) else x for x in xs]
        ys = [None] * length
        for t in (reversed(range(length)) if p["reverse"] else range(length)):
            outs = interpret(body.jaxpr, body.consts, [*consts, *carry, *(x[t] for x in xs)], rules, graph)
            carry, ys[t] = list(outs[:n_carry]), outs[n_carry:]
        n_ys = len(eqn.outvars) - n_carry
        stacked = []
        for k in range(n_ys):
            if length:
                stacked.append(stack(graph, [y[k] for y in ys]))
            else:
                aval = eqn.outvars[n_carry + k].aval
                stacked.append(np.zeros(aval.shape, dtype=aval.dtype))
        return carry + stacked

    def while_(graph, i, eqn, ins):
        p = eqn.params
        cond, body = p["cond_jaxpr"], p["body_jaxpr"]
        nc, nb = p["cond_nconsts"], p["body_nconsts"]
        cond_consts, body_consts, carry = ins[:nc], ins[nc:nc + nb], list(ins[nc + nb:])
        for _ in range(MAX_ITERATIONS + 1):
            (go,) = interpret(cond.jaxpr, cond.consts, [*cond_consts, *carry], rules, graph)
            if is_symbolic(go):
                raise Untranslatable("while", "a loop condition that depends on the state")
            if not bool(np.asarray(go)):
                return carry
            carry = interpret(body.jaxpr, body.consts, [*body_consts, *carry], rules, graph)
        raise Untranslatable("while", f"more than {MAX_ITERATIONS} iterations")

    return {"scan": scan, "while": while_}


__all__ = ["loop_rules", "MAX_ITERATIONS"]
