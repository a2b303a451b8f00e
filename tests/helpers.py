"""Shared helpers: cached analyses of zoo entries and their published numbers."""

import contextlib
import functools
import importlib.util
import logging
import os
import signal

import uio_jax as uj

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: Samples used by the paper tests: enough for a certificate, cheap to evaluate.
SAMPLES = 1024


def zoo_path(module: str) -> str:
    return os.path.join(ROOT, "systems", f"{module}.py")


def zoo_system(module: str, name: str) -> uj.System:
    return uj.load_system(f"{zoo_path(module)}:{name}")


@functools.cache
def zoo_report(module: str, name: str, method: str = "auto", samples: int = SAMPLES, seed: int = 0):
    return uj.analyze(zoo_system(module, name), method=method, samples=samples, seed=seed)


@functools.cache
def script_module(name: str):
    """The module ``scripts/NAME.py`` (an oracle or a tool of the repository), loaded once."""
    spec = importlib.util.spec_from_file_location(name, os.path.join(ROOT, "scripts", f"{name}.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@functools.cache
def zoo_module(module: str):
    spec = importlib.util.spec_from_file_location(f"zoo_{module}", zoo_path(module))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def published(module: str, name: str) -> dict:
    return zoo_module(module).PUBLISHED[name]


def observable_set(report) -> set:
    return {s for s, ok in report.observable.items() if ok}


def one_line_error(capsys) -> str:
    """The CLI's error as the tests expect it: one line on stderr, ``uio-jax: error: ...``,
    no traceback anywhere; returns that line."""
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("uio-jax: error: ")
    assert "Traceback" not in err + out
    return lines[0]


@contextlib.contextmanager
def deadline(seconds: int, what: str = "test"):
    """Fail the block if it runs past ``seconds`` (SIGALRM, in the main thread)."""
    def expired(signum, frame):
        raise TimeoutError(f"{what} ran past {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


@contextlib.contextmanager
def local_cluster_client(config=None):
    """A Dask client of a local cluster: 2 worker processes on 127.0.0.1, one thread each,
    the dashboard on a free port; ``config``: Dask settings while the cluster starts."""
    import dask
    import distributed

    with dask.config.set(config or {}):
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                           host="127.0.0.1", dashboard_address="127.0.0.1:0",
                                           silence_logs=logging.CRITICAL)
    client = distributed.Client(cluster, set_as_default=False)
    try:
        client.wait_for_workers(2, timeout=120)
        yield client
    finally:
        client.close()
        cluster.close()
