"""Benchmark: the first verdict on a model, against the exact symbolic route and StrikePy.

Three figures per model, in ONE run:

* **first call in a running process**: a process that has imported ``uio_jax`` (and run one
  unrelated model, so that nothing of the library's own start is counted) loads the model
  afresh and calls ``uj.analyze`` on it: the time of that call. Repeated ``--repeats``
  times, each on a newly loaded ``System`` object (a new object shares nothing with the
  earlier ones); median.
* **warm call**: a second ``uj.analyze`` of the same object and options; median.
* **fresh process** (``--fresh``): ``python -c "import uio_jax; load; analyze"`` in a new
  process, timed from outside: interpreter start, imports, load, first call; median of
  ``--fresh-repeats``.

Beside them, for the seed models, the **exact symbolic route** in sympy
(``scripts/sympy_oracle.py`` for the ORC and the single unknown input,
``scripts/general_ui_oracle.py`` for the general solution and the EORC: symbolic Lie
derivatives, ranks at random points in exact or 50-digit arithmetic), with the sympy cache
cleared before every run; median of ``--repeats``. For StrikePy's shipped models, StrikePy's
own time, from the cache of ``scripts/compare_strikepy.py`` (``docs/benchmarks/strikepy_runs.json``:
its date is printed; ``python scripts/compare_strikepy.py --rerun`` refreshes it).

Every measurement records the 1-minute load average. Usage (repository root)::

    python scripts/bench_cold.py --seed-models --repeats 5 --out docs/benchmarks/cold.md
    python scripts/bench_cold.py --zoo --strikepy --fresh --out docs/benchmarks/cold_all.md
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

SEED_MODELS = [
    *(f"systems/unicycle_polar.py:{o}_{u}" for o in ("range", "bearing", "phi")
      for u in ("known", "v_unknown", "omega_unknown")),
    "systems/gps.py:inputs_known", "systems/gps.py:inputs_unknown",
    "systems/gps.py:v_unknown", "systems/gps.py:omega_unknown",
    "systems/vehicle_wind.py:no_wind", "systems/vehicle_wind.py:wind_known",
    "systems/vehicle_wind.py:wind_unknown",
    *(f"systems/unicycle_disturbance.py:{c}_{o}" for c in ("no_disturbance", "gamma_known", "gamma_unknown")
      for o in ("range", "bearing", "phi")),
    "systems/counterexamples.py:single_ui_stop_rule", "systems/counterexamples.py:drift_example",
]
SAMPLES = 4096
FRESH_CODE = r"""
import json, sys, time
t0 = time.perf_counter()
import uio_jax as uj
t1 = time.perf_counter()
s = uj.load_system(sys.argv[1])
t2 = time.perf_counter()
r = uj.analyze(s, method=sys.argv[2], samples=int(sys.argv[3]))
t3 = time.perf_counter()
print("UJ " + json.dumps({"import_s": t1 - t0, "load_s": t2 - t1, "analyze_s": t3 - t2,
                          "dim": r.dim, "method": r.method}))
"""


def _load1() -> float:
    return os.getloadavg()[0]


def _median(xs):
    return statistics.median(xs) if xs else float("nan")


# ------------------------------------------------------------------ ours, in one process
def ours_in_process(spec, method, repeats):
    """First calls on freshly loaded Systems and warm calls; dims and certificate status."""
    import uio_jax as uj

    firsts, warms, rep = [], [], None
    for _ in range(repeats):
        system = uj.load_system(str(ROOT / spec) if spec.startswith("systems/") else spec)
        t0 = time.perf_counter()
        rep = uj.analyze(system, method=method, samples=SAMPLES)
        firsts.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        uj.analyze(system, method=method, samples=SAMPLES)
        warms.append(time.perf_counter() - t0)
    return {"first_s": _median(firsts), "firsts": firsts, "warm_s": _median(warms), "warms": warms,
            "method": rep.method, "dims": list(rep.dims), "dim": rep.dim, "n": rep.n,
            "status": rep.certificate.status, "k": rep.details.get("k"), "load1": _load1()}


def ours_fresh(spec, method, repeats):
    """Fresh processes: import, load and first call, timed from outside (wall)."""
    walls, inside = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", FRESH_CODE, spec, method, str(SAMPLES)],
                              capture_output=True, text=True, cwd=ROOT, timeout=600)
        walls.append(time.perf_counter() - t0)
        line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("UJ ")), None)
        if line is None:
            return {"error": (proc.stderr.strip().splitlines() or ["failed"])[-1]}
        inside.append(json.loads(line[3:]))
    return {"wall_s": _median(walls), "walls": walls,
            "import_s": _median([d["import_s"] for d in inside]),
            "analyze_s": _median([d["analyze_s"] for d in inside]),
            "dim": inside[-1]["dim"], "load1": _load1()}


# ------------------------------------------------------------------ the exact route
def sympy_route(spec, method, k, repeats):
    """The exact sympy route for ``method`` (the method ours ran), or None without a twin."""
    import _sympy_models
    import general_ui_oracle
    import sympy.core.cache
    import sympy_oracle

    if spec not in _sympy_models.MODELS:
        return None

    def run():
        sympy.core.cache.clear_cache()
        model = _sympy_models.get(spec)
        if method == "orc":
            return sympy_oracle.orc(model, seed=0)["dim"]
        if method == "single_ui":
            return sympy_oracle.single_ui(model, seed=0)["dim"]
        if method == "general_ui":
            return general_ui_oracle.general_ui_model(model)["dim"]
        if method == "eorc":
            return general_ui_oracle.eorc_model(model, k_max=k)["dims"][-1]
        return None

    times, dim = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        dim = run()
        times.append(time.perf_counter() - t0)
    return {"median_s": _median(times), "runs": times, "dim": dim}


# ------------------------------------------------------------------ StrikePy's models
def strikepy_models():
    """``(name, path)`` of StrikePy's shipped models, or [] without StrikePy."""
    import importlib.util

    spec = importlib.util.find_spec("StrikePy")
    if spec is None:
        return []
    models = Path(spec.origin).parent / "models"
    return [(p.stem, str(p)) for p in sorted(models.glob("*.py"))
            if p.name != "__init__.py" and not p.name.startswith("uj_")]


def strikepy_cached(name):
    cache = ROOT / "docs" / "benchmarks" / "strikepy_runs.json"
    if not cache.exists():
        return None
    run = json.loads(cache.read_text()).get(name)
    if run is None:
        return None
    return {"finished": run.get("finished"), "cpu_s": run.get("cpu_s"), "wall_s": run.get("wall_s"),
            "date": run.get("date")}


def zoo_models():
    """Every zoo entry (``systems/*.py`` functions returning a System, the data files)."""
    from uio_jax._batch.discovery import discover

    entries, _skipped = discover([str(ROOT / "systems")])
    return [os.path.relpath(e.label, ROOT) if e.label.startswith(str(ROOT)) else e.label
            for e in entries if getattr(e, "system", None) is not None]


# ------------------------------------------------------------------ report
def _fmt(x, digits=3):
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}f}" if x < 100 else f"{x:.0f}"
    return str(x)


def render(rows, meta) -> str:
    lines = [
        f"# First verdicts: uio_jax vs the exact symbolic route ({meta['date']})",
        "",
        f"`python scripts/bench_cold.py {meta['argv']}`; machine: {meta['machine']}; "
        f"{SAMPLES} samples; load {meta['load_before']:.1f} before, {meta['load_after']:.1f} after.",
        "",
        "first = the first `uj.analyze` of a freshly loaded System in a running process "
        f"(median of {meta['repeats']}); warm = a second call; fresh = a new process, "
        "import + load + first call, timed from outside; sympy = the exact route "
        "(sympy_oracle / general_ui_oracle, cache cleared, median of the same count).",
        "",
        "| model | method | n | dims | dim (sympy) | first (s) | warm (s) | sympy (s) | first / sympy "
        "| fresh (s) | status |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        o, s, f = r["ours"], r.get("sympy"), r.get("fresh") or {}
        ratio = (f"{o['first_s'] / s['median_s']:.2f}" if s and s["median_s"] > 0 else "-")
        lines.append(
            f"| {r['spec']} | {o['method']} | {o['n']} | {' '.join(map(str, o['dims']))} | "
            f"{o['dim']} ({_fmt(s['dim']) if s else '-'}) | {_fmt(o['first_s'])} | {_fmt(o['warm_s'])} | "
            f"{_fmt(s['median_s']) if s else '-'} | {ratio} | {_fmt(f.get('wall_s'))} | {o['status']} |")
    sp = [r for r in rows if r.get("strikepy")]
    if sp:
        lines += ["", "StrikePy's shipped models: ours (fresh process, import included) and StrikePy's "
                  "own time from `docs/benchmarks/strikepy_runs.json` (its date per row).", "",
                  "| model | n | method | dim | fresh (s) | first (s) | warm (s) | StrikePy (s, date) |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in sp:
            o, f, k = r["ours"], r.get("fresh") or {}, r["strikepy"]
            spt = ("-" if k is None else
                   f"{_fmt(k['wall_s'] or k['cpu_s'])}{'' if k['finished'] else ' (stopped)'}, {k['date']}")
            lines.append(f"| {r['spec']} | {o['n']} | {o['method']} | {o['dim']} | {_fmt(f.get('wall_s'))} | "
                         f"{_fmt(o['first_s'])} | {_fmt(o['warm_s'])} | {spt} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed-models", action="store_true", help="the seed models (default)")
    ap.add_argument("--zoo", action="store_true", help="every zoo entry")
    ap.add_argument("--strikepy", action="store_true", help="StrikePy's shipped models")
    ap.add_argument("--models", nargs="*", default=[], help="more FILE.py:NAME specs")
    ap.add_argument("--method", default="auto")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fresh", action="store_true", help="also fresh processes")
    ap.add_argument("--fresh-repeats", type=int, default=3)
    ap.add_argument("--no-sympy", action="store_true")
    ap.add_argument("--out", help="write the Markdown table here")
    ap.add_argument("--json", help="write the raw results here")
    args = ap.parse_args(argv)

    import uio_jax as uj

    uj.analyze(uj.load_system(str(ROOT / "systems/gps.py:inputs_known")), samples=64)  # library start
    specs = list(args.models)
    if args.seed_models or not (args.zoo or args.strikepy or args.models):
        specs += SEED_MODELS
    if args.zoo:
        specs += [s for s in zoo_models() if s not in specs]
    sp = dict(strikepy_models()) if args.strikepy else {}
    specs += list(sp.values())
    load_before = _load1()
    rows = []
    for spec in specs:
        row = {"spec": os.path.basename(spec) if spec in sp.values() else spec}
        try:
            row["ours"] = ours_in_process(spec, args.method, args.repeats)
        except Exception as exc:  # a model that fails is a row with its error
            print(f"{spec}: {type(exc).__name__}: {exc}", flush=True)
            continue
        o = row["ours"]
        if not args.no_sympy and spec not in sp.values():
            row["sympy"] = sympy_route(spec, o["method"], o["k"], args.repeats)
        if args.fresh:
            row["fresh"] = ours_fresh(spec, args.method, args.fresh_repeats)
        if spec in sp.values():
            name = next(k for k, v in sp.items() if v == spec)
            row["strikepy"] = strikepy_cached(name) or {"finished": None, "cpu_s": None, "wall_s": None,
                                                        "date": "not run"}
        s = row.get("sympy")
        print(f"{row['spec']:55s} {o['method']:10s} dim {o['dim']}/{o['n']} first {o['first_s']:.3f} "
              f"warm {o['warm_s']:.3f}" + (f" sympy {s['median_s']:.3f} (dim {s['dim']})" if s else "")
              + (f" fresh {row['fresh'].get('wall_s', float('nan')):.2f}" if args.fresh else "")
              + f" [{o['status']}]", flush=True)
        rows.append(row)
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "argv": " ".join(argv if argv is not None else sys.argv[1:]),
            "machine": f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
                       f"Python {platform.python_version()}",
            "repeats": args.repeats, "load_before": load_before, "load_after": _load1()}
    text = render(rows, meta)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps({"meta": meta, "rows": rows}, indent=1, default=str))
    print(text)


if __name__ == "__main__":
    main()
