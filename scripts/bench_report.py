"""What reading a report costs against the analysis: ``str(rep)`` and ``rep.to_dict()`` (which
serialise what was computed and run no search) beside the follow-up questions asked
explicitly (``uj.observable_functions``, ``uj.find_symmetries``), per model, CPU seconds,
median of repeats (a fresh analysis per repeat; the first call of the process dropped).

    python scripts/bench_report.py [--repeats 7] [--only SUBSTRING]
"""

import argparse
import statistics
import time
from pathlib import Path

import uio_jax as uj

ROOT = Path(__file__).resolve().parents[1]
MODELS = ("vehicle_wind.py:no_wind", "vehicle_wind.py:wind_unknown", "unicycle_polar.py:range_v_unknown",
          "unicycle_wind.py:range_gamma_unknown", "two_compartment.toml")


def cpu(fn):
    t = time.process_time()
    out = fn()
    return time.process_time() - t, out


def one(label: str, repeats: int) -> dict:
    system = uj.load_system(str(ROOT / "systems" / label))
    uj.analyze(system)  # warm: the first call of the process is not what is compared
    rows = {"analysis": [], "str + to_dict": [], "follow-ups": [], "str + to_dict after": []}
    for _ in range(repeats):
        t, rep = cpu(lambda: uj.analyze(system))
        rows["analysis"].append(t)
        rows["str + to_dict"].append(cpu(lambda: (str(rep), rep.to_dict()))[0])
        rows["follow-ups"].append(cpu(lambda: (uj.observable_functions(rep), uj.find_symmetries(rep)))[0])
        rows["str + to_dict after"].append(cpu(lambda: (str(rep), rep.to_dict()))[0])
    return {k: statistics.median(v) for k, v in rows.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--only", default="")
    args = ap.parse_args(argv)
    print(f"{'model':40s} {'analysis':>9s} {'str+dict':>9s} {'ratio':>6s} {'follow-ups':>10s} {'str+dict after':>14s}")
    for label in MODELS:
        if args.only not in label:
            continue
        r = one(label, args.repeats)
        print(f"{label:40s} {r['analysis']:9.4f} {r['str + to_dict']:9.4f} "
              f"{r['str + to_dict'] / r['analysis']:6.3f} {r['follow-ups']:10.4f} {r['str + to_dict after']:14.4f}")


if __name__ == "__main__":
    main()
