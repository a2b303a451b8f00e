"""What a new user found (issue 40), continued: no raw exceptions, JSON that says what the
text says, and the smaller items (notes, pipes, settings, model files)."""

import json
import os
import subprocess
import sys
import textwrap

import pytest
from helpers import ROOT, one_line_error, zoo_path
from new_user_models import TOML, TOY
from test_new_user import GOOD

import uio_jax as uj
from uio_jax import cli

# -- 6. tracebacks and raw exceptions ------------------------------------------------------

@pytest.mark.parametrize("name, text", [("deep.json", "[" * 100000), ("deep.toml", "a = " + "[" * 100000)],
                         ids=["json", "toml"])
def test_a_deeply_nested_model_file_is_a_one_line_error(tmp_path, capsys, name, text):
    path = tmp_path / name
    path.write_text(text)
    assert cli.main(["analyze", str(path)]) == 2
    assert "nested too deeply" in one_line_error(capsys)


def test_plot_functions_name_what_they_need():
    with pytest.raises(TypeError, match="plot_analysis needs a uio_jax.Report.*got str"):
        uj.plot_analysis("str")
    with pytest.raises(TypeError, match="plot_montecarlo needs a uio_jax MonteCarloResult.*got str"):
        uj.plot_montecarlo("str")


def test_batch_on_row_not_callable_is_refused_before_any_model_runs(monkeypatch):
    from uio_jax._batch import one_model

    ran = []
    monkeypatch.setattr(one_model, "analyze", lambda *a, **k: ran.append(a))
    system = uj.System(("a",), {"y": lambda x: x[0]})
    with pytest.raises(TypeError, match="on_row must be None or a function"):
        uj.batch_analyze([system], on_row=5, samples=64, progress=False)
    assert not ran


# -- 7. machine-readable output that disagrees with the text -------------------------------

def test_analyze_json_of_a_model_without_parameters_has_the_printed_directions(tmp_path, capsys):
    out_json = tmp_path / "r.json"
    assert cli.main(["analyze", GOOD, "--samples", "64", "--no-progress", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "unobservable directions at" in out and "+0.707 phi  +0.707 theta" in out, out
    d = json.loads(out_json.read_text())
    (direction,) = d["unobservable_directions"]
    assert direction["r"] == 0.0 and abs(direction["phi"] - 0.5 ** 0.5) < 1e-3, direction
    assert "off the centre" in d["directions_at"]["rule"] and d["identifiable_combinations"] == []


def test_markdown_status_cell_of_an_ok_row_says_ok(tmp_path, capsys):
    md = tmp_path / "t.md"
    assert cli.main(["batch", GOOD, "--samples", "64", "--no-progress", "--markdown", str(md)]) == 0
    row = next(ln for ln in md.read_text().splitlines() if "range_known" in ln)
    assert row.rstrip().endswith("| ok |"), row


def test_montecarlo_json_has_the_verdict_line_and_the_filter(tmp_path, capsys, toy):
    out_json = tmp_path / "mc.json"
    assert cli.main(["montecarlo", toy, "--trials", "2", "--keep", "0", "--no-progress", "--no-cache",
                     "--json", str(out_json)]) == 0
    verdict_line = capsys.readouterr().out.splitlines()[1]
    d = json.loads(out_json.read_text())
    assert d["headline"][0] == verdict_line and d["filter"] == "fast"
    assert d["outcome"] == d["comparison"]["verdict"] == "agrees", verdict_line
    assert d["comparison"]["agree"] is True


# -- 8. smaller items ----------------------------------------------------------------------

@pytest.mark.parametrize("expr", ["0", "a - a"])
def test_a_constant_output_gets_a_note(tmp_path, expr):
    path = tmp_path / "c.toml"
    path.write_text(textwrap.dedent(TOML).replace('y = "a"', f'y = "{expr}"\nz = "b"'))
    rep = uj.analyze(uj.load_system(str(path)), samples=64)
    assert any(n.startswith("output y adds no direction at m=0: constant") for n in rep.notes), rep.notes
    assert not any("output z" in n for n in rep.notes)


def test_a_reader_that_leaves_early_ends_the_command_quietly(tmp_path, toml_model):
    """``uio-jax analyze m.toml | head -0``: no 'error: Broken pipe', exit code 141 (SIGPIPE's)."""
    proc = subprocess.Popen([sys.executable, "-m", "uio_jax", "analyze", toml_model, "--samples", "64",
                             "--no-progress", "--no-cache"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env=dict(os.environ, PYTHONPATH=ROOT))
    proc.stdout.close()  # the reader is gone before the report is printed
    with proc.stderr:
        err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 141, err
    assert err == "", err


@pytest.mark.parametrize("command", ["batch", "montecarlo"])
def test_a_bad_pin_workers_setting_is_refused(monkeypatch, capsys, command):
    from uio_jax._filter import cluster

    monkeypatch.setenv("UIO_JAX_PIN_WORKERS", "maybe")
    model = GOOD if command == "batch" else zoo_path("unicycle_polar") + ":range_known"
    assert cli.main([command, model, "--scheduler", "tcp://127.0.0.1:1", "--no-progress"]) == 2
    assert "UIO_JAX_PIN_WORKERS must be 0" in one_line_error(capsys)
    monkeypatch.setattr(cluster, "_CLAIMED", [])
    with pytest.raises(uj.OptionError, match="got 'maybe'"):  # on a worker host: its task's error
        cluster.claim_one_cpu()


def test_k_max_on_an_orc_run_is_noted(capsys):
    assert cli.main(["analyze", GOOD, "--samples", "64", "--no-progress", "--k-max", "40"]) == 0
    out = capsys.readouterr().out
    assert "note: k_max=40 applies to the EORC only: the orc analysis that ran does not use it" in out, out


def test_a_model_file_with_a_byte_order_mark_loads(tmp_path):
    for name, text in (("m.toml", 'states = ["a"]\n[outputs]\ny = "a"\n'),
                       ("m.json", '{"states": ["a"], "outputs": {"y": "a"}}')):
        path = tmp_path / name
        path.write_bytes(b"\xef\xbb\xbf" + text.encode())
        assert uj.load_system(str(path)).states == ("a",)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_a_directory_or_fifo_named_like_a_model_is_not_called_missing(tmp_path, capsys):
    (tmp_path / "d.toml").mkdir()
    os.mkfifo(tmp_path / "f.toml")
    for name, words in (("d.toml", "is a directory"), ("f.toml", "is not a regular file")):
        assert cli.main(["analyze", str(tmp_path / name)]) == 2
        assert words in one_line_error(capsys)


def test_what_a_model_prints_goes_to_stderr_not_into_the_report(tmp_path, capsys):
    path = tmp_path / "chatty.py"
    path.write_text("import uio_jax as uj\nprint('hello from the module')\n"
                    "def f():\n    print('hello from f')\n    return uj.System(('a',), {'y': lambda x: x[0]})\n")
    assert cli.main(["analyze", f"{path}:f", "--samples", "64", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("uio_jax report: ") and "hello" not in out, out
    assert "hello from the module" in err and "hello from f" in err
    assert cli.main(["batch", f"{path}:f", "--samples", "64", "--no-progress"]) == 0
    out, err = capsys.readouterr()
    assert out.startswith("model ") and "hello" not in out, out


def test_a_name_that_shadows_a_built_in_of_expressions_is_noted(tmp_path):
    path = tmp_path / "seir.toml"
    path.write_text('states = ["E", "b"]\n[outputs]\ny = "E"\n[drift]\nE = "b"\nb = "0"\n')
    system = uj.load_system(str(path))
    assert "state 'E' shadows the built-in constant E of expressions: in this model's expressions 'E' " \
           "is the state" in system.notes


def test_a_domain_too_wide_for_float64_is_blamed_not_the_model(tmp_path, capsys):
    path = tmp_path / "wide.toml"
    path.write_text(textwrap.dedent(TOML) + '[domain]\na = [-1e308, 1e308]\n')
    assert cli.main(["analyze", str(path), "--samples", "64", "--no-progress"]) == 2
    line = one_line_error(capsys)
    assert "domain.a: box [-1e+308, 1e+308] too wide" in line and "NaN" not in line, line


def test_a_compile_cache_on_a_file_says_it_is_not_a_directory(tmp_path, toml_model):
    with pytest.raises(NotADirectoryError, match="not a directory"):
        uj.enable_compile_cache(toml_model)


@pytest.mark.parametrize("old, new, words", [
    ('prior_std=(5.0,), units={"x": "m"})',
     'prior_std=(5.0,), units={"x": "m"}, quantities=(uj.Quantity("v", lambda x: jnp.stack([x[0], x[0]])),))',
     "quantity 'v' must return a scalar (), got shape (2,)"),
    ("inputs=lambda s, z: (s, jnp.zeros(0), jnp.zeros(0))", "inputs=lambda s, z: (s, jnp.zeros(2), jnp.zeros(0))",
     "inputs(istate, z) returns u of shape (2,), expected 0 known inputs"),
    ("inputs=lambda s, z: (s, jnp.zeros(0), jnp.zeros(0))", "inputs=lambda s, z: (s, z[5], 0)",
     "inputs(istate, z) fails on istate of shape (0,) and z of shape (0,)"),
], ids=["vector_quantity", "input_law_shape", "input_law_fails"])
def test_an_experiment_function_of_the_wrong_shape_is_one_line(tmp_path, capsys, old, new, words):
    path = tmp_path / "toy.py"
    source = textwrap.dedent(TOY)
    assert old in source
    path.write_text(source.replace(old, new))
    assert cli.main(["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0", "--no-analysis",
                     "--no-progress", "--no-cache"]) == 2
    assert words in one_line_error(capsys)


def test_from_dynamics_measures_use_and_affinity_on_the_input_box():
    """sign(w) has no derivative anywhere yet f(w) is not f(0): not 'in no equation' but not
    affine (promoted); abs(w) on [-1, 1] is not affine either; 0 * w is in no equation."""
    import jax.numpy as jnp

    def system(fn, domain=None):
        return uj.System.from_dynamics(("x",), lambda x, u, w: jnp.array([fn(w[0]) + x[0]]),
                                       {"y": lambda x, u, w: x[0]}, unknown=("w",), domain=domain)

    for fn in (jnp.sign, jnp.abs):
        s = system(fn, {"w": (-1.0, 1.0)})
        assert s.states == ("x", "w") and any("is not affine between 0 and its box" in n for n in s.notes)
    s = system(lambda w: 0.0 * w)
    assert s.states == ("x",) and s.notes == ("unknown input 'w' appears in no equation: dropped",)
