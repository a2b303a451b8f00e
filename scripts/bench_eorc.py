"""Benchmark of the EORC (issue 4): the 3D vehicle in wind per order k, a sympy EORC beside
it, and the visual-inertial model.

Usage::

    python scripts/bench_eorc.py [--k-max 8] [--samples 4096] [--repeats 3] [--warm-k 6]
                                 [--sympy-limit 120] [--vi-k 3] [--out docs/benchmarks/eorc.md]

Per order k of one EORC run on ``vehicle_wind.py:wind_unknown`` (``Sigma^(k_max)``, built
once): trace size of the jitted gradient block of the order (jaxpr equations, counted
recursively), compile seconds (trace + lower + XLA compile, first call), warm seconds
(median of ``--repeats`` calls of the compiled block on the samples) and the rank work of
the order. Then the whole ``uj.analyze(..., k_max=k)`` warm (second and later calls of the
same System: every block cached), median of ``--repeats``, for ``k = k_max`` and each
``--warm-k`` (default 6; a smaller ``k_max`` is another extension, compiled once first).
The sympy EORC (exact Lie derivatives and gradients, the same pruning, ranks at one random
rational point) runs in a subprocess stopped after ``--sympy-limit`` seconds. ``os.getloadavg()`` is recorded with
every number: the machine is shared.
"""

import argparse
import multiprocessing as mp
import os
import statistics
import sys
import time

import jax

from uio_jax._analysis.rank import default_rtol

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "systems"))


def _load():
    return os.getloadavg()[0]


def _eqns(jaxpr):
    """Jaxpr equations, counted recursively (the library's own counter)."""
    from uio_jax._calculus.generators import jaxpr_sizes

    return jaxpr_sizes(jaxpr)[0]


def bench_jax(system_fn, k_max, samples, repeats, warm_ks=()):
    import uio_jax as uj
    from uio_jax._analysis import eorc as _eorc

    with jax.enable_x64(True):
        system = system_fn()
        t0 = time.perf_counter()
        run, history, reason, k = _eorc.run_eorc(system, samples=samples, seed=0,
                                                 rtol=default_rtol(), k_max=k_max)
        cold = time.perf_counter() - t0
        rows = []
        xs = run.ctx.xs
        for st in run.steps:
            key, row = st["key"], st.get("chain_row")
            if row:  # a later order of a chain program: computed with its first order
                rows.append(dict(k=st["k"], frontier=st["frontier"], candidates=st["candidates"],
                                 eqns=f"row {row} of the chain", compile_s=st["compile_s"],
                                 warm_s=0.0, load=_load()))
                continue
            block = run.blocks.blocks[(key[0], key[2])]  # (program, batch)
            eqns = _eqns(jax.make_jaxpr(block)(xs).jaxpr)
            if row == 0:
                eqns = f"{eqns} (chain of orders {st['k']}-{st['k'] + key[0][2] - 1})"
            compiled = run.blocks.compiled[key]
            times = []
            for _ in range(repeats):
                t = time.perf_counter()
                compiled(xs).block_until_ready()
                times.append(time.perf_counter() - t)
            rows.append(dict(k=st["k"], frontier=st["frontier"], candidates=st["candidates"],
                             eqns=eqns, compile_s=st["compile_s"],
                             warm_s=statistics.median(times), load=_load()))
        dims = [s.dim for s in history]
        aug = [s.extra["augmented_rank"] for s in history]
        warm_total = {}
        for kk in sorted({k_max, *(w for w in warm_ks if w < k_max)}):
            if kk != k_max:  # another extension Sigma^(kk): its blocks compile once first
                uj.analyze(system, method="eorc", samples=samples, k_max=kk)
            ts = []
            for _ in range(repeats):
                t = time.perf_counter()
                uj.analyze(system, method="eorc", samples=samples, k_max=kk)
                ts.append(time.perf_counter() - t)
            warm_total[kk] = (statistics.median(ts), _load())
    return dict(cold=cold, cold_load=_load(), rows=rows, dims=dims, aug=aug,
                reason=reason, warm_total=warm_total)


# ------------------------------------------------------------------ sympy EORC
def _sympy_vehicle(k_max, queue):
    """Exact EORC of the vehicle in wind: same recursion and pruning as uio_jax, ranks of
    the exact gradients at one random rational point (sympy). Puts (k, seconds) per order."""
    import random

    import sympy as sp

    x, y, z, qt, qx, qy, qz = sp.symbols("x y z qt qx qy qz")
    ws = sp.symbols(f"w0:{k_max}")
    X = [x, y, z, qt, qx, qy, qz] + list(ws)
    c1 = [qt**2 + qx**2 - qy**2 - qz**2, 2 * (qx * qy + qt * qz), 2 * (qx * qz - qt * qy)]
    c2 = [2 * (qx * qy - qt * qz), qt**2 - qx**2 + qy**2 - qz**2, 2 * (qy * qz + qt * qx)]
    c3 = [2 * (qx * qz + qt * qy), 2 * (qy * qz - qt * qx), qt**2 - qx**2 - qy**2 + qz**2]
    r = [x, y, z]
    F = [sum(a * b for a, b in zip(c, r)) for c in (c1, c2, c3)]
    outs = [F[0] / F[2], F[1] / F[2], qt**2 + qx**2 + qy**2 + qz**2]
    pad = [0] * k_max
    omega = [[0, 0, 0] + [sp.Rational(1, 2) * e for e in v] + pad for v in
             ([-qx, qt, qz, -qy], [-qy, -qz, qt, qx], [-qz, qy, -qx, qt])]
    speed = [list(c) + [0, 0, 0, 0] + pad for c in (c1, c2, c3)]
    F0 = [0, 0, ws[0], 0, 0, 0, 0] + list(ws[1:]) + [0]
    fields = [F0] + omega + speed
    rnd = random.Random(0)
    point = {s: sp.Rational(rnd.randint(5, 15), 10) for s in X}

    def grad(f):
        return [sp.diff(f, v) for v in X]

    kept, rows = [], []

    def absorb(cands):
        added = []
        for f in cands:
            g = [gi.subs(point) for gi in grad(f)]
            if sp.Matrix(rows + [g]).rank() > len(rows):
                rows.append(g)
                kept.append(f)
                added.append(f)
        return added

    t0 = time.perf_counter()
    frontier = absorb(outs)
    queue.put((0, time.perf_counter() - t0, len(rows)))
    for k in range(1, k_max + 1):
        cands = [sp.expand(sum(a * b for a, b in zip(grad(f), v))) for f in frontier for v in fields]
        frontier = absorb(cands)
        queue.put((k, time.perf_counter() - t0, len(rows)))


def bench_sympy(k_max, limit):
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_sympy_vehicle, args=(k_max, q), daemon=True)
    p.start()
    p.join(limit)
    stopped = p.is_alive()
    if stopped:
        p.terminate()
        p.join()
    out = []
    while not q.empty():
        out.append(q.get())
    return out, stopped, _load()


# ------------------------------------------------------------------ report
def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--k-max", type=int, default=8)
    ap.add_argument("--samples", type=int, default=4096)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sympy-limit", type=float, default=120.0)
    ap.add_argument("--vi-k", type=int, default=3)
    ap.add_argument("--warm-k", type=int, nargs="*", default=[6],
                    help="also time analyze(k_max=k) warm for these k (vehicle)")
    ap.add_argument("--skip-sympy", action="store_true")
    ap.add_argument("--skip-vehicle", action="store_true")
    ap.add_argument("--skip-vi", action="store_true")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)

    import vehicle_wind
    import visual_inertial

    lines = [f"machine: {os.cpu_count()} cores, jax {jax.__version__} "
             f"{jax.default_backend()}, load at start {_load():.2f}", ""]
    res = None if args.skip_vehicle else bench_jax(vehicle_wind.wind_unknown, args.k_max,
                                                     args.samples, args.repeats, args.warm_k)
    lines += [] if res is None else [f"### Vehicle in wind (`vehicle_wind.py:wind_unknown`), EORC to k = {args.k_max}, "
              f"{args.samples} samples", "",
              f"dims on the original state per k: {res['dims']}; augmented ranks: {res['aug']}; "
              f"stop: {res['reason']}", "",
              f"one cold run k = 0..{args.k_max} (compile included): **{res['cold']:.1f} s** "
              f"(load {res['cold_load']:.2f})", "",
              "| k | frontier | candidates | trace (jaxpr eqns) | compile s | warm block s "
              "(median) | load |", "|---|---|---|---|---|---|---|"]
    cum = 0.0
    for r in ([] if res is None else res["rows"]):
        cum += r["warm_s"]
        lines.append(f"| {r['k']} | {r['frontier']} | {r['candidates']} | {r['eqns']} | "
                     f"{r['compile_s']:.2f} | {r['warm_s']:.3f} (cum. {cum:.2f}) | "
                     f"{r['load']:.2f} |")
    lines += ["", "| analyze(k_max) warm, every block cached (median) | s | load |",
              "|---|---|---|"]
    for kk, (t, ld) in ({} if res is None else res["warm_total"]).items():
        lines.append(f"| k_max = {kk} | {t:.2f} | {ld:.2f} |")
    print("\n".join(lines), flush=True)

    if not args.skip_sympy:
        out, stopped, ld = bench_sympy(args.k_max, args.sympy_limit)
        lines += ["", f"### sympy EORC of the same model (exact Lie derivatives, same pruning, "
                      f"ranks at one rational point), limit {args.sympy_limit:.0f} s", "",
                  "| k | cumulative s | rank |", "|---|---|---|"]
        lines += [f"| {k} | {t:.2f} | {rk} |" for k, t, rk in out]
        if stopped:
            reached = out[-1][0] if out else -1
            lines.append(f"\nsympy stopped after {args.sympy_limit:.0f} s at k = {reached + 1} "
                         f"(load {ld:.2f}).")
        print("\n".join(lines[-(len(out) + 6):]), flush=True)

    if not args.skip_vi:
        for n_f, fn in ((2, visual_inertial.gyro_z_unknown),):
            vi = bench_jax(fn, args.vi_k, args.samples, 2)
            n = 10 + 3 * n_f
            lines += ["", f"### Visual-inertial, gyro z unknown, {n_f} features (n = {n}), "
                          f"EORC to k = {args.vi_k}, {args.samples} samples", "",
                      f"cold run (compile included): **{vi['cold']:.1f} s** (load "
                      f"{vi['cold_load']:.2f}); dims {vi['dims']}, augmented ranks "
                      f"{vi['aug']}", "",
                      "| k | frontier | candidates | trace (jaxpr eqns) | compile s | warm block s "
                      "| load |", "|---|---|---|---|---|---|---|"]
            for r in vi["rows"]:
                lines.append(f"| {r['k']} | {r['frontier']} | {r['candidates']} | {r['eqns']} "
                             f"| {r['compile_s']:.2f} | {r['warm_s']:.3f} | {r['load']:.2f} |")
            for kk, (t, ld) in vi["warm_total"].items():
                lines.append(f"\nanalyze(k_max={kk}) warm: {t:.2f} s (load {ld:.2f})")
            print("\n".join(lines[-(len(vi["rows"]) + 8):]), flush=True)

    if args.out:
        with open(args.out, "w") as fh:
            fh.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
