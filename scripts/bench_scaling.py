"""How the cost of an exact verdict grows with the model's size.

Two families (the exactness issue's targets):

* **chain**: one output, parameters: ``x_i' = -a_i x_i + x_{i+1} + 0.5 x_{i-1} x_i``
  (``x_{n}`` = 0, ``x_{-1}`` = 0), ``y = x_0``, the ``a_i`` unknown parameters; ``--fn sin``
  replaces ``x_{i-1} x_i`` by ``x_{i-1} sin(x_i)``. Variables: ``2 n_states``.
* **slam**: a planar robot ``(px, py, th)`` with known speed and turn rate, range and bearing
  to ``L`` landmarks at unknown fixed positions: ``3 + 2 L`` states, generic dimension
  ``n - 3`` (the rigid motions of the plane are hidden). The range is squared; ``--fn sqrt``
  writes it as the distance ``sqrt((lx - px)^2 + (ly - py)^2)``.

Each size runs in a fresh process (``python scripts/bench_scaling.py --one FAMILY SIZE``), so
the time is a first call: CPU time, wall time and peak memory (``ru_maxrss``) of the process,
with the report's dimension and arithmetic (BLAS and OpenMP on one thread, :data:`THREADS`).

    python scripts/bench_scaling.py chain 10 25 35 50 [--fn sin] [--repeat 3]
    python scripts/bench_scaling.py slam 10 40 100 200 [--fn sqrt]
    python scripts/bench_scaling.py chain 6 8 12 16 [--symbolic]   # the engine's choice, A/B
    python scripts/bench_scaling.py chain 50 --peer symident        # the same model, symident 0.12

``--peer symident`` times ``symident.detect`` (a C++ kernel over finite fields) on the same
equations in the same way (fresh process, the model built inside the timed span, one core).
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import time

#: every timed process runs its BLAS and OpenMP libraries on one thread: on a shared 2-core
#: machine spinning library threads count as CPU time (one SVD of 400 x 403: 0.02 s on one
#: thread, 0.5 s with OpenBLAS's default threads under load)
THREADS = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def chain(n_states: int, fn: str = "mul"):
    import jax.numpy as jnp

    import uio_jax as uj

    def drift(x, a):
        nxt = jnp.concatenate([x[1:], jnp.zeros(1)])
        prev = jnp.concatenate([jnp.zeros(1), x[:-1]])
        coupling = prev * (jnp.sin(x) if fn == "sin" else x)
        return -a * x + nxt + 0.5 * coupling

    return uj.System(states=tuple(f"x{i}" for i in range(n_states)), outputs={"y": lambda x, a: x[0]},
                     drift=drift, params={f"a{i}": (0.5, 1.5) for i in range(n_states)}, name=f"chain{n_states}")


def slam(landmarks: int, fn: str = "mul"):
    import jax.numpy as jnp

    import uio_jax as uj

    L = landmarks
    states = ("px", "py", "th") + tuple(f"{c}{j}" for j in range(L) for c in ("lx", "ly"))
    outputs = {}
    for j in range(L):
        def rng(x, j=j):
            squared = (x[3 + 2 * j] - x[0]) ** 2 + (x[4 + 2 * j] - x[1]) ** 2
            return jnp.sqrt(squared) if fn == "sqrt" else squared

        def bearing(x, j=j):
            dx, dy = x[3 + 2 * j] - x[0], x[4 + 2 * j] - x[1]
            return jnp.arctan2(dy, dx) - x[2]

        outputs[f"r{j}"], outputs[f"b{j}"] = rng, bearing
    n = 3 + 2 * L

    def speed(x):
        return jnp.zeros(n).at[0].set(jnp.cos(x[2])).at[1].set(jnp.sin(x[2]))

    def turn(x):
        return jnp.zeros(n).at[2].set(1.0)

    return uj.System(states=states, outputs=outputs, known={"v": speed, "omega": turn},
                     angles=("th",), name=f"slam{L}" + ("_sqrt" if fn == "sqrt" else ""))


def symident_model(family: str, size: int, fn: str):
    """The same model as a ``symident.Model`` (equations as text)."""
    import symident

    if family == "chain":
        n = size
        odes = {}
        for i in range(n):
            nxt = f" + x{i + 1}" if i + 1 < n else ""
            other = f"sin(x{i})" if fn == "sin" else f"x{i}"
            prev = f" + 0.5*x{i - 1}*{other}" if i else ""
            odes[f"x{i}"] = f"-a{i}*x{i}{nxt}{prev}"
        return symident.Model(odes=odes, observables={"y": "x0"})
    odes = {"px": "v*cos(th)", "py": "v*sin(th)", "th": "omega"}
    obs = {}
    for j in range(size):
        odes[f"lx{j}"], odes[f"ly{j}"] = "0", "0"
        squared = f"(lx{j} - px)^2 + (ly{j} - py)^2"
        obs[f"r{j}"] = f"sqrt({squared})" if fn == "sqrt" else squared
        obs[f"b{j}"] = f"atan2(ly{j} - py, lx{j} - px) - th"
    return symident.Model(odes=odes, observables=obs, known_inputs=["v", "omega"])


def one_peer(family: str, size: int, fn: str) -> dict:
    import symident

    t0, c0 = time.perf_counter(), time.process_time()
    res = symident.detect(symident_model(family, size, fn))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    status = (res.info.get("rank_status") or {}).get("status")
    return {"family": family, "size": size, "fn": fn, "variables": res.dim, "dim": res.rank, "method": "symident",
            "exact": status, "arithmetic": "", "wall_s": wall, "cpu_s": cpu,
            "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def one(family: str, size: int, fn: str) -> dict:
    import uio_jax as uj

    t0, c0 = time.perf_counter(), time.process_time()
    system = chain(size, fn) if family == "chain" else slam(size, fn)
    rep = uj.analyze(system)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"family": family, "size": size, "fn": fn, "variables": rep.n, "dim": rep.dim,
            "method": rep.method, "exact": rep.exact, "arithmetic": rep.certificate.arithmetic.name,
            "wall_s": wall, "cpu_s": cpu, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("family", choices=("chain", "slam"))
    ap.add_argument("sizes", type=int, nargs="+")
    ap.add_argument("--fn", choices=("mul", "sin", "sqrt"), default="mul",
                    help="chain: the coupling (mul, sin); slam: the range (mul: squared, sqrt: the distance)")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--one", action="store_true", help="run one size in this process, print JSON")
    ap.add_argument("--peer", choices=("symident",), help="time the peer on the same model instead")
    ap.add_argument("--symbolic", action="store_true",
                    help="force the symbolic route (no Taylor route at any size): the A/B of the engine's choice")
    args = ap.parse_args(argv)
    if args.symbolic:
        from uio_jax._analysis.recursions import taylor_route

        taylor_route.TAYLOR_MIN_VARIABLES = 10**9
    if args.one:
        run = one_peer if args.peer else one
        print(json.dumps(run(args.family, args.sizes[0], args.fn)))
        return
    print("| family | size | variables | dim | exact | median wall s | median CPU s | peak MB |")
    print("|---|---|---|---|---|---|---|---|", flush=True)
    for size in args.sizes:
        runs = []
        for _ in range(args.repeat):
            cmd = [sys.executable, __file__, args.family, str(size), "--fn", args.fn, "--one"]
            cmd += ["--peer", args.peer] if args.peer else []
            out = subprocess.run(cmd + (["--symbolic"] if args.symbolic else []), capture_output=True, text=True,
                                 env=dict(os.environ, **THREADS))
            if out.returncode:
                last = (out.stderr.strip().splitlines() or ["?"])[-1]
                print(f"| {args.family} | {size} | failed: {last} |", flush=True)
                break
            runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        if not runs:
            continue
        r = runs[0]
        label = f"{args.family} ({args.fn})" + (f", {args.peer}" if args.peer else "")
        print(f"| {label} | {size} | {r['variables']} | {r['dim']} | {r['exact']} "
              f"| {statistics.median(x['wall_s'] for x in runs):.2f} "
              f"| {statistics.median(x['cpu_s'] for x in runs):.2f} "
              f"| {max(x['peak_mb'] for x in runs):.0f} |", flush=True)


if __name__ == "__main__":
    main()
