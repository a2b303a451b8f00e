"""Every zoo model's ``Report.to_dict()`` at a fixed seed, as one JSON file.

Used to check that a change which should not move any number (a refactor) leaves every
report bit for bit unchanged: run it before and after, then compare the two files
(``tests/test_zoo_snapshot.py`` does this against ``tests/data/zoo_reports.json``).

    python scripts/snapshot_reports.py OUT.json [--samples 256] [--only SUBSTRING] [--compare OLD.json]

With ``--compare`` it prints every model whose report differs from OLD.json (the first
differing key) and exits 1 when one does.
"""

import argparse
import json
import sys
from pathlib import Path

import uio_jax as uj

ROOT = Path(__file__).resolve().parents[1]


def zoo_entries():
    """The zoo's models (``(label, System or None, error)``) by the batch's own discovery rule."""
    from uio_jax._batch.discovery import discover
    entries, _skipped = discover([str(ROOT / "systems")])
    return entries


def snapshot_label(label: str) -> str:
    """``FILE.py:NAME`` or ``MODEL.toml`` without the directory (the same on every checkout)."""
    path, sep, name = label.rpartition(":")
    return Path(path).name + sep + name if sep else Path(label).name


def snapshot(system, samples: int = 256) -> dict:
    """The snapshot of one model: ``Report.to_dict()`` at seed 0 with the follow-up answers
    (observable functions named, symmetries found) asked first, as the CLI prints them."""
    rep = uj.analyze(system, samples=samples, seed=0)
    uj.observable_functions(rep)
    uj.find_symmetries(rep)
    return rep.to_dict()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--samples", type=int, default=256)
    ap.add_argument("--only", default="")
    ap.add_argument("--compare", metavar="OLD.json", help="compare with an earlier snapshot")
    args = ap.parse_args(argv)
    out = {}
    for entry in zoo_entries():
        label = snapshot_label(entry.label)
        if args.only not in label:
            continue
        if entry.system is None:
            out[label] = {"error": entry.error}
            continue
        out[label] = snapshot(entry.system, args.samples)
        print(label, out[label].get("dims"), file=sys.stderr, flush=True)
    Path(args.out).write_text(json.dumps(out, indent=1, sort_keys=True))
    if args.compare:
        return compare(json.loads(Path(args.compare).read_text()), json.loads(json.dumps(out)))
    return 0


def first_difference(a, b, path=""):
    """The first key path where two JSON values differ, or None when they are equal."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}/{k} (only in {'new' if k in b else 'old'})"
            d = first_difference(a[k], b[k], f"{path}/{k}")
            if d:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_difference(x, y, f"{path}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{path}: {a!r} -> {b!r}"


def compare(old: dict, new: dict) -> int:
    """Print the models whose reports differ; 1 when any does, else 0."""
    bad = 0
    for label in sorted(new):
        if label not in old:
            print(f"{label}: not in the old snapshot")
            continue
        d = first_difference(old[label], new[label])
        if d:
            bad += 1
            print(f"{label}: {d}")
    print(f"{len(new) - bad} of {len(new)} reports equal")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
