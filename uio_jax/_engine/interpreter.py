"""One jaxpr interpreter: a walk over the equations, a rule per primitive from a table.

Every jaxpr walk of the package (the translation into the expression graph in
:mod:`.graph_rules`; the Monte Carlo's structural sparsity in
:mod:`uio_jax._filter.sparsity` and vectorised float64 trig in
:mod:`uio_jax._filter.fast_trig`) is :func:`interpret` with a rule table of its own
(:class:`Rules`) and a state of its own:

* the walk binds the jaxpr's constants and arguments to its variables, then takes the
  equations in order: ``outs = rules[eqn.primitive.name](state, i, eqn, ins)``, with
  ``i`` the equation's position in this jaxpr and ``ins`` the values of its operands
  (literals read as they are, or through the table's ``literal`` conversion);
* a primitive without an entry gets the table's ``default`` rule;
* call primitives (:data:`CALLS`: ``pjit``, ``closed_call``, ``custom_jvp_call``, ...)
  get the table's ``calls`` rule, which usually evaluates their sub-jaxpr
  (:func:`call_body`) by the same table: :func:`inline`.
"""

from jax.extend.core import Literal

#: call-like primitives: a sub-jaxpr (see :func:`call_body`) evaluated where they stand
CALLS = ("jit", "pjit", "closed_call", "core_call", "remat", "checkpoint", "custom_jvp_call",
         "custom_vjp_call", "custom_vjp_call_jaxpr")


class Rules(dict):
    """A rule table: primitive name -> ``rule(state, i, eqn, ins) -> list of outputs``.

    Args:
        table: ``{name: rule}``.
        default: the rule of a primitive without an entry.
        calls: the rule of every call primitive of :data:`CALLS` (entries of ``table``
            take precedence); None: they get ``default`` too.
        literal: ``literal(state, value) -> value`` applied to literals and to the
            jaxpr's constants (e.g. a constant's sparsity state); None: used as they are.
    """

    def __init__(self, table, default, calls=None, literal=None):
        super().__init__({name: calls for name in CALLS} if calls is not None else {})
        self.update(table)
        self.default = default
        self.literal = literal

    def __missing__(self, name):
        return self.default


def interpret(jaxpr, consts, args, rules, state=None):
    """The outputs of ``jaxpr`` evaluated on ``args`` by the rules of ``rules``.

    Args:
        jaxpr: a ``jax.extend.core.Jaxpr`` (``closed.jaxpr`` of ``jax.make_jaxpr``).
        consts: values of its constant variables (``closed.consts``).
        args: values of its input variables, one each.
        rules: the :class:`Rules` table; equation ``i`` of the jaxpr gives
            ``rules[name](state, i, eqn, ins)``: one value per output variable.
        state: whatever the rules share (passed to every rule as it is).

    Returns:
        list, one value per output variable of the jaxpr.
    """
    env = {}
    literal = rules.literal
    if literal is None:
        def read(v):
            return v.val if isinstance(v, Literal) else env[v]

        for v, c in zip(jaxpr.constvars, consts):
            env[v] = c
    else:
        def read(v):
            return literal(state, v.val) if isinstance(v, Literal) else env[v]

        for v, c in zip(jaxpr.constvars, consts):
            env[v] = literal(state, c)
    for v, a in zip(jaxpr.invars, args):
        env[v] = a
    for i, eqn in enumerate(jaxpr.eqns):
        outs = rules[eqn.primitive.name](state, i, eqn, [read(v) for v in eqn.invars])
        for v, o in zip(eqn.outvars, outs):
            env[v] = o
    return [read(v) for v in jaxpr.outvars]


def call_body(params):
    """``(jaxpr, consts)`` of the sub-jaxpr of a call primitive (:data:`CALLS`) from its
    parameters (``jaxpr``, ``call_jaxpr`` or ``fun_jaxpr``, closed or not), or None when
    they hold none."""
    sub = params.get("jaxpr") or params.get("call_jaxpr") or params.get("fun_jaxpr")
    if sub is None:
        return None
    return (sub.jaxpr, sub.consts) if hasattr(sub, "consts") else (sub, ())


def inline(rules, state, eqn, ins):
    """The outputs of a call equation's sub-jaxpr evaluated on ``ins`` by the same
    ``rules`` and ``state`` (:func:`interpret`), or None when it has no sub-jaxpr."""
    body = call_body(eqn.params)
    if body is None:
        return None
    return interpret(body[0], body[1], ins, rules, state)


def bind(eqn, ins):
    """The equation's primitive applied to the values ``ins``: the list of its outputs."""
    prim = eqn.primitive
    out = prim.bind(*ins, **eqn.params)
    return out if prim.multiple_results else [out]


__all__ = ["CALLS", "Rules",
           "interpret", "call_body", "inline", "bind"]
