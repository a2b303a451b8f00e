"""A/B timing of two checkouts of uio_jax: first call and warm calls, fresh processes, interleaved.

For a change that should move no time (a refactor), run the same cases on the old and the
new tree in alternating fresh processes, so that both see the same phase of a shared
machine. Each process imports the tree it is given (``PYTHONPATH``), loads the zoo model
with ``importlib`` (never the other tree's loader), starts JAX, then times:

* ``orc``, ``series``: ``vehicle_wind.py:no_wind``; ``single_ui``: ``vehicle_wind.py:wind_unknown``;
  ``eorc5``: the same with ``method="eorc", k_max=5`` (4096 samples each): the first
  ``uj.analyze`` (tracing and XLA compilation included) and the median of 3 warm calls;
* ``mc``: ``uj.run_montecarlo`` of ``unicycle_disturbance.py:range_gamma_unknown_experiment``,
  1024 trials: ``compile_s`` and ``run_s`` of the first run, and a second run (warm).

No disk cache is used (the library leaves JAX's configuration alone). Usage::

    python scripts/bench_ab.py OLD_TREE NEW_TREE [--repeats 3] [--cases orc series ...] [--out FILE.jsonl]
"""

import argparse
import importlib.util
import json
import os
import statistics
import subprocess
import sys
import time

CASES = ("orc", "series", "single_ui", "eorc5", "mc")


def _load(path):
    spec = importlib.util.spec_from_file_location(os.path.basename(path)[:-3], path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def one(tree: str, case: str) -> dict:
    """Run one case in this process (imports ``uio_jax`` from ``tree``)."""
    import jax

    jax.config.update("jax_enable_x64", True)
    jax.numpy.zeros(1).block_until_ready()
    import uio_jax as uj

    out = {"case": case, "tree": tree, "uio_jax": uj.__file__}
    if case == "mc":
        exp = _load(os.path.join(tree, "systems", "unicycle_disturbance.py")).range_gamma_unknown_experiment()
        t = time.perf_counter()
        res = uj.run_montecarlo(exp, 1024, seed=0, keep=0, progress=False)
        out["first"] = time.perf_counter() - t
        out["compile_s"], out["run_s"] = float(res.timings["compile_s"]), float(res.timings["run_s"])
        out["warm"] = _timed(lambda: uj.run_montecarlo(exp, 1024, seed=1, keep=0, progress=False))
        return out
    vehicle = _load(os.path.join(tree, "systems", "vehicle_wind.py"))
    system = vehicle.no_wind() if case in ("orc", "series") else vehicle.wind_unknown()
    kw = {"orc": {"method": "orc"}, "series": {"method": "series"}, "single_ui": {"method": "single_ui"},
          "eorc5": {"method": "eorc", "k_max": 5}}[case]
    out["first"] = _timed(lambda: uj.analyze(system, **kw))
    out["warm"] = statistics.median(_timed(lambda: uj.analyze(system, **kw)) for _ in range(3))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("old")
    ap.add_argument("new")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cases", nargs="*", default=list(CASES), choices=CASES)
    ap.add_argument("--out", default=None, help="append every measurement as a JSON line")
    ap.add_argument("--one", nargs=2, metavar=("TREE", "CASE"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(*args.one)))
        return 0
    rows = []
    for rep in range(args.repeats):
        for case in args.cases:
            for label, tree in (("old", args.old), ("new", args.new)):
                env = dict(os.environ, PYTHONPATH=os.path.abspath(tree))
                proc = subprocess.run([sys.executable, os.path.abspath(__file__), args.old, args.new,
                                       "--one", os.path.abspath(tree), case],
                                      capture_output=True, text=True, env=env, cwd=tree)
                row = json.loads(proc.stdout.strip().splitlines()[-1]) if proc.returncode == 0 else {
                    "case": case, "error": proc.stderr.strip().splitlines()[-1:]}
                row.update(side=label, rep=rep, load=os.getloadavg()[0])
                rows.append(row)
                if args.out:
                    with open(args.out, "a") as fh:
                        fh.write(json.dumps(row) + "\n")
                print(json.dumps(row), file=sys.stderr, flush=True)
    print("| case | side | first call (s), median | warm (s), median | runs |")
    print("|---|---|---|---|---|")
    for case in args.cases:
        for side in ("old", "new"):
            got = [r for r in rows if r["case"] == case and r["side"] == side and "first" in r]
            if got:
                first = statistics.median(r["first"] for r in got)
                warm = statistics.median(r["warm"] for r in got)
                print(f"| {case} | {side} | {first:.2f} | {warm:.3f} | {len(got)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
