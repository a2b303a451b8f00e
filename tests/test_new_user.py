"""What a new user found (issue 40): every output written or a one-line error with exit
code 2, a model file never overwritten by its report, user code that exits (or hangs at
import under --timeout) turned into an error or a row, complex functions refused, text from
model files made inert (the rest: tests/test_new_user_more.py)."""

import os
import stat
import textwrap

import pytest
from helpers import one_line_error, zoo_path, zoo_report
from new_user_models import TOML, TOY  # noqa: F401 (the models, also read by the fixtures)

import uio_jax as uj
from uio_jax import cli

GOOD = f"{zoo_path('unicycle_polar')}:range_known"

def _full_device(tmp_path, name="full", minor=7):
    """A private copy of /dev/full (every write fails with ENOSPC; ``minor=3``: /dev/null):
    an atomic write would replace the device node itself, harmless here, fatal on /dev/full
    as root."""
    path = tmp_path / name
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, minor))
    except (OSError, AttributeError):
        pytest.skip("cannot create a character device here")
    return str(path)


def _no_space(capsys, path):
    line = one_line_error(capsys)
    assert "No space left on device" in line and path in line, line
    assert stat.S_ISCHR(os.stat(path).st_mode)  # the device is still a device


# -- 1. output lost, success reported -------------------------------------------------------

@pytest.mark.parametrize("option", ["--json", "--csv", "--markdown"])
def test_batch_output_to_a_full_device_is_an_error(tmp_path, capsys, option):
    full = _full_device(tmp_path)
    assert cli.main(["batch", GOOD, "--samples", "64", "--no-progress", option, full]) == 2
    _no_space(capsys, full)


def test_analyze_plot_to_a_full_device_is_an_error(tmp_path, capsys):
    full = _full_device(tmp_path, "full.png")
    assert cli.main(["analyze", GOOD, "--samples", "64", "--no-progress", "--plot", full]) == 2
    _no_space(capsys, full)


@pytest.mark.parametrize("option, name", [("--json", "full"), ("--plot", "full.png")])
def test_montecarlo_output_to_a_full_device_is_an_error(tmp_path, capsys, toy, option, name):
    full = _full_device(tmp_path, name)
    assert cli.main(["montecarlo", toy, "--trials", "2", "--keep", "0", "--no-analysis",
                     "--no-progress", "--no-cache", option, full]) == 2
    _no_space(capsys, full)


@pytest.mark.parametrize("argv", [
    ["analyze", "{missing}", "--json", ""],
    ["analyze", "{missing}", "--plot", ""],
    ["batch", "{missing}", "--json", ""],
    ["batch", "{missing}", "--csv", " "],
    ["batch", "{missing}", "--markdown", ""],
    ["montecarlo", "{missing}:toy", "--json", ""],
    ["montecarlo", "{missing}:toy", "--plot", ""],
])
def test_an_empty_output_name_is_refused_before_any_work(tmp_path, capsys, argv):
    missing = str(tmp_path / "no_such_model.toml")
    assert cli.main([a.format(missing=missing) for a in argv]) == 2
    line = one_line_error(capsys)
    assert "needs a file name" in line and "no_such_model" not in line, line


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
@pytest.mark.parametrize("argv", [
    ["batch", "{missing}", "--csv", "/proc/t.csv"],
    ["analyze", "{missing}", "--json", "/proc/r.json"],
    ["montecarlo", "{missing}:toy", "--plot", "/proc/mc.png"],
])
def test_an_output_where_no_file_can_be_made_is_refused_before_any_work(tmp_path, capsys, argv):
    """/proc exists and, as root, passes the access check: the write is tried up front."""
    missing = str(tmp_path / "no_such_model.toml")
    assert cli.main([a.format(missing=missing) for a in argv]) == 2
    line = one_line_error(capsys)
    assert "cannot write" in line and "/proc/" in line and "no_such_model" not in line, line


def test_a_device_output_is_written_in_place(tmp_path, capsys):
    """/dev/null stays /dev/null (an atomic replace would turn it into a file)."""
    null = _full_device(tmp_path, "null", minor=3)
    assert cli.main(["batch", GOOD, "--samples", "64", "--no-progress", "--json", null]) == 0
    assert stat.S_ISCHR(os.stat(null).st_mode)
    assert f"written: {null}" in capsys.readouterr().out


def test_two_batches_writing_one_file_the_second_is_refused(tmp_path, capsys):
    """The last writer used to win silently; now the second batch stops before any work."""
    from uio_jax.cli.common import hold_outputs

    out = tmp_path / "t.json"
    missing = str(tmp_path / "no_such_model.toml")
    with hold_outputs([str(out)]):  # a first batch writing t.json
        assert cli.main(["batch", missing, "--json", str(out)]) == 2
        assert "being written by another uio-jax command" in one_line_error(capsys)
    assert cli.main(["batch", GOOD, "--samples", "64", "--no-progress", "--json", str(out)]) == 0


# -- 2. a model file overwritten ------------------------------------------------------------

@pytest.mark.parametrize("argv", [
    ["analyze", "{m}", "--json", "{m}"],
    ["analyze", "{m}", "--plot", "{m}.png", "--json", "{d}/../{dn}/m.toml"],
    ["batch", "{m}", "--markdown", "{m}"],
    ["batch", "{d}", "--csv", "{m}"],
    ["batch", "{d}/*.toml", "--json", "{m}"],
    ["analyze", "{d}/zoo.py:f", "--json", "{d}/zoo.py"],
    ["montecarlo", "{d}/zoo.py:toy", "--json", "{d}/zoo.py"],
])
def test_an_output_that_is_an_input_file_is_refused(tmp_path, capsys, toml_model, argv):
    zoo = tmp_path / "zoo.py"
    zoo.write_text("raise RuntimeError('imported')\n")
    before = {p: p.read_bytes() for p in tmp_path.iterdir()}
    d = str(tmp_path)
    argv = [a.format(m=toml_model, d=d, dn=os.path.basename(d)) for a in argv]
    assert cli.main(argv) == 2
    line = one_line_error(capsys)
    assert "input model file" in line and "overwrite" in line, line
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == before


# -- 3. user code that exits ---------------------------------------------------------------

EXITS_IN_OUTPUT = """
import sys
import uio_jax as uj

def _y(x):
    raise SystemExit(0)

def f():
    return uj.System(("a",), {"y": _y})

def g():
    sys.exit(0)
"""


@pytest.mark.parametrize("name", ["f", "g"])
def test_a_model_that_exits_is_a_one_line_error(tmp_path, capsys, name):
    path = tmp_path / "exits.py"
    path.write_text(textwrap.dedent(EXITS_IN_OUTPUT))
    assert cli.main(["analyze", f"{path}:{name}", "--samples", "64", "--no-progress"]) == 2
    assert "sys.exit(0)" in one_line_error(capsys)


def test_an_experiment_function_that_exits_in_the_run_is_a_one_line_error(tmp_path, capsys):
    """The measurement function runs only when JAX traces the filter, inside the run."""
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY).replace('uj.Measurement("y", lambda x: x[0], 0.1, 1)',
                                                 'uj.Measurement("y", _exits, 0.1, 1)')
                    + "\n\ndef _exits(x):\n    raise SystemExit(0)\n")
    assert cli.main(["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0", "--no-analysis",
                     "--no-progress", "--no-cache"]) == 2
    assert "called sys.exit(0) (SystemExit) during montecarlo" in one_line_error(capsys)


def test_a_model_file_that_exits_at_import_is_a_one_line_error(tmp_path, capsys):
    path = tmp_path / "exits.py"
    path.write_text("import sys\nsys.exit(0)\n")
    assert cli.main(["analyze", f"{path}:f", "--no-progress"]) == 2
    assert "fails to load (line 2): SystemExit: 0" in one_line_error(capsys)


def test_batch_dir_with_a_zoo_file_that_exits_goes_on(tmp_path, capsys, toml_model):
    (tmp_path / "exits.py").write_text("# uio-jax: models\nimport sys\nsys.exit(0)\n")
    (tmp_path / "zoo.py").write_text(textwrap.dedent("""
        # uio-jax: models
        import sys
        import uio_jax as uj

        def quits():
            sys.exit(3)

        def fine():
            return uj.System(("a",), {"y": lambda x: x[0]})
        """))
    assert cli.main(["batch", str(tmp_path), "--samples", "64", "--no-progress", "--no-cache"]) == 1
    out = capsys.readouterr().out
    assert "exits.py fails to load (line 3): SystemExit: 0" in out, out
    assert "quits called sys.exit(3)" in out, out
    ok = [ln.split()[0] for ln in out.splitlines() if ln.rstrip().endswith(" ok")]
    assert [os.path.basename(p) for p in ok] == ["m.toml", "zoo.py:fine"], out


# -- 3 (continued). imports under a time limit ---------------------------------------------

LISTED_ZOO = """
# uio-jax: models
import uio_jax as uj

__all__ = ["fine", "CONST", "typed", "rig_experiment", "helper"]

def fine():
    return uj.System(("a",), {"y": lambda x: x[0]})

def typed() -> int:
    return 3

def rig_experiment():
    pass

def helper(x):
    return x

def not_public():
    return uj.System(("a",), {"y": lambda x: x[0]})

CONST = uj.System(("a", "b"), {"y": lambda x: x[0]})
raise RuntimeError("never imported here")
"""


def test_a_zoo_file_is_read_not_imported_under_a_time_limit(tmp_path):
    from uio_jax._batch import discovery

    path = tmp_path / "zoo.py"
    path.write_text(textwrap.dedent(LISTED_ZOO))
    entries, skipped = discovery.discover(str(tmp_path), build=False, import_here=False)
    assert [(e.label.rpartition(":")[2], e.deferred) for e in entries] == [("fine", True), ("CONST", True)]
    assert [(s.rpartition(":")[2], why) for s, why in skipped] == [
        ("typed", "annotated to return int"), ("rig_experiment", "a Monte Carlo experiment (name ends in _experiment)")]
    path.write_text("# uio-jax: models\ndef f(:\n")
    (entry,), _ = discovery.discover(str(path), build=False, import_here=False)
    assert "fails to load (line 2): SyntaxError" in entry.error


@pytest.mark.slow
def test_zoo_files_that_hang_or_end_the_process_at_import_are_rows_under_a_timeout(tmp_path, capsys,
                                                                                  toml_model):
    """Issue 40: with --timeout the zoo files are imported in the workers, under the limit:
    ``os._exit(0)`` or ``while True: pass`` at import is that model's row, the TOML model
    beside them is analysed."""
    system = "def m():\n    return uj.System(('a',), {'y': lambda x: x[0]})\n"
    (tmp_path / "exits.py").write_text(f"# uio-jax: models\nimport os\nimport uio_jax as uj\nos._exit(0)\n{system}")
    (tmp_path / "hangs.py").write_text(f"# uio-jax: models\nimport uio_jax as uj\nwhile True:\n    pass\n{system}")
    # 20 s: the TOML model is analysed in a fresh worker well within it on a loaded machine too
    assert cli.main(["batch", str(tmp_path), "--timeout", "20", "--samples", "64", "--no-progress",
                     "--no-cache"]) == 1
    out = capsys.readouterr().out
    rows = {ln.split()[0].rpartition("/")[2]: ln for ln in out.splitlines() if ln.startswith(str(tmp_path))}
    assert "worker process died twice (exit code 0)" in rows["exits.py:m"], out
    assert "timed out after 20 s" in rows["hangs.py:m"], out
    assert rows["m.toml"].rstrip().endswith(" ok"), out


# -- 4. a complex function -----------------------------------------------------------------

def test_is_observable_of_a_complex_function_is_refused():
    """r is observable, phi is not: the old answer, True, was that of the real part."""
    rep = zoo_report("unicycle_polar", "range_known", samples=64)
    with pytest.raises(uj.ModelError, match="complex value .*must be real"):
        rep.is_observable(lambda x: x[0] + 1j * x[1])


# -- 5. terminal escapes from model text ---------------------------------------------------

ESC = "\x1b[2J"


def _inert(text):
    assert "\x1b" not in text and "\r" not in text, repr(text)
    assert not any(ln.startswith("forged") for ln in text.splitlines()), text


def test_report_text_of_a_hostile_name_is_inert(tmp_path, capsys):
    path = tmp_path / "evil.toml"
    path.write_text(TOML.replace('"two states"', '"evil\\u001b[2J\\nforged line\\r"'))
    assert cli.main(["analyze", str(path), "--samples", "64", "--no-progress"]) == 0
    out = capsys.readouterr().out
    _inert(out)
    assert out.splitlines()[0] == "uio_jax report: evil\\x1b[2J\\nforged line\\r (orc)"
    assert uj.load_system(str(path)).name.startswith("evil\x1b")  # the data keeps the text


def test_batch_table_and_errors_of_hostile_text_are_inert(tmp_path, capsys):
    (tmp_path / f"m{ESC}.toml").write_text(textwrap.dedent(TOML))
    (tmp_path / "zoo.py").write_text(textwrap.dedent(f"""
        # uio-jax: models
        def boom():
            raise RuntimeError({ESC!r} + "boom\\rforged")
        """))
    assert cli.main(["batch", str(tmp_path), "--samples", "64", "--no-progress", "--no-cache",
                     "--markdown", str(tmp_path / "t.md")]) == 1
    out = capsys.readouterr().out
    _inert(out)
    assert "m\\x1b[2J.toml" in out and "RuntimeError: \\x1b[2Jboom" in out, out
    _inert((tmp_path / "t.md").read_text())


def test_an_error_line_of_hostile_text_is_one_inert_line(tmp_path, capsys):
    path = tmp_path / "zoo.py"
    path.write_text(f"def f():\n    raise RuntimeError({ESC!r} + 'boom\\rforged')\n")
    assert cli.main(["analyze", f"{path}:f"]) == 2
    _inert(one_line_error(capsys))


def test_montecarlo_summary_of_hostile_units_is_inert(tmp_path, capsys):
    path = tmp_path / "toy.py"
    path.write_text(textwrap.dedent(TOY).replace('units={"x": "m"}', 'units={"x": "m\\x1b[2J\\nforged | 1"}')
                    .replace('name="toy"', 'name="toy\\x1b]0;title\\x07"'))
    assert cli.main(["montecarlo", f"{path}:toy", "--trials", "2", "--keep", "0", "--no-analysis",
                     "--no-progress", "--no-cache"]) == 0
    out = capsys.readouterr().out
    _inert(out)
    assert "\x07" not in out and "m\\x1b[2J\\nforged | 1" in out, out
