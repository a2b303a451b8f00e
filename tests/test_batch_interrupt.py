"""Ctrl-C (a real SIGINT) during ``uio-jax batch``: the rows done are printed and written,
marked partial, the workers are stopped and the exit code is 130; files are rewritten as
rows finish; a worker reports the steps it decides, so a timed-out row says how far it got."""

import json
import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

import uio_jax as uj
from uio_jax._batch import workers
from uio_jax._batch.discovery import Entry
from uio_jax._batch.executor import Executor, drive

SAMPLES = 64

# a fast model, then one whose analysis never ends (its output sleeps when the analysis
# traces it; building the System evaluates it too, outside analyze), then another
HANGING_ZOO = """
    # uio-jax: models
    import os
    import time

    import uio_jax as uj
    from uio_jax._calculus import generators

    PID_FILE = os.environ.get("HANG_PID_FILE")
    _gradients = generators.Builder.gradients

    def _sleeping_gradients(self, nodes, xs):
        # the analysis evaluates nothing of the user's functions (they were translated into
        # the expression graph when the System was built): the gradients of "hangs" hang
        if getattr(self._system(), "name", "") != "hangs":
            return _gradients(self, nodes, xs)
        if PID_FILE:
            with open(PID_FILE + ".part", "w") as f:
                f.write(str(os.getpid()))
            os.replace(PID_FILE + ".part", PID_FILE)
        time.sleep(600)

    generators.Builder.gradients = _sleeping_gradients

    def quick():
        return uj.System(("a",), {"y": lambda x: x[0]})

    def hangs():
        return uj.System(("a",), {"y": lambda x: x[0]}, name="hangs")

    def never_reached():
        return uj.System(("a", "b"), {"y": lambda x: x[0]})
    """


def _write(path, source):
    path.write_text(textwrap.dedent(source))
    return str(path)


def _interrupt_after_first_row(argv, env=None, wait_for=None, sig=signal.SIGINT):
    """Start ``python -m uio_jax batch ARGV``, wait for its first progress line (a finished
    row) on stderr (and for the file ``wait_for`` to exist, if given), send ``sig``; returns
    (exit code, stdout, stderr)."""
    proc = subprocess.Popen([sys.executable, "-m", "uio_jax", "batch", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env)
    try:
        first = []
        for line in proc.stderr:
            first.append(line)
            if line.startswith("batch 1/"):
                break
        assert first and first[-1].startswith("batch 1/"), "".join(first)
        deadline = time.monotonic() + 600
        while wait_for is not None and not os.path.exists(wait_for) and time.monotonic() < deadline:
            time.sleep(0.05)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=600)  # a loaded machine is slow, not a failure
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()  # reaps it and closes the pipes (no ResourceWarning later)
    return proc.returncode, out, "".join(first) + err


def test_sigint_keeps_the_rows_done(tmp_path):
    zoo = _write(tmp_path / "hanging_zoo.py", HANGING_ZOO)
    md, js = tmp_path / "t.md", tmp_path / "t.json"
    code, out, err = _interrupt_after_first_row(
        [zoo, "--samples", str(SAMPLES), "--no-cache", "--markdown", str(md), "--json", str(js)])
    assert code == 130, err
    assert "Traceback" not in out + err
    assert "uio-jax: interrupted after 1 of 3 models" in err
    assert "hanging_zoo.py:quick" in out and "interrupted after 1 of 3 models: 1 of 1 models analysed" in out
    table = md.read_text()
    assert "hanging_zoo.py:quick" in table and "hangs" not in table
    assert "*Partial table: interrupted after 1 of 3 models.*" in table
    d = json.loads(js.read_text())
    assert [m["model"].rpartition(":")[2] for m in d["models"]] == ["quick"]
    assert d["partial"] == "interrupted after 1 of 3 models"
    assert not list(tmp_path.glob("*.tmp"))  # the atomic writes left no temporary file


@pytest.mark.slow
def test_sigint_stops_the_workers(tmp_path):
    """With worker processes (--timeout): the hanging worker is killed, the parent exits 130."""
    zoo = _write(tmp_path / "hanging_zoo.py", HANGING_ZOO)
    pid_file = tmp_path / "worker.pid"
    md = tmp_path / "t.md"
    env = dict(os.environ, HANG_PID_FILE=str(pid_file))
    code, out, err = _interrupt_after_first_row(
        [zoo, "--samples", str(SAMPLES), "--no-cache", "--timeout", "600", "--markdown", str(md)], env,
        wait_for=pid_file)
    assert code == 130, err
    assert "hanging_zoo.py:quick" in md.read_text() and "interrupted after 1 of 3 models" in md.read_text()
    pid = int(pid_file.read_text())
    try:
        with open(f"/proc/{pid}/status") as f:
            state = next(ln for ln in f if ln.startswith("State:"))
        assert "Z" in state  # at most a zombie waiting for its reaper
    except FileNotFoundError:
        pass  # gone


@pytest.mark.slow
def test_sigterm_stops_the_workers_without_tracebacks(tmp_path):
    """SIGTERM to ``batch --jobs 2`` (issue 40): stopped as by Ctrl-C, exit code 143, the
    partial table kept, and no worker prints a BrokenPipeError traceback (their stderr is
    this one: read to its end, after every worker is gone)."""
    zoo = _write(tmp_path / "hanging_zoo.py", HANGING_ZOO)
    pid_file = tmp_path / "worker.pid"
    md = tmp_path / "t.md"
    env = dict(os.environ, HANG_PID_FILE=str(pid_file))
    code, out, err = _interrupt_after_first_row(
        [zoo, "--samples", str(SAMPLES), "--no-cache", "--jobs", "2", "--markdown", str(md)], env,
        wait_for=pid_file, sig=signal.SIGTERM)
    assert code == 143, err
    assert "Traceback" not in out + err and "BrokenPipeError" not in err, err
    assert "hanging_zoo.py:quick" in md.read_text() and "interrupted after" in md.read_text()


def test_outputs_are_rewritten_after_each_row(tmp_path):
    """``on_row`` gets the partial result after every model: in the given order, marked
    running until the last one."""
    models = [uj.System(("a",), {"y": lambda x: x[0]}, name="one"),
              uj.System(("a", "b"), {"y": lambda x: x[0]}, name="two")]
    seen = []
    res = uj.batch_analyze(models, samples=SAMPLES, progress=False, on_row=seen.append)
    assert [[r.model for r in p] for p in seen] == [["one"], ["one", "two"]]
    assert seen[0].partial == "running: 1 of 2 models done" and seen[1].partial is None
    assert res.partial is None and json.loads(res.to_json())["partial"] is None
    assert "Partial" not in res.to_markdown() and "Partial" in seen[0].to_markdown()


def test_library_interrupt_carries_the_partial_result():
    """A KeyboardInterrupt inside the batch becomes BatchInterrupted with the rows done."""
    from uio_jax._batch.run import BatchInterrupted

    def stop(partial):
        raise KeyboardInterrupt

    models = [uj.System(("a",), {"y": lambda x: x[0]}, name="one"),
              uj.System(("a",), {"y": lambda x: x[0]}, name="two")]
    with pytest.raises(KeyboardInterrupt) as info:
        uj.batch_analyze(models, samples=SAMPLES, progress=False, on_row=stop)
    assert isinstance(info.value, BatchInterrupted)
    assert [r.model for r in info.value.result] == ["one"]
    assert info.value.result.partial == "interrupted after 1 of 2 models"
    assert info.value.result.summary().startswith("interrupted after 1 of 2 models: 1 of 1 models analysed")


class _Conn:
    def __init__(self):
        self.sent = []

    def send(self, msg):
        self.sent.append(msg)


def test_a_worker_sends_every_decided_step(tmp_path):
    """The worker's analysis announces its steps to the parent: ``m=0, dim 1/3`` ..."""
    zoo = _write(tmp_path / "chain_zoo.py", """
        # uio-jax: models
        import jax.numpy as jnp
        import uio_jax as uj

        def chain():
            return uj.System(("a", "b", "c"), {"y": lambda x: x[0]},
                             drift=lambda x: jnp.stack([x[1], x[2], 0.0 * x[0]]))
        """)
    conn = _Conn()
    row = workers.worker_run(f"{zoo}:chain", f"{zoo}:chain", "spec", {"samples": SAMPLES}, conn=conn)
    assert row["dim"] == 3 and row["reached"] is None
    assert conn.sent == [("step", "m=0, dim 1/3"), ("step", "m=1, dim 2/3"), ("step", "m=2, dim 3/3")]


class _ScriptedExecutor(Executor):
    """Runs nothing: each submitted model starts and reaches ``k=5, dim 4/7``, then its
    worker dies (``die``) or it hangs until killed."""

    def __init__(self, die):
        self.die, self.out, self.busy, self.killed = die, [], False, []

    def free(self):
        return 0 if self.busy else 1

    def submit(self, i, task):
        self.busy = True
        self.out += [("started", i), ("step", i, "k=5, dim 4/7")] + ([("lost", i, "exit code -9")] if self.die else [])

    def events(self, wait_s):
        out, self.out = self.out, []
        if out and out[-1][0] == "lost":
            self.busy = False
        if not out:
            time.sleep(wait_s or 0)
        return out

    def kill(self, i):
        self.killed.append(i)
        self.busy = False

    def close(self):
        pass


def test_a_stopped_model_names_the_last_step_reached():
    """Timed out or dead: the row's error and ``reached`` name the last step received; a
    model whose worker dies is sent once more, then its row says so."""
    rows = {}

    class Tracker:
        def start(self, i):
            pass

        def finish(self, i, row):
            rows[i] = row

    entries = [Entry("m.py:f", "m.py:f")]
    ex = _ScriptedExecutor(die=False)
    drive(ex, entries, [0], 0.2, {}, Tracker())
    assert ex.killed == [0]
    assert rows[0].error == "timed out after 0.2 s at order k=5, dim 4/7 (worker stopped)"
    assert rows[0].reached == "k=5, dim 4/7" and rows[0].seconds >= 0.2
    assert uj.BatchResult((rows[0],)).to_dict()["models"][0]["reached"] == "k=5, dim 4/7"
    assert "k=5, dim 4/7" in uj.BatchResult((rows[0],)).to_csv().splitlines()[1]
    ex = _ScriptedExecutor(die=True)
    submitted = []
    ex.submit = lambda i, task, f=ex.submit: (submitted.append(i), f(i, task))
    drive(ex, entries, [0], None, {}, Tracker())
    assert submitted == [0, 0]  # retried once on a fresh worker
    assert rows[0].error == "worker process died twice (exit code -9) at order k=5, dim 4/7"


@pytest.mark.slow
def test_a_timed_out_worker_reports_its_order(tmp_path):
    """A real worker: the analysis hangs after the first step (its second gradient
    evaluation, in a worker), the row says which step it had reached."""
    zoo = _write(tmp_path / "stuck_zoo.py", """
        # uio-jax: models
        import multiprocessing
        import time

        import jax.numpy as jnp
        import uio_jax as uj
        from uio_jax._calculus import generators

        CALLS = []
        _gradients = generators.Builder.gradients

        def _slow_gradients(self, nodes, xs):
            if multiprocessing.parent_process() is not None and getattr(self._system(), "name", "") == "stuck":
                CALLS.append(1)
                if len(CALLS) > 1:
                    time.sleep(600)
            return _gradients(self, nodes, xs)

        generators.Builder.gradients = _slow_gradients

        def stuck():
            return uj.System(("a", "b", "c"), {"y": lambda x: x[0]},
                             drift=lambda x: jnp.stack([x[1], x[2], 0.0 * x[0]]), name="stuck")
        """)
    res = uj.batch_analyze([f"{zoo}:stuck"], timeout=10.0, samples=SAMPLES, progress=False)
    assert res[0].reached is not None and res[0].reached.startswith("m=")
    assert f"at step {res[0].reached}" in res[0].error


def test_workers_ignore_sigint_in_their_main():
    """The worker's entry point ignores SIGINT (the parent stops it), checked in a child."""
    ctx = multiprocessing.get_context("spawn")
    parent, child = ctx.Pipe()
    proc = ctx.Process(target=workers._worker_main, args=(child, None, None), daemon=True)
    proc.start()
    child.close()
    try:
        assert parent.recv() == "ready"
        os.kill(proc.pid, signal.SIGINT)
        parent.send(None)  # still alive and listening: asked to stop, it exits cleanly
        proc.join(timeout=60)
        assert proc.exitcode == 0
    finally:
        if proc.is_alive():
            proc.kill()
