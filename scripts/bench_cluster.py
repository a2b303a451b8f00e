"""Benchmark: the batch and the Monte Carlo on a Dask cluster against one machine.

Three measurements, each in fresh processes (what a user gets from the command line):

* ``engines``: what the two engines considered cost on this machine: start-up of a local
  cluster of 2 worker processes, round trip of a no-op task, throughput of 1000 no-op
  tasks, the time from killing a running task's worker to the next task done on a fresh
  one, closing; and ``dask scheduler`` + ``dask worker --nworkers 2`` from the command
  line to 2 workers connected. Dask always; Ray when ``import ray`` works (run the script
  with a Python that has it, e.g. a venv with ``--system-site-packages``).
* ``batch``: ``uio-jax batch PATHS --samples 4096 --k-max 2 --method fast`` (the command of
  ``docs/benchmarks/batch.md``) cold and warm, per *variant*: ``local:TREE`` runs
  ``--jobs W`` from the source tree TREE (``PYTHONPATH=TREE``: A/B of two commits in the
  same hour), ``cluster:TREE`` runs ``--scheduler`` on a cluster started for the phase with
  ``dask scheduler`` and ``dask worker --nworkers W --nthreads 1`` (same tree). Cold: an
  empty cache each (``--cold N``: the first N variants); warm: ``--rounds`` rounds, variants
  interleaved (reversed every other round), every warm run on a copy of the cache the first
  cold run filled (its recorded times give the longest-first order). Wall time of the
  command, the batch's own time, load before and after.
* ``montecarlo``: ``run_montecarlo(EXPERIMENT, TRIALS)`` in one process (its devices: one
  per core) and on clusters of 1 and 2 workers (``--nthreads 1``), fresh each time:
  trial-steps/s over the run (slowest shard, the faster of two calls) and over the wall
  time of the first call (fresh workers: import, compile) and of a second call on the same
  cluster (programs compiled), compile time.

Usage (from the repository root)::

    python scripts/bench_cluster.py engines --out /tmp/engines.json
    /tmp/rayenv/bin/python scripts/bench_cluster.py engines --out /tmp/engines_ray.json
    SP=$(python -c 'import StrikePy, os; print(os.path.dirname(StrikePy.__file__))')
    python scripts/bench_cluster.py batch systems "$SP/models" --variant local:. \\
        --variant cluster:. --variant local:/tmp/old --cold 2 --rounds 2 --out /tmp/batch.json
    python scripts/bench_cluster.py montecarlo systems/unicycle_disturbance.py:range_gamma_known \\
        --trials 8192 --out /tmp/mc.json
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


# ---------------------------------------------------------------------- engines
def _noop(x):
    return x


def _sleeper(s):
    time.sleep(s)
    return os.getpid()


def _import_uio_jax():
    t = time.perf_counter()
    import uio_jax  # noqa: F401

    return time.perf_counter() - t


def probe_dask():
    """Start-up, per-task cost and kill-to-fresh-worker of a local Dask cluster (2 workers)."""
    from distributed import Client, LocalCluster

    out = {}
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=50)
    client = Client(cluster)
    client.wait_for_workers(2)
    out["start_s"] = time.perf_counter() - t0
    out["first_import_uio_jax_s"] = client.submit(_import_uio_jax, pure=False).result()
    ts = []
    for i in range(200):
        t = time.perf_counter()
        client.submit(_noop, i, pure=False).result()
        ts.append(time.perf_counter() - t)
    out["task_roundtrip_ms"] = statistics.median(ts) * 1e3
    t = time.perf_counter()
    client.gather([client.submit(_noop, i, pure=False) for i in range(1000)])
    out["tasks_per_s"] = 1000 / (time.perf_counter() - t)
    addrs = sorted(client.nthreads())
    f = client.submit(_sleeper, 60, workers=[addrs[0]], pure=False)
    while not client.processing(workers=[addrs[0]]).get(addrs[0]):
        time.sleep(0.01)
    time.sleep(0.5)
    t = time.perf_counter()
    client.cancel(f)
    client.run(os._exit, 1, workers=[addrs[0]], on_error="ignore")
    out["kill_call_s"] = time.perf_counter() - t
    while True:
        ws = set(client.nthreads())
        if addrs[0] not in ws and len(ws) == 2:
            break
        time.sleep(0.01)
    new = sorted(ws - {addrs[1]})[0]
    client.submit(_noop, 1, workers=[new], pure=False).result()
    out["kill_to_task_on_fresh_worker_s"] = time.perf_counter() - t
    t = time.perf_counter()
    client.close()
    cluster.close()
    out["close_s"] = time.perf_counter() - t
    # the engine's own commands
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        procs = _start_dask_cli(Path(tmp), 2, env=os.environ)
        out["cli_scheduler_and_2_workers_s"] = time.perf_counter() - t
        _stop(procs)
    import dask
    import distributed

    out["version"] = f"dask {dask.__version__}, distributed {distributed.__version__}"
    return out


def probe_ray():
    """The same for Ray (``ray.init`` with 2 CPUs; kill = ``ray.cancel(force=True)``)."""
    import ray

    out = {}
    t0 = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR", log_to_driver=False)
    out["start_s"] = time.perf_counter() - t0
    rnoop, rsleep, rimport = ray.remote(_noop), ray.remote(_sleeper), ray.remote(_import_uio_jax)
    out["first_import_uio_jax_s"] = ray.get(rimport.remote())
    ts = []
    for i in range(200):
        t = time.perf_counter()
        ray.get(rnoop.remote(i))
        ts.append(time.perf_counter() - t)
    out["task_roundtrip_ms"] = statistics.median(ts) * 1e3
    t = time.perf_counter()
    ray.get([rnoop.remote(i) for i in range(1000)])
    out["tasks_per_s"] = 1000 / (time.perf_counter() - t)
    ref = rsleep.remote(60)
    time.sleep(1.5)
    t = time.perf_counter()
    ray.cancel(ref, force=True)
    out["kill_call_s"] = time.perf_counter() - t
    ray.get([rsleep.remote(0) for _ in range(2)])  # both CPUs: one of them on a fresh worker
    out["kill_to_task_on_fresh_worker_s"] = time.perf_counter() - t
    t = time.perf_counter()
    ray.shutdown()
    out["close_s"] = time.perf_counter() - t
    t = time.perf_counter()
    subprocess.run(["ray", "start", "--head", "--num-cpus", "2", "--include-dashboard=false",
                    "--disable-usage-stats"], capture_output=True, check=True)
    out["cli_ray_start_head_s"] = time.perf_counter() - t
    subprocess.run(["ray", "stop"], capture_output=True)
    out["version"] = f"ray {ray.__version__}"
    return out


def engines(args):
    res = {"load_before": os.getloadavg()[0], "dask": probe_dask()}
    try:
        import ray  # noqa: F401

        res["ray"] = probe_ray()
    except ImportError:
        pass
    res["load_after"] = os.getloadavg()[0]
    return res


# ---------------------------------------------------------------------- a Dask cluster by its commands
def _start_dask_cli(tmp, workers, env, timeout_s=120):
    """``dask scheduler`` and ``dask worker --nworkers N --nthreads 1`` on 127.0.0.1; returns
    ``(procs, address)`` once N workers are connected."""
    from distributed import Client

    sfile = tmp / "scheduler.json"
    bindir = Path(sys.executable).parent
    dask_cmd = [str(bindir / "dask")] if (bindir / "dask").exists() else [sys.executable, "-m", "dask"]
    log = open(tmp / "dask.log", "w")
    sched = subprocess.Popen(dask_cmd + ["scheduler", "--host", "127.0.0.1", "--no-dashboard",
                                         "--scheduler-file", str(sfile)], env=env, stdout=log, stderr=log)
    deadline = time.monotonic() + timeout_s
    while not sfile.exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    address = json.loads(sfile.read_text())["address"]
    work = subprocess.Popen(dask_cmd + ["worker", address, "--nworkers", str(workers), "--nthreads", "1",
                                        "--no-dashboard", "--host", "127.0.0.1"], env=env, stdout=log,
                            stderr=log)
    with Client(address, set_as_default=False) as c:
        c.wait_for_workers(workers, timeout=timeout_s)
    return ([work, sched], address)


def _stop(procs):
    for p in procs[0] if isinstance(procs, tuple) else procs:
        p.terminate()
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


# ---------------------------------------------------------------------- batch
def _batch_cmd(files, args, cache_dir, out_json, variant_kind, address):
    cmd = [sys.executable, "-m", "uio_jax", "batch", *files, "--samples", str(args.samples), "--seed", "0",
           "--k-max", str(args.k_max), "--method", args.method, "--cache-dir", str(cache_dir),
           "--json", str(out_json), "--no-progress"]
    if variant_kind == "local":
        cmd += ["--jobs", str(args.workers)]
    else:
        cmd += ["--scheduler", address]
    return cmd


def _run_batch(variant, files, args, cache_dir, tmp, label):
    kind, _, tree = variant.partition(":")
    tree = str(Path(tree).resolve())
    env = dict(os.environ, PYTHONPATH=tree)
    procs, address, start_s = None, None, None
    if kind == "cluster":
        t = time.perf_counter()
        procs = _start_dask_cli(tmp, args.workers, env)
        address = procs[1]
        start_s = time.perf_counter() - t
    out_json = tmp / f"{label}.json"
    load0 = os.getloadavg()[0]
    t = time.perf_counter()
    proc = subprocess.run(_batch_cmd(files, args, cache_dir, out_json, kind, address), cwd=tree, env=env,
                          capture_output=True, text=True)
    wall = time.perf_counter() - t
    load1 = os.getloadavg()[0]
    if procs is not None:
        _stop(procs)
    if proc.returncode not in (0, 1):
        sys.exit(f"{label} failed:\n{proc.stderr[-3000:]}")
    batch = json.loads(out_json.read_text())
    ok = sum(m["ok"] for m in batch["models"])
    rec = {"variant": variant, "wall_s": wall, "batch_s": batch["seconds"], "load": [load0, load1],
           "ok": ok, "models": len(batch["models"]), "cluster_start_s": start_s}
    print(f"  {label} {variant}: {wall:.1f} s wall (batch {batch['seconds']:.1f} s), {ok}/{len(batch['models'])} "
          f"ok, load {load0:.2f} -> {load1:.2f}" + (f", cluster start {start_s:.1f} s" if start_s else ""),
          flush=True)
    return rec


def batch(args):
    from uio_jax._batch.discovery import expand

    files = [f for path in args.paths for f in expand(path)]
    tmp = Path(tempfile.mkdtemp(prefix="uio_bench_cluster_"))
    res = {"paths": args.paths, "variants": args.variant, "workers": args.workers, "cold": [], "warm": [],
           "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    try:
        warm_cache = None
        if args.cold:
            for v in args.variant[:args.cold]:
                cache = tmp / f"cold_{len(res['cold'])}"
                res["cold"].append(_run_batch(v, files, args, cache, tmp, "cold"))
                warm_cache = warm_cache or cache
        else:
            warm_cache = tmp / "fill"
            res["fill"] = _run_batch(args.variant[0], files, args, warm_cache, tmp, "fill")
        for r in range(args.rounds):
            for v in args.variant if r % 2 == 0 else args.variant[::-1]:  # ABBA: drift cancels
                cache = tmp / "warm"
                shutil.rmtree(cache, ignore_errors=True)
                shutil.copytree(warm_cache, cache)
                res["warm"].append(_run_batch(v, files, args, cache, tmp, f"warm {r}"))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    res["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    return res


# ---------------------------------------------------------------------- Monte Carlo
_MC_CODE = """
import json, os, sys, time
import jax
if sys.argv[4] == "local":
    jax.config.update("jax_num_cpu_devices", os.cpu_count())
from uio_jax._io.experiment_loading import load_experiment
from uio_jax._filter.montecarlo import run_montecarlo
exp = load_experiment(sys.argv[1])
walls, runs = [], []
for again in range(2):  # the second call: the same process and cluster, programs compiled
    t = time.perf_counter()
    res = run_montecarlo(exp, int(sys.argv[2]), seed=0, keep=0, progress=False,
                         client=None if sys.argv[4] == "local" else sys.argv[3])
    walls.append(time.perf_counter() - t)
    runs.append(res.timings["run_s"])
    tm = res.timings if not again else tm
print("RESULT " + json.dumps({"wall_s": walls[0], "wall2_s": walls[1], "compile_s": tm["compile_s"],
      "run_s": tm["run_s"], "run2_s": runs[1], "trial_steps": tm["trial_steps"], "devices": tm["devices"],
      "workers": tm.get("workers", 1)}))
"""


def montecarlo(args):
    res = {"experiment": args.experiment, "trials": args.trials, "runs": [],
           "started": time.strftime("%Y-%m-%d %H:%M:%S")}
    for r in range(args.rounds):
        for workers in [0, *args.workers]:  # 0: one process, no cluster
            tmp = Path(tempfile.mkdtemp(prefix="uio_bench_mc_"))
            procs, address, start_s = None, "-", None
            try:
                if workers:
                    t = time.perf_counter()
                    procs = _start_dask_cli(tmp, workers, os.environ)
                    address, start_s = procs[1], time.perf_counter() - t
                load0 = os.getloadavg()[0]
                proc = subprocess.run([sys.executable, "-c", _MC_CODE, args.experiment, str(args.trials), address,
                                       "cluster" if workers else "local"], capture_output=True, text=True,
                                      cwd=ROOT)
                load1 = os.getloadavg()[0]
            finally:
                if procs is not None:
                    _stop(procs)
                shutil.rmtree(tmp, ignore_errors=True)
            line = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
            if not line:
                sys.exit(f"montecarlo run failed:\n{proc.stderr[-3000:]}")
            m = json.loads(line[0][7:])
            m.update({"round": r, "cluster_workers": workers, "load": [load0, load1], "cluster_start_s": start_s})
            m["rate_run"] = m["trial_steps"] / min(m["run_s"], m["run2_s"])
            m["rate_wall"] = m["trial_steps"] / m["wall_s"]
            m["rate_wall2"] = m["trial_steps"] / m["wall2_s"]
            res["runs"].append(m)
            print(f"  round {r} {'one process' if not workers else f'{workers} workers'}: "
                  f"{m['rate_run'] / 1e6:.2f} M trial-steps/s (run), {m['rate_wall'] / 1e6:.2f} (wall "
                  f"{m['wall_s']:.1f} s, compile {m['compile_s']:.1f} s), second call {m['rate_wall2'] / 1e6:.2f} "
                  f"(wall {m['wall2_s']:.1f} s), load {load0:.2f} -> {load1:.2f}",
                  flush=True)
    res["finished"] = time.strftime("%Y-%m-%d %H:%M:%S")
    return res


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    e = sub.add_parser("engines")
    b = sub.add_parser("batch")
    b.add_argument("paths", nargs="+")
    b.add_argument("--variant", action="append", required=True, help="local:TREE or cluster:TREE")
    b.add_argument("--workers", type=int, default=2, help="--jobs of local, workers of cluster (default 2)")
    b.add_argument("--samples", type=int, default=4096)
    b.add_argument("--k-max", type=int, default=2)
    b.add_argument("--method", default="fast")
    b.add_argument("--rounds", type=int, default=2, help="warm rounds (variants interleaved)")
    b.add_argument("--cold", type=int, default=0, metavar="N",
                   help="a cold run of each of the first N variants first (the first fills the warm cache)")
    m = sub.add_parser("montecarlo")
    m.add_argument("experiment")
    m.add_argument("--trials", type=int, default=8192)
    m.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    m.add_argument("--rounds", type=int, default=2)
    for q in (e, b, m):
        q.add_argument("--out", help="write the measurements as JSON here")
    args = p.parse_args(argv)
    res = {"engines": engines, "batch": batch, "montecarlo": montecarlo}[args.what](args)
    res["machine"] = {"cores": os.cpu_count(), "python": sys.version.split()[0]}
    text = json.dumps(res, indent=1)
    if args.out:  # first: a closed stdout (``| head``) must not lose the measurements
        Path(args.out).write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
