"""A batch over a folder of SBML files with one outputs/inputs rule, timed.

Writes ``--count`` SBML models (python-libsbml) into a temporary folder: linear pathways
``X1 -> X2 -> ... -> X(n-1) -> P`` (n = 2, 3, ... species) in a compartment of size 1 or 2.5, fed by an inflow
``cell * k_in`` into X1, with Michaelis-Menten steps (a local ``Km`` per reaction), mass-action
steps, an assignment rule for the last step's rate and, on every third model, feedback
inhibition of the first step by P. One rule for all: output ``y = P``, ``k_in`` an unknown
input, every other parameter identified. Then:

* the conversion alone (``load_system`` of each file: libsbml, sbmlmath, sympy, System);
* ``uj.batch_analyze(folder, sbml=rule)`` in this process: the first call, then the median of
  ``--repeats`` further calls (fresh Systems each time: nothing is reused but the imports);
* ``uio-jax batch folder --outputs y=P --unknown k_in`` in a fresh process (import included),
  with its CPU time and peak memory (``getrusage`` of the child).

    python scripts/bench_sbml.py [--count 10] [--repeats 3]
"""

import argparse
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time

RULE = {"outputs": {"y": "P"}, "unknown": ["k_in"]}


def write_model(path, n, seed):
    """A pathway of ``n`` species (see the module doc), written to ``path``."""
    import libsbml

    doc = libsbml.SBMLDocument(3, 2)
    m = doc.createModel()
    m.setId(f"pathway_{n}")
    c = m.createCompartment()
    c.setId("cell")
    c.setSize(2.5 if seed % 2 else 1.0)
    c.setConstant(True)
    names = [f"X{i}" for i in range(1, n)] + ["P"]  # the last one named alike in every model
    for name in names:
        s = m.createSpecies()
        for setter, value in ((s.setId, name), (s.setCompartment, "cell"), (s.setInitialConcentration, 0.5),
                              (s.setHasOnlySubstanceUnits, False), (s.setBoundaryCondition, False),
                              (s.setConstant, False)):
            setter(value)
    params = ["k_in", "k_out"] + [f"V{i}" for i in range(1, n)] + (["Ki"] if seed % 3 == 0 else [])
    for pid in params + ["v_last"]:
        p = m.createParameter()
        p.setId(pid)
        p.setConstant(pid != "v_last")
        if pid != "v_last":
            p.setValue(0.1 * (1 + len(pid)))
    _reaction(m, "inflow", None, names[0], "cell*k_in")
    for i in range(1, n):
        inhibit = "/(1 + P/Ki)" if seed % 3 == 0 and i == 1 else ""
        law = f"cell*V{i}*X{i}/(Km + X{i}){inhibit}" if i % 2 else f"cell*V{i}*X{i}{inhibit}"
        _reaction(m, f"step{i}", f"X{i}", names[i], law, {"Km": 0.3} if i % 2 else None)
    rule = m.createAssignmentRule()
    rule.setVariable("v_last")
    rule.setMath(libsbml.parseL3Formula("cell*k_out*P"))
    _reaction(m, "outflow", "P", None, "v_last")
    assert libsbml.writeSBMLToFile(doc, path) == 1


def _reaction(m, rid, reactant, product, formula, local=None):
    import libsbml

    r = m.createReaction()
    r.setId(rid)
    r.setReversible(False)
    for sid, create in ((reactant, r.createReactant), (product, r.createProduct)):
        if sid is not None:
            ref = create()
            ref.setSpecies(sid)
            ref.setStoichiometry(1)
            ref.setConstant(True)
    law = r.createKineticLaw()
    for pid, value in (local or {}).items():
        lp = law.createLocalParameter()
        lp.setId(pid)
        lp.setValue(value)
    law.setMath(libsbml.parseL3Formula(formula))


def timed_batch(folder):
    import uio_jax as uj

    t0, c0 = time.perf_counter(), time.process_time()
    result = uj.batch_analyze(folder, sbml=RULE, progress=False, keep_reports=False)
    return time.perf_counter() - t0, time.process_time() - c0, result


def fresh_cli(folder):
    """Wall time, CPU time (user + sys) and peak memory of ``uio-jax batch`` in a new process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "uio_jax", "batch", folder, "--outputs", "y=P", "--unknown", "k_in",
           "--no-progress", "--no-cache"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        raise SystemExit(f"uio-jax batch failed ({proc.returncode}): {proc.stderr.strip()[-400:]}")
    return wall, cpu, after.ru_maxrss / 1024


def machine() -> str:
    """The CPU's model name (Linux), else the platform's."""
    try:
        with open("/proc/cpuinfo") as fh:
            return next(line.split(":", 1)[1].strip() for line in fh if line.startswith("model name"))
    except (OSError, StopIteration):
        return platform.processor() or platform.machine()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=10)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    import uio_jax as uj

    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for k in range(args.count):
            paths.append(os.path.join(folder, f"pathway_{k + 2:02d}.xml"))
            write_model(paths[-1], k + 2, k)
        loads = []
        for p in paths:
            t0 = time.perf_counter()
            uj.load_system(p, **RULE)
            loads.append(time.perf_counter() - t0)
        first, first_cpu, result = timed_batch(folder)
        warm = [timed_batch(folder)[:2] for _ in range(args.repeats)]
        wall, cpu, peak = fresh_cli(folder)
    import libsbml
    import sbmlmath

    print(f"machine: {machine()}, {os.cpu_count()} CPUs, libsbml {libsbml.getLibSBMLDottedVersion()}, "
          f"sbmlmath {sbmlmath.__version__}, "
          f"Python {platform.python_version()}, load {os.getloadavg()[0]:.2f}")
    print(result.table())
    print(f"conversion (load_system) per file: median {statistics.median(loads) * 1e3:.0f} ms, "
          f"max {max(loads) * 1e3:.0f} ms (the first includes importing libsbml/sbmlmath)")
    print(f"batch_analyze of {len(paths)} files, first call: {first:.2f} s wall, {first_cpu:.2f} s CPU")
    print(f"batch_analyze, median of {args.repeats}: {statistics.median(w for w, _ in warm):.2f} s wall, "
          f"{statistics.median(c for _, c in warm):.2f} s CPU")
    print(f"uio-jax batch in a fresh process: {wall:.2f} s wall, {cpu:.2f} s CPU, peak memory {peak:.0f} MB")
    exact = sum(bool(r.exact) for r in result)
    print(f"exact reports: {exact} of {len(result)}; errors: {sum(r.error is not None for r in result)}")


if __name__ == "__main__":
    main()
