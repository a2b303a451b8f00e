"""Global identifiability on StructuralIdentifiability.jl's benchmark models, beside SI.jl's
published global times and symident's ``solution_count`` measured in the same run.

Each measurement runs in a fresh process with a wall-clock limit (``--limit``): ours is
``uj.global_identifiability`` (the local test, SIAN's system, msolve) with msolve's own limit a
little under it; symident is ``detect`` then ``solution_count`` (its Taylor coefficients in
sympy, msolve at the prime 1000003), pointed at the same msolve binary (``SYMIDENT_MSOLVE``).
Reported: wall seconds timed inside the process (the package's import and, for ours, building
the System from the model text not counted; symident's model built inside), CPU seconds of
the process and its children (msolve), peak resident memory of the process and of its
largest child, the verdicts, and the load average. SI.jl's ``glob_time`` is its own record (benchmarking/
benchmark_result.md: Julia 1.7, an Intel i5-8210Y at 1.6 GHz), not re-measured.

    python scripts/bench_global.py [--limit 120] [--models NAME ...] [--no-symident] [--out FILE]
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_si_models import MODELS  # noqa: E402  (the transcribed SI.jl models)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

#: SI.jl's published global times (seconds, benchmarking/benchmark_result.md, column glob_time).
SI_GLOBAL_SECONDS = {"Goodwin oscillator": 0.09, "SIWR (cholera)": 13.08, "SIRS forced": 8.97,
                     "HIV (Wodarz)": 0.41, "chemical reaction network": 0.14, "Modified LV": 2.46}

EXTRA = {  # states, params, right-hand sides, outputs, known inputs
    "Modified LV": (["x1", "x2"], ["a", "b", "c", "d"],
                    {"x1": "(a + b)*x1 - c*x1*x2", "x2": "-a*b*x2 + d*x1*x2"}, ["x1"], []),
    "Bilirubin2_io": (["x1", "x2", "x3", "x4"], ["k01", "k12", "k13", "k14", "k21", "k31", "k41"],
                      {"x1": "-(k21 + k31 + k41 + k01)*x1 + k12*x2 + k13*x3 + k14*x4 + u",
                       "x2": "k21*x1 - k12*x2", "x3": "k31*x1 - k13*x3", "x4": "k41*x1 - k14*x4"}, ["x1"], ["u"]),
}


def spec(name):
    """``(states, params, rhs, outputs, known inputs)`` of a model."""
    if name in EXTRA:
        return EXTRA[name]
    states, params, rhs, outputs = MODELS[name]
    return states, params, rhs, outputs, []


def build(name):
    """The System of a model (through a model file's text: no JAX needed)."""
    import tempfile

    import uio_jax as uj

    states, params, rhs, outputs, known = spec(name)
    lines = [f'name = "{name}"', "states = [" + ", ".join(f'"{s}"' for s in states) + "]", "[params]"]
    lines += [f"{p} = [0.5, 1.5]" for p in params]
    lines += ["[outputs]"] + [f'y{i + 1} = "{y}"' for i, y in enumerate(outputs)]
    if known:
        lines += ["[inputs]", "known = [" + ", ".join(f'"{u}"' for u in known) + "]"]
    lines += ["[dynamics]"] + [f'{s} = "{rhs[s]}"' for s in states]
    with tempfile.NamedTemporaryFile("w", suffix=".toml", delete=False) as fh:
        fh.write("\n".join(lines) + "\n")
    try:
        return uj.load_system(fh.name)
    finally:
        os.unlink(fh.name)


def one(name, tool, limit):
    """Measure one model with one tool in this process (its import not counted); prints a
    JSON line."""
    if tool == "ours":
        import uio_jax as uj

        system = build(name)
        t0, c0 = time.perf_counter(), time.process_time()
        result = uj.global_identifiability(system, timeout=max(limit - 10, 5))
        out = {"verdicts": {k: v.value for k, v in result.global_identifiability.items()},
               "counts": dict(result.value_counts), "solutions": result.solution_count,
               "undecided": result.undecided_reason, "seconds_parts": dict(result.seconds)}
    else:
        import symident

        t0, c0 = time.perf_counter(), time.process_time()
        states, params, rhs, outputs, known = spec(name)
        model = symident.Model(odes={s: rhs[s].replace("**", "^") for s in states},
                               observables={f"y{i + 1}": y for i, y in enumerate(outputs)}, known_inputs=known)
        res = symident.detect(model)
        count = res.solution_count(timeout=max(limit - 10, 5)) if res.identifiable else None
        out = {"identifiable": bool(res.identifiable), "count": count}
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    own = resource.getrusage(resource.RUSAGE_SELF)
    out.update(name=name, tool=tool, wall=time.perf_counter() - t0,
               cpu=time.process_time() - c0 + children.ru_utime + children.ru_stime,
               peak_mb=own.ru_maxrss / 1024, child_peak_mb=children.ru_maxrss / 1024)
    print(json.dumps(out))


def measure(name, tool, limit):
    """Run :func:`one` in a fresh process with a wall-clock limit."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    try:
        proc = subprocess.run([sys.executable, __file__, "--one", name, "--tool", tool, "--limit", str(limit)],
                              capture_output=True, text=True, timeout=limit, env=env)
    except subprocess.TimeoutExpired:
        return {"name": name, "tool": tool, "wall": None, "error": f"over the {limit} s limit"}
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    if proc.returncode != 0 or not lines:
        return {"name": name, "tool": tool, "wall": None, "error": (proc.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(lines[-1])


def table(rows, limit):
    """The markdown table of the measurements."""
    out = ["| model | SI.jl glob_time (published) | ours: wall / CPU s | ours: verdicts | ours: peak MB (msolve) "
           "| symident solution_count: wall s | symident count |", "|---|---|---|---|---|---|---|"]
    by = {}
    for r in rows:
        by.setdefault(r["name"], {})[r["tool"]] = r
    for name, tools in by.items():
        o, s = tools.get("ours", {}), tools.get("symident")
        if o.get("wall") is None:
            ours, verdicts, mem = o.get("error", "-"), "-", "-"
        else:
            ours = f"{o['wall']:.2f} / {o['cpu']:.2f}"
            v = list(o["verdicts"].values())
            verdicts = ", ".join(f"{v.count(k)} {k}" for k in ("global", "local", "not", "undecided") if v.count(k))
            if o.get("undecided"):
                verdicts += f" ({o['undecided']})"
            mem = f"{o['peak_mb']:.0f} ({o['child_peak_mb']:.0f})"
        if s is None:
            sym, count = "not run", "-"
        elif s.get("wall") is None:
            sym, count = s.get("error", "-"), "-"
        else:
            sym = f"{s['wall']:.2f}"
            count = (s["count"] or {}).get("count", "none") if s.get("identifiable") else "not identifiable"
        pub = SI_GLOBAL_SECONDS.get(name, "-")
        out.append(f"| {name} | {pub} | {ours} | {verdicts} | {mem} | {sym} | {count} |")
    return "\n".join(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--limit", type=float, default=120.0, help="wall seconds per measurement")
    ap.add_argument("--models", nargs="*", default=None)
    ap.add_argument("--no-symident", action="store_true")
    ap.add_argument("--out", default=None, help="also write the table and the raw rows (markdown)")
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--tool", default="ours", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        one(args.one, args.tool, args.limit)
        return 0
    names = args.models or [*MODELS, *EXTRA]
    rows = []
    for name in names:
        for tool in ("ours",) + (() if args.no_symident else ("symident",)):
            row = measure(name, tool, args.limit)
            row["load"] = os.getloadavg()[0]
            rows.append(row)
            print(json.dumps(row), flush=True)
    text = table(rows, args.limit)
    print(text)
    if args.out:
        with open(args.out, "w") as fh:
            fh.write(text + "\n\nRaw rows:\n\n```\n" + "\n".join(json.dumps(r) for r in rows) + "\n```\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
