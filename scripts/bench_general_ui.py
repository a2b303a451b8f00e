"""Benchmark of the general unknown-input solution against the EORC and the exact sympy oracle.

Usage::

    python scripts/bench_general_ui.py [--repeats 3] [--samples 4096] [--cases gps,hiv]
                                       [--out docs/benchmarks/general_ui.md]

Per case (a zoo model and the EORC order that reaches the general solution's answer, or the
order a paper computed to): in a FRESH process each time (import included, nothing cached),
``uj.analyze(method="general_ui")``, then ``uj.analyze(method="eorc", k_max=K)``, and the
exact sympy oracle (``scripts/general_ui_oracle.py``) where the case has a sympy twin. The
first call and the warm call (the same System analysed again in that process) are reported
separately; medians of ``--repeats`` runs, with the load average of the machine (shared).
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: case -> (zoo spec, EORC order, known_inputs, sympy twin name or None)
CASES = {
    "gps": ("gps.py:inputs_unknown", 1, "switchable", "systems/gps.py:inputs_unknown"),
    "drift_example": ("counterexamples.py:drift_example", 4, "switchable", None),
    "polar_11_1_1_smooth": ("unicycle_polar.py:range_v_unknown", 4, "smooth",
                            "systems/unicycle_polar.py:range_v_unknown"),
    "hiv": ("multi_ui.py:hiv", 4, "switchable", "systems/multi_ui.py:hiv"),
    "tac2025": ("multi_ui.py:tac2025", 4, "switchable", "systems/multi_ui.py:tac2025"),
    "visfm_case1": ("visual_inertial_partial.py:calibrated_one_acc", 7, "smooth", None),
    "visfm_case1_local": ("visual_inertial_partial.py:calibrated_one_acc_local", 7, "smooth", None),
    "extension_two_kept": ("multi_ui.py:extension_two_kept", 4, "switchable",
                           "systems/multi_ui.py:extension_two_kept"),
}

_CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import uio_jax as uj
t_import = time.perf_counter() - t0
spec, method, k, known, samples = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], int(sys.argv[5])
system = uj.load_system(spec)
kw = dict(samples=samples, method=method, known_inputs=known)
if method == "eorc":
    kw["k_max"] = k
t1 = time.perf_counter()
rep = uj.analyze(system, **kw)
first = time.perf_counter() - t1
t2 = time.perf_counter()
rep2 = uj.analyze(system, **kw)
warm = time.perf_counter() - t2
print(json.dumps({"import_s": t_import, "first_s": first, "warm_s": warm, "dim": rep.dim,
                  "observable": [s for s, v in rep.observable.items() if v], "exact": rep.exact}))
"""

_ORACLE = r"""
import json, sys, time
sys.path.insert(0, sys.argv[2])
t0 = time.perf_counter()
from _sympy_models import get
from general_ui_oracle import general_ui_model
res = general_ui_model(get(sys.argv[1]))
print(json.dumps({"first_s": time.perf_counter() - t0, "dim": res["dim"]}))
"""


def _run(code, args, timeout):
    t = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                             timeout=timeout, cwd=ROOT)
    except subprocess.TimeoutExpired:
        return {"error": f"timed out after {timeout} s"}
    if out.returncode:
        return {"error": (out.stderr.strip().splitlines() or ["failed"])[-1]}
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["process_s"] = time.perf_counter() - t
    res["load"] = os.getloadavg()[0]
    return res


def _median(runs, key):
    vals = [r[key] for r in runs if key in r]
    return statistics.median(vals) if vals else None


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--samples", type=int, default=4096)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--timeout", type=float, default=900)
    ap.add_argument("--out", default=None, help="append the table (markdown) to this file")
    args = ap.parse_args(argv)
    rows = []
    for name in args.cases.split(","):
        spec, k, known, twin = CASES[name]
        path = os.path.join(ROOT, "systems", spec)
        row = {"case": name, "k": k, "known_inputs": known}
        for method in ("general_ui", "eorc"):
            runs = [_run(_CHILD, [path, method, str(k), known, str(args.samples)], args.timeout)
                    for _ in range(args.repeats)]
            ok = [r for r in runs if "error" not in r]
            row[method] = {"runs": runs, "first_s": _median(ok, "first_s"), "warm_s": _median(ok, "warm_s"),
                           "process_s": _median(ok, "process_s"),
                           "dim": ok[0]["dim"] if ok else None,
                           "error": None if ok else runs[0]["error"]}
            print(name, method, row[method]["first_s"], row[method]["warm_s"], row[method]["dim"],
                  row[method]["error"] or "", flush=True)
        if twin and known == "switchable":
            runs = [_run(_ORACLE, [twin, os.path.join(ROOT, "scripts")], args.timeout)
                    for _ in range(args.repeats)]
            ok = [r for r in runs if "error" not in r]
            row["oracle"] = {"first_s": _median(ok, "first_s"), "dim": ok[0]["dim"] if ok else None,
                             "error": None if ok else runs[0]["error"]}
            print(name, "oracle", row["oracle"], flush=True)
        rows.append(row)
    lines = [f"samples={args.samples}, {args.repeats} fresh processes per cell (medians), "
             f"load {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores", "",
             "| case | general_ui first (s) | general_ui warm (s) | dim | EORC k | EORC first (s) | "
             "EORC warm (s) | EORC dim | sympy oracle (s) |", "|---|---|---|---|---|---|---|---|---|"]
    fmt = lambda v: "-" if v is None else f"{v:.2f}"  # noqa: E731
    for r in rows:
        g, e, o = r["general_ui"], r["eorc"], r.get("oracle", {})
        lines.append(f"| {r['case']} ({r['known_inputs']}) | {fmt(g['first_s'])} | {fmt(g['warm_s'])} | "
                     f"{g['dim'] if g['dim'] is not None else g['error']} | {r['k']} | {fmt(e['first_s'])} | "
                     f"{fmt(e['warm_s'])} | {e['dim'] if e['dim'] is not None else e['error']} | "
                     f"{fmt(o.get('first_s'))} |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        with open(args.out, "a") as fh:
            fh.write("\n" + text + "\n")
        with open(os.path.splitext(args.out)[0] + ".jsonl", "a") as fh:
            for r in rows:
                fh.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    main()
