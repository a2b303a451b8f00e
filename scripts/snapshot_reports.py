"""Every zoo model's ``Report.to_dict()`` at a fixed seed, as one JSON file.

Used to check that a change which should not move any number (a refactor) leaves every
report bit for bit unchanged: run it before and after, then compare the two files
(``tests/test_zoo_snapshot.py`` does this against ``tests/data/zoo_reports.json``).

    python scripts/snapshot_reports.py OUT.json [--samples 256] [--only SUBSTRING]
"""

import argparse
import json
import sys
from pathlib import Path

import uio_jax as uj

ROOT = Path(__file__).resolve().parents[1]


def zoo_entries():
    """The zoo's models (``(label, System or None, error)``) by the batch's own discovery rule."""
    from uio_jax._batch.batch import discover
    entries, _skipped = discover([str(ROOT / "systems")])
    return entries


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--only", default="")
    args = ap.parse_args(argv)
    out = {}
    for entry in zoo_entries():
        label = Path(entry.label.split(":")[0]).name + ":" + entry.label.split(":")[-1]
        if args.only not in label:
            continue
        if entry.system is None:
            out[label] = {"error": entry.error}
            continue
        rep = uj.analyze(entry.system, samples=args.samples, seed=0)
        out[label] = rep.to_dict()
        print(label, rep.dims, file=sys.stderr, flush=True)
    Path(args.out).write_text(json.dumps(out, indent=1, sort_keys=True))


if __name__ == "__main__":
    main()
