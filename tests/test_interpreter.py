"""The one jaxpr interpreter (``uio_jax._engine.interpreter``): the walk, its rule tables,
calls and literals."""

import ast
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from uio_jax._engine import interpreter
from uio_jax._engine.interpreter import CALLS, Rules, bind, call_body, inline, interpret

ENGINE = Path(interpreter.__file__).parent


@jax.jit
def _inner(x):
    return jnp.sin(x[0]) * x[1] + 2.0


def _fn(x):
    return jnp.stack([_inner(x), x[2] ** 2 - 1.5, jnp.cos(x[0])])


def _plain(state, i, eqn, ins):
    return bind(eqn, ins)


def _call(state, i, eqn, ins):
    return inline(state["rules"], state, eqn, ins)


def test_a_table_of_plain_rules_evaluates_the_function():
    """Default: the primitive; calls: their sub-jaxpr inline. Same values, no call left."""
    rules = Rules({}, default=_plain, calls=_call)
    x = jnp.array([0.3, -1.2, 2.0])
    closed = jax.make_jaxpr(_fn)(x)
    assert any(e.primitive.name in CALLS for e in closed.jaxpr.eqns)
    (out,) = interpret(closed.jaxpr, closed.consts, [x], rules, {"rules": rules})
    np.testing.assert_array_equal(out, _fn(x))
    walked = jax.make_jaxpr(lambda y: interpret(closed.jaxpr, closed.consts, [y], rules, {"rules": rules}))(x)
    assert not any(e.primitive.name in CALLS for e in walked.jaxpr.eqns)


def test_rules_are_looked_up_by_primitive_with_the_equation_position():
    seen = []

    def sin_rule(state, i, eqn, ins):
        seen.append((state, i, eqn.primitive.name))
        return [jnp.zeros_like(ins[0])]

    rules = Rules({"sin": sin_rule}, default=_plain)  # calls not inlined: the default binds them
    assert rules["sin"] is sin_rule and rules["cos"] is _plain and rules["jit"] is _plain
    closed = jax.make_jaxpr(lambda x: jnp.sin(x) + jnp.cos(x))(1.0)
    (out,) = interpret(closed.jaxpr, closed.consts, [0.5], rules, "state")
    assert float(out) == float(jnp.cos(0.5))
    assert seen == [("state", 0, "sin")]


def test_table_entries_take_precedence_over_the_call_rule():
    marker = []
    closed = jax.make_jaxpr(_fn)(jnp.ones(3))
    (name,) = {e.primitive.name for e in closed.jaxpr.eqns} & set(CALLS)  # "jit" or "pjit"
    rules = Rules({name: lambda s, i, eqn, ins: marker.append(1) or bind(eqn, ins)}, default=_plain,
                  calls=lambda *a: pytest.fail("the call rule"))
    interpret(closed.jaxpr, closed.consts, [jnp.ones(3)], rules)
    assert marker == [1]


def test_literals_and_constants_go_through_the_literal_conversion():
    const = np.array([1.0, 0.0, 3.0])

    def fn(x):
        return x * const + 2.0

    closed = jax.make_jaxpr(fn)(jnp.ones(3))
    converted = []

    def literal(state, value):
        converted.append(np.asarray(value).shape)
        return value

    rules = Rules({}, default=_plain, literal=literal)
    (out,) = interpret(closed.jaxpr, closed.consts, [jnp.ones(3)], rules)
    np.testing.assert_array_equal(out, fn(jnp.ones(3)))
    assert len(converted) == len(closed.consts) + sum(
        isinstance(v, jax.extend.core.Literal) for e in closed.jaxpr.eqns for v in e.invars)
    assert (3,) in converted or not closed.consts


def test_call_body_reads_the_sub_jaxpr():
    closed = jax.make_jaxpr(_fn)(jnp.ones(3))
    (call,) = [e for e in closed.jaxpr.eqns if e.primitive.name in CALLS]
    body, consts = call_body(call.params)
    assert len(body.invars) == len(call.invars)
    assert call_body({}) is None


def test_the_uses_import_the_interpreter_not_each_other():
    """The graph translation and the Monte Carlo's sparsity and fast trig walk jaxprs through
    the interpreter module only; none defines a walk of its own."""
    package = ENGINE.parent
    for path in (ENGINE / "graph_trace.py", ENGINE / "graph_loops.py", package / "_filter" / "sparsity.py",
                 package / "_filter" / "fast_trig.py"):
        tree = ast.parse(path.read_text())
        sources = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
        assert any(m and m.endswith("interpreter") for m in sources), path.name
        assert not any(isinstance(n, ast.FunctionDef) and n.name in ("interpret", "_eval", "_propagate")
                       for n in tree.body), path.name
