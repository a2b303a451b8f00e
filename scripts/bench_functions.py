"""Time added by the named observable functions (``Report.observable_functions``), per model.

For every zoo model (or those whose label contains ``--only``): the analysis' own time (first
call, fresh seed-0 report), then the time of naming its observable functions on first access,
how many were named of ``dim``, and the functions.

    python scripts/bench_functions.py [--only SUBSTRING] [--samples 4096] [--strikepy]

``--strikepy`` adds StrikePy's shipped models (the importer's test data).
"""

import argparse
import time
from pathlib import Path

import uio_jax as uj

ROOT = Path(__file__).resolve().parents[1]


def entries(strikepy: bool):
    """``(label, System or None)`` of the zoo (and of StrikePy's models)."""
    from snapshot_reports import snapshot_label, zoo_entries
    out = [(snapshot_label(e.label), e.system) for e in zoo_entries()]
    if strikepy:
        from uio_jax._io.strikepy_import import load_strikepy
        for path in sorted((ROOT / "tests" / "data" / "strikepy_models").glob("*.py")):
            try:
                out.append((path.name, load_strikepy(str(path))))
            except uj.UioJaxError:
                out.append((path.name, None))
    return out


def measure(system, samples):
    """``(analysis seconds, naming seconds, report)``."""
    t0 = time.perf_counter()
    rep = uj.analyze(system, samples=samples)
    t1 = time.perf_counter()
    uj.observable_functions(rep)
    return t1 - t0, time.perf_counter() - t1, rep


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="")
    ap.add_argument("--samples", type=int, default=4096)
    ap.add_argument("--strikepy", action="store_true")
    args = ap.parse_args(argv)
    print(f"{'model':48s} {'dim/n':>7s} {'analysis':>9s} {'naming':>8s}  named")
    for label, system in entries(args.strikepy):
        if args.only not in label or system is None:
            continue
        analysis, naming, rep = measure(system, args.samples)
        nf = uj.observable_functions(rep)
        print(f"{label:48s} {rep.dim:>3d}/{rep.n:<3d} {analysis:9.3f} {naming:8.3f}  "
              f"{len(nf.functions)}/{nf.dim}{'' if nf.complete else ' INCOMPLETE'}: {'; '.join(nf.texts)[:150]}")


if __name__ == "__main__":
    import os
    import sys
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    main()
