"""Benchmark: ``uio-jax batch`` of the model zoo, cold and warm persistent compilation cache.

Each run, in fresh processes (what a user gets from the command line):

* **cold**: ``uio-jax batch PATHS --cache-dir D`` with an empty directory D: tracing, XLA
  compilation (written to D) and evaluation of every model;
* **warm**: the same command again with the same D: the compiled programs are loaded from D
  (the program cache, ``D/uio_jax_programs``, keyed without tracing; JAX's own persistent
  cache for the small shared kernels), evaluation is redone.

Once (after the first run, ``--no-run-only`` skips it), a driver process analyses every
model twice in one process (``uj.batch_analyze`` on the same System objects, warm cache):
the second pass reuses the in-memory compiled functions, so it measures **evaluation
only** (sampling, vmapped gradients, rank decisions). Hence per model:

    cold - warm        = what the caches save (tracing, lowering, XLA compile, minus reads)
    warm - evaluation  = what they cannot save (model loading, fingerprints, cache reads)

``--jobs 1 2`` repeats cold and warm with ``uio-jax batch --jobs 2`` (worker processes).
Every process records wall time, CPU time (children's rusage) and ``os.getloadavg()``
before and after; medians over ``--runs`` runs.

Adding models is one argument: ``python scripts/bench_batch.py systems tests/data/strikepy_models``.

Usage (from the repository root)::

    python scripts/bench_batch.py --runs 3 --out docs/benchmarks/batch.md
    python scripts/bench_batch.py systems/unicycle_polar.py --runs 1 --samples 256   # quick look
    SP=$(python -c 'import StrikePy, os; print(os.path.dirname(StrikePy.__file__))')
    python scripts/bench_batch.py systems "$SP/models" --method fast
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _cli(paths, args, cache_dir, jobs, out_json):
    cmd = [sys.executable, "-m", "uio_jax", "batch", *paths, "--samples", str(args.samples),
           "--seed", "0", "--cache-dir", str(cache_dir), "--json", str(out_json), "--no-progress"]
    if args.k_max:
        cmd += ["--k-max", str(args.k_max)]
    if args.method != "auto":
        cmd += ["--method", args.method]
    if jobs > 1:
        cmd += ["--jobs", str(jobs)]
    return cmd


def _measure(cmd, label):
    """Run ``cmd`` in a fresh process: wall, CPU of the process tree, load before/after."""
    load0 = os.getloadavg()[0]
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    load1 = os.getloadavg()[0]
    print(f"  {label}: {wall:.1f} s wall, {cpu:.1f} s CPU, load {load0:.2f} -> {load1:.2f}, "
          f"exit {proc.returncode}", flush=True)
    if proc.returncode not in (0, 1):
        sys.exit(f"{label} failed:\n{proc.stderr}")
    return {"wall_s": wall, "cpu_s": cpu, "load": [load0, load1], "rc": proc.returncode,
            "stdout": proc.stdout}


def _dir_size(path) -> int:
    return sum(f.stat().st_size for f in Path(path).rglob("*") if f.is_file())


def _driver(paths, samples, k_max, cache_dir, method):
    """In this process: every model analysed twice (second pass = evaluation only)."""
    import uio_jax as uj
    from uio_jax._batch.discovery import discover
    from uio_jax._batch.one_model import load_entry

    uj.enable_compile_cache(cache_dir)
    entries, _ = discover(paths)
    systems, labels = [], []
    for e in entries:
        try:
            systems.append(load_entry(e))
            labels.append(e.label)
        except Exception:  # failed models are rows of the CLI runs already
            pass
    kw = {"samples": samples, "method": method, **({"k_max": k_max} if k_max else {})}
    first = uj.batch_analyze(systems, **kw)
    second = uj.batch_analyze(systems, **kw)
    return {lab: [a.seconds, b.seconds] for lab, a, b in zip(labels, first, second) if a.ok and b.ok}


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("paths", nargs="*", default=["systems"], help="what to batch (default: systems)")
    p.add_argument("--samples", type=int, default=4096)
    p.add_argument("--k-max", type=int, default=2,
                   help="EORC order cap (default 2: the 16-19 state visual-inertial models would "
                        "otherwise run to k = n + 2); 0 = the library default")
    p.add_argument("--method", default="auto", help="analysis method for every model (default auto)")
    p.add_argument("--runs", type=int, default=3, help="cold/warm pairs (median)")
    p.add_argument("--jobs", type=int, nargs="+", default=[1], help="jobs values to measure (e.g. 1 2)")
    p.add_argument("--no-run-only", action="store_true", help="skip the evaluation-only driver")
    p.add_argument("--share-cache", action="store_true",
                   help="later --jobs values run warm only, on the cache the first one filled")
    p.add_argument("--out", help="write the Markdown report here")
    p.add_argument("--raw", help="write every measurement as JSON here")
    p.add_argument("--driver", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--cache-dir", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.driver:
        print(json.dumps(_driver(args.paths, args.samples, args.k_max, args.cache_dir, args.method)))
        return 0

    from uio_jax._batch.discovery import expand

    # the model files are listed once, so that every phase runs the same ones even if files
    # are added to a directory meanwhile
    files = [f for path in args.paths for f in expand(path)]
    tmp = Path(tempfile.mkdtemp(prefix="uio_bench_batch_"))
    raw = {"paths": args.paths, "files": files, "samples": args.samples, "k_max": args.k_max,
           "method": args.method, "runs": [],
           "started": datetime.datetime.now().isoformat(timespec="seconds")}
    try:
        for i in range(args.runs):
            for idx, jobs in enumerate(args.jobs):
                shared = args.share_cache and idx > 0  # warm only, on the first jobs value's cache
                cache = tmp / f"cache_{i}_{args.jobs[0] if shared else jobs}"
                rec = {"run": i, "jobs": jobs}
                for phase in ("warm",) if shared else ("cold", "warm"):
                    out = tmp / f"{phase}_{i}_{jobs}.json"
                    m = _measure(_cli(files, args, cache, jobs, out), f"run {i} jobs {jobs} {phase}")
                    m["batch"] = json.loads(out.read_text())
                    m.pop("stdout")
                    rec[phase] = m
                    if phase == "cold":
                        rec["cache_bytes"] = _dir_size(cache)
                raw["runs"].append(rec)
            if i == 0 and not args.no_run_only:
                cmd = [sys.executable, str(Path(__file__).resolve()), "--driver", *files,
                       "--samples", str(args.samples), "--k-max", str(args.k_max), "--method", args.method,
                       "--cache-dir", str(tmp / "cache_0_1" if 1 in args.jobs else tmp / f"cache_0_{args.jobs[0]}")]
                m = _measure(cmd, "evaluation-only driver")
                raw["evaluation"] = json.loads(m.pop("stdout").strip().splitlines()[-1])
                raw["evaluation_process"] = m
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    raw["finished"] = datetime.datetime.now().isoformat(timespec="seconds")
    if args.raw:
        Path(args.raw).write_text(json.dumps(raw, indent=1))
    text = report(raw, argv if argv is not None else sys.argv[1:])
    print(text)
    if args.out:
        Path(args.out).write_text(text)
    return 0


def _med(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else None


def _f(x, fmt="{:.1f}"):
    return "-" if x is None else fmt.format(x)


def report(raw, argv) -> str:
    """Markdown tables from the raw measurements."""
    import jax

    runs = raw["runs"]
    jobs_values = sorted({r["jobs"] for r in runs})
    lines = [
        "# Batch certification: cold and warm caches",
        "",
        f"Command: `python scripts/bench_batch.py {' '.join(argv)}` ({raw['started']} to {raw['finished']}).",
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
        f"{platform.python_version()}, jax {jax.__version__} (CPU, float64). Batch: "
        f"`uio-jax batch {' '.join(raw['paths'])} --samples {raw['samples']}"
        + (f" --k-max {raw['k_max']}" if raw["k_max"] else "")
        + (f" --method {raw.get('method')}" if raw.get("method", "auto") != "auto" else "")
        + "`, each phase a fresh process; "
        "load = `os.getloadavg()[0]` before -> after each process (above 2 = waiting for a core).",
        "",
        "## Whole batch",
        "",
        "| phase | jobs | runs | process wall (median) | batch time (median) | CPU (median) | load | "
        "models ok / all |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for jobs in jobs_values:
        rs = [r for r in runs if r["jobs"] == jobs]
        for phase in ("cold", "warm"):
            ms = [r[phase] for r in rs if phase in r]
            if not ms:
                continue
            loads = [x for m in ms for x in m["load"]]
            b = ms[-1]["batch"]
            ok = sum(m["ok"] for m in b["models"])
            lines.append(
                f"| {phase} | {jobs} | {len(ms)} | {_f(_med([m['wall_s'] for m in ms]))} s | "
                f"{_f(_med([m['batch']['seconds'] for m in ms]))} s | {_f(_med([m['cpu_s'] for m in ms]))} s | "
                f"{min(loads):.2f}-{max(loads):.2f} | {ok} / {len(b['models'])} |")
    cache_mb = _med([r.get("cache_bytes") for r in runs])
    lines += ["", f"Cache directory after a cold run: {_f(cache_mb / 2**20 if cache_mb else None)} MiB.", ""]

    rs1 = [r for r in runs if r["jobs"] == jobs_values[0]]
    models = [m["model"] for m in rs1[0]["cold"]["batch"]["models"]]
    per = {m: {"cold": [], "warm": []} for m in models}
    info = {}
    for r in rs1:
        for phase in ("cold", "warm"):
            for m in r[phase]["batch"]["models"]:
                if m["model"] in per:
                    per[m["model"]][phase].append(m["seconds"])
                    info[m["model"]] = m
    evaluation = raw.get("evaluation", {})
    lines += [
        f"## Per model (jobs {jobs_values[0]}; medians of {len(rs1)} runs; seconds)",
        "",
        "cold = trace + XLA compile + evaluation; warm = program load + evaluation; "
        "evaluation = second analysis of the same System in one process (nothing compiled).",
        "",
        "| model | method | dim / n | cold | warm | saved by the caches | evaluation | warm - evaluation |",
        "|---|---|---|---|---|---|---|---|",
    ]
    tot = {"cold": 0.0, "warm": 0.0, "eval": 0.0}
    for m in models:
        c, w = _med(per[m]["cold"]), _med(per[m]["warm"])
        ev = evaluation.get(m, [None, None])[1]
        d = info[m]
        what = f"{d['dim']} / {d['n']}" if d["ok"] else "failed: " + (d["error"] or "")[:60]
        tot["cold"] += c or 0
        tot["warm"] += w or 0
        tot["eval"] += ev or 0
        lines.append(f"| `{m}` | {d['method'] or '-'} | {what} | {_f(c, '{:.2f}')} | {_f(w, '{:.2f}')} | "
                     f"{_f(None if c is None or w is None else c - w, '{:.2f}')} | {_f(ev, '{:.2f}')} | "
                     f"{_f(None if w is None or ev is None else w - ev, '{:.2f}')} |")
    lines.append(f"| **sum** | | | **{tot['cold']:.1f}** | **{tot['warm']:.1f}** | "
                 f"**{tot['cold'] - tot['warm']:.1f}** | **{tot['eval']:.1f}** | "
                 f"**{tot['warm'] - tot['eval']:.1f}** |")
    if "evaluation_process" in raw:
        ep = raw["evaluation_process"]
        lines += ["", f"Evaluation-only driver: {ep['wall_s']:.1f} s wall, load {ep['load'][0]:.2f} -> "
                  f"{ep['load'][1]:.2f}."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
