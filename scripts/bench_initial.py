"""Known initial states: the analysis at t = 0 timed on StructuralIdentifiability.jl's models.

SI.jl documents ``known_ic`` (initial conditions known but *generic*) on its own test models
(Lotka-Volterra with ``x2(0)`` known; ``x1' = a + x2 + x3, x2' = b^2 + c, x3' = -c`` with
``x2(0), x3(0)`` known) and its benchmark models are in ``scripts/bench_si_models.py``. Here
each gets a *specific* known initial state of the kind a modeller has (a compartment that
starts empty, the phase of a forcing oscillator), and ``uj.analyze(system, initial=...)`` is
timed: the first call on the freshly built System (in a process that analysed another model
first), the median of 5 warm calls, the process CPU time of the first call and the peak
Python memory of one call (``tracemalloc``).

    python scripts/bench_initial.py
"""

import os
import platform
import statistics
import sys
import time
import tracemalloc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from bench_si_models import MODELS  # noqa: E402

#: model -> (known initial state, domain boxes that contain it)
INITIAL = {
    "Goodwin oscillator": ({"x2": 0}, {"x2": (0.0, 1.5)}),
    "SIWR (cholera)": ({"R": 0, "W": 0}, {"R": (0.0, 1.5), "W": (0.0, 1.5)}),
    "SIRS forced": ({"x1": 1, "x2": 0, "r": 0}, {"x2": (-1.0, 1.0), "r": (0.0, 1.5)}),
    "HIV (Wodarz)": ({"z": 0}, {"z": (0.0, 1.5)}),
    "chemical reaction network": ({"x4": 0, "x6": 0}, {"x4": (0.0, 1.5), "x6": (0.0, 1.5)}),
}

KIC = {  # SI.jl's known_ic test models, at a specific value of the known initial states
    "Lotka-Volterra (SI.jl kic)": (["x1", "x2"], ["a", "b", "c", "d"],
                                   {"x1": "a*x1 - b*x1*x2", "x2": "-c*x2 + d*x1*x2"}, ["x1"]),
    "x2, x3 known (SI.jl kic)": (["x1", "x2", "x3"], ["a", "b", "c"],
                                 {"x1": "a + x2 + x3", "x2": "b**2 + c", "x3": "-c"}, ["x1"]),
}
INITIAL["Lotka-Volterra (SI.jl kic)"] = ({"x2": 1}, {})
INITIAL["x2, x3 known (SI.jl kic)"] = ({"x2": 1, "x3": 1}, {})


def build(name, domain):
    import sympy as sp

    import uio_jax as uj

    states, params, rhs, outputs = {**MODELS, **KIC}[name]
    symbols = {s: sp.Symbol(s) for s in states + params}
    drift = [sp.sympify(rhs[s], locals=symbols) for s in states]
    return uj.system_from_sympy([symbols[s] for s in states], [sp.sympify(y, locals=symbols) for y in outputs],
                                drift=drift, params=[symbols[p] for p in params], name=name, domain=domain)


def run(name):
    import uio_jax as uj

    initial, domain = INITIAL[name]
    system = build(name, domain)
    cpu, t = time.process_time(), time.perf_counter()
    rep = uj.analyze(system, initial=initial)
    first, first_cpu = time.perf_counter() - t, time.process_time() - cpu
    warm = []
    for _ in range(5):
        t = time.perf_counter()
        uj.analyze(system, initial=initial)
        warm.append(time.perf_counter() - t)
    tracemalloc.start()
    uj.analyze(system, initial=initial)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return rep, first, first_cpu, statistics.median(warm), peak


def main():
    import uio_jax as uj

    uj.analyze(build("Lotka-Volterra (SI.jl kic)", {}), initial={"x2": 1})  # the library warmed
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}")
    print("| model | known initial state | unknowns | determined | undecided | order | exact | first (s) "
          "| first CPU (s) | warm median (s) | peak Python memory (MiB) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|", flush=True)
    for name in INITIAL:
        rep, first, cpu, warm, peak = run(name)
        known = ", ".join(f"{k}={v}" for k, v in INITIAL[name][0].items())
        det = sum(v is uj.Verdict.DETERMINED for v in rep.verdicts.values())
        print(f"| {name} | {known} | {len(rep.verdicts)} | {det} | {len(rep.undecided)} | {rep.order} | "
              f"{rep.exact} | {first:.3f} | {cpu:.3f} | {warm:.3f} | {peak / 2**20:.1f} |", flush=True)


if __name__ == "__main__":
    main()
