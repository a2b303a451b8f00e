"""Benchmark of the Monte Carlo EKF: 003 section 5, 4096 trials x 10 s (20 000 Euler steps).

For the 5-state (gamma known) and 6-state (gamma unknown) filters with range output:
trial-steps/s (median of ``--repeats`` runs, compile time apart), peak memory (max RSS of a
fresh process per configuration), filterpy on a few trials of the same data in the same
run, and the ceiling of this machine (truth + readings + RNG, no filter). Every number is
recorded with the load average and the process CPU time, since the machine is shared.

Usage::

    python scripts/bench_ekf.py [--trials 4096] [--repeats 3] [--filterpy-trials 2] [--compile-samples 4]
                                [--out docs/benchmarks/ekf.md]
"""

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CASES = {"5-state": "range_gamma_known_experiment", "6-state": "range_gamma_unknown_experiment"}


def _setup():
    import jax

    jax.config.update("jax_num_cpu_devices", os.cpu_count() or 1)
    jax.config.update("jax_enable_x64", True)
    from uio_jax._io.loading import load_module

    return load_module(os.path.join(ROOT, "systems", "unicycle_disturbance.py"))


def one(case, trials, repeats, floor=False):
    """Run one configuration in this (fresh) process; print a JSON line."""
    zoo = _setup()
    import jax

    from uio_jax._filter import montecarlo as mc
    from uio_jax._filter import trial
    from uio_jax._filter.trials import chunk_records

    if floor:  # the ceiling: truth, readings and RNG only (the EKF predict/update skipped)
        trial.predict = lambda model, xa, P, u: (xa, P)
        trial.update = lambda model, xa, P, y, mask=None: (xa, P)
    exp = getattr(zoo, CASES[case])()
    if repeats == 0:  # compile only: the same programs, one chunk of run
        n_dev = len(jax.devices())
        per_chunk, _ = chunk_records(exp, -(-trials // n_dev) * n_dev)
        exp = exp.with_(n_steps=per_chunk * exp.record_every * exp.epoch_steps)
        res = mc.run_montecarlo(exp, trials, seed=0, keep=0, progress=False)
        print("RESULT " + json.dumps({"compile_s": res.timings["compile_s"],
                                      "load1": res.timings["loadavg"][0]}))
        return
    runs = []
    for _ in range(repeats):
        res = mc.run_montecarlo(exp, trials, seed=0, keep=0, progress=False)
        tm = res.timings
        runs.append({"rate": tm["trial_steps_per_s"], "run_s": tm["run_s"],
                     "process_s": tm["process_s"], "compile_s": tm["compile_s"],
                     "load1": tm["loadavg"][0]})
    out = {
        "case": case + (" floor" if floor else ""), "trials": trials,
        "steps": exp.n_steps, "devices": len(jax.devices()),
        "rate_median": statistics.median(r["rate"] for r in runs),
        "compile_s_first": runs[0]["compile_s"], "runs": runs,
        "max_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
    }
    if not floor:
        v = res.verdict()["quantities"]["bearing phi"]
        out["phi_ratio"] = v["ratio"]
    print("RESULT " + json.dumps(out))


def filterpy_rate(case, n_trials):
    """filterpy (analytic Jacobians) on the data of the first trials; trial-steps/s."""
    zoo = _setup()
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    from test_ekf import _run_filterpy

    from uio_jax._filter.montecarlo import trajectories

    exp = getattr(zoo, CASES[case])()
    total, cpu = 0.0, 0.0
    for i in range(n_trials):
        tr = trajectories(exp, [i], seed=0)
        t0, p0 = time.perf_counter(), time.process_time()
        _run_filterpy(exp, tr, case == "5-state", "range")
        total += time.perf_counter() - t0
        cpu += time.process_time() - p0
    rate = n_trials * exp.n_steps / total
    print("RESULT " + json.dumps({"case": case, "filterpy_rate": rate, "trials": n_trials,
                                  "seconds": total, "process_s": cpu,
                                  "cpu_rate": n_trials * exp.n_steps / cpu,
                                  "load1": os.getloadavg()[0]}))


def _spawn(args):
    cmd = [sys.executable, os.path.abspath(__file__)] + args
    out = subprocess.run(cmd, capture_output=True, text=True, check=False)
    for line in out.stdout.splitlines():
        if line.startswith("RESULT "):
            return json.loads(line[7:])
    raise RuntimeError(f"{' '.join(args)} failed:\n{out.stderr[-2000:]}")


def _machine():
    cpu = platform.processor() or ""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import jax
    import numpy

    return (f"{cpu}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
            f"jax {jax.__version__}, numpy {numpy.__version__}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=4096)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--filterpy-trials", type=int, default=2)
    p.add_argument("--compile-samples", type=int, default=4,
                   help="extra fresh processes per filter that only compile (default 4)")
    p.add_argument("--out", default=os.path.join(ROOT, "docs", "benchmarks", "ekf.md"))
    p.add_argument("--one", help=argparse.SUPPRESS)
    p.add_argument("--floor", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--filterpy", help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.one:
        return one(a.one, a.trials, a.repeats, a.floor)
    if a.filterpy:
        return filterpy_rate(a.filterpy, a.filterpy_trials)

    started = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
    load0 = os.getloadavg()
    rows = []
    for case in CASES:
        r = _spawn(["--one", case, "--trials", str(a.trials), "--repeats", str(a.repeats)])
        f = _spawn(["--filterpy", case, "--filterpy-trials", str(a.filterpy_trials)])
        r["filterpy"] = f
        r["compile_samples"] = [r["compile_s_first"]] + [
            _spawn(["--one", case, "--trials", str(a.trials), "--repeats", "0"])["compile_s"]
            for _ in range(a.compile_samples)]
        rows.append(r)
        print(json.dumps(r), flush=True)
    floor = _spawn(["--one", "5-state", "--trials", str(a.trials), "--repeats", "1", "--floor"])
    print(json.dumps(floor), flush=True)
    _write(a.out, rows, floor, started, load0, _machine())
    return 0


def _write(path, rows, floor, started, load0, machine):
    targets = {"5-state": 7e6, "6-state": 3.5e6}
    lines = [
        "# Monte Carlo EKF benchmark (003 section 5)",
        "",
        f"Made by `scripts/bench_ekf.py` on {started}. Machine: {machine}.",
        f"Load average at start: {load0[0]:.2f} / {load0[1]:.2f} / {load0[2]:.2f} (1/5/15 min); "
        "other jobs shared the machine, so every run records its own load and CPU time.",
        "",
        f"Workload: {rows[0]['trials']} trials x {rows[0]['steps']} Euler steps (10 s at "
        "5e-4 s), range output every 50 steps, truth simulation and RNG inside the timed "
        f"run, trials sharded over {rows[0]['devices']} CPU devices. Rate = trial-steps/s, "
        "median of the runs; compile time apart: from the call's start (the model check "
        "included) to both programs compiled (the chunk program's trace, lowering and XLA "
        "compile, the initial state's beside it), median (min-max) over fresh processes (the "
        "timed run's and the compile-only ones, which compile the same programs and run one "
        "chunk).",
        "",
        "| filter | trial-steps/s (median) | target | runs: M/s (load, CPU s / wall s) | "
        "per CPU-second | compile | peak RSS | filterpy (same data): wall, per CPU-s | "
        "speed-up vs filterpy: wall, per CPU-s |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        runs = "; ".join(f"{x['rate'] / 1e6:.2f} ({x['load1']:.1f}, "
                         f"{x['process_s']:.0f}/{x['run_s']:.0f})" for x in r["runs"])
        f = r["filterpy"]
        cpu_rate = statistics.median(r["trials"] * r["steps"] / max(x["process_s"], 1e-9)
                                     for x in r["runs"])
        lines.append(
            f"| {r['case']} | **{r['rate_median'] / 1e6:.2f} M** | "
            f">= {targets[r['case']] / 1e6:.1f} M | {runs} | {cpu_rate / 1e6:.2f} M | "
            f"{statistics.median(r['compile_samples']):.1f} s ({min(r['compile_samples']):.1f}-"
            f"{max(r['compile_samples']):.1f}, {len(r['compile_samples'])} processes) | "
            f"{r['max_rss_mb']:.0f} MB | {f['filterpy_rate'] / 1e3:.1f} k/s, "
            f"{f['cpu_rate'] / 1e3:.1f} k/s ({f['trials']} trials, load {f['load1']:.1f}) | "
            f"**{r['rate_median'] / f['filterpy_rate']:.0f}x**, "
            f"**{cpu_rate / f['cpu_rate']:.0f}x** |")
    fl = floor["rate_median"]
    fr = floor["runs"][0]
    fl_cpu = floor["trials"] * floor["steps"] / fr["process_s"]

    def cpu_of(r):
        return statistics.median(r["trials"] * r["steps"] / x["process_s"] for x in r["runs"])

    lines += [
        "",
        f"Ceiling measured in the same session: truth + readings + RNG with the filter "
        f"skipped runs at {fl / 1e6:.2f} M trial-steps/s wall, {fl_cpu / 1e6:.2f} M per "
        f"CPU-second (load {fr['load1']:.1f}); "
        + ", ".join(f"the {r['case']} filter reaches {100 * r['rate_median'] / fl:.0f}% of it "
                    f"in wall time, {100 * cpu_of(r) / fl_cpu:.0f}% per CPU-second"
                    for r in rows) + ".",
        "",
        "Sanity: bearing-phi RMSE ratio end/prior "
        + ", ".join(f"{r['case']} {r['phi_ratio']:.2f}" for r in rows)
        + " (converges with gamma known, not with gamma unknown).",
        "",
        "Raw JSON:",
        "",
        "```json",
        json.dumps({"rows": rows, "floor": floor}, indent=1),
        "```",
        "",
    ]
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as fh:
        fh.write("\n".join(lines))
    print(f"written {path}")



if __name__ == "__main__":
    sys.exit(main())
