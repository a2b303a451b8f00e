"""``scripts/reproduce_papers.py``: the rows of a published entry, a documented difference,
the notes written under the table."""

import types

from helpers import script_module


def test_a_documented_difference_is_its_own_status_and_any_other_value_fails():
    script = script_module("reproduce_papers")
    pub = {"differs": {"k_first": {"ours": 3, "why": "notes"}}}
    rows = [("dim", 21, 21, True), ("first order at the verdict", 2, 3, False)]
    assert script._documented("one_acc", pub, rows) == [rows[0], ("first order at the verdict", 2, 3, "differs")]
    moved = [("first order at the verdict", 2, 4, False)]  # not the documented value: a failure
    assert script._documented("one_acc", pub, moved) == moved
    assert script._documented("other", {}, rows) == rows  # nothing documented: unchanged


def test_first_order_and_exact_rows():
    script = script_module("reproduce_papers")
    rep = types.SimpleNamespace(dim=21, dims=(10, 15, 20, 21, 21), exact=True, details={})
    system = types.SimpleNamespace(box=lambda: (0.0, 1.0))
    rows = script._compare(None, "x", {"k_first": 2, "exact": True}, rep, system)
    assert rows == [("first order at the verdict", 2, 3, False), ("exact verdict", True, True, True)]


def test_notes_come_from_the_zoo_files():
    script = script_module("reproduce_papers")
    mods = [("a.py", types.SimpleNamespace(REPRODUCTION_NOTES="\n**A.** words\n")),
            ("b.py", types.SimpleNamespace())]
    assert script._notes(mods) == "\n## Notes\n\n### `a.py`\n\n**A.** words\n"
    assert script._notes(mods[1:]) == ""
