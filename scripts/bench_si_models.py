"""StructuralIdentifiability.jl's benchmark models, timed here (the exactness issue's peer).

The models are transcribed from the DAISY inputs of SI.jl's ``benchmarking`` folder (states,
unknown parameters, equations, outputs), every parameter unknown. Each is analysed by
``uj.analyze`` (default options: every decision exact modulo p) in a process that has
imported ``uio_jax`` and analysed one other model (so that the library's own start is not
counted): the first call on the freshly built System and the median of three warm calls;
and a fresh process (import, build, analyse) timed from outside. SI.jl's recorded local
test takes 0.03-0.11 s on these models (its own records, a 1.6 GHz laptop).

    python scripts/bench_si_models.py [--fresh]
"""

import argparse
import statistics
import subprocess
import sys
import time

MODELS = {
    "Goodwin oscillator": (
        ["x1", "x2", "x3", "x4"], ["b", "alpha", "c", "gama", "delta", "sigma", "beta"],
        {"x1": "(-b*c*x1 - b*x1*x4 + 1) / (c + x4)", "x2": "alpha*x1 - beta*x2",
         "x3": "gama*x2 - delta*x3", "x4": "(gama*sigma*x2*x4 - delta*sigma*x3*x4) / x3"},
        ["x1"]),
    "SIWR (cholera)": (
        ["S", "I", "R", "W"], ["bi", "gam", "mu", "bw", "k", "xi", "a"],
        {"S": "-bi*S*I - S*mu - S*bw*W + R*a + mu", "I": "bi*S*I - gam*I + S*bw*W - mu*I",
         "R": "gam*I - R*mu - R*a", "W": "xi*I - xi*W"},
        ["k*I"]),
    "SIRS forced": (
        ["s", "i", "r", "x1", "x2"], ["nu", "b1", "b0", "M", "mu", "g"],
        {"s": "-b1*b0*s*x1*i - b0*s*i - s*mu + mu + g*r", "i": "-nu*i + b1*b0*s*x1*i + b0*s*i - mu*i",
         "r": "nu*i - mu*r - g*r", "x1": "-M*x2", "x2": "M*x1"},
        ["i", "r"]),
    "HIV (Wodarz)": (
        ["x", "y", "v", "w", "z"], ["b", "c", "h", "lm", "d", "k", "u", "q", "a", "beta"],
        {"x": "lm - x*d - x*v*beta", "y": "x*v*beta - a*y", "v": "k*y - v*u",
         "w": "-b*w + c*w*x*y - c*w*q*y", "z": "c*w*q*y - h*z"},
        ["w", "z"]),
    "chemical reaction network": (
        ["x1", "x2", "x3", "x4", "x5", "x6"], ["k1", "k2", "k3", "k4", "k5", "k6"],
        {"x1": "k4*x6 + k2*x4 - k1*x1*x2", "x2": "k3*x4 + k2*x4 + k1*x1*x2",
         "x3": "k5*x6 + k3*x4 - k6*x5*x3", "x4": "-k3*x4 - k2*x4 + k1*x1*x2",
         "x5": "k5*x6 + k4*x6 - k6*x5*x3", "x6": "-k5*x6 - k4*x6 + k6*x5*x3"},
        ["x3", "x2"]),
}


def build(name):
    import sympy as sp

    import uio_jax as uj

    states, params, rhs, outputs = MODELS[name]
    symbols = {s: sp.Symbol(s) for s in states + params}
    drift = [sp.sympify(rhs[s], locals=symbols) for s in states]
    return uj.system_from_sympy([symbols[s] for s in states], [sp.sympify(y, locals=symbols) for y in outputs],
                                drift=drift, params=[symbols[p] for p in params], name=name)


def in_process(name):
    import uio_jax as uj

    uj.analyze(build("SIWR (cholera)" if name != "SIWR (cholera)" else "Goodwin oscillator"))  # warm the library
    system = build(name)
    t = time.perf_counter()
    rep = uj.analyze(system)
    first = time.perf_counter() - t
    warm = []
    for _ in range(3):
        t = time.perf_counter()
        uj.analyze(system)
        warm.append(time.perf_counter() - t)
    ident = sum(rep.identifiable.values())
    return first, statistics.median(warm), rep, ident


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fresh", action="store_true", help="also time fresh processes (import included)")
    ap.add_argument("--one", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.one:
        import uio_jax as uj

        uj.analyze(build(args.one))
        return
    print("| model | states + parameters | method | dim | exact | identifiable | first call (s) | warm (s) |"
          + (" fresh process (s) |" if args.fresh else ""))
    print("|---|---|---|---|---|---|---|---|" + ("---|" if args.fresh else ""), flush=True)
    for name in MODELS:
        first, warm, rep, ident = in_process(name)
        row = (f"| {name} | {rep.n} | {rep.method} | {rep.dim} | {rep.exact} | {ident} of {len(rep.params)} "
               f"| {first:.3f} | {warm:.3f} |")
        if args.fresh:
            t = time.perf_counter()
            subprocess.run([sys.executable, __file__, "--one", name], check=True)
            row += f" {time.perf_counter() - t:.2f} |"
        print(row, flush=True)


if __name__ == "__main__":
    main()
