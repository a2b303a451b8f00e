"""Every model shipped with StrikePy 1.0, imported and analysed by uio_jax, compared with StrikePy.

For each ``StrikePy/models/*.py`` of the installed package (files named ``uj_*.py``, written
by an old benchmark of ours, and ``__init__.py`` excluded), in ONE run:

* **StrikePy** (``pip install strikepy==1.0``): the installed ``StrikePy`` package directory is
  copied to a temporary directory (nothing is written into site-packages); an options module
  ``custom_options/options_<model>.py`` is written there with ``checkObser = 1``,
  ``maxLietime = inf``, ``nnzDerU = [inf] * max(1, len(u))``, ``nnzDerW = [inf] * max(1, len(w))``
  and ``prev_ident_pars = []``; ``strike_goldd('options_<model>')`` runs in a subprocess with
  ``PYTHONPATH`` and the working directory set to the copy, under a time limit
  (``--timeout``, default 120 s). Time is measured inside the subprocess around the call
  (imports excluded). Its printed verdict (observable / unobservable / directly measured
  states, identifiable / unidentifiable parameters, observable unknown inputs, FISPO, rank)
  and the raw tail of its output are cached per model in ``docs/benchmarks/strikepy_runs.json``
  with the machine, the load and the StrikePy version. ``--rerun`` refreshes the cache.
* **ours**: ``uio_jax._io.strikepy_import.load_strikepy(path)``, then
  ``uj.analyze(system, method="auto", samples=4096)``. *cold* = the first call on the freshly
  loaded ``System`` (JIT compilation included; the JAX backend is started once beforehand, so
  its start-up is not in any model's time; the process is shared by all models);
  *warm* = median of 3 further calls on the same ``System`` object (they reuse its cached
  compiled functions).
* **compare**: for a model with known inputs only, every state and parameter verdict of ours
  against StrikePy's (where StrikePy finished); inputs that our importer promoted to states are
  compared too where StrikePy reports them. Unknown-input models are compared for information
  only: the two tools give "unknown input" different meanings (see the generated document).

Writes ``docs/benchmarks/strikepy.md``. Exit code 1 when a known-input-only model disagrees
where StrikePy finished.

Usage (from the repository root)::

    python scripts/compare_strikepy.py --rerun            # everything, StrikePy re-run
    python scripts/compare_strikepy.py --models C2M CR    # a subset (StrikePy from the cache)
    python scripts/compare_strikepy.py --strikepy-only    # only fill the StrikePy cache
    python scripts/compare_strikepy.py --rerun --cpu-limit --oracle   # the published document

``--cpu-limit`` applies the StrikePy limit to CPU time instead of wall time (fair on a shared
machine); ``--oracle`` also runs the sympy oracle of ``tests/test_strikepy_oracle.py`` on every
known-input model; ``--render-only`` re-renders the document from the raw results of the last
run (``--raw``), e.g. after editing ``EXPLANATIONS``.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.metadata as md
import importlib.util
import json
import os
import platform
import re
import resource
import runpy
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CACHE = ROOT / "docs" / "benchmarks" / "strikepy_runs.json"
OUT = ROOT / "docs" / "benchmarks" / "strikepy.md"
SAMPLES = 4096
WARM = 3
TAIL_CHARS = 4000

# The options module written for every model (StrikePy reads it with importlib from
# StrikePy/custom_options/). ``inf`` for a known input: every derivative of u is a free
# symbol (arbitrary smooth known input); for an unknown input: w and all its derivatives
# become extra states of the extended system (STRIKE-GOLDD's "nnzDerW = inf").
_OPTIONS = """\
# Written by uio_jax scripts/compare_strikepy.py for the shipped model {model}
from math import inf
modelname = {model!r}
checkObser = 1
maxLietime = inf
nnzDerU = [inf] * {nu}
nnzDerW = [inf] * {nw}
prev_ident_pars = []
"""

# Why a model's verdicts differ (or cannot be compared), written after investigating each case
# by hand (an independent sympy rank on the joint [x; p] system, the model's symmetries). The
# code is never adjusted to match StrikePy; these notes are printed next to the table.
EXPLANATIONS: dict[str, str] = {
    "MAPK": (
        "the shipped file creates the Michaelis constants with `KK1, KK2 = sym.symbols('n1 n2')`, so they ARE the "
        "Hill exponents `n1, n2` (same sympy symbols) and `p` lists `n1` and `n2` twice: 12 distinct unknowns, "
        "not 14. Our importer keeps each symbol once (System note) and finds all 3 + 12 = 15 coordinates "
        "observable. StrikePy appends both copies as columns of its matrix; removing one of two equal columns "
        "never lowers the rank, so StrikePy would call `n1` and `n2` unidentifiable whatever the model. Checked "
        "on a toy: C2M_2outputs (FISPO) with `x6` listed twice in `p` makes StrikePy 1.0 print `x6` "
        "unidentifiable (twice) and the model not FISPO. Where StrikePy finishes on MAPK, `n1`, `n2` are "
        "therefore expected to differ for this reason alone."
    ),
}

_RUNNER = r"""
import json, sys, time
from StrikePy.strike_goldd import strike_goldd
c0, t0 = time.process_time(), time.perf_counter()
strike_goldd(sys.argv[1])
print("UJ_TIMING " + json.dumps({"wall_s": time.perf_counter() - t0,
                                 "cpu_s": time.process_time() - c0}))
"""


# --------------------------------------------------------------------------------------
# Models
# --------------------------------------------------------------------------------------

def _strikepy_dir():
    """The installed ``StrikePy`` package directory, or ``None`` (the package is not imported)."""
    spec = importlib.util.find_spec("StrikePy")
    return None if spec is None or spec.origin is None else Path(spec.origin).parent


def _shipped_models(sp_dir):
    """Names of the models shipped with StrikePy (``uj_*`` and ``__init__`` excluded), sorted."""
    return sorted(p.stem for p in (sp_dir / "models").glob("*.py")
                  if p.name != "__init__.py" and not p.name.startswith("uj_"))


def _names(seq):
    """Flatten a StrikePy list (``[a, b]`` or ``[[a], [b]]`` or a numpy column) into names."""
    out = []
    for item in list(seq) if seq is not None else []:
        if isinstance(item, (list, tuple)) or hasattr(item, "tolist") and not hasattr(item, "free_symbols"):
            out.extend(_names(list(item)))
        else:
            out.append(str(item))
    return out


def _declared(path):
    """What the model module declares (evaluated with sympy: a trusted package file)."""
    ns = runpy.run_path(str(path))
    return {"x": _names(ns.get("x")), "p": _names(ns.get("p")), "u": _names(ns.get("u", [])),
            "w": _names(ns.get("w", [])), "h": [str(e) for e in _names(ns.get("h"))]}


# --------------------------------------------------------------------------------------
# StrikePy
# --------------------------------------------------------------------------------------

def _copy_strikepy(sp_dir, tmp):
    """Copy the installed package into ``tmp/StrikePy`` (caches and old results left out)."""
    dst = Path(tmp) / "StrikePy"
    shutil.copytree(sp_dir, dst, ignore=shutil.ignore_patterns("__pycache__", "results", "uj_*.py",
                                                               "options_uj_*.py"))
    return dst


def _options_text(model, decl):
    return _OPTIONS.format(model=model, nu=max(1, len(decl["u"])), nw=max(1, len(decl["w"])))


def _parse_list(text, header):
    """The bracketed list printed on the line after ``header`` (``None`` when absent)."""
    m = re.search(re.escape(header) + r"[^\n]*:\s*\n\s*\[(.*?)\]\s*\n", text)
    if m is None:
        return None
    body = m.group(1).replace("[", " ").replace("]", " ")
    return [s.strip() for s in body.split(",") if s.strip()]


def _parse_strikepy(text, decl):
    """StrikePy's verdicts from its printed output.

    Returns states / params / inputs: name -> True (observable, identifiable), False
    (unobservable, unidentifiable) or None (StrikePy printed no decision); plus rank, the
    number of Lie derivatives, FISPO.
    """
    ranks = re.findall(r"Rank = (\d+)", text)
    nlie = re.findall(r"matrix built with (\d+) Lie derivatives", text)
    fispo = "Fully Input-State-Parameter Observable" in text
    obs = _parse_list(text, ">>> These states are observable") or []
    unobs = _parse_list(text, ">>> These states are unobservable") or []
    meas = _parse_list(text, ">>> These states are directly measured") or []
    pid = _parse_list(text, ">>> These parameters are identifiable") or []
    pun = _parse_list(text, ">>> These parameters are unidentifiable") or []
    win = _parse_list(text, ">>> These unmeasured inputs are observable") or []
    wun = _parse_list(text, ">>> These unmeasured inputs are unobservable") or []
    all_id = fispo or "The model is structurally identifiable" in text

    def verdict(name, yes, no, every):
        if every or name in yes:
            return True
        return False if name in no else None

    # Unknown-input derivatives (w_d1, ...) are states of StrikePy's extended system: kept apart.
    w_all = sorted(set(win) | set(wun) | set(decl["w"]))
    return {
        "rank": int(ranks[-1]) if ranks else None,
        "n_lie": int(nlie[-1]) if nlie else None,
        "fispo": fispo,
        "states": {x: verdict(x, set(obs) | set(meas), unobs, fispo) for x in decl["x"]},
        "measured": meas,
        "params": {p: verdict(p, pid, pun, all_id) for p in decl["p"]},
        "inputs": {w: verdict(w, win, wun, fispo and w in decl["w"]) for w in w_all},
    }


def _parse_partial(text):
    """Decisions StrikePy printed before it was stopped.

    Only the positive ones are final (a column whose removal lowers the rank keeps doing so when
    rows are added); "cannot decide at the moment" is not a verdict.
    """
    def names(kind, verdict):
        pat = rf"=> {kind} \[?([^\]\s]+)\]? is {verdict}\n"
        return sorted(set(re.findall(pat, text)))

    return {"rank": [int(r) for r in re.findall(r"Rank = (\d+)", text)],
            "identifiable": names("Parameter", "structurally identifiable"),
            "observable": names("State", "observable"),
            "inputs_observable": names("Input", "observable")}


def _child_cpu():
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def run_strikepy(sp_copy, model, decl, timeout_s, cpu_limit=False):
    """One StrikePy run of ``model`` in a subprocess; the cache record.

    The limit is ``timeout_s`` seconds of wall time, or with ``cpu_limit`` of CPU time
    (``RLIMIT_CPU`` in the subprocess; wall limit then 4 x ``timeout_s``), which does not
    depend on how busy the machine is.
    """
    opts = sp_copy / "custom_options" / f"options_{model}.py"
    opts.write_text(_options_text(model, decl))
    env = dict(os.environ, PYTHONPATH=str(sp_copy.parent), PYTHONHASHSEED="0", PYTHONDONTWRITEBYTECODE="1",
               PYTHONUNBUFFERED="1")
    rec = {"model": model, "date": _now(), "load_before": os.getloadavg(), "timeout_s": timeout_s,
           "limit": "cpu" if cpu_limit else "wall", "options": opts.read_text(),
           "strikepy": _version("strikepy"), "machine": _machine()}

    def limit_cpu():
        lim = int(timeout_s) + 1
        resource.setrlimit(resource.RLIMIT_CPU, (lim, lim + 5))

    cpu0, t0 = _child_cpu(), time.perf_counter()
    try:
        proc = subprocess.run([sys.executable, "-c", _RUNNER, f"options_{model}"], capture_output=True,
                              text=True, timeout=timeout_s * (4 if cpu_limit else 1), cwd=str(sp_copy.parent),
                              env=env, preexec_fn=limit_cpu if cpu_limit else None)
    except subprocess.TimeoutExpired as e:
        out = e.stdout.decode(errors="replace") if isinstance(e.stdout, bytes) else (e.stdout or "")
        rec.update(finished=False, timeout=True, subprocess_s=time.perf_counter() - t0,
                   subprocess_cpu_s=_child_cpu() - cpu0, load_after=os.getloadavg(), tail=out[-TAIL_CHARS:],
                   partial=_parse_partial(out))
        return rec
    rec.update(subprocess_s=time.perf_counter() - t0, subprocess_cpu_s=_child_cpu() - cpu0,
               load_after=os.getloadavg(), tail=(proc.stdout + proc.stderr)[-TAIL_CHARS:],
               returncode=proc.returncode)
    m = re.search(r"UJ_TIMING (\{.*\})", proc.stdout)
    if cpu_limit and proc.returncode in (-signal.SIGXCPU, -signal.SIGKILL) and m is None:
        rec.update(finished=False, timeout=True, partial=_parse_partial(proc.stdout))
        return rec
    if proc.returncode != 0 or m is None:
        rec.update(finished=False, timeout=False, error=(proc.stderr or proc.stdout)[-1500:])
        return rec
    rec.update(json.loads(m.group(1)), finished=True, timeout=False, parsed=_parse_strikepy(proc.stdout, decl))
    return rec


def strikepy_all(models, decls, sp_dir, cache, rerun, timeout_s, log, cpu_limit=False):
    """StrikePy records for ``models``: from the cache, or run now (sequentially)."""
    todo = [m for m in models if rerun or m not in cache]
    if todo:
        with tempfile.TemporaryDirectory(prefix="uj_strikepy_") as tmp:
            sp_copy = _copy_strikepy(sp_dir, tmp)
            for m in todo:
                log(f"StrikePy {m} ...")
                cache[m] = run_strikepy(sp_copy, m, decls[m], timeout_s, cpu_limit)
                r = cache[m]
                log(f"  {'finished' if r['finished'] else 'TIMEOUT' if r.get('timeout') else 'FAILED'} "
                    f"{r.get('wall_s', r['subprocess_s']):.2f} s, load {r['load_before'][0]:.2f}")
                _save_cache(cache)
    return {m: cache[m] for m in models}


# --------------------------------------------------------------------------------------
# Ours
# --------------------------------------------------------------------------------------

def _warm_up_jax():
    """Start the JAX backend once so that no model's cold time includes it."""
    import jax
    import jax.numpy as jnp

    with jax.enable_x64(True):
        jnp.linalg.svd(jnp.eye(3) + 1.0)[1].block_until_ready()


def _timed(fn):
    load = os.getloadavg()[0]
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return out, {"wall_s": time.perf_counter() - t0, "cpu_s": time.process_time() - c0, "load1": load}


def _ours_worker(path, samples, warm, method="auto"):
    """In the worker process: import ``path`` with the project's importer and analyse it (cold + warm)."""
    import uio_jax as uj
    from uio_jax._io.strikepy_import import load_strikepy

    _warm_up_jax()
    rec = {"load_before": os.getloadavg()}
    try:
        system, t_load = _timed(lambda: load_strikepy(str(path)))
        rep, cold = _timed(lambda: uj.analyze(system, samples=samples, method=method))
        warms = [_timed(lambda: uj.analyze(system, samples=samples, method=method))[1] for _ in range(warm)]
    except Exception as e:  # recorded in the table: a failure is a result too
        rec.update(ok=False, error=f"{type(e).__name__}: {e}")
        return rec
    cert = rep.certificate
    rec.update(
        ok=True, load=t_load, cold=cold, warm=warms, warm_s=statistics.median(w["wall_s"] for w in warms),
        method=rep.method, dim=rep.dim, n=rep.n, states=list(rep.states), params=list(rep.params),
        known=list(system.known), unknown=list(system.unknown), notes=list(system.notes),
        observable={k: bool(v) for k, v in rep.observable.items()},
        identifiable={k: bool(v) for k, v in rep.identifiable.items()},
        fraction=getattr(cert, "fraction", None), load_after=os.getloadavg(),
    )
    return rec


def run_ours(path, samples, warm, timeout_s, method="auto"):
    """Our analysis of ``path`` in a fresh process (``--ours-worker``), under a wall-time limit."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--ours-worker", str(path), "--samples", str(samples),
           "--method", method]
    load = os.getloadavg()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, cwd=str(ROOT),
                              env=dict(os.environ, PYTHONUNBUFFERED="1"))
    except subprocess.TimeoutExpired:
        return {"ok": False, "timeout": True, "error": f"no result within {timeout_s:.0f} s", "load_before": load}
    m = re.search(r"^UJ_OURS (\{.*\})$", proc.stdout, re.M)
    if m is None:
        return {"ok": False, "error": (proc.stderr or proc.stdout)[-800:], "load_before": load}
    return json.loads(m.group(1))


# --------------------------------------------------------------------------------------
# Independent sympy oracle (the one of tests/test_strikepy_oracle.py)
# --------------------------------------------------------------------------------------

ORACLE_FILE = ROOT / "tests" / "test_strikepy_oracle.py"


def _oracle_worker(path):
    """In the worker process: the Hermann-Krener sympy oracle of the test suite on ``path``."""
    spec = importlib.util.spec_from_file_location("_strikepy_oracle", ORACLE_FILE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    t0 = time.perf_counter()
    try:
        obs, ident, dim = mod.hk_oracle(mod._read_model(Path(path)))
    except AssertionError as e:  # e.g. an input that does not enter affinely
        return {"ok": False, "error": f"not applicable: {e}"}
    return {"ok": True, "observable": obs, "identifiable": ident, "dim": dim, "wall_s": time.perf_counter() - t0}


def run_oracle(path, timeout_s):
    """The sympy oracle on ``path`` in a fresh process, under a wall-time limit."""
    cmd = [sys.executable, str(Path(__file__).resolve()), "--oracle-worker", str(path)]
    load = os.getloadavg()[0]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s, cwd=str(ROOT))
    except subprocess.TimeoutExpired:
        return {"ok": False, "timeout": True, "error": f"no result within {timeout_s:.0f} s", "load1": load}
    m = re.search(r"^UJ_ORACLE (\{.*\})$", proc.stdout, re.M)
    if m is None:
        return {"ok": False, "error": (proc.stderr or proc.stdout)[-500:], "load1": load}
    return dict(json.loads(m.group(1)), load1=load)


def _oracle_agrees(ours, orc):
    """'yes', 'no: names', or why there is no comparison."""
    if orc is None:
        return "not run"
    if not orc.get("ok"):
        return "timed out" if orc.get("timeout") else orc.get("error", "failed")[:80]
    if not ours.get("ok"):
        return "ours failed"
    diff = [k for k, v in orc["observable"].items() if ours["observable"].get(k) != v]
    diff += [k for k, v in orc["identifiable"].items() if ours["identifiable"].get(k) != v]
    return "yes" if not diff else "no: " + ", ".join(diff)


# --------------------------------------------------------------------------------------
# Comparison
# --------------------------------------------------------------------------------------

def compare(decl, ours, sp):
    """Per-name comparison. Returns (status, differing names, compared count)."""
    if not ours.get("ok"):
        return "ours failed", [], 0
    if not sp.get("finished"):
        return ("StrikePy timed out" if sp.get("timeout") else "StrikePy failed"), [], 0
    p = sp["parsed"]
    pairs = []
    for x, v in p["states"].items():
        if x in ours["observable"]:
            pairs.append((x, ours["observable"][x], v))
        elif x in ours["identifiable"]:  # the importer may have moved a name
            pairs.append((x, ours["identifiable"][x], v))
        else:
            pairs.append((x, None, v))
    for q, v in p["params"].items():
        mine = ours["identifiable"].get(q, ours["observable"].get(q))
        pairs.append((q, mine, v))
    for w, v in p["inputs"].items():  # promoted inputs (states of ours) where StrikePy reports them
        if w in ours["observable"] and v is not None:
            pairs.append((w, ours["observable"][w], v))
    diff = [name for name, a, b in pairs if a is None or b is None or a != b]
    return ("yes" if not diff else "no"), diff, len(pairs)


# --------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------

def _now():
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")


def _version(pkg):
    try:
        return md.version(pkg)
    except md.PackageNotFoundError:
        return "not installed"


def _machine():
    cpu = platform.processor() or "?"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
        m = re.search(r"Model name:\s*(.+)", out)
        cpu = m.group(1).strip() if m else cpu
    except (OSError, subprocess.SubprocessError):
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(), "platform": platform.platform()}


def _git():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              cwd=ROOT, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "?"


def _load_cache():
    if CACHE.exists():
        return json.loads(CACHE.read_text())
    return {}


def _save_cache(cache):
    CACHE.parent.mkdir(parents=True, exist_ok=True)
    CACHE.write_text(json.dumps(dict(sorted(cache.items())), indent=1, sort_keys=True) + "\n")


def _fmt(x, digits=3):
    if x is None or x != x:
        return "—"
    return f"{x:.{digits}g}" if abs(x) < 1000 else f"{x:.0f}"


def _is_known_only(decl):
    return not decl["w"]


def _row(model, decl, ours, sp, cmp, oracle=None):
    status, diff, _ = cmp
    sp_time = sp.get("wall_s") if sp.get("finished") else None
    if sp.get("finished"):
        sp_cell = _fmt(sp_time)
        rank = str(sp["parsed"]["rank"])
    elif sp.get("timeout"):
        cpu = sp.get("subprocess_cpu_s")
        sp_cell = f"> {sp['timeout_s']:.0f} {'CPU ' if sp.get('limit') == 'cpu' else ''}(timeout" + (
            f"; {cpu:.0f} CPU s)" if cpu is not None and sp.get("limit") != "cpu" else ")")
        rank = "—"
    else:
        sp_cell, rank = "failed", "—"
    if status == "no":
        agree = "**no**: " + ", ".join(diff)
    elif status == "yes":
        agree = "yes"
    else:
        agree = status
    if not _is_known_only(decl) and status in ("yes", "no"):
        agree += " (UI: information)"
    if oracle is not None and status not in ("yes", "no"):
        agree += f"; sympy oracle agrees: {_oracle_agrees(ours, oracle)}"
    inputs = f"{len(decl['u'])} / {len(decl['w'])}"
    n_p = len(decl["p"])
    n_p = f"{n_p} ({len(set(decl['p']))} distinct)" if len(set(decl["p"])) != n_p else str(n_p)
    if ours.get("ok"):
        method, dim = ours["method"], f"{ours['dim']}/{ours['n']}"
        cold, warm = ours["cold"]["wall_s"], ours["warm_s"]
        ratio = _fmt(sp_time / warm) if sp_time and warm else "—"
        loads = [ours["cold"]["load1"], *(w["load1"] for w in ours["warm"]), sp["load_before"][0]]
        load = _fmt(statistics.mean(loads), 2)
    else:
        method, dim, cold, warm, ratio = "failed", "—", None, None, "—"
        load = _fmt(sp["load_before"][0], 2)
    return (f"| {model} | {len(decl['x'])} | {n_p} | {inputs} | {method} | {dim} | {rank} | {agree} | "
            f"{_fmt(cold)} | {_fmt(warm)} | {sp_cell} | {ratio} | {load} |")


def _semantics():
    return textwrap.dedent("""\
        ## What "unknown input" means in each tool

        - **StrikePy with `nnzDerW = inf`** (used here): an unknown input `w` and all its time
          derivatives `w, w', ..., w^(k)` are appended to the state as unknown constants of the
          extended system (`w^(i)' = w^(i+1)`, the last one left free); the verdict is the rank test
          on `[x; p; w; w'; ...]` with as many Lie derivatives as StrikePy decides to compute. This is
          the extended system of Martinelli's RR-8608 (004, sections 4-6), i.e. our **EORC**: a
          *sufficient* condition (a state observable for the extended system is observable; the
          converse need not hold).
        - **Ours, `single_ui`** (one unknown input, no drift): Martinelli's analytic observable
          codistribution: the exact answer for a smooth (analytic) disturbance of unknown shape.
        - **Ours, `eorc`** (several unknown inputs, or a drift, as in every unknown-input model shipped
          with StrikePy): the same extended-system construction as StrikePy's `nnzDerW = inf`, up to
          order `k_max = n + 2`.
        - **StrikePy with a finite `nnzDerW = d`**: `w` is a polynomial in time of degree `d - 1`
          (derivatives above `d - 1` set to zero): a smaller class of inputs, hence possibly more
          observable than either answer above. Not used here.
        - **Known inputs, `nnzDerU = inf`** (used here): every derivative of `u` is a free symbol, i.e.
          arbitrary smooth known inputs, which is what our ORC (Hermann-Krener codistribution with the
          input fields, inputs freely chosen) answers. A finite `nnzDerU = d` would restrict the
          experiment to polynomial inputs of degree `d - 1` (`nnzDerU = 0`: a constant input).
        """)


def _shipped_options_note(sp_dir):
    """Where the options files shipped with StrikePy differ from ours."""
    rows = []
    for f in sorted((sp_dir / "custom_options").glob("options_*.py")):
        if f.name.startswith("options_uj_"):
            continue
        txt = f.read_text()
        vals = {}
        for key in ("maxLietime", "nnzDerU", "nnzDerW"):
            m = re.search(rf"^{key}\s*=\s*([^#\n]+)", txt, re.M)
            vals[key] = m.group(1).strip() if m else "?"
        differs = [f"`{k} = {v}`" for k, v in vals.items() if "inf" not in v or k == "maxLietime" and v != "inf"]
        if differs:
            rows.append(f"`{f.stem}`: " + ", ".join(differs))
    return rows


def render(models, decls, ours, sps, cmps, meta, sp_dir, oracles=None):
    """The Markdown document."""
    lines = ["# StrikePy's shipped models: uio_jax vs StrikePy 1.0", ""]
    lines += [f"Generated by `{meta['command']}` on {meta['date']} (git {meta['git']}).", ""]
    m = meta["machine"]
    lines += ["## Machine and versions", "",
              f"- CPU: {m['cpu']}, {m['cores']} cores ({m['platform']}), Python {m['python']}; "
              "the machine is shared with other jobs (see the load column).",
              "- " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()),
              f"- load average (1, 5, 15 min) at start / end: {_load3(meta['load_start'])} / "
              f"{_load3(meta['load_end'])}", ""]
    dates = sorted({sps[k]["date"] for k in models})
    lines += ["## What is measured", "",
              f"- **StrikePy** 1.0: the installed package copied to a temporary directory, one options "
              f"module per model (below), `strike_goldd('options_<model>')` in a subprocess with "
              f"`PYTHONPATH` and cwd in the copy, limit {meta['timeout']:.0f} s of "
              + ("CPU time (`RLIMIT_CPU` in the subprocess, so that the limit does not depend on the other jobs "
                 "of the shared machine; wall time allowed up to 4x that)" if _limit(models, sps) == "cpu"
                 else "wall time") +
              "; time measured inside the subprocess around the call (imports excluded). StrikePy runs dated "
              + (dates[0] if len(dates) == 1 else f"{dates[0]} to {dates[-1]}") +
              (" (this run)." if meta["rerun"] else " (from the cache `strikepy_runs.json`; "
               "`--rerun` to measure them in the same run)."),
              f"- **ours**: `load_strikepy(path)` then `uj.analyze(system, method=\"{meta.get('method', 'auto')}\", "
              f"samples={meta.get('samples', SAMPLES)})`, "
              "each model in a fresh Python process (limit "
              f"{meta['ours_timeout']:.0f} s). *cold* = the first call on the freshly loaded `System`: tracing "
              "and XLA compilation included (JAX's persistent compilation cache is off; the JAX backend is "
              "started in that process before the clock starts); *warm* = median of "
              f"{WARM} further calls on the same `System` (its compiled functions are cached).",
              "- *ratio* = StrikePy time / our warm time; *load* = mean 1-minute load average over the "
              "model's measurements (2 cores: above 2, measurements waited for a core).",
              "- *agree*: every state and parameter verdict of ours equals StrikePy's (observable / "
              "identifiable, or not). Inputs our importer promoted to states are compared too where "
              "StrikePy reports them (it never reports known inputs).", ""]
    lines += ["## Options written for every model", "", "```python",
              _OPTIONS.format(model="<model>", nu="max(1, len(u))", nw="max(1, len(w))").rstrip(), "```", "",
              "`maxLietime = inf`: no time limit per Lie derivative (so StrikePy never stops undecided "
              "for that reason; the subprocess limit applies instead). The options files shipped with "
              "StrikePy use other values for:", ""]
    lines += [f"- {r}" for r in _shipped_options_note(sp_dir)] + [""]
    lines += [_semantics()]

    known = [k for k in models if _is_known_only(decls[k])]
    ui = [k for k in models if not _is_known_only(decls[k])]
    bad = [k for k in known if cmps[k][0] == "no"]
    timed = [k for k in models if not sps[k].get("finished")]
    fin = [k for k in known if sps[k].get("finished")]
    lines += ["## Summary", "",
              f"- {len(models)} models: {len(known)} with known inputs only, {len(ui)} with unknown inputs.",
              f"- Known inputs only: StrikePy finished on {len(fin)}; ours "
              + ("agrees on every state and parameter of all of them." if not bad and all(
                  cmps[k][0] == "yes" for k in fin) else
                  "DISAGREES on " + ", ".join(bad) + " (explained below).") ,
              "- StrikePy did not finish (time limit or error) on: " + (", ".join(timed) or "none") + ".",
              _totals(models, ours, sps), ""]
    head = ("| model | n states | n params | inputs (known / unknown) | our method | ours dim/n | StrikePy rank | "
            "agree | ours cold (s) | ours warm (s) | StrikePy (s) | StrikePy/ours warm | load |")
    sep = "|" + "---|" * 13
    lines += ["## Known inputs only", "", head, sep]
    lines += [_row(k, decls[k], ours[k], sps[k], cmps[k], (oracles or {}).get(k)) for k in known] + [""]
    if oracles:
        lines += ["### Independent check: the sympy oracle of `tests/test_strikepy_oracle.py`", "",
                  "Hermann-Krener codistribution of the joint system `[x; p]` (Lie derivatives of `h` along "
                  "the drift and the input fields, level after level until the rank stops growing), exact "
                  "ranks at random rational points for polynomial models, 50-digit SVD otherwise; "
                  f"each model in a fresh process, limit {meta['oracle_timeout']:.0f} s.", "",
                  "| model | oracle dim | ours dim | ours = oracle (every state and parameter) | oracle (s) | load |",
                  "|---|---|---|---|---|---|"]
        for k in known:
            o = oracles.get(k)
            if o is None:
                continue
            lines.append(f"| {k} | {o.get('dim', '—')} | {ours[k].get('dim', '—')} | {_oracle_agrees(ours[k], o)} | "
                         f"{_fmt(o.get('wall_s'))} | {_fmt(o.get('load1'), 2)} |")
        lines.append("")
    if ui:
        lines += ["## Unknown inputs (compared for information: see the semantics above)", "", head, sep]
        lines += [_row(k, decls[k], ours[k], sps[k], cmps[k]) for k in ui] + [""]
    lines += ["## Disagreements and notes", ""]
    noted = [k for k in models if k in EXPLANATIONS or cmps[k][0] == "no"]
    for k in noted:
        text = EXPLANATIONS.get(k, "NOT YET EXPLAINED.")
        lines += [f"- **{k}** ({'agree: ' + cmps[k][0]}): {text}"]
    lines += ([] if noted else ["none"]) + [""]
    lines += ["## Per model", ""]
    for k in models:
        lines += _details(k, decls[k], ours[k], sps[k], cmps[k])
    return "\n".join(lines)


def _limit(models, sps):
    kinds = {sps[k].get("limit", "wall") for k in models}
    return kinds.pop() if len(kinds) == 1 else "mixed (see strikepy_runs.json)"


def _load3(t):
    return ", ".join(f"{v:.2f}" for v in t)


def _totals(models, ours, sps):
    sp_fin = sum(sps[k]["wall_s"] for k in models if sps[k].get("finished"))
    n_to = sum(1 for k in models if sps[k].get("timeout"))
    ok = [k for k in models if ours[k].get("ok")]
    cold = sum(ours[k]["cold"]["wall_s"] for k in ok)
    warm = sum(ours[k]["warm_s"] for k in ok)
    return (f"- Totals: StrikePy {sp_fin:.1f} s on the models it finished"
            + (f" (+ {n_to} time-outs)" if n_to else "")
            + f"; ours cold {cold:.1f} s, warm {warm:.2f} s over {len(ok)} models.")


def _vd(v):
    return {True: "yes", False: "no", None: "?"}[v]


def _partial_lines(part, ours):
    """What StrikePy had decided before its limit (positive decisions only: final) vs ours."""
    if not part:
        return []
    out = []
    if part["rank"]:
        out.append(f"  - ranks printed before the limit: {part['rank']}")
    for key, label, mine in (("identifiable", "parameters identifiable", "identifiable"),
                             ("observable", "states observable", "observable"),
                             ("inputs_observable", "unknown inputs observable", None)):
        names = part.get(key) or []
        if not names:
            continue
        line = f"  - decided before the limit, {label}: {', '.join(names)}"
        if mine and ours.get("ok"):
            bad = [q for q in names if not ours[mine].get(q, ours["observable"].get(q, False))]
            line += "; ours agrees" if not bad else f"; ours DIFFERS on {', '.join(bad)}"
        out.append(line)
    return out


def _details(model, decl, ours, sp, cmp):
    out = [f"### {model}", ""]
    out.append(f"- declared: x = {decl['x']}, p = {decl['p']}, u = {decl['u']}, w = {decl['w']}, h = {decl['h']}")
    if ours.get("ok"):
        out.append(f"- ours: method {ours['method']}, dim {ours['dim']}/{ours['n']}, known {ours['known']}, "
                   f"unknown {ours['unknown']}; cold {_fmt(ours['cold']['wall_s'])} s (load "
                   f"{ours['cold']['load1']:.2f}), warm " + ", ".join(
                       f"{w['wall_s']:.3g} s" for w in ours["warm"]))
        for note in ours["notes"]:
            out.append(f"  - importer note: {note}")
        unobs = [s for s, v in ours["observable"].items() if not v]
        unid = [q for q, v in ours["identifiable"].items() if not v]
        if ours["method"] == "eorc":
            out.append(f"  - ours (EORC, sufficient only) not shown observable: {unobs or 'none'}; "
                       f"not shown identifiable: {unid or 'none'}")
        else:
            out.append(f"  - ours unobservable: {unobs or 'none'}; unidentifiable: {unid or 'none'}")
    else:
        out.append(f"- ours FAILED: `{ours.get('error')}`")
    if sp.get("finished"):
        p = sp["parsed"]
        out.append(f"- StrikePy: {sp['wall_s']:.3g} s (load {sp['load_before'][0]:.2f}), rank {p['rank']} with "
                   f"{p['n_lie']} Lie derivatives, FISPO {p['fispo']}")
        out.append("  - states: " + ", ".join(f"{x} {_vd(v)}" for x, v in p["states"].items()))
        out.append("  - params: " + (", ".join(f"{q} {_vd(v)}" for q, v in p["params"].items()) or "none"))
        if p["inputs"]:
            out.append("  - unknown inputs (and derivatives): " + ", ".join(
                f"{w} {_vd(v)}" for w, v in p["inputs"].items()))
    elif sp.get("timeout"):
        cpu = sp.get("subprocess_cpu_s")
        out.append(f"- StrikePy: no verdict within {sp['timeout_s']:.0f} s "
                   + ("of CPU time" if sp.get("limit") == "cpu" else "wall")
                   + (f" ({cpu:.0f} s of CPU time used)" if cpu is not None else "")
                   + f", load {sp['load_before'][0]:.2f}")
        out += _partial_lines(sp.get("partial"), ours)
    else:
        out.append(f"- StrikePy FAILED: `{(sp.get('error') or '').strip()[-300:]}`")
    status, diff, n = cmp
    out.append(f"- agree: {status}" + (f" ({n} verdicts compared)" if n else "")
               + (f"; differ: {diff}" if diff else ""))
    out.append("")
    return out


# --------------------------------------------------------------------------------------
# Main
# --------------------------------------------------------------------------------------

def main(argv=None):
    """Command line: see the module docstring."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="*", help="model names (default: every shipped model)")
    ap.add_argument("--rerun", action="store_true", help="re-run StrikePy even where cached")
    ap.add_argument("--timeout", type=float, default=120.0, help="StrikePy time limit per model (s)")
    ap.add_argument("--cpu-limit", action="store_true",
                    help="apply --timeout to StrikePy's CPU time (RLIMIT_CPU) instead of wall time")
    ap.add_argument("--samples", type=int, default=SAMPLES)
    ap.add_argument("--method", default="auto",
                    help="our method (default auto; 'fast' = the series test for known-input models)")
    ap.add_argument("--strikepy-only", action="store_true", help="only fill the StrikePy cache")
    ap.add_argument("--ours-timeout", type=float, default=900.0,
                    help="wall-time limit of our analysis of one model (s), compile included")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--ours-worker", help=argparse.SUPPRESS)
    ap.add_argument("--oracle", action="store_true",
                    help="also run the sympy oracle of tests/test_strikepy_oracle.py on the known-input models")
    ap.add_argument("--oracle-timeout", type=float, default=300.0)
    ap.add_argument("--oracle-worker", help=argparse.SUPPRESS)
    ap.add_argument("--raw", type=Path, default=Path(tempfile.gettempdir()) / "uj_compare_strikepy_raw.json",
                    help="where every result of this run is saved (for --render-only)")
    ap.add_argument("--render-only", action="store_true",
                    help="re-render the document from --raw (after editing the explanations); no run")
    args = ap.parse_args(argv)
    if args.oracle_worker:
        print("UJ_ORACLE " + json.dumps(_oracle_worker(args.oracle_worker)), flush=True)
        return 0
    if args.ours_worker:
        print("UJ_OURS " + json.dumps(_ours_worker(args.ours_worker, args.samples, WARM, args.method)), flush=True)
        return 0

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    sp_dir = _strikepy_dir()
    if sp_dir is None:
        log("StrikePy is not installed (pip install strikepy==1.0)")
        return 2
    shipped = _shipped_models(sp_dir)
    models = args.models or shipped
    unknown = [m for m in models if m not in shipped]
    if unknown:
        log(f"not a shipped model: {', '.join(unknown)}")
        return 2
    meta = {"command": "python scripts/compare_strikepy.py " + " ".join(argv if argv is not None else sys.argv[1:]),
            "date": _now(), "git": _git(), "machine": _machine(), "load_start": os.getloadavg(),
            "timeout": args.timeout, "rerun": args.rerun, "ours_timeout": args.ours_timeout,
            "method": args.method, "samples": args.samples,
            "cpu_limit": args.cpu_limit, "oracle_timeout": args.oracle_timeout,
            "versions": {k: _version(k) for k in ("uio_jax", "jax", "jaxlib", "numpy", "sympy", "strikepy",
                                                  "symbtools")}}
    decls = {m: _declared(sp_dir / "models" / f"{m}.py") for m in models}
    if args.render_only:
        raw = json.loads(args.raw.read_text())
        models = [m for m in raw["models"] if not args.models or m in args.models]
        cmps = {m: compare(decls[m], raw["ours"][m], raw["strikepy"][m]) for m in models}
        text = render(models, decls, raw["ours"], raw["strikepy"], cmps, raw["meta"], sp_dir, raw["oracles"])
        args.out.write_text(text + "\n")
        log(f"wrote {args.out} from {args.raw}")
        return 1 if any(_is_known_only(decls[m]) and cmps[m][0] == "no" for m in models) else 0
    cache = _load_cache()
    sps = strikepy_all(models, decls, sp_dir, cache, args.rerun, args.timeout, log, args.cpu_limit)
    if args.strikepy_only:
        return 0
    ours = {}
    for m in models:
        log(f"ours {m} ...")
        ours[m] = run_ours(sp_dir / "models" / f"{m}.py", args.samples, WARM, args.ours_timeout, args.method)
        o = ours[m]
        log(f"  {'ok' if o.get('ok') else 'FAILED ' + o.get('error', '')[:200]}"
            + (f" {o['method']} dim {o['dim']}/{o['n']} cold {o['cold']['wall_s']:.2f} s warm {o['warm_s']:.3f} s"
               if o.get("ok") else ""))
    oracles = {}
    if args.oracle:
        for m in models:
            if _is_known_only(decls[m]):
                log(f"sympy oracle {m} ...")
                oracles[m] = run_oracle(sp_dir / "models" / f"{m}.py", args.oracle_timeout)
                log(f"  {_oracle_agrees(ours[m], oracles[m])}")
    cmps = {m: compare(decls[m], ours[m], sps[m]) for m in models}
    meta["load_end"] = os.getloadavg()
    args.raw.write_text(json.dumps({"models": models, "meta": meta, "ours": ours, "strikepy": sps,
                                    "oracles": oracles}, indent=1))
    text = render(models, decls, ours, sps, cmps, meta, sp_dir, oracles)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text + "\n")
    log(f"wrote {args.out}")
    bad = [m for m in models if _is_known_only(decls[m]) and cmps[m][0] == "no"]
    for m in models:
        log(f"{m}: {cmps[m][0]}" + (f" {cmps[m][1]}" if cmps[m][1] else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
