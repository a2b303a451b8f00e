"""Every zoo report equals the stored snapshot (``tests/data/zoo_reports.json``).

The snapshot was written by ``scripts/snapshot_reports.py`` (256 samples, seed 0); it was
last refreshed when the reports gained their named observable functions and found
symmetries (issue 38: two new keys, every other value unchanged); before that when the
recursions moved to 128 decision samples and a step keeping nothing
got its rejections settled exactly (every certificate's counts and margins moved; four
visual-inertial EORCs no longer stop on a false "Omega-bar closed" but run to k_max, with
the same verdicts on the states and more input derivatives observable). Refreshed again
when the EORC learned to stop at the known-input bound (four visual-inertial EORCs stop at
k = 2 or 7 instead of k_max, with the same verdicts, now exact) and clear rejections after a
contradicted float64 vote were verified exactly (every certificate gained
``rejections_verified``; the uncalibrated Vi-SfM EORC's counts moved, its verdicts did
not), then for the degree bounds of modular dependences (common denominators shared: three
probability bounds of the partial Vi-SfM EORCs went down by about 1000x), and when the
exact checks of the trial span that computes a dimension were counted in
``Certificate.verified`` (14 counts grew), and when Systems could declare symmetries (every
EORC report gained ``details["symmetries"]``, None without any; the uncalibrated Vi-SfM
with one accelerometer declares its internal rotation and stops at its bound, k = 10
instead of 25, same verdicts, now exact). Refreshed when every decision became exact (issue 37:
constants exact, elementary functions made rational modulo p, every vote verified; every
certificate gained its arithmetic and counts, the screen of an exact analysis stops at the
decision samples, the general solution's zero tests count the extension's chain tests, a
report keeps its StopReason member as ``stop``; every verdict, dimension and step unchanged,
57 of 57 analysed reports exact in arithmetic), then when every answer for switchable known
inputs gained the note on the other meaning (issue 40), and when every report gained
``question`` (``generic_states``; issue 39: the known-initial-state analysis answers another).
Refreshed when the symmetry check settled its zero tests with the Settler (issue 47 item 7: the
``how`` of every found or declared symmetry and the probability it reports, charged to the five
reports whose EORC or declared symmetries use it) and the named functions gained the
identifiable combinations (``observable_functions.combinations``, ``combinations_dim``): every
verdict, dimension, named function and symmetry field unchanged. Entries added, no report
moved: the Vi-SfM with partial input knowledge at the paper's orders
(``visual_inertial_no_offset.py``) and the standard Vi-SfM with a full IMU
(``visual_inertial_standard.py``). Refreshed when the analysis wing got its floor plan (issue
44): every report gained ``answer``, ``route`` and ``plan`` (what the chooser decided before
any sample, and why); every other value unchanged; the follow-up answers are the script's
(:func:`snapshot_reports.snapshot` asks them, as the CLI does: ``to_dict`` runs no search). A change that
should move no number (a refactor) must leave every report equal. Integers, booleans,
strings and labels compare exactly; floats (singular-value margins of the certificate) to a
relative 1e-9, so that a new XLA build's last-bit differences do not fail the test while any
real change does.

To refresh after a change that is meant to move numbers: rerun the script, read the diff
(``--compare`` prints it), and commit the new file with the reason.

Every zoo file is in it (the whole zoo takes about a minute at 256 samples since the
analyses evaluate the models' expression graphs instead of compiling programs; the
visual-inertial EORCs, the multi-UI general solutions and the Vi-SfM with partial input
knowledge used to take tens of minutes and were left out).
"""

import json
import math
import os

import pytest
from conftest import ROOT
from helpers import script_module

with open(os.path.join(ROOT, "tests", "data", "zoo_reports.json")) as _fh:
    SNAPSHOT = json.load(_fh)
#: Files left out of the comparison (none: every zoo report is compared).
HEAVY = ()
#: Files whose reports are not in the snapshot at all (none).
UNRECORDED = ()


def _script():
    return script_module("snapshot_reports")


def _close(old, new, path=""):
    """The first place where two JSON values differ beyond the float tolerance, or None."""
    if isinstance(old, dict) and isinstance(new, dict):
        if set(old) != set(new):
            return f"{path}: keys {sorted(set(old) ^ set(new))}"
        return next((d for k in sorted(old) if (d := _close(old[k], new[k], f"{path}/{k}"))), None)
    if isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            return f"{path}: length {len(old)} -> {len(new)}"
        return next((d for i, (a, b) in enumerate(zip(old, new)) if (d := _close(a, b, f"{path}[{i}]"))),
                    None)
    if isinstance(old, float) and isinstance(new, float):
        return None if math.isclose(old, new, rel_tol=1e-9, abs_tol=0.0) else f"{path}: {old!r} -> {new!r}"
    return None if (type(old) is type(new) and old == new) else f"{path}: {old!r} -> {new!r}"


@pytest.fixture(scope="module")
def entries():
    script = _script()
    return {script.snapshot_label(e.label): e for e in script.zoo_entries()}


def test_the_snapshot_covers_the_zoo(entries):
    assert sorted(k for k in entries if not (UNRECORDED and k.startswith(UNRECORDED))) == sorted(SNAPSHOT)


@pytest.mark.slow
@pytest.mark.parametrize("label", [k for k in sorted(SNAPSHOT) if not (HEAVY and k.startswith(HEAVY))])
def test_report_equals_the_snapshot(entries, label):
    entry = entries[label]
    if "error" in SNAPSHOT[label]:
        assert entry.system is None and entry.error == SNAPSHOT[label]["error"]
        return
    got = json.loads(json.dumps(_script().snapshot(entry.system, 256)))
    assert _close(SNAPSHOT[label], got) is None, _close(SNAPSHOT[label], got)
