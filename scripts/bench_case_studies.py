"""The case studies of the 2023 identifiability benchmark, timed against symident in one run.

Rey Barreiro and Villaverde (2023), "Benchmarking tools for a priori identifiability
analysis", Bioinformatics 39(2), published the inputs of every tool they compared; their
StrikePy inputs (``StrikePy/*.py`` of https://github.com/Xabo-RB/Benchmarking_files, commit
914ab26) are read here, not copied into this repository (they carry no licence)::

    git clone https://github.com/Xabo-RB/Benchmarking_files
    python scripts/bench_case_studies.py Benchmarking_files/StrikePy [--repeat 3]

For each model file (``options*.py`` excluded), in fresh processes:

* **uio_jax**: ``uio_jax._io.strikepy_import.load_strikepy`` then ``uj.analyze(system)``
  (default options: every decision exact modulo p where the model is made rational);
* **symident** 0.12 (``pip install symident``; a C++ kernel over finite fields): a
  ``symident.Model`` built from the same equations (our importer's expression texts: the
  same states, parameters, known and unknown inputs, outputs renamed ``obs_*``, StrikePy's
  known constants ``fixed``), then ``symident.detect(model)`` (its defaults, one core).

Each process reports the CPU and wall seconds of the analysis call alone (``analyze`` /
``detect``: the import of the library and the building of the model excluded) and of the
whole process; the table gives medians over ``--repeat`` runs, our dimension and arithmetic,
symident's rank, number of coordinates and rank status, and whether the two leave the same
number of directions hidden (coordinates less rank: a known input that enters non-affinely is
a state of ours, a function of symident's; a declared parameter that no equation uses is a
hidden coordinate of ours and unknown to symident; for models without unknown inputs only, the
two tools give unknown inputs different meanings).
"""

import argparse
import glob
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import time

#: the environment of every timed process: one BLAS / OpenMP thread (on a shared machine
#: spinning library threads count as CPU time of the process)
THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def _ours(path) -> dict:
    import uio_jax as uj
    from uio_jax._io.strikepy_import import load_strikepy

    system = load_strikepy(path)
    c0, t0 = time.process_time(), time.perf_counter()
    rep = uj.analyze(system)
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    return {"cpu_s": cpu, "wall_s": wall, "coords": rep.n, "states": len(system.states),
            "known": len(system.known), "unknown": len(system.unknown), "method": rep.method, "dim": rep.dim,
            "arithmetic": rep.certificate.arithmetic.name.lower(),
            "taylor": any("Taylor series" in note for note in rep.notes)}


def _symident(path) -> dict:
    import symident

    from uio_jax._io.strikepy_import import read_strikepy

    spec = read_strikepy(path)
    model = symident.Model(odes=dict(spec.dynamics), observables={f"obs_{k}": v for k, v in spec.outputs.items()},
                           known_inputs=list(spec.inputs_known), unknown_inputs=list(spec.inputs_unknown),
                           fixed=list(spec.constants))
    texts = " ".join(list(spec.dynamics.values()) + list(spec.outputs.values()))
    used = set(re.findall(r"[A-Za-z_][A-Za-z_0-9]*", texts))
    unused = [q for q in spec.params if q not in used]  # hidden for us, unknown to symident
    c0, t0 = time.process_time(), time.perf_counter()
    try:
        res = symident.detect(model)
    except Exception as exc:  # noqa: BLE001 - a peer's refusal is a row of the table
        return {"error": f"{type(exc).__name__}: {str(exc).splitlines()[0][:90]}"}
    cpu, wall = time.process_time() - c0, time.perf_counter() - t0
    status = (res.info.get("rank_status") or {}).get("status")
    return {"cpu_s": cpu, "wall_s": wall, "rank": res.rank, "coords": res.dim, "status": status, "unused": len(unused)}


def one(tool: str, path: str) -> dict:
    """Run one tool on one model in this process (the parent times the process)."""
    c0 = time.process_time()
    out = _ours(path) if tool == "uio_jax" else _symident(path)
    out["process_cpu_s"] = time.process_time() - c0
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


def _run(tool, path, timeout) -> dict:
    env = dict(os.environ, **THREADS)
    t0 = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, __file__, "--one", tool, path], capture_output=True, text=True,
                             timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        return {"error": f"timeout {timeout} s"}
    if out.returncode:
        return {"error": (out.stderr.strip().splitlines() or ["?"])[-1][:100]}
    res = json.loads(out.stdout.strip().splitlines()[-1])
    res["process_wall_s"] = time.perf_counter() - t0
    return res


def _median(runs, key):
    values = [r[key] for r in runs if key in r]
    return statistics.median(values) if values else float("nan")


def _row(name, ours, theirs):
    o, s = ours[0], theirs[0]
    if "error" in o:
        return f"| {name} | failed: {o['error']} |"
    inputs = f"{o['known']}/{o['unknown']}"
    route = o["method"] + (" (Taylor)" if o["taylor"] else "")
    mine = f"{_median(ours, 'cpu_s'):.3f} | {_median(ours, 'process_cpu_s'):.2f}"
    if "error" in s:
        peer, agree = f"refused ({s['error']}) | - | -", "-"
    else:
        peer = (f"{_median(theirs, 'cpu_s'):.3f} | {_median(theirs, 'process_cpu_s'):.2f} "
                f"| {s['rank']}/{s['coords']} {s['status']}")
        same = s["coords"] - s["rank"] + s["unused"] == o["coords"] - o["dim"]  # the same hidden directions
        agree = ("yes" if same else "NO") if not o["unknown"] else "n/a (unknown inputs)"
    return (f"| {name} | {o['states']} | {o['coords'] - o['states']} | {inputs} | {route} | {o['dim']}/{o['coords']} "
            f"| {o['arithmetic']} | {mine} | {peer} | {agree} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("models", nargs="?", help="the StrikePy folder of Xabo-RB/Benchmarking_files")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=600.0)
    ap.add_argument("--only", nargs="*", default=None, help="model file names (without .py)")
    ap.add_argument("--one", nargs=2, metavar=("TOOL", "PATH"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(*args.one)))
        return
    if not args.models:
        ap.error("give the StrikePy folder of the benchmark's repository")
    files = sorted(f for f in glob.glob(os.path.join(args.models, "*.py"))
                   if not os.path.basename(f).startswith("options"))
    if args.only:
        files = [f for f in files if os.path.splitext(os.path.basename(f))[0] in args.only]
    print("| case study | states | params | inputs known/unknown | uio_jax route | dim/coords | arithmetic "
          "| uio_jax analyze CPU s | uio_jax process CPU s | symident detect CPU s | symident process CPU s "
          "| symident rank/coords | ranks agree |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|", flush=True)
    for path in files:
        ours = [_run("uio_jax", path, args.timeout) for _ in range(args.repeat)]
        theirs = [_run("symident", path, args.timeout) for _ in range(args.repeat)]
        print(_row(os.path.splitext(os.path.basename(path))[0], ours, theirs), flush=True)


if __name__ == "__main__":
    main()
