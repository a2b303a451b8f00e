"""Benchmark on an accelerator: the Monte Carlo EKF of 003 section 5 and one analysis.

The CPU benchmarks (``bench_ekf.py``) measure the 2-core machine the
targets are set for; this script measures the same code on whatever JAX device is the
default (a GPU where one is installed), at trial counts a CPU cannot reach in seconds:

* the 5-state and 6-state filters (range output), ``--trials`` trials x 20 000 steps each:
  compile time, steady-state trial-steps/s (median of ``--repeats`` runs), and a sanity
  number (end/start ratio of the bearing error's RMSE, which must be < 1 with gamma known);
* the vehicle in wind (002 section III-C) by the EORC at ``k_max = --k-max`` with 4096
  samples: cold (trace + compile) and warm (a second analysis of the same System).

Prints one JSON line per measurement and writes them all to ``--out`` if given.

Usage::

    python scripts/bench_gpu.py [--trials 4096 65536] [--repeats 2] [--k-max 4] [--out FILE]
"""

import argparse
import json
import os
import platform
import statistics
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)


def _emit(rows, row):
    print(json.dumps(row, default=float), flush=True)
    rows.append(row)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, nargs="+", default=[4096, 65536])
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--k-max", type=int, default=4)
    p.add_argument("--skip-analysis", action="store_true")
    p.add_argument("--out")
    args = p.parse_args(argv)

    import jax

    jax.config.update("jax_enable_x64", True)
    import numpy as np

    import uio_jax as uj
    from uio_jax._filter import montecarlo as mc
    from uio_jax._io.loading import load_module

    dev = jax.devices()[0]
    rows = []
    _emit(rows, {"what": "machine", "platform": dev.platform, "device": dev.device_kind,
                 "devices": len(jax.devices()), "jax": jax.__version__, "python": platform.python_version()})
    zoo = load_module(os.path.join(ROOT, "systems", "unicycle_disturbance.py"))
    for case, name in (("5-state", "range_gamma_known_experiment"), ("6-state", "range_gamma_unknown_experiment")):
        exp = getattr(zoo, name)()
        for trials in args.trials:
            runs = []
            for _ in range(args.repeats):
                res = mc.run_montecarlo(exp, trials, seed=0, keep=0, progress=False)
                runs.append(res.timings)
            v = res.verdict()
            _emit(rows, {
                "what": "montecarlo", "case": case, "trials": trials, "steps": exp.n_steps,
                "compile_s": runs[0]["compile_s"],
                "run_s": [round(r["run_s"], 3) for r in runs],
                "trial_steps_per_s_median": statistics.median(r["trial_steps_per_s"] for r in runs),
                "finite": bool(np.isfinite(res.stats).all()),
                "ratio_end_over_prior": {q: float(d["ratio"]) for q, d in v["quantities"].items()},
                "divergent_fraction": float(v["divergent_fraction"]),
            })
    if not args.skip_analysis:
        vz = load_module(os.path.join(ROOT, "systems", "vehicle_wind.py"))
        system = vz.wind_unknown()
        for phase in ("cold", "warm"):
            t0 = time.perf_counter()
            rep = uj.analyze(system, method="eorc", k_max=args.k_max, samples=4096)
            _emit(rows, {"what": "eorc vehicle_wind", "phase": phase, "k_max": args.k_max,
                         "seconds": round(time.perf_counter() - t0, 3), "dim": rep.dim,
                         "observable": [s for s, ok in rep.observable.items() if ok]})
    if args.out:
        with open(args.out, "w") as fh:
            for r in rows:
                fh.write(json.dumps(r, default=float) + "\n")


if __name__ == "__main__":
    main()
