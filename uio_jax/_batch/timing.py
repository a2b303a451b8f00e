"""Each model's recorded batch time, and the longest-first order of a parallel batch.

With a cache directory (:func:`uio_jax.enable_compile_cache`), every batch records each
model's time in ``batch_seconds.json`` there (keyed by the model's spec and the analysis
options); the workers of a later batch take the models longest first (models without a time
first), so that no long model started last leaves the other workers idle at the end.
"""

import contextlib
import json
import math
import os

from .._filter.compile_cache import cache_dir_in_use
from .rows import BatchRow

#: File in the cache directory with each model's last batch time in seconds.
SECONDS_FILE = "batch_seconds.json"


def time_key(entry, analyze_kwargs):
    """Key of a model's recorded time: its spec and the analysis options (None: an
    in-memory System or a failed entry, never recorded)."""
    if entry.spec is None or entry.error is not None:
        return None
    opts = ",".join(f"{k}={v!r}" for k, v in sorted(analyze_kwargs.items()) if v is not None)
    if entry.options:  # an SBML model's outputs and inputs: another model
        opts += "|" + ",".join(f"{k}={v!r}" for k, v in sorted(entry.options.items()))
    return f"{entry.kind}|{entry.spec}|{opts}"


def _seconds_path():
    d = cache_dir_in_use()
    return None if d is None else os.path.join(d, SECONDS_FILE)


def _read_seconds(path):
    """The recorded times (a dict); empty without a cache directory, a file, or a valid one."""
    try:
        with open(path, encoding="utf-8") as f:
            known = json.load(f)
    except (TypeError, OSError, ValueError):
        return {}
    return known if isinstance(known, dict) else {}


def recorded_seconds(keys):
    """Recorded time in seconds of each key of :func:`time_key` (None: unknown)."""
    known = _read_seconds(_seconds_path())
    out = []
    for k in keys:
        v = known.get(k) if k is not None else None
        out.append(float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None)
    return out


def record_seconds(keys, rows):
    """Add this batch's times (``rows[i].seconds`` under ``keys[i]``) to the file in the
    cache directory (atomic replace; a cache directory that cannot be written only loses
    the ordering of the next batch)."""
    path = _seconds_path()
    if path is None:
        return
    known = _read_seconds(path)
    for k, row in zip(keys, rows):
        if k is not None and isinstance(row, BatchRow):
            known[k] = round(float(row.seconds), 3)
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as f:
            json.dump(known, f, indent=0, sort_keys=True)
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            os.remove(tmp)


def longest_first(todo, recorded):
    """``todo`` (entry indices) reordered: unknown times first in the given order, then
    decreasing recorded time (a stable sort); ``recorded[i]`` is entry i's time or None."""
    if not recorded:
        return list(todo)
    return sorted(todo, key=lambda i: -math.inf if recorded[i] is None else -recorded[i])
