"""Candidate kernels of the Taylor engine's modular arithmetic, side by side on its recurrences.

1. **The Cauchy sums of one order** (``sum_j v[g, j] M[g, j, :]`` for ``m`` products of one
   level, ``J`` past orders, ``W`` gradient columns: the engine's inner loop), by:

   * ``object``: numpy object arrays of Python integers modulo ``2^127 - 1`` (the old engine);
   * ``int64``: numpy ``einsum`` on int64 modulo a prime below ``2^26`` (sums of up to 2048
     products unreduced; the engine now);
   * ``float64``: the same ``einsum`` on float64 (no modular reduction: the memory-bound
     ceiling of this formulation);
   * ``flint``: python-flint's ``nmod_mat`` products modulo a 62-bit prime, one per product
     (its matrices have no views: ``+conv`` counts building them from the history's arrays,
     which a kernel storing its orders in numpy must do every order);
   * ``jax``: a ``jax.jit`` int64 program (``einsum`` and ``%``), compiled once per shape
     (``compile`` separately: one compilation per bucket of ``J`` in a run).

2. **The whole engine** on the one-output chain of ``bench_scaling.py`` (``2 n`` variables):
   the object-integer arithmetic modulo ``2^127 - 1`` against one int64 lane, CPU seconds per
   order and per order and tangent column, and the multiply-adds of its Cauchy sums per second
   (their count: ``2 m (k + 1) W`` per order ``k`` for the ``m`` products with two moving
   factors, ``W`` the columns), also as a fraction of the int64 ``einsum``'s rate of part 1 (the
   arithmetic's limit in this formulation: what the engine does besides its Cauchy sums).

CPU seconds (``time.process_time``), one process, BLAS and OpenMP at one thread:

    OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 python scripts/bench_kernels.py [--sizes 25 50]
"""

import argparse
import time

import numpy as np

P127 = 2**127 - 1
P62 = 2**62 - 57


def _cpu(fn, repeat=3):
    """Median CPU seconds of ``fn()``."""
    times = []
    for _ in range(repeat):
        t = time.process_time()
        fn()
        times.append(time.process_time() - t)
    return sorted(times)[len(times) // 2]


def primitive(m, J, W):
    """Rows of part 1 for one shape: ``(name, seconds, multiply-adds per second)``."""
    from uio_jax._engine.primes import random_prime

    rng = np.random.default_rng(0)
    p = random_prime(rng)
    v = rng.integers(0, p, size=(m, J))
    M = rng.integers(0, p, size=(m, J, W))
    work = m * J * W
    rows = []

    def int64():
        return np.einsum("gj,gjw->gw", v, M) % p

    rows.append(("int64", _cpu(int64)))
    vf, Mf = v.astype(np.float64), M.astype(np.float64)
    rows.append(("float64", _cpu(lambda: np.einsum("gj,gjw->gw", vf, Mf))))
    vo, Mo = v.astype(object), M.astype(object)
    rows.append(("object", _cpu(lambda: np.matmul(vo[:, None, :], Mo)[:, 0] % P127, repeat=1)))
    rows += _flint(v, M)
    rows += _jax(v, M, p)
    return [(name, t, work / t if t > 0 else float("inf")) for name, t in rows]


def _flint(v, M):
    try:
        import flint
    except ImportError:
        return [("flint (not installed)", float("nan"))]
    m, J, W = M.shape
    vs = [flint.nmod_mat(1, J, [int(a) for a in v[g]], P62) for g in range(m)]
    Ms = [flint.nmod_mat(J, W, [int(a) for a in M[g].ravel()], P62) for g in range(m)]

    def products():
        return [vs[g] * Ms[g] for g in range(m)]

    def converted():
        return [flint.nmod_mat(1, J, v[g].tolist(), P62) * flint.nmod_mat(J, W, M[g].ravel().tolist(), P62)
                for g in range(m)]

    return [("flint nmod_mat", _cpu(products)), ("flint nmod_mat +conv", _cpu(converted, repeat=1))]


def _jax(v, M, p):
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    step = jax.jit(lambda a, b: jnp.einsum("gj,gjw->gw", a, b) % p)
    a, b = jnp.asarray(v), jnp.asarray(M)
    t = time.process_time()
    step(a, b).block_until_ready()
    compile_s = time.process_time() - t
    return [("jax int64", _cpu(lambda: step(a, b).block_until_ready())), ("jax compile (one shape)", compile_s)]


def engine(n_states, arithmetic):
    """Part 2: CPU seconds of the chain's output series to order ``2 n`` and its Cauchy work."""
    import sys

    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from bench_scaling import chain

    from uio_jax._analysis.decisions.context import Context
    from uio_jax._engine import graph_elementary
    from uio_jax._engine.primes import random_prime
    from uio_jax._engine.taylor import Modular, TaylorSeries
    from uio_jax._engine.taylor_word import Word

    ctx = Context(chain(n_states).autonomous(), 16, 0, 1e-8)
    g, N = ctx.builder.graph, 2 * n_states
    f0 = list(ctx.field_node("f0").expr)
    h = ctx.output_nodes()[0].expr
    rng = np.random.default_rng(1)
    if arithmetic == "object":
        point = [int(v) for v in rng.integers(0, 2**62, size=N)]
        ar = Modular([point], graph_elementary.Draws(P127, 1, [1]))
    else:
        p = random_prime(rng)
        ar = Word([p], [rng.integers(0, p, size=N)], rng)
    series = TaylorSeries(g, [f0], [], [h], ar, N)
    t = time.process_time()
    series.coefficient(h, N)
    cpu = time.process_time() - t
    products = sum(len(step[2][0]) for step in series.plan.steps if step[0] == "mul")
    work = sum(2 * products * (k + 1) * series.W for k in range(N + 1))
    return cpu, work


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[25, 50], help="chain states (part 2)")
    ap.add_argument("--shapes", default="50x100x101,200x400x401", help="m x J x W of part 1")
    args = ap.parse_args(argv)
    print("| kernel | m x J x W | CPU s | multiply-adds / s |")
    print("|---|---|---|---|")
    peak = 0.0
    for shape in args.shapes.split(","):
        m, J, W = (int(v) for v in shape.split("x"))
        for name, t, rate in primitive(m, J, W):
            print(f"| {name} | {shape} | {t:.4f} | {rate:.2e} |", flush=True)
            peak = max(peak, rate) if name == "int64" else peak
    print()
    print("| engine | chain variables | orders | CPU s | s / order | us / order / tangent | Cauchy multiply-adds "
          "| per s | of the int64 einsum's rate |")
    print("|---|---|---|---|---|---|---|---|---|")
    for n in args.sizes:
        for arithmetic in ("object", "int64"):
            if arithmetic == "object" and n > 50:
                continue
            cpu, work = engine(n, arithmetic)
            orders = 2 * n + 1
            print(f"| {arithmetic} | {2 * n} | {orders} | {cpu:.2f} | {cpu / orders:.4f} "
                  f"| {1e6 * cpu / orders / (2 * n + 1):.1f} | {work:.2e} | {work / cpu:.2e} "
                  f"| {work / cpu / peak:.0%} |", flush=True)


if __name__ == "__main__":
    main()
