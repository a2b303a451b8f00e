"""Monte Carlo trials split over the workers of a Dask cluster (``run_montecarlo(client=...)``,
``uio-jax montecarlo --scheduler``).

Oracle: the one-process run with the same seed (this process, one CPU device): the
per-trial records, the kept trajectories and so every statistic are equal bit for bit.
The cluster is started here: a scheduler and 2 worker processes on 127.0.0.1 (one thread
each, HTTP on a free port); every test is bounded in time. Without Dask distributed (the
``cluster`` extra, part of ``dev``) the module is skipped, which fails under CI
(``tests/strict_skips.py``).
"""

import json
import socket

import numpy as np
import pytest
from conftest import zoo
from helpers import deadline, local_cluster_client

distributed = pytest.importorskip("distributed")

import uio_jax as uj  # noqa: E402
from uio_jax import cli  # noqa: E402
from uio_jax._filter import cluster as mc_cluster  # noqa: E402
from uio_jax._filter.montecarlo import run_montecarlo  # noqa: E402
from uio_jax._io.loading import load_module  # noqa: E402

UNI = load_module(zoo("unicycle_disturbance.py"))
#: Seconds any test here may take.
DEADLINE_S = 240
#: 2000 steps (1 s) of the 003 range experiment: 40 records; an odd trial count, so the
#: second worker's shard is padded past the last trial
N_STEPS, TRIALS, SEED = 2000, 37, 5


@pytest.fixture(autouse=True)
def _deadline():
    with deadline(DEADLINE_S, "cluster test"):
        yield


@pytest.fixture(scope="module")
def client():
    """A client of a local cluster: 2 worker processes on 127.0.0.1, one thread each."""
    with local_cluster_client() as c:
        yield c


def _experiment():
    return UNI.range_gamma_known_experiment().with_(n_steps=N_STEPS)


def test_two_workers_equal_one_process_bit_for_bit(client, capsys):
    """Records, kept trajectories, verdict: equal to the one-process run with the same seed;
    the progress bar adds up the trial-steps of both workers."""
    exp = _experiment()
    one = run_montecarlo(exp, TRIALS, seed=SEED, keep=2, progress=False)
    two = run_montecarlo(exp, TRIALS, seed=SEED, keep=2, client=client, progress=True)
    assert two.timings["workers"] == 2 and two.timings["shards"] == 2
    assert two.stats.dtype == one.stats.dtype and two.stats.shape == one.stats.shape == (TRIALS, 41, 15)
    np.testing.assert_array_equal(two.stats, one.stats)
    assert set(two.trajectories) == set(one.trajectories)
    for k, v in one.trajectories.items():
        np.testing.assert_array_equal(two.trajectories[k], v)
    np.testing.assert_array_equal(two.rmse(), one.rmse())
    assert json.dumps(two.verdict()) == json.dumps(one.verdict())
    err = capsys.readouterr().err
    assert "range_gamma_known [2 workers]" in err and "100.0%" in err.splitlines()[-1]


def test_cli_montecarlo_on_a_scheduler(client, tmp_path, capsys):
    """``--scheduler ADDRESS``: the same summary table as in one process."""
    spec = f"{zoo('unicycle_disturbance.py')}:range_gamma_known"
    args = ["montecarlo", spec, "--trials", "16", "--keep", "0", "--no-analysis", "--no-progress", "--no-cache"]
    assert cli.main(args) == 0
    here = capsys.readouterr().out
    assert cli.main(args + ["--scheduler", client.scheduler.address]) == 0
    there = capsys.readouterr().out
    drop = ("trial-steps/s",)  # the timings line

    def table(text):
        return [ln for ln in text.splitlines() if not any(d in ln for d in drop)]

    assert table(there) == table(here) and "verdict" in there


def test_bad_scheduler_for_montecarlo_is_one_line_error(capsys):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    spec = f"{zoo('unicycle_disturbance.py')}:range_gamma_known"
    assert cli.main(["montecarlo", spec, "--scheduler", f"tcp://127.0.0.1:{port}"]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "connection refused" in err and "Traceback" not in out + err


def test_devices_and_client_exclude_each_other():
    with pytest.raises(uj.OptionError, match="devices or client"):
        run_montecarlo(_experiment(), 4, devices=[], client="tcp://127.0.0.1:1")


def test_the_experiment_travels_by_value():
    """An experiment of a model file loaded by path pickles with its functions (the workers
    could not import the file's module by its name)."""
    import pickle

    exp = _experiment()
    again = pickle.loads(mc_cluster.dumps_experiment(exp))
    assert again.name == exp.name and again.n_steps == N_STEPS
    assert again.system.states == exp.system.states
