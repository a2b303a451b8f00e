"""A model that is not a Python program reaches the expression graph without JAX.

* ``import uio_jax`` does not import JAX, and ``uio-jax analyze`` on a model file, a StrikePy
  model or a sympy model runs to its report without importing it (fresh processes; a Python
  model does import it: the check can fail);
* the expression a declarative model's function builds itself (``emit``, no JAX) is the
  expression the translation of its JAX version makes, node for node: random expression
  trees over every whitelisted function, the general form's drift and input fields, and the
  functions of the model files of the repository (their Systems' joint and autonomous
  functions included).
"""

import os
import random
import subprocess
import sys

import numpy as np
import pytest
from conftest import ROOT

import uio_jax as uj
from uio_jax._engine.graph import Graph
from uio_jax._engine.graph_trace import translate
from uio_jax._io.affine import split_general
from uio_jax._io.expression_functions import to_function
from uio_jax._io.expressions import FUNCTIONS, parse_expression
from uio_jax._model.validation import named_functions

TOML = os.path.join(ROOT, "systems", "two_compartment.toml")
STRIKEPY = os.path.join(ROOT, "tests", "data", "strikepy_models", "C2M.py")


def _imported_modules(args, code=None):
    """The top-level names of the modules a fresh process imports (``python -X importtime``),
    and its stdout; ``code``: a ``-c`` program instead of ``-m uio_jax ARGS``."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(ROOT)
    cmd = [sys.executable, "-X", "importtime"] + (["-c", code] if code else ["-m", "uio_jax", *args])
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    names = {ln.split("|")[-1].strip().split(".")[0] for ln in proc.stderr.splitlines()
             if ln.startswith("import time:") and "|" in ln}
    return names, proc.stdout


def test_import_uio_jax_does_not_import_jax():
    names, _ = _imported_modules((), code="import uio_jax; print(sorted(uio_jax.__all__))")
    assert "uio_jax" in names and "numpy" in names
    assert "jax" not in names and "jaxlib" not in names


def test_the_cli_analyses_a_model_file_without_jax(tmp_path):
    names, out = _imported_modules(["analyze", TOML, "--samples", "64", "--no-cache"])
    assert "dim 5 of 5" in out
    assert "jax" not in names and "jaxlib" not in names
    names, out = _imported_modules(["analyze", STRIKEPY, "--samples", "64", "--no-cache"])
    assert "observable codistribution" in out and "jax" not in names
    # a known initial state given as an expression in the parameters, and smooth known inputs
    names, out = _imported_modules(["analyze", TOML, "--initial", "x2=2*k12", "--samples", "64", "--no-cache"])
    assert "answer: exact" in out and "jax" not in names
    names, out = _imported_modules(["analyze", TOML, "--known-inputs", "smooth", "--samples", "64", "--no-cache"])
    assert "observable codistribution" in out and "jax" not in names
    # the check can fail: a Python model's functions are JAX callables, traced
    names, out = _imported_modules(["analyze", os.path.join(ROOT, "systems", "gps.py") + ":inputs_known",
                                    "--samples", "64", "--no-cache"])
    assert "observable codistribution" in out and "jax" in names


def test_a_sympy_model_is_analysed_without_jax():
    code = ("import sys, sympy as sp, uio_jax as uj\n"
            "x1, x2, k = sp.symbols('x1 x2 k')\n"
            "s = uj.System.from_sympy(states=[x1, x2], outputs={'y': x1}, params={k: (0.5, 1.5)},\n"
            "                         drift=[-k*x1 + x2, sp.sin(x1)])\n"
            "r = uj.analyze(s, samples=64); print(r.dim, r.identifiable['k'])\n"
            "print('JAX', 'jax' in sys.modules)\n")
    names, out = _imported_modules((), code=code)
    assert "JAX False" in out and "3 True" in out


# ---------------------------------------------------------------------------- the same graph
_COMMUTATIVE = {"add", "mul"}


def _canonical(graph, roots, table):
    """Ids of the ``roots`` in ``table``, shared between graphs: two nodes get one id when they
    are the same operation with the same parameter on operands of the same ids (the operands
    of ``add`` and ``mul`` in either order): equal ids, equal expressions."""
    memo = {}
    for k in graph.reachable(roots):
        op, param = graph.op[k], graph.param[k]
        kids = tuple(memo[a] for a in graph.args[k])
        if op in _COMMUTATIVE:
            kids = tuple(sorted(kids))
        memo[k] = table.setdefault((op, (type(param).__name__, param), kids), len(table))
    return [memo[r] for r in roots]


def _same_graph(fn, n, shape, extra=()):
    """Whether ``fn``'s own expression (``emit``) equals the translation of its JAX version
    (the same function behind a lambda, which has no ``emit``: traced); ``extra``: shapes of
    arguments after the state (parameters, time)."""
    width = n + sum(int(np.prod(e)) for e in extra)
    own, traced = Graph(width), Graph(width)
    a = translate(own, fn, shape, extra)
    b = translate(traced, lambda *args: fn(*args), shape, extra)
    assert a is not None and b is not None
    table = {}
    roots_a = [a] if shape == () else list(a)
    roots_b = [b] if shape == () else list(b)
    return _canonical(own, roots_a, table) == _canonical(traced, roots_b, table)


_NAMES = ("x1", "x2", "x3", "p")
_UNARY = [f for f, k in FUNCTIONS.items() if k == 1]
_BINARY = [f for f, k in FUNCTIONS.items() if k == 2 or isinstance(k, tuple)]


#: functions finite at every real argument (the general form's models must be finite somewhere)
_SMOOTH = ["sin", "cos", "atan", "tanh", "exp", "sinh", "asinh"]


def _random_text(rng, depth, unary=tuple(_UNARY), binary=tuple(_BINARY), powers=True):
    if depth == 0 or rng.random() < 0.2:
        return rng.choice([*_NAMES, "pi", "E", "2", "0.5", "1.3", "-3", "0", "1"])
    kind = rng.random()
    a = _random_text(rng, depth - 1, unary, binary, powers)
    b = _random_text(rng, depth - 1, unary, binary, powers)
    if kind < 0.4:
        return f"({a}) {rng.choice(['+', '-', '*'] + (['/'] if powers else []))} ({b})"
    if kind < 0.55 and powers:
        return f"({a})**{rng.choice(['2', '-1', '3', '0.5', '2.5', '100', '0', '1', '(' + b + ')'])}"
    if kind < 0.85 or not binary:
        return f"{rng.choice(unary)}({a})"
    return f"{rng.choice(binary)}({a}, {b})"


@pytest.mark.parametrize("seed", range(6))
def test_a_tree_builds_the_expression_its_jax_version_translates_to(seed):
    rng = random.Random(seed)
    for _ in range(40):
        text = _random_text(rng, 4)
        fn = to_function(parse_expression(text, _NAMES), _NAMES)
        assert _same_graph(fn, len(_NAMES), ()), text


def test_the_general_form_builds_the_expressions_of_its_jax_version():
    """Drift, input fields (dual numbers against ``jax.jvp``), outputs and the fields of
    promoted inputs of random models affine in their inputs."""
    rng = random.Random(7)
    states = ("x1", "x2", "x3")

    def text(depth):
        return _random_text(rng, depth, _SMOOTH, ("atan2",), powers=False)

    for _ in range(12):
        dynamics = {}
        for s in states:
            terms = [text(2)]
            for v in ("u", "w"):
                if rng.random() < 0.7:
                    terms.append(f"{v}*({text(2)})" if rng.random() < 0.6
                                 else f"({text(2)})*{v}/(exp({text(1)}) + 3)")
            if rng.random() < 0.2:
                terms.append("u*w")  # a cross term: one input promoted
            dynamics[s] = " + ".join(terms)
        names = states + ("p", "u", "w")
        trees = {k: parse_expression(t, names) for k, t in dynamics.items()}
        parts = split_general(states, trees, {"y": parse_expression("x1 + sin(x2)", names)}, ("u",), ("w",),
                              {"p": (0.5, 1.5)}, {}, {}, ())
        n = len(parts.states) + 1  # z = [x; promoted; p]
        fns = [(parts.drift, (len(parts.states),))] if parts.drift is not None else []
        fns += [(f, (len(parts.states),)) for f in (*parts.known.values(), *parts.unknown.values())]
        fns += [(h, ()) for h in parts.outputs.values()]
        for fn, shape in fns:
            assert _same_graph(fn, n, shape), dynamics


def test_the_model_files_build_the_expressions_of_their_jax_versions():
    """Every function of the Systems the analyses run on (joint, autonomous: wrappers of the
    model's own functions) of the repository's model files and StrikePy models."""
    paths = [os.path.join(ROOT, "systems", f) for f in sorted(os.listdir(os.path.join(ROOT, "systems")))
             if f.endswith(".toml")]
    folder = os.path.join(ROOT, "tests", "data", "strikepy_models")
    paths += [os.path.join(folder, f) for f in sorted(os.listdir(folder)) if f.endswith(".py")]
    checked = 0
    for path in paths:
        analysed = uj.load_system(path).autonomous()
        for what, fn, shape in named_functions(analysed):
            assert _same_graph(fn, analysed.n, shape), f"{path}: {what}"
            checked += 1
    assert checked >= 50


def test_a_time_varying_model_file_with_parameters(tmp_path):
    """``(x, p, t)`` functions: the user's System's own (three arguments), and the joint and
    autonomous wrappers around them."""
    path = tmp_path / "tv.toml"
    path.write_text('states = ["x1", "x2"]\ntime = "t"\nparams = ["k"]\n[outputs]\ny = "x1 + t*x2"\n'
                    '[drift]\nx1 = "-k*x1 + sin(t)"\nx2 = "x1*t"\n[unknown.w]\nx2 = "1 + t**2"\n')
    system = uj.load_system(str(path))
    for what, fn, shape in named_functions(system):
        assert _same_graph(fn, system.n, shape, extra=((1,), ())), what
    for layer in (system.joint(), system.autonomous()):
        extra = ((),) if layer.time is not None else ()
        for what, fn, shape in named_functions(layer):
            assert _same_graph(fn, layer.n, shape, extra=extra), what
