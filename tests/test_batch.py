"""``uio-jax batch`` / ``uj.batch_analyze``: discovery, one row per model, outputs, exit codes, cache."""

import csv
import io
import json
import os
import subprocess
import sys
import textwrap

import jax
import pytest
from helpers import one_line_error, zoo_path

import uio_jax as uj
from uio_jax import cli
from uio_jax._batch import discovery, pinning, run, timing
from uio_jax._filter.compile_cache import compile_cache, default_cache_dir, disable_compile_cache
from uio_jax._progress import CountProgress

SAMPLES = 64

# a small zoo file: two models, an experiment-like entry that must not be called, a helper
# with a required argument, a function giving a non-System, an imported function, a broken one
ZOO = """
    import jax.numpy as jnp
    from math import pi  # noqa: F401  (not a function of this file)
    from os.path import basename  # imported function: never called
    import uio_jax as uj

    CALLS = []

    def _private():
        CALLS.append("_private")
        return two_states()

    def two_states():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])}, name="")

    def blind():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([1.0 + 0.0 * x[0], 0.0 * x[0]])})

    def needs_arg(x):
        return x

    def not_a_model():
        return 42

    def flight_experiment():
        CALLS.append("flight_experiment")
        raise AssertionError("an experiment must not be called")

    def annotated() -> "Experiment":
        CALLS.append("annotated")
        raise AssertionError("annotated to return no System: must not be called")

    def broken():
        raise RuntimeError("boom")

    CONSTANT = uj.System(("a",), {"y": lambda x: x[0]})
    """


def _write(path, source):
    path.write_text(textwrap.dedent(source))
    return str(path)


@pytest.fixture
def zoo_file(tmp_path):
    return _write(tmp_path / "tiny_zoo.py", ZOO)


def test_zoo_file_discovery(zoo_file):
    entries, skipped = discovery.discover(zoo_file)
    names = [e.label.rpartition(":")[2] for e in entries]
    assert names == ["two_states", "blind", "broken", "CONSTANT"]  # definition order
    assert [e.error is not None for e in entries] == [False, False, True, False]
    assert "raised RuntimeError: boom" in entries[2].error
    reasons = {name.rpartition(":")[2]: why for name, why in skipped}
    assert set(reasons) == {"not_a_model", "flight_experiment", "annotated"}
    assert reasons["not_a_model"] == "returns int"
    assert "experiment" in reasons["flight_experiment"] and "Experiment" in reasons["annotated"]
    from uio_jax._io.loading import load_module

    assert load_module(zoo_file).CALLS == []  # neither private nor skipped functions were called
    assert entries[0].system.name == "tiny_zoo.py:two_states"  # unnamed: named after its entry


def test_batch_analyze_rows(zoo_file):
    res = uj.batch_analyze([zoo_file, f"{zoo_path('unicycle_polar')}:range_known"], samples=SAMPLES)
    assert len(res) == 5 and [r.model.rpartition(":")[2] for r in res] == [
        "two_states", "blind", "broken", "CONSTANT", "range_known"]
    two, blind, broken, constant, polar = res
    assert (two.method, two.dim, two.n, two.unobservable, two.observable) == ("orc", 2, 2, 0, ("a", "b"))
    assert (blind.dim, blind.unobservable, blind.observable) == (1, 1, ("a",))
    assert constant.ok and constant.dim == 1
    assert (polar.dim, polar.n, polar.observable) == (2, 3, ("r",))
    assert polar.fraction == 1.0 and polar.gap_decades > 3 and polar.seconds > 0
    assert polar.report is not None and polar.report.dim == 2
    assert not broken.ok and broken.error.endswith("raised RuntimeError: boom") and broken.dim is None
    assert res.failed == (broken,) and not res.ok
    assert "4 of 5 models analysed, 1 failed" in res.summary()
    assert "3 functions giving no System skipped" in res.summary()


def test_outputs_json_csv_markdown_table(zoo_file):
    res = uj.batch_analyze(zoo_file, samples=SAMPLES, keep_reports=False)
    assert all(r.report is None for r in res)
    d = json.loads(res.to_json())
    assert [m["ok"] for m in d["models"]] == [True, True, False, True]
    assert d["failed"] == 1 and d["options"]["samples"] == SAMPLES
    assert d["models"][0]["observable"] == ["a", "b"] and d["models"][0]["unobservable"] == 0
    rows = list(csv.DictReader(io.StringIO(res.to_csv())))
    assert rows[1]["observable"] == "a" and rows[1]["dim"] == "1" and rows[2]["error"].endswith("boom")
    md = res.to_markdown().splitlines()
    assert md[0].startswith("| model | method | dim / n |") and len(md) == 2 + 4
    assert "FAILED: " in md[4]
    table = res.table().splitlines()
    assert len(table) == 2 + 4 and "FAILED:" in table[4]
    assert len({ln.index("2 / 2") for ln in table[2:3]}) == 1  # aligned column


def test_systems_given_directly():
    sysm = uj.load_system(f"{zoo_path('unicycle_polar')}:phi_known")
    res = uj.batch_analyze([sysm], samples=SAMPLES, method="orc")
    assert res[0].model == "unicycle_polar:phi_known" and res[0].dim == 3


def test_cli_batch_writes_files_and_exit_codes(tmp_path, zoo_file, capsys):
    good = f"{zoo_path('unicycle_polar')}:range_known"
    out = {k: tmp_path / f"t.{k}" for k in ("json", "csv", "md")}
    argv = ["batch", good, "--samples", str(SAMPLES), "--no-cache", "--json", str(out["json"]),
            "--csv", str(out["csv"]), "--markdown", str(out["md"])]
    assert cli.main(argv) == 0
    stdout, err = capsys.readouterr()
    assert "range_known" in stdout and "2 / 3" in stdout and "1 of 1 models analysed" in stdout
    # not on a terminal: one progress line per finished model, no bar
    assert err.splitlines() == [err.strip()] and err.startswith("batch 1/1  ") and "range_known  dim 2/3" in err
    assert "\r" not in err
    assert json.loads(out["json"].read_text())["models"][0]["dim"] == 2
    assert out["csv"].read_text().startswith("model,ok,method")
    assert out["md"].read_text().startswith("| model |")
    # a failing model: one row with its one-line error, the others still analysed, exit 1
    assert cli.main(["batch", zoo_file, good, "--samples", str(SAMPLES), "--no-cache"]) == 1
    stdout, err = capsys.readouterr()
    assert "Traceback" not in stdout + err
    lines = err.splitlines()
    assert [ln.split()[1] for ln in lines] == ["1/5", "2/5", "3/5", "4/5", "5/5"]
    assert sum("error: " in ln for ln in lines) == 1 and "ETA" in lines[0] and "ETA" not in lines[-1]
    assert sum("FAILED:" in ln for ln in stdout.splitlines()) == 1
    assert "4 of 5 models analysed, 1 failed" in stdout


def test_bad_model_files_are_rows(tmp_path):
    bad = _write(tmp_path / "syntax.py", "def f(:\n")
    nan = _write(tmp_path / "nan.py", """
        import jax.numpy as jnp, uio_jax as uj
        def f():
            return uj.System(("a",), {"y": lambda x: jnp.log(-x[0])})
        """)
    toml = tmp_path / "model.toml"
    toml.write_text("this is not a model\n")
    res = uj.batch_analyze([bad, f"{nan}:f", str(toml)], samples=SAMPLES)
    assert [r.ok for r in res] == [False, False, False]
    assert "fails to load" in res[0].error and "NaN" in res[1].error
    assert res[2].error and "\n" not in res[2].error


@pytest.mark.parametrize("argv, message", [
    (["batch"], "at least one PATH"),
    (["batch", "no/such/dir"], "no such file, directory or model: no/such/dir"),
    (["batch", "no/such/*.py"], "no model file matches"),
    (["batch", "missing.py:f"], "model file not found: missing.py"),
    (["batch", "systems", "--jobs", "0"], "jobs must be a positive integer"),
    (["batch", "systems", "--jobs", "-2"], "jobs must be a positive integer"),
    (["batch", "systems", "--jobs", "nan"], "invalid int value: 'nan'"),
    (["batch", "systems", "--jobs", "inf"], "invalid int value: 'inf'"),
    (["batch", "systems", "--timeout", "0"], "timeout must be a positive number"),
    (["batch", "systems", "--timeout", "-1"], "timeout must be a positive number"),
    (["batch", "systems", "--timeout", "nan"], "timeout must be a positive number"),
    (["batch", "systems", "--timeout", "inf"], "timeout must be a positive number"),
    (["batch", "systems", "--samples", "0"], "samples must be an integer >= 8"),
    (["batch", "systems", "--method", "magic"], "invalid choice: 'magic'"),
    (["batch", "systems", "--json", "no/dir/t.json"], "cannot write --json no/dir/t.json"),
])
def test_cli_batch_usage_errors(capsys, argv, message):
    assert cli.main(argv + ["--no-cache"]) == 2
    assert message in one_line_error(capsys)


def test_directory_and_glob(tmp_path, zoo_file):
    sub = tmp_path / "more"
    sub.mkdir()
    _write(sub / "one.py", "import uio_jax as uj\ndef m():\n    return uj.System(('a',), {'y': lambda x: x[0]})\n")
    _write(tmp_path / "_ignored.py", "raise RuntimeError\n")
    files = discovery.expand(str(tmp_path))
    assert [os.path.basename(f) for f in files] == ["tiny_zoo.py", "one.py"]  # files, then subdirectories
    assert discovery.expand(str(tmp_path / "*.py")) == [zoo_file]
    with pytest.raises(uj.OptionError, match="no model file"):
        discovery.expand(str(tmp_path / "*.toml"))


def test_progress_bar_only_when_asked():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    quiet = CountProgress(3, stream=io.StringIO(), delay=0.0)
    quiet.start("m")
    assert quiet.stream.getvalue() == ""  # not a terminal: nothing until a model is done
    silenced = CountProgress(3, stream=io.StringIO(), enabled=False)
    silenced.start("m")
    silenced.finish("m", "dim 1/1", 0.5)
    assert silenced.stream.getvalue() == ""  # --no-progress
    stream = Tty()
    bar = CountProgress(2, stream=stream, delay=0.0)
    bar.start("sys.py:a")
    bar.finish("sys.py:a", "dim 1/2", 0.1)
    bar.close()
    text = stream.getvalue()
    assert "batch [" in text and "1/2" in text and "running sys.py:a" in text
    late = CountProgress(2, stream=Tty(), delay=60.0)
    late.start("x")
    late.close()
    assert late.stream.getvalue() == ""  # quick batches print nothing on a terminal
    off = io.StringIO()  # not a terminal (the default): one finished line per model, no redraws
    bar = CountProgress(2, stream=off, delay=60.0)
    for name, verdict in (("a.py:m", "dim 2/3"), ("b.py:n", "timed out after 5 s at order k=2, dim 1/3")):
        bar.start(name)
        bar.finish(name, verdict, 4.0)
    bar.close()
    lines = off.getvalue().splitlines()
    assert "\r" not in off.getvalue() and len(lines) == 2
    assert lines[0] == "batch 1/2  a.py:m  dim 2/3  4.0 s  ETA 4 s"  # the mean so far: 4 s a model
    assert lines[1] == "batch 2/2  b.py:n  timed out after 5 s at order k=2, dim 1/3  4.0 s"


def test_eta_uses_recorded_times_and_grows_while_a_model_runs():
    """Recorded times first, the mean so far for the others; a running model needs at least
    as long again as it has run, so the ETA grows while one long model runs."""
    bar = CountProgress(3, stream=io.StringIO(), expected=[10.0, None, 30.0])
    assert bar.eta() is None  # nothing known about model 1 yet
    bar.start("a", key=0)
    t0 = bar.running[0][1]
    assert bar.eta(now=t0 + 2.0) == pytest.approx(8.0 + 2.0 + 30.0, abs=1e-6)  # model 1: 2 s elapsed
    bar.finish("a", "dim 1/1", 6.0, key=0)
    assert bar.eta() == 6.0 + 30.0  # model 1 now at the mean, 6 s
    bar.start("c", key=2)
    t2 = bar.running[2][1]
    early, late, later = (bar.eta(now=t2 + t) for t in (5.0, 100.0, 200.0))
    # grows past 30 s (``now - start`` on the monotonic clock: equal up to its round-off)
    assert (early, late, later) == pytest.approx((25.0 + 6.0, 100.0 + 6.0, 200.0 + 6.0), abs=1e-6)
    two = CountProgress(4, stream=io.StringIO(), expected=[10.0] * 4, workers=2)
    assert two.eta() == 20.0  # 40 s of work on two workers
    two.start("a", key=0)
    assert two.eta(now=two.running[0][1] + 30.0) == pytest.approx(30.0, abs=1e-6)  # the long one bounds it
    two.close()


def test_terminal_bar_is_redrawn_while_a_model_runs():
    """On a terminal the bar is redrawn between events (the ETA and running time move)."""
    import time

    class Tty(io.StringIO):
        def isatty(self):
            return True

    bar = CountProgress(2, stream=Tty(), delay=0.0, tick=0.01)
    bar.start("slow.py:m", key=0)
    deadline = time.monotonic() + 30
    while bar.stream.getvalue().count("\r") < 3 and time.monotonic() < deadline:
        time.sleep(0.01)
    bar.close()
    assert bar.stream.getvalue().count("running slow.py:m") >= 3


def test_progress_is_one_mechanism():
    """The Monte Carlo bar and the batch bar are the same mechanism: both appear after their
    delay, redraw in place on a terminal, and write whole lines elsewhere."""
    from uio_jax._progress import Progress

    class Tty(io.StringIO):
        def isatty(self):
            return True

    assert issubclass(CountProgress, Progress)
    tty = Tty()
    mc = Progress(100, stream=tty, delay=0.0, label="run")
    mc.update(50)
    mc.close()
    assert tty.getvalue().startswith("\rrun [") and " 50.0%" in tty.getvalue() and tty.getvalue().endswith("\n")
    log = io.StringIO()
    mc = Progress(100, stream=log, delay=0.0, label="run")
    mc.update(50)
    mc.update(50)
    mc.close()
    assert "\r" not in log.getvalue() and len(log.getvalue().splitlines()) == 2
    assert Progress(10, enabled=False, stream=log).enabled is False


def test_toml_and_strikepy_files_are_models(tmp_path):
    """A model file and a StrikePy module in a batch are one model each (loaded by
    ``load_system``), as ``uio-jax analyze`` reads them."""
    toml = tmp_path / "decay.toml"
    toml.write_text('states = ["a", "b"]\n[outputs]\ny = "a"\n[dynamics]\na = "-a + b"\nb = "-b"\n')
    strike = _write(tmp_path / "strike.py", """
        import sympy as sym
        x1, x2 = sym.symbols("x1 x2")
        x = [[x1], [x2]]
        h = [x1]
        u = []
        p = []
        f = [[x2], [-x1]]
        """)
    entries, _ = discovery.discover([str(toml), strike])
    assert [e.kind for e in entries] == ["file", "strikepy"]
    res = uj.batch_analyze([str(toml), strike], samples=SAMPLES)
    assert [r.ok for r in res] == [True, True], [r.error for r in res]
    assert [(r.dim, r.n) for r in res] == [(2, 2), (2, 2)]


@pytest.mark.parametrize("kw, message", [
    (dict(method="magic"), "unknown method 'magic'"),
    (dict(samples=4), "samples must be an integer >= 8"),
    (dict(seed=-1), "seed must be a non-negative integer"),
    (dict(rtol=2.0), "rtol must be a number in (0, 1)"),
    (dict(max_order=-1), "max_order must be a non-negative integer"),
    (dict(k_max=0), "k_max must be a positive integer"),
    (dict(sample=64), "unknown analysis option 'sample'"),
])
def test_batch_refuses_bad_options_before_any_model(kw, message):
    """The analysis options are checked once, by the same function as ``analyze``'s."""
    with pytest.raises(uj.OptionError) as err:
        uj.batch_analyze(["no/such/dir"], **kw)  # the options first: the path is never looked at
    assert message in str(err.value)


# ----------------------------------------------------------------- persistent compilation cache
def test_default_cache_dir(monkeypatch, tmp_path):
    monkeypatch.setenv("UIO_JAX_CACHE_DIR", str(tmp_path / "c"))
    assert default_cache_dir() == str(tmp_path / "c")
    monkeypatch.delenv("UIO_JAX_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "x"))
    assert default_cache_dir() == str(tmp_path / "x" / "uio_jax" / "xla")
    monkeypatch.delenv("XDG_CACHE_HOME")
    assert default_cache_dir() == os.path.join(os.path.expanduser("~"), ".cache", "uio_jax", "xla")


def test_compile_cache_settings_and_restore(tmp_path):
    before = jax.config.values["jax_compilation_cache_dir"]
    with compile_cache(tmp_path / "cc") as path:
        assert path == str(tmp_path / "cc") and os.path.isdir(path)
        assert jax.config.values["jax_compilation_cache_dir"] == path
        assert jax.config.values["jax_persistent_cache_min_compile_time_secs"] == 0.0
        assert jax.config.values["jax_persistent_cache_min_entry_size_bytes"] == -1
        jax.jit(lambda x: x * 3.0 + 1.0)(jax.numpy.ones(5)).block_until_ready()
        assert os.listdir(path)  # even a tiny compile is written
    assert jax.config.values["jax_compilation_cache_dir"] == before
    try:
        assert uj.enable_compile_cache(tmp_path / "cc2") == str(tmp_path / "cc2")
        assert jax.config.values["jax_compilation_cache_dir"] == str(tmp_path / "cc2")
    finally:
        disable_compile_cache()
    assert jax.config.values["jax_compilation_cache_dir"] is None


def test_cli_uses_the_cache_dir_from_the_environment(tmp_path):
    """A fresh process: ``batch`` runs with the cache in ``$UIO_JAX_CACHE_DIR`` and with
    ``--no-cache``, which writes nothing (the analyses compile nothing; the cache serves
    JAX's own programs)."""
    cache = tmp_path / "cache"
    env = dict(os.environ, UIO_JAX_CACHE_DIR=str(cache))
    spec = f"{zoo_path('unicycle_polar')}:range_known"
    cmd = [sys.executable, "-m", "uio_jax", "batch", spec, "--samples", str(SAMPLES)]
    proc = subprocess.run(cmd + ["--no-cache"], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert not cache.exists()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr


def test_jobs_run_models_in_worker_processes(zoo_file):
    polar = zoo_path("unicycle_polar")
    sysm = uj.load_system(f"{polar}:phi_known")
    models = [f"{polar}:range_known", sysm, f"{polar}:bearing_known", f"{zoo_file}:broken"]
    res = uj.batch_analyze(models, jobs=2, samples=SAMPLES)
    assert [r.model for r in res] == [f"{polar}:range_known", "unicycle_polar:phi_known",
                                      f"{polar}:bearing_known", f"{zoo_file}:broken"]
    assert [r.dim for r in res] == [2, 3, 2, None] and [r.ok for r in res] == [True, True, True, False]
    assert res[0].report is None and res[0].seconds > 0  # reports stay in the workers
    assert "raised RuntimeError: boom" in res[3].error


def test_parallel_batch_calls_zoo_functions_in_the_workers(tmp_path, zoo_file):
    """With jobs > 1 the caller does not build the zoo's Systems (the workers do, once): the
    rows, the errors and the skipped functions are those of the in-process batch."""
    from uio_jax._io.loading import load_module

    counted = _write(tmp_path / "counted_zoo.py", ZOO.replace(
        "def two_states():\n", "def two_states():\n        CALLS.append('two_states')\n"))
    serial = uj.batch_analyze(zoo_file, samples=SAMPLES)
    parallel = uj.batch_analyze(counted, jobs=2, samples=SAMPLES)
    assert load_module(counted).CALLS == []  # nothing called in this process
    assert [r.model.rpartition(":")[2] for r in parallel] == ["two_states", "blind", "broken", "CONSTANT"]
    for a, b in zip(serial, parallel):
        assert (a.ok, a.method, a.dim, a.n, a.observable) == (b.ok, b.method, b.dim, b.n, b.observable)
        assert (a.error is None) == (b.error is None)
    assert parallel[2].error.endswith("raised RuntimeError: boom")
    assert parallel[0].seconds > 0
    why = lambda res: {name.rpartition(":")[2]: reason for name, reason in res.skipped}  # noqa: E731
    assert why(parallel) == why(serial) and why(parallel)["not_a_model"] == "returns int"
    assert "3 functions giving no System skipped" in parallel.summary()


def test_a_worker_is_bound_to_the_cpu_of_its_slot():
    """Worker k runs on the k-th allowed CPU (cyclically); a lone worker (None) keeps all.
    Where the platform has no CPU affinity, binding does nothing (and raises nothing)."""
    if not hasattr(os, "sched_setaffinity"):
        assert pinning.pin_to_one_cpu(0) is None
        return
    allowed = sorted(os.sched_getaffinity(0))
    code = ("import os, sys; from uio_jax._batch.pinning import pin_to_one_cpu; "
            "pin_to_one_cpu(None if sys.argv[1] == 'None' else int(sys.argv[1])); "
            "print(sorted(os.sched_getaffinity(0)))")
    for slot, want in [(0, [allowed[0]]), (len(allowed) + 1, [allowed[1 % len(allowed)]]), (None, allowed)]:
        out = subprocess.run([sys.executable, "-c", code, str(slot)], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr
        assert json.loads(out.stdout) == want


SLOW_ZOO = """
    import multiprocessing
    import time

    import uio_jax as uj

    def _output(x):
        if multiprocessing.parent_process() is not None:  # only when analysed in a worker
            time.sleep(600)
        return x[0]

    def slow():
        return uj.System(("a",), {"y": _output})

    def fast():
        return uj.System(("a", "b"), {"y": lambda x: x[0] * x[1]})
    """


def test_timeout_stops_a_slow_model_and_goes_on(tmp_path, capsys):
    """A model over the limit is killed with its worker; a fresh worker runs the next one.
    The limit leaves the fast model (a fresh process compiling its analysis) ample room on a
    loaded machine: 2 s was once too short with four test workers on two cores."""
    slow = _write(tmp_path / "slow_zoo.py", SLOW_ZOO)
    models = [f"{slow}:slow", f"{slow}:fast"]
    res = uj.batch_analyze(models, timeout=12.0, samples=SAMPLES)
    assert [r.ok for r in res] == [False, True], [r.error for r in res]
    assert "timed out after 12 s" in res[0].error and 12.0 <= res[0].seconds < 60
    assert res[1].dim == 1
    code = cli.main(["batch", f"{slow}:slow", "--timeout", "1.5", "--samples", "64", "--no-cache"])
    out = capsys.readouterr().out
    assert code == 1 and "timed out after 1.5 s" in out


@pytest.mark.parametrize("timeout", [0, -1.0, float("nan"), float("inf"), True, "5"])
def test_timeout_must_be_positive(timeout):
    with pytest.raises(uj.OptionError, match="timeout must be a positive number"):
        uj.batch_analyze(["systems"], timeout=timeout)


def test_recorded_times_order_the_workers_longest_first(tmp_path, zoo_file, monkeypatch):
    """A batch records each model's time in the cache directory; the next parallel batch
    hands the models to its workers longest first (unknown ones first, in the given order),
    and its rows keep the given order."""

    specs = [f"{zoo_file}:two_states", f"{zoo_file}:blind"]
    with compile_cache(tmp_path / "cc") as path:
        res = uj.batch_analyze(specs, samples=64)
        with open(os.path.join(path, timing.SECONDS_FILE)) as f:
            recorded = json.load(f)
        assert len(recorded) == 2 and all(v > 0 for v in recorded.values())
        keys = [k for k in recorded if k.split("|")[1] == specs[1]]
        assert len(keys) == 1 and "samples=64" in keys[0]
        # pretend the first model was short and the second long; add a model never timed
        recorded = {k: (1.0 if k.split("|")[1] == specs[0] else 50.0) for k in recorded}
        with open(os.path.join(path, timing.SECONDS_FILE), "w") as f:
            json.dump(recorded, f)
        sent = []

        def fake_workers(entries, todo, jobs, timeout, kw, tracker):
            sent.extend(entries[i].spec for i in todo)
            for i in todo:
                tracker.finish(i, uj.BatchRow(entries[i].label, seconds=0.5))

        monkeypatch.setattr(run, "run_in_workers", fake_workers)
        res = uj.batch_analyze(specs + [f"{zoo_file}:CONSTANT"], jobs=2, samples=64)
        assert sent == [f"{zoo_file}:CONSTANT", specs[1], specs[0]]
        assert [r.model for r in res] == specs + [f"{zoo_file}:CONSTANT"]
        with open(os.path.join(path, timing.SECONDS_FILE), "w") as f:
            f.write("{broken")  # a broken file only loses the ordering
        sent.clear()
        uj.batch_analyze(specs, jobs=2, samples=64)
        assert sent == specs
