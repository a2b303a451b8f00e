"""What a new user found (issue 47 items 9-12), from the user's side: batch discovery of
assignment-style zoo entries and of a model file's ``[initial]`` table, Ctrl-C that always
ends a command promptly with one line, one-line errors instead of raw exceptions or wrong
reasons, and reports without lines of kilobytes."""

import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import time

import jax.numpy as jnp
import pytest
from conftest import ROOT

import uio_jax as uj
from uio_jax import cli
from uio_jax._batch.discovery import _zoo_entries, listed_entries

SAMPLES = 64


# ----------------------------------------------------------------------------- item 9: batch
@pytest.mark.parametrize("name", sorted(f for f in os.listdir(os.path.join(ROOT, "systems"))
                                        if f.endswith(".py") and not f.startswith("_")))
def test_reading_a_zoo_file_finds_what_importing_it_finds(name):
    """With ``--timeout`` the zoo files are read, not imported: every entry the import finds
    (``unicycle_wind.py``'s ``name = _alias(...)`` included) is found by reading too."""
    path = os.path.join(ROOT, "systems", name)
    read = {e.spec for e in listed_entries(path)[0] if e.error is None}
    imported = {e.spec for e in _zoo_entries(path, build=False)[0] if e.error is None}
    assert imported and imported <= read, sorted(imported - read)


def test_batch_of_assignment_style_entries_with_a_timeout_exits_0(tmp_path, capsys):
    path = os.path.join(ROOT, "systems", "unicycle_wind.py")
    js = tmp_path / "t.json"
    code = cli.main(["batch", path, "--timeout", "300", "--samples", str(SAMPLES), "--json", str(js)])
    assert code == 0, capsys.readouterr()
    rows = json.loads(js.read_text())["models"]
    assert len(rows) == 7 and all(r["ok"] for r in rows)


@pytest.mark.slow
def test_the_readme_zoo_batch_exits_0(tmp_path):
    """``uio-jax batch systems/ --timeout 300`` (the README's command) exits 0."""
    proc = subprocess.run([sys.executable, "-m", "uio_jax", "batch", os.path.join(ROOT, "systems"), "--timeout",
                           "300", "--markdown", str(tmp_path / "zoo.md")], capture_output=True, text=True,
                          cwd=tmp_path, timeout=3000)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]


def test_batch_notes_a_model_files_initial_table(tmp_path, capsys):
    path = tmp_path / "m.toml"
    path.write_text('states = ["x1", "x2"]\nparams = ["k"]\n[outputs]\ny = "x1"\n[drift]\nx1 = "-k*x1 + x2"\n'
                    'x2 = "0"\n[initial]\nx2 = 0\n')
    js = tmp_path / "t.json"
    assert cli.main(["batch", str(path), "--samples", str(SAMPLES), "--json", str(js)]) == 0
    out = capsys.readouterr().out
    assert "its [initial] table (x2 = 0) is not used" in out
    (row,) = json.loads(js.read_text())["models"]
    assert row["notes"] and "uio-jax analyze" in row["notes"][0]


# ----------------------------------------------------------------------------- item 10: Ctrl-C
BUSY = """
    # uio-jax: models
    import gc
    import os
    import time

    import uio_jax as uj


    def _slow(phase, info):  # a collector callback that holds most of the time, as JAX's can
        if phase == "start":
            time.sleep(0.02)


    def busy():
        gc.callbacks.append(_slow)
        open(os.environ["BUSY_FILE"], "w").close()
        end = time.time() + 300
        while time.time() < end:
            for _ in range(3000):
                a = []
                a.append(a)
        return uj.System(("a",), {"y": lambda x: x[0]})
    """


#: ``uio-jax`` with Ctrl-C at Python's default (a test runner may start its children with
#: SIGINT ignored; a ``preexec_fn`` would run JAX's fork hooks in the child)
UIO_JAX = ("import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
           "from uio_jax.cli import main; sys.exit(main(sys.argv[1:]))")


def _interrupt(argv, ready, env=None):
    """Start ``uio-jax ARGV`` (SIGINT at its default), wait until ``ready(pid)`` (the command
    is past its imports, doing its work), send SIGINT; returns (exit code, seconds to exit,
    stderr)."""
    proc = subprocess.Popen([sys.executable, "-c", UIO_JAX, *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        deadline = time.monotonic() + 300
        while not ready(proc.pid) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert proc.poll() is None and ready(proc.pid), proc.stderr.read() if proc.poll() is not None else "not ready"
        time.sleep(0.5)
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        err = proc.communicate(timeout=120)[1]
        return proc.returncode, time.monotonic() - start, err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def test_ctrl_c_inside_a_collector_callback_ends_the_command(tmp_path):
    """Before, the KeyboardInterrupt raised inside the callback was swallowed ("Exception
    ignored in ...") and the command ran on to its end."""
    zoo = tmp_path / "busy.py"
    zoo.write_text(textwrap.dedent(BUSY))
    marker = tmp_path / "started"
    env = dict(os.environ, BUSY_FILE=str(marker))
    code, seconds, err = _interrupt(["analyze", f"{zoo}:busy", "--no-progress"], lambda pid: marker.exists(), env)
    assert code == 130 and err.strip() == "uio-jax: interrupted", err
    assert seconds < 60  # the watchdog ends it by 5 s in any case; the callback's deferral sooner


def test_ctrl_c_while_printing_a_large_report_ends_with_one_line(tmp_path):
    """stdout is a pipe nobody reads (the report blocks on it): Ctrl-C ends the command with
    its one line even though the unflushed report cannot be written."""
    names = [f"state_with_a_rather_long_name_number_{i:05d}" for i in range(800)]  # a report of 90 kB
    path = tmp_path / "wide.toml"
    path.write_text('states = [' + ", ".join(f'"{s}"' for s in names) + f']\n[outputs]\ny = "{names[0]} + {names[1]}"\n'
                    "[drift]\n" + "".join(f'{s} = "0"\n' for s in names))
    proc = subprocess.Popen([sys.executable, "-c", UIO_JAX, "analyze", str(path), "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        head = proc.stdout.read(64)  # the report has started
        assert head
        time.sleep(2.0)
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=120)
        seconds = time.monotonic() - start
        err = proc.stderr.read().decode()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        proc.stderr.close()
    assert proc.returncode == 130 and err.strip().splitlines()[-1] == "uio-jax: interrupted", err
    assert "Traceback" not in err and seconds < 60


@pytest.mark.slow
def test_ctrl_c_during_save_model_of_a_large_sbml_file(tmp_path):
    pytest.importorskip("libsbml")
    from test_sbml import Builder

    b = Builder().compartment("c", 1)
    for i in range(2000):
        b.species(f"S{i}", "c").parameter(f"k{i}", 0.1)
    for i in range(1999):
        b.reaction(f"R{i}", {f"S{i}": 1}, {f"S{i + 1}": 1}, f"k{i}*S{i}")
    xml = b.write(tmp_path / "big.xml")
    def reading(pid):  # the command has the SBML file open: it is loading it
        try:
            return any(os.readlink(f"/proc/{pid}/fd/{fd}") == xml for fd in os.listdir(f"/proc/{pid}/fd"))
        except OSError:
            return False

    code, seconds, err = _interrupt(["save-model", xml, str(tmp_path / "big.toml"), "--outputs", "y=S0"], reading)
    assert code == 130 and err.strip() == "uio-jax: interrupted", err
    assert seconds < 60 and not (tmp_path / "big.toml").exists()


# ----------------------------------------------------------------------------- item 11: errors
def test_save_model_of_something_that_is_no_system_says_so():
    with pytest.raises(uj.ModelError, match="needs a uio_jax.System or a model dictionary, got NoneType"):
        uj.save_model(None, "x.toml")


def test_shared_named_twice_is_refused():
    s = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]}, drift=lambda x, p: -p[0] * x, params=("a",))
    with pytest.raises(uj.OptionError, match="shared names 'a' more than once"):
        uj.analyze([s, s], shared=("a", "a"))


def test_options_that_do_not_apply_at_a_known_initial_state_are_noted(capsys):
    path = os.path.join(ROOT, "systems", "two_compartment.toml")
    assert cli.main(["analyze", path, "--initial", "x2=0", "--samples", "100", "--k-max", "3",
                     "--known-inputs", "smooth"]) == 0
    out = capsys.readouterr().out.replace("\n    ", " ")
    assert "samples=100, k_max=3, known_inputs='smooth' not used" in out


def test_a_parameter_in_no_equation_is_noted():
    s = uj.System(states=("x",), outputs={"y": lambda x, p: x[0]}, drift=lambda x, p: jnp.stack([-p[0] * x[0]]),
                  params=("a", "a2"))
    rep = uj.analyze(s, samples=SAMPLES)
    assert any("parameter a2 appears in no equation" in n for n in rep.notes) and not rep.identifiable["a2"]
    at = uj.analyze(s, initial={"x": 1})
    assert any("parameter a2 appears in no equation" in n for n in at.notes)
    assert at.identifiable["a2"] is uj.Verdict.NOT_DETERMINED


@pytest.mark.parametrize("fixed, words", [({"cell": 0}, "size 0 (fixed)"), ({"cell": -1}, "size -1 (fixed)")])
def test_a_compartment_size_that_is_not_positive_is_refused(tmp_path, fixed, words):
    pytest.importorskip("libsbml")
    from test_sbml import Builder

    path = (Builder().compartment("cell", 1).species("S", "cell").parameter("k", 0.3)
            .reaction("r", {"S": 1}, {}, "k*S").write(tmp_path / "m.xml"))
    with pytest.raises(uj.OptionError, match=re.escape(words + ": a compartment's size must be positive")):
        uj.load_system(path, outputs={"y": "S"}, fixed=fixed)
    negative = (Builder().compartment("cell", -2).species("S", "cell").parameter("k", 0.3)
                .reaction("r", {"S": 1}, {}, "k*S").write(tmp_path / "n.xml"))
    with pytest.raises(uj.ModelError, match="has size -2 in the file"):
        uj.load_system(negative, outputs={"y": "S"})


# ----------------------------------------------------------------------------- item 12: lines
def test_no_report_line_is_kilobytes_long(capsys):
    """A 401-state model: the point of the directions is abridged, every line is short."""
    n = 401
    s = uj.System(states=tuple(f"x{i}" for i in range(n)), outputs={"y": lambda x: x[0] + x[1]},
                  drift=lambda x: 0.0 * x)
    rep = uj.analyze(s, samples=8)
    text = str(rep) + "\n" + rep.format_directions()
    assert max(len(line) for line in text.splitlines()) <= 160
    assert "401 coordinates: x0=1" in rep.format_directions() and "(401 in all)" in rep.format_directions()
