"""``uio-jax batch --scheduler`` / ``uj.batch_analyze(client=...)`` on a Dask cluster.

Each test that needs a cluster gets one started here: a scheduler and 2 worker processes
(one thread each, their nannies) on the loopback interface (HTTP on a free port), with
``allowed-failures`` 1 (a model whose worker dies is run once more elsewhere). Every test
is bounded in time (:func:`_deadline`). Oracle: the in-process batch of the same models
(the same rows, in the same order).

Without Dask distributed (the ``cluster`` extra, part of ``dev``) the module is skipped,
which fails under CI (``tests/strict_skips.py``).
"""

import os
import signal
import socket
import textwrap
import time

import pytest
from helpers import deadline, local_cluster_client, one_line_error, zoo_path

distributed = pytest.importorskip("distributed")

import uio_jax as uj  # noqa: E402
from uio_jax import cli  # noqa: E402
from uio_jax._batch import cluster as batch_cluster  # noqa: E402
from uio_jax._batch.run import BatchInterrupted  # noqa: E402

SAMPLES = 64
#: Seconds any test here may take (a hung cluster fails the test instead of the suite).
DEADLINE_S = 240

# models that behave otherwise in a Dask worker: ``sleepy`` sleeps until killed (its pid
# in PID_DIR/sleepy), ``killed_once`` writes its pid and sleeps the first time only (the
# test kills that worker); ``quick`` and ``blind`` as everywhere
CLUSTER_ZOO = """
    # uio-jax: models
    import os
    import time

    import jax.numpy as jnp
    import uio_jax as uj

    PID_DIR = {pid_dir!r}

    def _in_dask_worker():
        try:
            from distributed import get_worker
            get_worker()
        except (ImportError, ValueError):
            return False
        return True

    def _mark(name):
        path = os.path.join(PID_DIR, name)
        first = not os.path.exists(path)
        if first:
            with open(path + ".part", "w") as f:
                f.write(str(os.getpid()))
            os.replace(path + ".part", path)
        return first

    def _sleepy(x):
        if _in_dask_worker():
            _mark("sleepy")
            time.sleep(600)
        return x[0]

    def _killed_once(x):
        if _in_dask_worker() and _mark("killed_once"):
            time.sleep(600)
        return x[0]

    def quick():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])})

    def sleepy():
        return uj.System(("a",), {"y": _sleepy})

    def killed_once():
        return uj.System(("a", "b"), {"y": _killed_once},
                         known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])})

    def blind():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([1.0 + 0.0 * x[0], 0.0 * x[0]])})

    """

# a zoo file: two models, a function giving no System, a broken one
PLAIN_ZOO = """
    # uio-jax: models
    import jax.numpy as jnp
    import uio_jax as uj

    def quick():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([x[1], 0.0 * x[0]])})

    def not_a_model():
        return 42

    def broken():
        raise RuntimeError("boom")

    def blind():
        return uj.System(("a", "b"), {"y": lambda x: x[0]},
                         known={"u": lambda x: jnp.stack([1.0 + 0.0 * x[0], 0.0 * x[0]])})
    """

FIELDS = ("model", "method", "n", "dim", "observable", "params", "identifiable", "fraction",
          "gap_decades", "error", "exact", "inputs")


def _write(path, source):
    path.write_text(textwrap.dedent(source))
    return str(path)


def _stall_zoo(tmp_path):
    """:data:`CLUSTER_ZOO` in ``tmp_path``, its pid files there too."""
    return _write(tmp_path / "cluster_zoo.py", CLUSTER_ZOO.replace("{pid_dir!r}", repr(str(tmp_path))))


def _fields(row):
    return {k: getattr(row, k) for k in FIELDS}


@pytest.fixture(autouse=True)
def _deadline():
    """Fail a test that runs past :data:`DEADLINE_S`."""
    with deadline(DEADLINE_S, "cluster test"):
        yield


@pytest.fixture(scope="module")
def client():
    """A client of a local cluster: 2 worker processes on 127.0.0.1, one thread each; a
    model whose worker dies is re-run once."""
    with local_cluster_client({"distributed.scheduler.allowed-failures": 1}) as c:
        yield c


def _two_workers(client):
    """Wait until the cluster has its 2 workers again (after a test killed one)."""
    client.wait_for_workers(2, timeout=120)
    deadline = time.monotonic() + 120
    while len(client.nthreads()) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)


def _closed_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# ---------------------------------------------------------------------- bad input, no cluster
@pytest.mark.parametrize("address, needle", [
    ("foo", "missing port number"),
    ("http://host:1", "unknown scheme 'http'"),
    ("", "is empty"),
    ("tcp://127.0.0.1:99999", "bad host or port"),
    (None, "connection refused"),  # a port nothing listens on
])
def test_bad_scheduler_isone_line_error(address, needle, capsys):
    address = f"tcp://127.0.0.1:{_closed_port()}" if address is None else address
    code = cli.main(["batch", zoo_path("gps"), "--samples", str(SAMPLES), "--scheduler", address])
    assert code == 2
    assert needle in one_line_error(capsys)


def test_scheduler_with_jobs_is_a_usage_error(capsys):
    code = cli.main(["batch", zoo_path("gps"), "--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"])
    assert code == 2 and "--jobs 2 and --scheduler exclude each other" in one_line_error(capsys)
    with pytest.raises(uj.OptionError, match="exclude each other"):
        uj.batch_analyze(zoo_path("gps"), jobs=2, client="tcp://127.0.0.1:1")


def test_a_client_of_another_type_is_refused():
    with pytest.raises(uj.OptionError, match="client must be a distributed.Client"):
        uj.batch_analyze(zoo_path("gps"), client=8786)


def test_without_the_extra_a_cluster_run_isone_line_error(monkeypatch, capsys):
    monkeypatch.setitem(__import__("sys").modules, "distributed", None)  # import fails
    code = cli.main(["batch", zoo_path("gps"), "--scheduler", "tcp://127.0.0.1:8786"])
    assert code == 2 and 'pip install "uio_jax[cluster]"' in one_line_error(capsys)


def test_specs_travel_as_absolute_paths():
    assert batch_cluster.absolute_spec("systems/gps.py:v_unknown", "spec") == \
        os.path.abspath("systems/gps.py") + ":v_unknown"
    assert batch_cluster.absolute_spec("m.toml", "file") == os.path.abspath("m.toml")
    assert batch_cluster.absolute_spec(None, "system") is None


# ---------------------------------------------------------------------- on a local cluster
def test_cluster_rows_equal_the_in_process_rows(client, tmp_path, monkeypatch):
    """The same rows, in the same order, with the same skipped functions and errors; the
    zoo functions are called in the workers only; the progress lines name every model."""
    zoo = _write(tmp_path / "plain_zoo.py", PLAIN_ZOO)
    models = [zoo, f"{zoo_path('unicycle_polar')}:range_v_unknown", f"{zoo_path('gps')}:omega_unknown"]
    here = uj.batch_analyze(models, samples=SAMPLES, progress=False)
    lines = []

    class Stream:
        def write(self, text):
            lines.append(text)

        def flush(self):
            pass

    monkeypatch.setattr("sys.stderr", Stream())
    there = uj.batch_analyze(models, samples=SAMPLES, client=client, progress=True)
    monkeypatch.undo()
    assert [_fields(r) for r in there] == [_fields(r) for r in here]
    assert len(there) == 5 and there[1].error.endswith("raised RuntimeError: boom")
    assert there.skipped == here.skipped and there.skipped[0][1] == "returns int"
    assert all(r.report is None and r.seconds > 0 for r in there if r.ok)
    finished = [ln for ln in "".join(lines).splitlines() if ln.startswith("batch ")]
    assert len(finished) == 6 and finished[-1].startswith("batch 6/6")  # 5 rows, 1 skipped


def test_cli_batch_on_a_scheduler_address(client, tmp_path, capsys):
    """``--scheduler ADDRESS`` connects, runs, writes the same table as without it."""
    spec = f"{zoo_path('unicycle_polar')}:range_known"
    js = tmp_path / "t.json"
    code = cli.main(["batch", spec, "--samples", str(SAMPLES), "--no-progress", "--no-cache",
                     "--scheduler", client.scheduler.address, "--json", str(js)])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "range_known" in out and "1 of 1 models analysed" in out and js.exists()


def test_cluster_order_is_longest_first_from_recorded_times(client, tmp_path, monkeypatch):
    """The driver hands the cluster the models in the order of the recorded times."""
    from uio_jax._batch import timing
    from uio_jax._filter.compile_cache import compile_cache

    specs = [f"{zoo_path('gps')}:v_unknown", f"{zoo_path('gps')}:omega_unknown"]
    sent = []

    def fake(entries, todo, c, timeout, kw, tracker):
        assert c is not None
        sent.extend(entries[i].spec for i in todo)
        for i in todo:
            tracker.finish(i, uj.BatchRow(entries[i].label, seconds=0.5))

    with compile_cache(tmp_path / "cc") as path:
        keys = [f"spec|{s}|samples={SAMPLES}" for s in specs]
        with open(os.path.join(path, timing.SECONDS_FILE), "w") as f:
            f.write(f'{{"{keys[0]}": 1.0, "{keys[1]}": 30.0}}')
        monkeypatch.setattr(batch_cluster, "run_on_cluster", fake)
        res = uj.batch_analyze(specs, samples=SAMPLES, client=client, progress=False)
    assert sent == specs[::-1] and [r.model for r in res] == specs


@pytest.mark.slow
def test_a_model_over_its_timeout_is_killed_and_the_next_runs(client, tmp_path):
    """The sleeping model's worker process is killed at the limit; the next models run
    (on the other worker, or on the fresh one its nanny started)."""
    zoo = _stall_zoo(tmp_path)
    _two_workers(client)
    res = uj.batch_analyze([f"{zoo}:sleepy", f"{zoo}:quick", f"{zoo}:blind"], timeout=8.0,
                           samples=SAMPLES, client=client, progress=False)
    assert [r.ok for r in res] == [False, True, True], [r.error for r in res]
    assert res[0].error.startswith("timed out after 8 s") and 8.0 <= res[0].seconds < 60
    pid = int((tmp_path / "sleepy").read_text())
    deadline = time.monotonic() + 30
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(pid)  # the worker that ran it is gone
    _two_workers(client)


def test_a_worker_killed_mid_batch_loses_no_row(client, tmp_path):
    """SIGKILL to the worker running a model: Dask runs the model again on another worker;
    every row is there and equal to the in-process batch's."""
    zoo = _stall_zoo(tmp_path)
    models = [f"{zoo}:killed_once", f"{zoo}:quick", f"{zoo}:blind"]
    here = uj.batch_analyze(models, samples=SAMPLES, progress=False)
    _two_workers(client)
    killed = []

    def kill_when_marked():
        path = tmp_path / "killed_once"
        while not path.exists():
            time.sleep(0.05)
        pid = int(path.read_text())
        os.kill(pid, signal.SIGKILL)
        killed.append(pid)

    import threading

    killer = threading.Thread(target=kill_when_marked, daemon=True)
    killer.start()
    there = uj.batch_analyze(models, samples=SAMPLES, client=client, progress=False)
    killer.join(timeout=5)
    assert killed, "the model never ran in a worker"
    assert [_fields(r) for r in there] == [_fields(r) for r in here]
    _two_workers(client)


def test_interrupt_stops_the_cluster_tasks_and_keeps_the_rows_done(client, tmp_path):
    """Ctrl-C (a KeyboardInterrupt after the first row): the partial result is kept, the
    model still running is cancelled and its worker process killed."""
    zoo = _stall_zoo(tmp_path)
    _two_workers(client)

    def interrupt(partial):
        deadline = time.monotonic() + 60
        while not (tmp_path / "sleepy").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        raise KeyboardInterrupt

    with pytest.raises(BatchInterrupted) as info:
        uj.batch_analyze([f"{zoo}:sleepy", f"{zoo}:quick", f"{zoo}:blind"], samples=SAMPLES,
                         client=client, progress=False, on_row=interrupt)
    result = info.value.result
    assert [r.model.rpartition(":")[2] for r in result] == ["quick"]
    assert result.partial == "interrupted after 1 of 3 models"
    pid = int((tmp_path / "sleepy").read_text())
    deadline = time.monotonic() + 30
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _alive(pid)
    _two_workers(client)


def _alive(pid) -> bool:
    """Whether process ``pid`` runs (a zombie waiting for its reaper counts as gone)."""
    try:
        with open(f"/proc/{pid}/status") as f:
            return "Z" not in next(ln for ln in f if ln.startswith("State:"))
    except (FileNotFoundError, ProcessLookupError):
        return False


def test_a_worker_claims_a_cpu_no_other_worker_holds(tmp_path):
    """Two worker processes of one host bind themselves to two different CPUs (the lock
    files of the first are held while it lives); ``UIO_JAX_PIN_WORKERS=0`` leaves a worker
    unbound."""
    import subprocess
    import sys

    if not hasattr(os, "sched_setaffinity") or len(os.sched_getaffinity(0)) < 2:
        assert __import__("uio_jax._filter.cluster", fromlist=["x"]).claim_one_cpu() is None
        return
    code = ("import os, sys, time; from uio_jax._filter.cluster import claim_one_cpu; "
            "cpu = claim_one_cpu(); print(cpu, sorted(os.sched_getaffinity(0)), flush=True); "
            "time.sleep(float(sys.argv[1]))")
    env = dict(os.environ, TMPDIR=str(tmp_path))
    # the first holds its CPU until it is killed below (however slow the others start)
    first = subprocess.Popen([sys.executable, "-c", code, "3600"], stdout=subprocess.PIPE, text=True, env=env)
    try:
        cpu1, mask1 = first.stdout.readline().split(" ", 1)
        out = subprocess.run([sys.executable, "-c", code, "0"], capture_output=True, text=True, env=env,
                             timeout=120).stdout
        cpu2, mask2 = out.split(" ", 1)
        assert cpu1 != cpu2 and mask1.strip() == f"[{cpu1}]" and mask2.strip() == f"[{cpu2}]"
        off = subprocess.run([sys.executable, "-c", code, "0"], capture_output=True, text=True, timeout=120,
                             env=dict(env, UIO_JAX_PIN_WORKERS="0")).stdout
        assert off.startswith("None ")
    finally:
        first.kill()
        first.wait()
        first.stdout.close()
