"""Command line: readable reports, one-line errors with exit code 2, no tracebacks."""

import itertools
import json
import os
import subprocess
import sys
import textwrap

import pytest
from helpers import one_line_error, zoo_path

from uio_jax import cli
from uio_jax._analysis.decisions import memory

#: the estimate of ``--samples 1e9`` on a 3-state model (the sampled states alone are 24 GB)
HUGE = memory.format_bytes(sum(memory.analysis_bytes(10**9, 3).values()))

GOOD = f"{zoo_path('unicycle_polar')}:range_known"

BAD_MODELS = {
    "wrong_length": ("""
        import jax.numpy as jnp, uio_jax as uj
        def f():
            return uj.System(("a", "b"), {"y": lambda x: x[0]}, known={"u": lambda x: jnp.ones(3)})
        """, "known field 'u' returns shape (3,), expected shape (2,)"),
    "nan_everywhere": ("""
        import jax.numpy as jnp, uio_jax as uj
        def f():
            return uj.System(("a",), {"y": lambda x: jnp.log(-x[0])})
        """, "returns NaN/inf at every one of"),
    "syntax": ("def f(:\n", "fails to load"),
    "raises": ("""
        def f():
            raise RuntimeError("boom")
        """, "raised RuntimeError: boom"),
    "not_a_system": ("""
        def f():
            return 42
        """, "did not give a uio_jax.System (got int)"),
    "import_error": ("import not_a_module_anywhere\n", "ModuleNotFoundError"),
}


def _write(tmp_path, name, source):
    path = tmp_path / f"{name}.py"
    path.write_text(textwrap.dedent(source))
    return str(path)


@pytest.mark.parametrize("name", sorted(BAD_MODELS))
def test_bad_model_files(tmp_path, capsys, name):
    source, message = BAD_MODELS[name]
    path = _write(tmp_path, name, source)
    assert cli.main(["analyze", f"{path}:f"]) == 2
    assert message in one_line_error(capsys)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["analyze", "nowhere.py:f"], "model file not found: nowhere.py"),
        (["analyze", f"{zoo_path('unicycle_polar')}:nope"], "has no 'nope'"),
        (["analyze", "no_colon"], "FILE.py:NAME"),
        (["analyze", GOOD, "--method", "magic"], "invalid choice: 'magic'"),
        (["analyze", GOOD, "--samples", "0"], "samples must be an integer >= 8"),
        (["analyze", GOOD, "--samples", "lots"], "invalid int value"),
        (["analyze", GOOD, "--seed", "-1"], "seed must be a non-negative integer"),
        (["analyze", GOOD, "--rtol", "2"], "rtol must be a number in (0, 1)"),
        (["analyze", f"{zoo_path('unicycle_polar')}:range_v_unknown", "--method", "orc"],
         "method 'orc' needs every input known"),
        (["frobnicate"], "invalid choice: 'frobnicate'"),
    ],
)
def test_bad_arguments(capsys, argv, message):
    assert cli.main(argv) == 2
    assert message in one_line_error(capsys)


def test_analyze_prints_a_report_and_writes_json(tmp_path, capsys):
    out_json = tmp_path / "r.json"
    assert cli.main(["analyze", GOOD, "--samples", "256", "--json", str(out_json)]) == 0
    out, err = capsys.readouterr()
    assert "observable codistribution: dim 2 of 3" in out
    assert "m=0: dim 1" in out and "certificate:" in out
    assert "unobservable directions at the centre of the domain" in out
    data = json.loads(out_json.read_text())
    assert data["dim"] == 2 and data["observable"] == {"r": True, "phi": False, "theta": False}
    assert data["certificate"]["samples"] == 256


@pytest.mark.parametrize("spec, method", [
    (GOOD, "orc"), (GOOD, "series"),
    (f"{zoo_path('unicycle_polar')}:range_omega_unknown", "single_ui"),
    (f"{zoo_path('gps')}:inputs_unknown", "eorc"),
])
def test_each_decided_step_is_announced_once(spec, method):
    """The steps printed while an analysis runs are exactly its history, in order."""
    import io

    import uio_jax as uj
    from uio_jax._io.loading import load_system
    from uio_jax._progress import StepPrinter, step_listener

    seen, buf = [], io.StringIO()
    printer = StepPrinter(enabled=True, stream=buf)
    with step_listener(lambda step: (seen.append(step), printer(step))):
        rep = uj.analyze(load_system(spec), method=method, samples=64)
    assert rep.method == method
    assert [(s.m, s.dim, s.added) for s in seen] == [(s.m, s.dim, s.added) for s in rep.history]
    lines = buf.getvalue().splitlines()
    name = "k" if method == "eorc" else "m"
    assert [ln.split()[1] for ln in lines] == [f"{name}={s.m}" for s in rep.history]
    assert all(f"dim {s.dim} " in ln for s, ln in zip(rep.history, lines))


def _progress_step():
    from uio_jax._analysis.results.evidence import Step

    return Step(3, 2, ("a",), 1.0)


def test_analyze_progress_on_a_terminal_and_for_long_runs_elsewhere(capsys, monkeypatch):
    """Every step on a terminal; off a terminal (a log) only the steps of a run that has lasted
    ``OFF_TERMINAL_AFTER`` seconds (issue 40: long work printed nothing off a terminal)."""
    import io

    from uio_jax import _progress

    assert cli.main(["analyze", GOOD, "--samples", "64"]) == 0
    assert "uio-jax: m=" not in capsys.readouterr().err  # a short run, stderr not a terminal
    log = io.StringIO()
    printer = _progress.StepPrinter(stream=log)
    step = _progress_step()
    printer(step)
    assert log.getvalue() == ""
    printer.t0 -= _progress.OFF_TERMINAL_AFTER + 1  # the run has lasted longer
    printer(step)
    assert log.getvalue().startswith("uio-jax: m=3  dim 2")
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    assert cli.main(["analyze", GOOD, "--samples", "64"]) == 0
    assert "uio-jax: m=0  dim 1" in capsys.readouterr().err
    assert cli.main(["analyze", GOOD, "--samples", "64", "--no-progress"]) == 0
    assert "uio-jax: m=" not in capsys.readouterr().err


def test_unwritable_json_is_one_line(tmp_path, capsys):
    assert cli.main(["analyze", GOOD, "--samples", "64", "--json", str(tmp_path / "no" / "r.json")]) == 2
    one_line_error(capsys)


def test_installed_script_smoke():
    """The console script and ``python -m uio_jax`` both run (subprocess)."""
    exe = os.path.join(os.path.dirname(sys.executable), "uio-jax")
    cmd = [exe] if os.path.exists(exe) else [sys.executable, "-m", "uio_jax"]
    proc = subprocess.run(cmd + ["analyze", GOOD, "--samples", "64"], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "dim 2 of 3" in proc.stdout
    proc = subprocess.run([sys.executable, "-m", "uio_jax", "analyze", "missing.py:f"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1


def test_the_option_defaults_are_those_of_analyze():
    """``analyze``, ``batch`` and the library take their defaults and checks from one place."""
    import inspect

    import numpy as np

    import uio_jax as uj
    from uio_jax._analysis.options import DEFAULTS, check_options

    for command in (["analyze", GOOD], ["batch", GOOD]):
        args = cli._build_parser().parse_args(command)
        assert {k: getattr(args, k) for k in DEFAULTS} == DEFAULTS
    params = inspect.signature(uj.analyze).parameters
    assert {k: params[k].default for k in DEFAULTS} == DEFAULTS
    opts = check_options(samples=np.int64(64), seed=np.uint32(3))
    assert opts == {**DEFAULTS, "samples": 64, "seed": 3, "rtol": 1e-8}
    assert type(opts["samples"]) is int and type(opts["seed"]) is int


# ---------------------------------------------------------------------------- option ranges (H2)
SORT_MODEL = """
    import jax, jax.numpy as jnp, uio_jax as uj
    def f():
        return uj.System(states=("a", "b"), outputs={"y": lambda x: jax.lax.sort(x)[0]},
                         known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])},
                         domain={"a": (0.5, 1.0), "b": (2.0, 3.0)})
    """
EORC_MODEL = f"{zoo_path('gps')}:inputs_unknown"  # two unknown inputs (run with --method eorc)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["analyze", GOOD, "--seed", str(2**64)], "seed must be a non-negative integer below 2**64"),
        (["batch", GOOD, "--seed", str(2**64)], "seed must be a non-negative integer below 2**64"),
        (["analyze", GOOD, "--samples", str(10**9)],
         f"samples=1000000000 x 3 states needs about {HUGE}"),
        (["analyze", EORC_MODEL, "--method", "eorc", "--k-max", "2000"],
         "the EORC to k_max=2000 (samples=4096 x N=4003"),
        (["analyze", GOOD, "--max-order", "-1"], "max_order must be a non-negative integer"),
        (["analyze", GOOD, "--k-max", "0"], "k_max must be a positive integer"),
        (["analyze", GOOD, "--rtol", "nan"], "rtol must be a number in (0, 1)"),
        (["analyze", GOOD, "--rtol", "inf"], "rtol must be a number in (0, 1)"),
        (["analyze", GOOD, "--rtol=-inf"], "rtol must be a number in (0, 1)"),
        (["analyze", GOOD, "--samples", "7"], "samples must be an integer >= 8"),
        (["batch", GOOD, "--jobs", "0"], "jobs must be a positive integer"),
        (["batch", GOOD, "--timeout", "0"], "timeout must be a positive number of seconds"),
        (["batch", GOOD, "--timeout", "-1"], "timeout must be a positive number of seconds"),
        (["batch", GOOD, "--timeout", "nan"], "timeout must be a positive number of seconds"),
        (["batch", GOOD, "--k-max", "0"], "k_max must be a positive integer"),
        (["analyze", GOOD, "--no-cache", "--cache-dir", "somewhere"],
         "--no-cache and --cache-dir somewhere contradict each other"),
        (["batch", GOOD, "--no-cache", "--cache-dir", "somewhere"], "contradict each other"),
        (["montecarlo", f"{zoo_path('unicycle_disturbance')}:range_gamma_unknown_experiment",
          "--no-cache", "--cache-dir", "somewhere"], "contradict each other"),
    ],
)
def test_option_ranges_are_one_line_usage_errors(monkeypatch, capsys, argv, message):
    monkeypatch.setenv("UIO_JAX_MEMORY_LIMIT", "8G")
    assert cli.main(argv + ["--no-progress"] if argv[0] != "montecarlo" else argv) == 2
    assert message in one_line_error(capsys)


def test_a_seed_past_2_63_runs(capsys):
    assert cli.main(["analyze", GOOD, "--samples", "64", "--seed", str(2**63), "--no-progress"]) == 0
    assert "dim 2 of 3" in capsys.readouterr().out


def test_a_model_outside_the_graph_is_refused_in_one_line(tmp_path, capsys):
    path = _write(tmp_path, "sorted_model", SORT_MODEL)
    for method in ("fast", "orc"):
        assert cli.main(["analyze", f"{path}:f", "--method", method, "--samples", "64", "--no-progress"]) == 2
        assert "the expression graph has no rule for the JAX primitive 'sort'" in one_line_error(capsys)


def test_cache_dir_help_states_the_default_rule(capsys):
    from uio_jax._filter.compile_cache import DEFAULT_DIR_RULE

    for command in ("analyze", "batch", "montecarlo"):
        with pytest.raises(SystemExit):
            cli.main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert f"(default: {DEFAULT_DIR_RULE})" in text
        assert "$XDG_CACHE_HOME/uio_jax/xla" in text


def test_batch_row_of_a_model_too_large(monkeypatch, capsys):
    """In a batch the memory check is per model (it depends on its size): a failed row."""
    monkeypatch.setenv("UIO_JAX_MEMORY_LIMIT", "8G")
    assert cli.main(["batch", GOOD, "--samples", str(10**9), "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert f"needs about {HUGE}" in out and "lower samples" in out


@pytest.mark.parametrize("command", ["analyze", "batch"])
def test_output_paths_checked_before_any_work(command, tmp_path, capsys):
    """An output path that is a directory, or two outputs naming one file, is one line and
    exit 2 before the model is even loaded (the model path does not exist)."""
    missing_model = str(tmp_path / "no_such_model.toml")
    first = "--json"
    second = "--plot" if command == "analyze" else "--csv"
    cases = [
        [first, str(tmp_path)],                                            # a directory
        [first, str(tmp_path / "out.png"), second, str(tmp_path / "out.png")],  # the same file
    ]
    for extra in cases:
        assert cli.main([command, missing_model, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "Traceback" not in err
        assert "directory" in err or "same file" in err, err


def test_analysis_options_checked_before_the_model_is_loaded(tmp_path, capsys):
    """A bad option is named even when the model would fail too (it is never loaded)."""
    missing_model = str(tmp_path / "no_such_model.toml")
    for command, (extra, words) in itertools.product(
            ("analyze", "batch"),
            ((["--seed", str(2**64)], "seed"), (["--samples", "3"], "samples"), (["--k-max", "0"], "k_max"))):
        assert cli.main([command, missing_model, *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and words in err and "no_such_model" not in err, err
