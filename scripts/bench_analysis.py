"""Benchmark: uio_jax analyses against a plain sympy route and StrikePy.

For each zoo model with known inputs only (ORC), and for the single-unknown-input case
(``vehicle_wind.py:wind_unknown``, ``method="single_ui"``), in ONE run:

* **ours**: ``uj.analyze`` with a 4096-sample certificate. Compile = first call on a fresh
  ``System`` object minus warm; warm = median of ``--repeats`` later calls on the same object
  (they reuse its cached jitted functions). JAX is initialised once beforehand, so the
  compile time of the first model does not include the backend start-up.
* **sympy**: ``scripts/sympy_oracle.py`` on the sympy model of ``scripts/_sympy_models.py``
  (symbolic Lie derivatives, pruning, rank at one random point). The sympy cache is cleared
  and the model rebuilt before every run, so repeats do not reuse earlier results.
* **StrikePy** (``pip install strikepy==1.0``, ORC models only): the model and an options file
  are written into StrikePy's package directory (``models/uj_*.py``,
  ``custom_options/options_uj_*.py``; StrikePy only loads models from there), then
  ``strike_goldd('options_uj_*')`` runs in a subprocess with a timeout (``--strikepy-timeout``,
  default 120 s); the time is measured inside the subprocess around that call (imports
  excluded). Known inputs get ``nnzDerU = inf`` (arbitrary smooth inputs); StrikePy's rank
  of its observability matrix is compared with our dimension.

Every measurement records wall time, process CPU time and ``os.getloadavg()``. A peer run
that takes more than ``--long`` seconds (default 30) is repeated only while the total stays
under ``--budget`` seconds (default 90) -- the table says how many runs each median has.

Usage (from the repository root)::

    python scripts/bench_analysis.py --repeats 5 --out docs/benchmarks/analysis.md
    python scripts/bench_analysis.py --models systems/unicycle_polar.py:range_known --no-strikepy
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata as md
import json
import os
import platform
import re
import statistics
import subprocess
import sys
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

ORC_MODELS = [
    "systems/vehicle_wind.py:no_wind",
    "systems/vehicle_wind.py:wind_known",
    "systems/unicycle_polar.py:range_known",
    "systems/unicycle_polar.py:bearing_known",
    "systems/unicycle_polar.py:phi_known",
    "systems/unicycle_disturbance.py:no_disturbance_range",
    "systems/unicycle_disturbance.py:no_disturbance_bearing",
    "systems/unicycle_disturbance.py:no_disturbance_phi",
    "systems/gps.py:inputs_known",
]
SINGLE_UI_MODELS = ["systems/vehicle_wind.py:wind_unknown"]
SAMPLES = 4096


# --------------------------------------------------------------------------------------
# Measurement helpers
# --------------------------------------------------------------------------------------

def _measure(fn):
    """Run ``fn()``; return (result, record) with wall/process time and load average."""
    load = os.getloadavg()[0]
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    t1, c1 = time.perf_counter(), time.process_time()
    return out, {"wall_s": t1 - t0, "cpu_s": c1 - c0, "load1": load}


def _repeat(fn, repeats, long_s, budget_s):
    """Run ``fn`` up to ``repeats`` times; runs longer than ``long_s`` only while the total
    stays under ``budget_s``. Returns (last result, records)."""
    records, out, total = [], None, 0.0
    for _ in range(repeats):
        out, rec = _measure(fn)
        records.append(rec)
        total += rec["wall_s"]
        if rec["wall_s"] > long_s and total + rec["wall_s"] > budget_s:
            break
    return out, records


def _median(records, key="wall_s"):
    return statistics.median(r[key] for r in records) if records else float("nan")


# --------------------------------------------------------------------------------------
# Ours
# --------------------------------------------------------------------------------------

def bench_ours(spec, method, repeats):
    import uio_jax as uj

    system = uj.load_system(str(ROOT / spec))
    try:
        rep, first = _measure(lambda: uj.analyze(system, method=method, samples=SAMPLES, seed=0))
    except uj.OptionError as e:
        if "not available" in str(e):
            print(f"  {method} not available ({e})")
            return {"available": False, "error": str(e)}
        raise
    warm = []
    for _ in range(repeats):
        rep, rec = _measure(lambda: uj.analyze(system, method=method, samples=SAMPLES, seed=0))
        warm.append(rec)
    w = _median(warm)
    return {"available": True, "dims": list(rep.dims), "dim": rep.dim, "n": system.n,
            "first": first, "warm": warm, "warm_s": w, "compile_s": first["wall_s"] - w,
            "fraction": rep.certificate.fraction}


# --------------------------------------------------------------------------------------
# Sympy route
# --------------------------------------------------------------------------------------

def bench_sympy(spec, method, repeats, long_s, budget_s):
    import _sympy_models
    import sympy.core.cache
    import sympy_oracle

    def run():
        sympy.core.cache.clear_cache()
        model = _sympy_models.get(spec)
        if method == "orc":
            return sympy_oracle.orc(model, seed=0)
        return sympy_oracle.single_ui(model, seed=0)

    res, recs = _repeat(run, repeats, long_s, budget_s)
    out = {"dims": res["dims"], "dim": res["dim"], "runs": recs, "median_s": _median(recs)}
    if method == "single_ui":
        out.update(m_prime=res["m_prime"], m_star=res["m_star"], lemma1=res["lemma1"])
    return out


# --------------------------------------------------------------------------------------
# StrikePy
# --------------------------------------------------------------------------------------

def strikepy_dir():
    import importlib.util

    spec = importlib.util.find_spec("StrikePy")
    return None if spec is None else Path(spec.origin).parent


def _tag(spec):
    return "uj_" + re.sub(r"[^A-Za-z0-9]", "_", spec.split("/")[-1].replace(".py", ""))


def write_strikepy_model(spec, model):
    import _sympy_models

    """Write ``model`` as a StrikePy model + options file; return the options name.

    StrikePy reads ``x`` (states, column list), ``h`` (outputs), ``u`` (known inputs),
    ``w`` (unknown inputs), ``p`` (parameters) and ``f`` (the full right-hand side, affine
    in the inputs) from ``StrikePy/models/<modelname>.py``, and the options from
    ``StrikePy/custom_options/<name>.py``.
    """
    import sympy as sp

    d = strikepy_dir()
    tag = _tag(spec)
    # StrikePy's model module uses the names x, h, u, w, p, f itself: prefix every state.
    ren = {s: sp.Symbol(f"s_{s}", real=True) for s in model.states}
    model = _sympy_models.SympyModel(
        model.name, tuple(ren.values()),
        {k: sp.sympify(e).xreplace(ren) for k, e in model.outputs.items()},
        {k: f.xreplace(ren) for k, f in model.known.items()},
        {k: f.xreplace(ren) for k, f in model.unknown.items()},
        None if model.drift is None else model.drift.xreplace(ren), model.domain)
    states = [str(s) for s in model.states]
    u_names = [f"u_{k}" for k in model.known]
    w_names = [f"w_{k}" for k in model.unknown]
    rhs = []
    for i in range(model.n):
        terms = [f"({model.known[k][i]})*{u}" for k, u in zip(model.known, u_names)
                 if model.known[k][i] != 0]
        terms += [f"({model.unknown[k][i]})*{w}" for k, w in zip(model.unknown, w_names)
                  if model.unknown[k][i] != 0]
        if model.drift is not None and model.drift[i] != 0:
            terms.append(f"({model.drift[i]})")
        rhs.append(" + ".join(terms) if terms else "0")
    src = textwrap.dedent(f"""\
        # Written by uio_jax scripts/bench_analysis.py: {spec}
        import numpy as np
        from sympy import *

        {", ".join(states)}, = symbols("{" ".join(states)}", real=True)
        """)
    names = u_names + w_names
    if names:
        src += f'{", ".join(names)}, = symbols("{" ".join(names)}")\n'
    src += f"x = [{', '.join(f'[{s}]' for s in states)}]\n"
    src += f"h = [{', '.join(str(e) for e in model.outputs.values())}]\n"
    src += f"u = [{', '.join(f'[{u}]' for u in u_names)}]\n"
    if w_names:
        src += f"w = [{', '.join(f'[{w}]' for w in w_names)}]\n"
    # StrikePy cannot np.append an empty list to the state column: an empty (0, 1) array.
    src += "p = np.empty((0, 1), dtype=object)\n"
    src += "f = [" + ", ".join(f"[{r}]" for r in rhs) + "]\n"
    src += "variables_locales = locals().copy()\n"
    (d / "models" / f"{tag}.py").write_text(src)
    opts = textwrap.dedent(f"""\
        # Written by uio_jax scripts/bench_analysis.py: {spec}
        from math import inf
        modelname = "{tag}"
        checkObser = 1
        maxLietime = inf
        nnzDerU = {[float("inf")] * max(1, len(u_names))}
        nnzDerW = {[float("inf")] * max(1, len(w_names))}
        prev_ident_pars = []
        """)
    (d / "custom_options" / f"options_{tag}.py").write_text(opts)
    return f"options_{tag}"


_RUNNER = r"""
import json, sys, time
from StrikePy.strike_goldd import strike_goldd
c0, t0 = time.process_time(), time.perf_counter()
strike_goldd(sys.argv[1])
print("UJ_TIMING " + json.dumps({"wall_s": time.perf_counter() - t0,
                                 "cpu_s": time.process_time() - c0}))
"""


def _parse_strikepy(text):
    ranks = re.findall(r"Rank = (\d+)", text)

    def lst(pattern):  # state names without the s_ prefix of the model file
        m = re.search(pattern + r":\s*\n\s*(\[.*?\])", text)
        return m.group(1).replace("s_", "") if m else None

    return {"rank": int(ranks[-1]) if ranks else None,
            "observable": lst(r"These states are observable[^\n]*"),
            "unobservable": lst(r"These states are unobservable[^\n]*"),
            "measured": lst(r"These states are directly measured"),
            "fispo": "Fully Input-State-Parameter Observable" in text}


def bench_strikepy(spec, repeats, timeout_s, long_s, budget_s):
    import _sympy_models

    if strikepy_dir() is None:
        return {"available": False, "error": "StrikePy not installed (pip install strikepy==1.0)"}
    opts = write_strikepy_model(spec, _sympy_models.get(spec))
    runs, parsed, total = [], None, 0.0
    for _ in range(repeats):
        load = os.getloadavg()[0]
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, "-c", _RUNNER, opts], capture_output=True,
                                  text=True, timeout=timeout_s, cwd=str(strikepy_dir()),
                                  env=dict(os.environ, PYTHONHASHSEED="0"))
        except subprocess.TimeoutExpired:
            runs.append({"wall_s": None, "cpu_s": None, "load1": load, "timeout": True,
                         "subprocess_s": time.perf_counter() - t0})
            return {"available": True, "finished": False, "runs": runs, "timeout_s": timeout_s,
                    "median_s": float("nan"), "parsed": parsed}
        sub = time.perf_counter() - t0
        m = re.search(r"UJ_TIMING (\{.*\})", proc.stdout)
        if proc.returncode != 0 or m is None:
            tail = (proc.stdout + proc.stderr)[-2000:]
            return {"available": True, "finished": False, "error": tail, "runs": runs,
                    "median_s": float("nan"), "parsed": parsed}
        rec = json.loads(m.group(1))
        rec.update(load1=load, subprocess_s=sub)
        runs.append(rec)
        parsed = _parse_strikepy(proc.stdout)
        total += rec["wall_s"]
        if rec["wall_s"] > long_s and total + rec["wall_s"] > budget_s:
            break
    return {"available": True, "finished": True, "runs": runs, "median_s": _median(runs),
            "parsed": parsed}


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------

def _machine():
    model = platform.processor() or "?"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        m = re.search(r"Model name:\s*(.+)", out)
        model = m.group(1).strip() if m else model
    except (OSError, subprocess.SubprocessError):
        pass
    return {"cpu": model, "cores": os.cpu_count(), "python": platform.python_version(),
            "platform": platform.platform()}


def _versions():
    out = {}
    for pkg in ("uio_jax", "jax", "jaxlib", "numpy", "sympy", "strikepy", "symbtools"):
        try:
            out[pkg] = md.version(pkg)
        except md.PackageNotFoundError:
            out[pkg] = "not installed"
    return out


def _git():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, cwd=ROOT, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def _fmt(x, digits=3):
    if x is None or x != x:
        return "—"
    return f"{x:.{digits}g}" if abs(x) < 1000 else f"{x:.0f}"


def _strikepy_verdict(sp_res):
    if sp_res is None:
        return "not run"
    if not sp_res.get("available"):
        return "not installed"
    if not sp_res.get("finished"):
        if sp_res.get("runs") and sp_res["runs"][-1].get("timeout"):
            return f"did not finish in {sp_res['timeout_s']:.0f} s"
        return "failed (see details)"
    p = sp_res["parsed"]
    if p["fispo"]:
        return f"rank {p['rank']} (all observable)"
    obs = [s for s in (p["observable"], p["measured"]) if s]
    return f"rank {p['rank']}" + (f", obs {' '.join(obs)}" if obs else ", no state obs.")


def _ratio(a, b):
    return a / b if a == a and b == b and b and a else float("nan")


def render(results, meta):
    lines = ["# Analysis benchmark: uio_jax vs a sympy route vs StrikePy", ""]
    lines += [f"Generated by `{meta['command']}` on {meta['date']} (git {meta['git']}).", ""]
    lines += ["## Machine and versions", "",
              f"- CPU: {meta['machine']['cpu']}, {meta['machine']['cores']} cores "
              f"({meta['machine']['platform']}), Python {meta['machine']['python']}",
              "- " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()),
              f"- load average (1 min) at start / end: {meta['load_start']:.2f} / "
              f"{meta['load_end']:.2f}", ""]
    lines += ["## What is measured", "",
              f"- **ours**: `uj.analyze(system, method=..., samples={SAMPLES}, seed=0)`. "
              "*compile* = first call on a fresh `System` object minus *warm*; *warm* = median "
              f"of {meta['repeats']} later calls on the same object (cached jitted functions).",
              "- **sympy**: `scripts/sympy_oracle.py` (plain sympy: unsimplified symbolic Lie "
              "derivatives, pruning, rank of the gradients at one random point evaluated in "
              "50 digits, float64 SVD); sympy cache cleared before every run.",
              "- **StrikePy** 1.0 (STRIKE-GOLDD in Python): model and options written into its "
              "package directory, run in a subprocess with a "
              f"{meta['strikepy_timeout']:.0f} s limit; time measured inside the subprocess "
              "around `strike_goldd()` (imports excluded); known inputs with `nnzDerU = inf`. "
              "Its verdict is the rank of its observability matrix and its list of observable "
              "states.",
              f"- Peer runs longer than {meta['long']:.0f} s are repeated only while the total "
              f"stays under {meta['budget']:.0f} s: column *runs* gives the count behind each "
              "median.",
              "- Ratios are peer median / our warm median.", ""]

    orc = [r for r in results if r["method"] == "orc"]
    sui = [r for r in results if r["method"] == "single_ui"]
    bad = [r["spec"] for r in results if "NO" in r["agree"]]
    lines += ["## Summary", "",
              "- Dimensions: " + ("ours, sympy and StrikePy (where it finished) agree on "
                                  "every model." if not bad else
                                  "DISAGREEMENT on " + ", ".join(bad) + "."),
              "- StrikePy gave no verdict (time limit or error) on: " + (", ".join(
                  r["spec"] for r in orc if r.get("strikepy") and r["strikepy"].get(
                      "available") and not r["strikepy"].get("finished")) or "none") + ".",
              "- Column *load* is the mean 1-minute load average over the model's "
              "measurements (2 cores: a load above 2 means the measurements waited for a "
              "core).", ""]
    if orc:
        lines += ["## ORC (known inputs only)", "",
                  "| model | n | ours dim | sympy dim | StrikePy verdict | ours warm (ms) | "
                  "ours compile (s) | sympy (s) [runs] | StrikePy (s) [runs] | sympy/ours | "
                  "StrikePy/ours | agree | load |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in orc:
            lines.append(_row(r, strike=True))
        lines.append("")
    if sui:
        lines += ["## Single unknown input (`method=\"single_ui\"`)", "",
                  "| model | n | ours dims | sympy dims (m', m*) | ours warm (ms) | "
                  "ours compile (s) | sympy (s) [runs] | sympy/ours | agree | load |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for r in sui:
            lines.append(_row(r, strike=False))
        lines.append("")
    lines += ["## Targets (issue 2)", ""]
    for r in results:
        o = r["ours"]
        if not o.get("available"):
            lines.append(f"- {r['spec']} ({r['method']}): ours not available: {o.get('error')}")
            continue
        if r["method"] == "orc" and "vehicle" in r["spec"]:
            ratio = _ratio(r["sympy"]["median_s"], o["warm_s"])
            cpu = _ratio(_median(r["sympy"]["runs"], "cpu_s"), _median(o["warm"], "cpu_s"))
            lines.append(f"- {r['spec']}: warm ORC {_fmt(ratio)}x faster than sympy in wall "
                         f"time, {_fmt(cpu)}x in process CPU time "
                         f"(target >= 100x: {'met' if ratio >= 100 else 'NOT met'}); compile "
                         f"{_fmt(o['compile_s'])} s (target < 10 s: "
                         f"{'met' if o['compile_s'] < 10 else 'NOT met'})")
        elif r["method"] == "single_ui":
            lines.append(f"- {r['spec']}: warm single_ui {_fmt(o['warm_s'] * 1e3)} ms wall, "
                         f"{_fmt(_median(o['warm'], 'cpu_s') * 1e3)} ms CPU (target "
                         f"<= 50 ms: {'met' if o['warm_s'] <= 0.05 else 'NOT met'}); compile "
                         f"{_fmt(o['compile_s'])} s (target <= 10 s: "
                         f"{'met' if o['compile_s'] <= 10 else 'NOT met'})")
        elif o["compile_s"] >= 10:
            lines.append(f"- {r['spec']}: compile {_fmt(o['compile_s'])} s "
                         "(target < 10 s: NOT met)")
    lines += ["", "## Every measurement", "",
              "Wall time, process CPU time (all threads of the process; for StrikePy the "
              "subprocess) and the 1-minute load average when the measurement started.", ""]
    for r in results:
        lines.append(f"### {r['spec']} ({r['method']})")
        lines.append("")
        o = r["ours"]
        if o.get("available"):
            lines.append(f"- ours first call: {_rec(o['first'])}")
            lines.append("- ours warm: " + "; ".join(_rec(x) for x in o["warm"]))
            lines.append(f"- ours certificate: fraction at generic rank {o['fraction']:.4f}")
        lines.append("- sympy: " + "; ".join(_rec(x) for x in r["sympy"]["runs"]))
        s = r.get("strikepy")
        if s is not None and s.get("available"):
            lines.append("- StrikePy: " + ("; ".join(_rec(x) for x in s["runs"]) or "no run"))
            if s.get("error"):
                lines.append(f"- StrikePy error: `{s['error'][-300:].strip()}`")
        lines.append("")
    lines += ["## Notes", "",
              "- The machine is shared (2 cores, other jobs running: see the load averages); "
              "numbers are noisy and are best re-run on a quiet machine with the command above.",
              "- Semantics differ: uio_jax and the sympy route answer Martinelli's question "
              "(unknown inputs analytic in time, known inputs free); StrikePy treats inputs "
              "through their time derivatives (`nnzDerU`), which for known inputs only gives "
              "the same generic rank.",
              "- The sympy route decides ranks at one random point; ours certifies each rank "
              f"at {SAMPLES} sampled states.", ""]
    return "\n".join(lines)


def _rec(x):
    if x.get("timeout"):
        return f"timeout after {x['subprocess_s']:.1f} s (load {x['load1']:.2f})"
    return f"{x['wall_s']:.4g} s wall / {x['cpu_s']:.4g} s cpu (load {x['load1']:.2f})"


def _row(r, strike):
    o, s = r["ours"], r["sympy"]
    if o.get("available"):
        ours_dim = o["dim"] if strike else str(o["dims"])
        warm_ms, comp, n = _fmt(o["warm_s"] * 1e3), _fmt(o["compile_s"]), o["n"]
        ratio_s = _fmt(_ratio(s["median_s"], o["warm_s"]))
    else:
        ours_dim, warm_ms, comp, ratio_s, n = "n/a", "n/a", "n/a", "—", r["n"]
    sym_t = f"{_fmt(s['median_s'])} [{len(s['runs'])}]"
    if strike:
        sp_res = r.get("strikepy")
        sp_t = "—"
        ratio_p = "—"
        if sp_res and sp_res.get("available") and sp_res.get("finished"):
            sp_t = f"{_fmt(sp_res['median_s'])} [{len(sp_res['runs'])}]"
            if o.get("available"):
                ratio_p = _fmt(_ratio(sp_res["median_s"], o["warm_s"]))
        elif sp_res and sp_res.get("runs") and sp_res["runs"][-1].get("timeout"):
            sp_t = f"> {sp_res['timeout_s']:.0f} (timeout)"
        return (f"| {r['spec'].split('/')[-1]} | {n} | {ours_dim} | {s['dim']} | "
                f"{_strikepy_verdict(sp_res)} | {warm_ms} | {comp} | {sym_t} | {sp_t} | "
                f"{ratio_s} | {ratio_p} | {r['agree']} | {_load(r)} |")
    return (f"| {r['spec'].split('/')[-1]} | {n} | {ours_dim} | {s['dims']} "
            f"({s['m_prime']}, {s['m_star']}) | {warm_ms} | {comp} | {sym_t} | {ratio_s} | "
            f"{r['agree']} | {_load(r)} |")


def _load(r):
    recs = list(r["sympy"]["runs"])
    if r["ours"].get("available"):
        recs += [r["ours"]["first"], *r["ours"]["warm"]]
    if r.get("strikepy") and r["strikepy"].get("runs"):
        recs += r["strikepy"]["runs"]
    return f"{statistics.mean(x['load1'] for x in recs):.1f}" if recs else "—"


def _agree(r):
    o, s = r["ours"], r["sympy"]
    parts = []
    if o.get("available"):
        parts.append("dims" if list(o["dims"]) == list(s["dims"]) else
                     ("dim" if o["dim"] == s["dim"] else "NO (ours vs sympy)"))
    else:
        parts.append("sympy only")
    sp_res = r.get("strikepy")
    if sp_res and sp_res.get("finished") and sp_res["parsed"]["rank"] is not None:
        parts.append("StrikePy yes" if sp_res["parsed"]["rank"] == s["dim"] else "StrikePy NO")
    return ", ".join(parts)


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------

def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=None, help="markdown report to write")
    ap.add_argument("--json", type=Path, default=None, help="raw results to write")
    ap.add_argument("--models", nargs="*", default=None,
                    help="zoo specs to run (default: every ORC model, then single_ui)")
    ap.add_argument("--no-strikepy", action="store_true")
    ap.add_argument("--no-single-ui", action="store_true")
    ap.add_argument("--strikepy-timeout", type=float, default=120.0)
    ap.add_argument("--long", type=float, default=30.0,
                    help="peer runs longer than this (s) are repeated within --budget")
    ap.add_argument("--budget", type=float, default=90.0)
    ap.add_argument("--from-json", type=Path, default=None,
                    help="only re-render the report from a --json file of an earlier run")
    args = ap.parse_args(argv)
    if args.from_json:
        saved = json.loads(args.from_json.read_text())
        text = render(saved["results"], saved["meta"])
        print(text)
        if args.out:
            args.out.write_text(text)
        return 0

    import jax
    import jax.numpy as jnp

    with jax.enable_x64(True):  # start the backend before any measured call
        jax.jit(lambda x: x + 1)(jnp.ones(3)).block_until_ready()

    specs = args.models
    if specs is None:
        specs = ORC_MODELS + ([] if args.no_single_ui else SINGLE_UI_MODELS)
    meta = {"command": "python scripts/bench_analysis.py " + " ".join(argv or sys.argv[1:]),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "git": _git(), "machine": _machine(), "versions": _versions(),
            "repeats": args.repeats, "strikepy_timeout": args.strikepy_timeout,
            "long": args.long, "budget": args.budget, "load_start": os.getloadavg()[0]}
    import _sympy_models

    results = []
    for spec in specs:
        method = "single_ui" if spec in SINGLE_UI_MODELS else "orc"
        print(f"== {spec} ({method})", flush=True)
        r = {"spec": spec, "method": method, "n": _sympy_models.get(spec).n}
        r["ours"] = bench_ours(spec, method, args.repeats)
        if r["ours"].get("available"):
            print(f"  ours: dims {r['ours']['dims']} warm {r['ours']['warm_s'] * 1e3:.1f} ms "
                  f"compile {r['ours']['compile_s']:.2f} s", flush=True)
        r["sympy"] = bench_sympy(spec, method, args.repeats, args.long, args.budget)
        print(f"  sympy: dims {r['sympy']['dims']} median {r['sympy']['median_s']:.2f} s "
              f"({len(r['sympy']['runs'])} runs)", flush=True)
        if method == "orc" and not args.no_strikepy:
            r["strikepy"] = bench_strikepy(spec, args.repeats, args.strikepy_timeout,
                                           args.long, args.budget)
            print(f"  StrikePy: {_strikepy_verdict(r['strikepy'])}, median "
                  f"{r['strikepy']['median_s']:.2f} s", flush=True)
        r["agree"] = _agree(r)
        print(f"  agree: {r['agree']}", flush=True)
        results.append(r)
    meta["load_end"] = os.getloadavg()[0]
    text = render(results, meta)
    print()
    print(text)
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    if args.json:
        args.json.write_text(json.dumps({"meta": meta, "results": results}, indent=1,
                                        default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
