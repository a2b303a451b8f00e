"""Benchmark: the first verdict on the seed systems against the exact sympy route, and the fresh
process of the command line on a model file.

In ONE run:

* **first call in a running process**, per seed system (``bench_cold.SEED_MODELS``: the papers'
  models of the zoo): a process that has imported ``uio_jax`` and analysed one unrelated model
  loads the model afresh (``load_s``, timed apart) and calls ``uj.analyze`` on it (default
  options, 4096 samples): wall and CPU time of that call, median of ``--repeats`` newly loaded
  Systems;
* **the exact sympy route** on the same model in the same process, right after
  (``scripts/_exact_sympy_route.py``: symbolic Lie derivatives, gradients at one random rational
  point by exact forward-mode differentiation, exact ranks over QQ; the ORC and the single
  unknown input; sympy's cache cleared before every run), median of as many runs; for the
  general solution, ``scripts/general_ui_oracle.py`` (exact for rational models, 60 digits
  otherwise: labelled). A model the exact route cannot evaluate exactly (a constant such as
  ``cos(7 pi / 10)``, 004 section 7's output change) has no peer figure (``-``, the reason);
* **fresh processes** of ``uio-jax analyze systems/two_compartment.toml``: wall (timed from
  outside) and CPU (``RUSAGE_CHILDREN``) of ``--fresh-repeats`` processes, median, with the
  environment's bytecode setting and with a warmed bytecode cache (``PYTHONPYCACHEPREFIX``, what an
  installed package has), whether JAX was imported (``python -X importtime``), and the same for
  ``python -c "import jax"`` as the reference; ``--tree OTHER`` adds another checkout's command
  (e.g. the tree before this change) to the same run.

Every row records the 1-minute load average. Usage (repository root)::

    python scripts/bench_first_call.py --repeats 5 --fresh-repeats 5 --out docs/benchmarks/first_call.md
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

MODEL_FILE = "systems/two_compartment.toml"
SAMPLES = 4096


def _median(xs):
    return statistics.median(xs) if xs else float("nan")


def _timed(fn):
    w, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w, time.process_time() - c


# ------------------------------------------------------------------ ours, in one process
def ours(spec, repeats):
    """Load times, first-call wall and CPU times on newly loaded Systems; the last report."""
    import uio_jax as uj

    loads, walls, cpus, rep = [], [], [], None
    for _ in range(repeats):
        system, load_s, _ = _timed(lambda: uj.load_system(str(ROOT / spec)))
        rep, wall, cpu = _timed(lambda: uj.analyze(system, samples=SAMPLES))
        loads.append(load_s)
        walls.append(wall)
        cpus.append(cpu)
    return {"load_s": _median(loads), "first_s": _median(walls), "first_cpu_s": _median(cpus), "firsts": walls,
            "method": rep.method, "dims": list(rep.dims), "dim": rep.dim, "n": rep.n, "exact": rep.exact,
            "k": rep.details.get("k")}


# ------------------------------------------------------------------ the exact sympy route
def sympy_route(spec, method, k, repeats):
    """The exact sympy route of ``method`` on the twin of ``spec``: median wall time and dims,
    or ``{"error": reason}``; None without a twin."""
    import _exact_sympy_route as exact
    import _sympy_models
    import general_ui_oracle
    import sympy.core.cache

    if spec not in _sympy_models.MODELS:
        return None

    def run():
        sympy.core.cache.clear_cache()
        model = _sympy_models.get(spec)
        if method == "orc":
            return exact.orc(model)["dims"], "exact"
        if method == "single_ui":
            return exact.single_ui(model)["dims"], "exact"
        if method == "general_ui":
            out = general_ui_oracle.general_ui_model(model)
            return [out["dim"]], "exact" if out.get("exact", True) else "60 digits"
        if method == "eorc":
            out = general_ui_oracle.eorc_model(model, k_max=k)
            return out["dims"], "exact" if out.get("exact", True) else "60 digits"
        return None, None

    times, dims, kind = [], None, None
    try:
        for _ in range(repeats):
            (dims, kind), wall, _ = _timed(run)
            times.append(wall)
    except Exception as exc:  # the route does not apply: no peer figure
        return {"error": f"{type(exc).__name__}: {str(exc)[:80]}"}
    return {"median_s": _median(times), "runs": times, "dims": dims, "arithmetic": kind}


# ------------------------------------------------------------------ fresh processes
def fresh(cmd, repeats, env, cwd):
    """Wall (outside) and CPU (children's user + system) of ``cmd``, median of ``repeats``."""
    walls, cpus = [], []
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        w = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=cwd, timeout=600)
        walls.append(time.perf_counter() - w)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
        if proc.returncode != 0:
            return {"error": (proc.stderr.strip().splitlines() or ["failed"])[-1]}
    return {"wall_s": _median(walls), "cpu_s": _median(cpus), "walls": walls}


def imports_jax(cmd, env, cwd) -> bool:
    proc = subprocess.run([cmd[0], "-X", "importtime", *cmd[1:]], capture_output=True, text=True, env=env,
                          cwd=cwd, timeout=600)
    return any(ln.split("|")[-1].strip() == "jax" for ln in proc.stderr.splitlines())


def fresh_rows(trees, repeats):
    """The command line on the model file per tree, and ``import jax``, in both bytecode settings."""
    rows = []
    cache = tempfile.mkdtemp(prefix="uio_jax_pyc_")
    for label, pyc in (("environment as is", None), ("bytecode cache (installed package)", cache)):
        env = dict(os.environ)
        if pyc is not None:
            env.pop("PYTHONDONTWRITEBYTECODE", None)
            env["PYTHONPYCACHEPREFIX"] = pyc
        for name, tree in trees:
            env_t = dict(env, PYTHONPATH=str(tree))
            cmd = [sys.executable, "-m", "uio_jax", "analyze", str(ROOT / MODEL_FILE), "--no-cache"]
            if pyc is not None:
                subprocess.run(cmd, capture_output=True, env=env_t, cwd=tree, timeout=600)  # write the cache
            row = fresh(cmd, repeats, env_t, tree)
            row.update(what=f"uio-jax analyze {MODEL_FILE} ({name})", setting=label,
                       jax=imports_jax(cmd, env_t, tree), load1=os.getloadavg()[0])
            rows.append(row)
        row = fresh([sys.executable, "-c", "import jax"], repeats, env, ROOT)
        row.update(what="python -c 'import jax'", setting=label, jax=True, load1=os.getloadavg()[0])
        rows.append(row)
    return rows


# ------------------------------------------------------------------ report
def _f(x, digits=3):
    return "-" if x is None else f"{x:.{digits}f}"


def render(rows, fresh_list, meta) -> str:
    lines = [
        f"# First call on the seed systems and the fresh command line ({meta['date']})",
        "",
        f"`python scripts/bench_first_call.py {meta['argv']}`; commit {meta['commit']}; machine: "
        f"{meta['machine']}; load {meta['load_before']:.2f} before, {meta['load_after']:.2f} after; "
        f"{SAMPLES} samples.",
        "",
        "first = `uj.analyze` of a freshly loaded System in a running process (median of "
        f"{meta['repeats']}; load apart); exact sympy = `scripts/_exact_sympy_route.py` (ORC, single "
        "unknown input) or `general_ui_oracle` (general solution), sympy cache cleared, same process, "
        "same count.",
        "",
        "| model | method | dims | dims (sympy) | load (s) | first (s) | first CPU (s) | exact sympy (s) "
        "| first / sympy |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        o, s = r["ours"], r.get("sympy")
        if s is None:
            peer, ratio, sdims = "- (no twin)", "-", "-"
        elif "error" in s:
            peer, ratio, sdims = f"- ({s['error']})", "-", "-"
        else:
            peer = _f(s["median_s"]) + ("" if s["arithmetic"] == "exact" else f" ({s['arithmetic']})")
            ratio = f"{o['first_s'] / s['median_s']:.2f}" if s["median_s"] > 0 else "-"
            sdims = " ".join(map(str, s["dims"] or []))
        lines.append(f"| {r['spec']} | {o['method']} | {' '.join(map(str, o['dims']))} | {sdims} | "
                     f"{_f(o['load_s'])} | {_f(o['first_s'])} | {_f(o['first_cpu_s'])} | {peer} | {ratio} |")
    if fresh_list:
        lines += ["", "Fresh processes (median; wall timed from outside, CPU of the child):", "",
                  "| command | setting | wall (s) | CPU (s) | JAX imported | load |", "|---|---|---|---|---|---|"]
        for f in fresh_list:
            if "error" in f:
                lines.append(f"| {f['what']} | {f['setting']} | error: {f['error']} | | | |")
                continue
            lines.append(f"| {f['what']} | {f['setting']} | {_f(f['wall_s'])} | {_f(f['cpu_s'])} | "
                         f"{'yes' if f['jax'] else 'no'} | {f['load1']:.2f} |")
    return "\n".join(lines) + "\n"


def _commit(tree) -> str:
    try:
        out = subprocess.run(["git", "-C", str(tree), "rev-parse", "--short", "HEAD"], capture_output=True,
                             text=True, timeout=30).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(tree), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=30).stdout.strip()
        return out + (" (with uncommitted changes)" if dirty else "")
    except OSError:
        return "unknown"


def main(argv=None):
    import bench_cold

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--fresh-repeats", type=int, default=5)
    ap.add_argument("--models", nargs="*", default=None, help="specs (default: the seed systems)")
    ap.add_argument("--tree", action="append", default=[], help="another checkout for the fresh rows")
    ap.add_argument("--no-fresh", action="store_true")
    ap.add_argument("--out", help="write the Markdown table here")
    ap.add_argument("--json", help="write the raw results here")
    args = ap.parse_args(argv)

    import uio_jax as uj

    uj.analyze(uj.load_system(str(ROOT / "systems/multi_ui.py:trivial_drift")), samples=64)  # library start
    load_before = os.getloadavg()[0]
    rows = []
    for spec in args.models or bench_cold.SEED_MODELS:
        row = {"spec": spec, "ours": ours(spec, args.repeats)}
        o = row["ours"]
        row["sympy"] = sympy_route(spec, o["method"], o["k"], args.repeats)
        s = row["sympy"]
        print(f"{spec:52s} {o['method']:10s} first {o['first_s']:.4f} (cpu {o['first_cpu_s']:.4f}) "
              + ("" if s is None else s.get("error", f"sympy {s.get('median_s', 0):.4f} dims {s.get('dims')}")),
              flush=True)
        rows.append(row)
    trees = [("this tree", ROOT)] + [(f"tree {t}", Path(t).resolve()) for t in args.tree]
    fresh_list = [] if args.no_fresh else fresh_rows(trees, args.fresh_repeats)
    for f in fresh_list:
        print(f, flush=True)
    meta = {"date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "argv": " ".join(argv if argv is not None else sys.argv[1:]), "commit": _commit(ROOT),
            "machine": f"{os.cpu_count()} cores, {platform.processor() or platform.machine()}, "
                       f"Python {platform.python_version()}",
            "repeats": args.repeats, "load_before": load_before, "load_after": os.getloadavg()[0]}
    text = render(rows, fresh_list, meta)
    if args.out:
        Path(args.out).write_text(text)
    if args.json:
        Path(args.json).write_text(json.dumps({"meta": meta, "rows": rows, "fresh": fresh_list}, indent=1,
                                              default=str))
    print(text)


if __name__ == "__main__":
    main()
