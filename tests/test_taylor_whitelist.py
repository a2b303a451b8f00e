"""Every function a model file may use translates into the expression graph.

The functions are those of the model-file whitelist (``uio_jax._io.expressions.FUNCTIONS``,
walked, not listed here), compiled as model files compile them
(``uio_jax._io.expression_functions.to_function``). For each one, its expression in the
graph (:func:`uio_jax._engine.graph_trace.translate`) gives the values and gradients JAX
gives (its own derivative rules), at a few points of the function's domain. Then one model
file using every function runs through ``uio-jax analyze --method series`` with the ORC's
verdict; a primitive without a rule is one line naming it.
"""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from uio_jax import cli
from uio_jax._engine.graph import Graph
from uio_jax._engine.graph_numpy import evaluate
from uio_jax._engine.graph_trace import translate
from uio_jax._io.expression_functions import to_function
from uio_jax._io.expressions import FUNCTIONS, parse_expression

#: candidate ranges of an argument: the first on which the function is finite is used
RANGES = ((0.2, 0.6), (1.2, 1.6))

NAMES = ("a", "b", "c")


def _arities(name):
    """The argument counts to check: the fixed one, or the least and one more."""
    n = FUNCTIONS[name]
    return (n,) if isinstance(n, int) else (n[0], n[0] + 1)


def _compiled(name, m):
    """``f(z)`` of ``z`` of shape (m,) compiled from the text ``name(a, b, ..)``."""
    names = NAMES[:m]
    return to_function(parse_expression(f"{name}({', '.join(names)})", names), names)


def _domain(fn, m):
    """The first range of :data:`RANGES` on which ``fn`` (every argument in it) is finite."""
    grid = np.linspace(0.0, 1.0, 7)
    for lo, hi in RANGES:
        z = np.stack(np.meshgrid(*[lo + (hi - lo) * grid] * m), axis=-1).reshape(-1, m)
        if all(np.isfinite(fn(row)) for row in z):
            return lo, hi
    raise AssertionError("no range of RANGES in the domain")  # pragma: no cover


CASES = [(name, m) for name in FUNCTIONS for m in _arities(name)]


@pytest.mark.parametrize("name,m", CASES, ids=[f"{n}/{m}" for n, m in CASES])
def test_the_graph_translates_every_whitelisted_function(name, m):
    fn = _compiled(name, m)
    lo, hi = _domain(fn, m)
    rng = np.random.default_rng([m, len(name)])
    # 3 points in the range (the arguments apart, so that min/max pick one)
    points = lo + (hi - lo) * (0.15 + 0.7 * rng.permutation(np.linspace(0, 1, 3 * m)).reshape(3, m))
    g = Graph(m)
    expr = translate(g, fn, ())
    values, grads = evaluate(g, [expr], points)
    with jax.enable_x64(True):
        z = jnp.asarray(points)
        want = np.asarray(jax.vmap(fn)(z))
        want_grads = np.asarray(jax.vmap(jax.grad(fn))(z))
    assert np.all(np.isfinite(want))
    np.testing.assert_allclose(values[:, 0], want, rtol=1e-12, atol=1e-14, err_msg=name)
    np.testing.assert_allclose(grads[:, 0], want_grads, rtol=1e-10, atol=1e-12, err_msg=name)


def _model_file(tmp_path):
    """A model file whose output and dynamics use every whitelisted function (aliases too),
    each once, in turn in the output and the two dynamics, every argument an affine map of a
    state into the function's domain."""
    terms = ([], [], [])
    for j, name in enumerate(FUNCTIONS):
        m = _arities(name)[-1]
        lo, hi = _domain(_compiled(name, m), m)
        # states are sampled in [0.5, 1.5]: lo + (hi - lo) (x - 0.5) lies in [lo, hi]
        args = [f"{lo} + {hi - lo:.3f}*(x{(j + i) % 2 + 1} - 0.5)" for i in range(m)]
        terms[j % 3].append(f"{name}({', '.join(args)})")
    y, f1, f2 = (" + ".join(t) for t in terms)
    text = "\n".join([
        'name = "every_function"',
        'states = ["x1", "x2"]',
        "[domain]", "x1 = [0.5, 1.5]", "x2 = [0.5, 1.5]",
        "[params]", "k = [0.5, 1.5]",
        "[inputs]", 'known = ["u"]',
        "[outputs]", f'y = "x1 + 0.1*({y})"',
        "[dynamics]", f'x1 = "x2 + 0.1*({f1})"', f'x2 = "-k*x1 + u + 0.1*({f2})"',
    ])
    path = tmp_path / "every_function.toml"
    path.write_text(text + "\n")
    return path


def _verdict(path):
    report = json.loads(path.read_text())
    return {key: report[key] for key in ("dim", "observable", "identifiable")}


@pytest.mark.slow  # two analyses of a model with some thirty transcendental terms
def test_series_runs_on_a_model_file_using_every_function(tmp_path, capsys):
    verdicts = _cli_verdicts(_model_file(tmp_path), tmp_path, capsys, 64)
    assert verdicts["series"] == verdicts["orc"]
    assert verdicts["series"]["dim"] == 3


def _cli_verdicts(model, tmp_path, capsys, samples, methods=("series", "orc")):
    """``{method: verdict}`` of ``uio-jax analyze MODEL --method M``."""
    verdicts = {}
    for method in methods:
        out = tmp_path / f"{method}.json"
        code = cli.main(["analyze", str(model), "--method", method, "--samples", str(samples), "--json", str(out),
                         "--no-progress", "--no-cache"])
        assert code == 0, capsys.readouterr().err
        verdicts[method] = _verdict(out)
    return verdicts


def test_series_runs_on_an_angle_output(tmp_path, capsys):
    """The two-compartment model observed through ``atan2(x2, x1)`` (no rule before): the
    verdict ``--method orc`` gives on it (every state observable, both rates identifiable)."""
    model = tmp_path / "angle.toml"
    model.write_text("\n".join([
        'name = "angle"', 'states = ["x1", "x2"]', "[params]", "k01 = [0.5, 1.5]", "k12 = [0.5, 1.5]",
        "[inputs]", 'known = ["u"]', "[outputs]", 'y = "atan2(x2, x1)"',
        "[dynamics]", 'x1 = "-(k01 + k12)*x1 + k12*x2 + u"', 'x2 = "k12*x1 - k12*x2"', ""]))
    verdict = _cli_verdicts(model, tmp_path, capsys, 32, methods=("series",))["series"]
    assert verdict == {"dim": 4, "observable": {"x1": True, "x2": True}, "identifiable": {"k01": True, "k12": True}}


def test_a_primitive_without_a_rule_is_one_line(tmp_path, capsys):
    model = tmp_path / "lgamma_model.py"
    model.write_text(
        "import jax\nimport jax.numpy as jnp\nimport uio_jax as uj\n\n"
        "def system():\n"
        "    return uj.System(states=('x1', 'x2'), outputs={'y': lambda x: x[0]},\n"
        "                     drift=lambda x: jnp.stack([jax.scipy.special.gammaln(1.0 + x[1]), -x[0]]))\n"
    )
    code = cli.main(["analyze", f"{model}:system", "--method", "series", "--samples", "16", "--no-progress",
                     "--no-cache"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "drift: the expression graph has no rule for the JAX primitive 'lgamma' (supported: " in err[0]
