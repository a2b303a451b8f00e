"""``uio-jax batch DIR`` executes only the Python files that declare themselves zoo files
(``# uio-jax: models``), those the user names, or all with ``--import-python``; a StrikePy
module is parsed, never executed."""

import os
import textwrap

import pytest
from helpers import zoo_path

import uio_jax as uj
from uio_jax import cli
from uio_jax._batch import discovery

SAMPLES = 64


def _write(path, source):
    path.write_text(textwrap.dedent(source))
    return str(path)


def _plain(flag):
    """A plain module whose top level creates ``flag`` when it runs."""
    return f"""
        import pathlib
        pathlib.Path({str(flag)!r}).write_text("ran")
        import uio_jax as uj

        def model():
            return uj.System(("a",), {{"y": lambda x: x[0]}})
        """


def _strikepy_looking(flag):
    """Looks like a StrikePy module (imports sympy, x and f at top level) but has no ``h``
    (so it is no StrikePy module to the check) and a side effect at its top level."""
    return f"""
        import os
        import sympy as sym
        os.system("touch {flag}")
        x1 = sym.Symbol("x1")
        x = [[x1]]
        f = [[-x1]]
        y = [x1]
        """


def _strikepy_with_side_effect(flag):
    """A StrikePy module (x, f, h) with a side effect at its top level: parsed, so the
    statement is the row's error and never runs."""
    return f"""
        import os
        import sympy as sym
        x1 = sym.Symbol("x1")
        os.system("touch {flag}")
        x = [[x1]]
        f = [[-x1]]
        h = [x1]
        """


MARKED = """\
# uio-jax: models
import uio_jax as uj

def marked():
    return uj.System(("a", "b"), {"y": lambda x: x[0] + x[1] ** 2})  # no dynamics: dim 1
"""


@pytest.fixture
def folder(tmp_path):
    d = tmp_path / "models"
    d.mkdir()
    flags = {k: tmp_path / f"{k}.flag" for k in ("plain", "looking", "strike")}
    _write(d / "plain.py", _plain(flags["plain"]))
    _write(d / "looking.py", _strikepy_looking(flags["looking"]))
    _write(d / "strike.py", _strikepy_with_side_effect(flags["strike"]))
    (d / "zoo.py").write_text(MARKED)
    return d, flags


def test_batch_dir_runs_only_marked_files(folder, capsys):
    d, flags = folder
    assert cli.main(["batch", str(d), "--samples", str(SAMPLES), "--no-cache", "--no-progress"]) == 1
    out = capsys.readouterr().out
    assert not any(f.exists() for f in flags.values())  # no top-level code of theirs ran
    for name in ("plain.py", "looking.py"):
        assert f"not imported: {d / name} (no '# uio-jax: models' marker" in out
    assert "2 .py files not imported" in out
    assert "zoo.py:marked" in out and "1 / 2" in out  # the marked zoo file ran
    assert "strike.py" in out and "FAILED" in out and "not supported" in out  # parsed: its error


def test_library_skips_unmarked_files_with_the_reason(folder):
    d, flags = folder
    res = uj.batch_analyze(str(d), samples=SAMPLES, progress=False)
    assert [r.model for r in res] == [str(d / "strike.py"), f"{d / 'zoo.py'}:marked"]
    assert set(res.not_imported) == {str(d / "plain.py"), str(d / "looking.py")}
    assert dict(res.skipped)[str(d / "plain.py")] == discovery.NOT_IMPORTED
    assert "name the file or pass --import-python" in discovery.NOT_IMPORTED
    glob_res = uj.batch_analyze(str(d / "*.py"), samples=SAMPLES, progress=False)  # a glob: the same
    assert [r.model for r in glob_res] == [r.model for r in res]
    assert not any(f.exists() for f in flags.values())


def test_named_files_and_import_python_are_imported(folder):
    d, flags = folder
    entries, skipped = discovery.discover(str(d / "plain.py"), build=False)  # named: imported
    assert [e.label.rpartition(":")[2] for e in entries] == ["model"] and skipped == []
    assert flags["plain"].exists()
    flags["plain"].unlink()
    discovery.discover(str(d), build=False, import_python=True)
    assert flags["looking"].exists()  # every unmarked file is imported when asked for
    assert not flags["strike"].exists()  # but a StrikePy module is still only parsed


@pytest.mark.parametrize("text, marked", [
    ("# uio-jax: models\n", True),
    ("#!/usr/bin/env python\n# -*- coding: utf-8 -*-\n#uio-jax:models\n", True),
    ("#   UIO-JAX :  Models   \n", True),
    ("\n" * discovery.MARKER_LINES + "# uio-jax: models\n", False),  # too far down
    ("x = 1  # uio-jax: models\n", False),  # not alone on its line
    ("# uio-jax: models, maybe\n", False),
    ('"""# uio-jax: models"""\n', False),
])
def test_the_marker_rule(tmp_path, text, marked):
    path = tmp_path / "m.py"
    path.write_text(text + "def f():\n    return 1\n")
    assert discovery.has_zoo_marker(path) is marked


def test_every_zoo_file_is_marked():
    """``uio-jax batch systems/`` certifies the whole zoo: every systems/*.py declares itself."""
    folder = os.path.dirname(zoo_path("gps"))
    files = sorted(f for f in os.listdir(folder) if f.endswith(".py") and not f.startswith("_"))
    assert files and all(discovery.has_zoo_marker(os.path.join(folder, f)) for f in files)
    entries, skipped = discovery.discover(folder, build=False)
    assert not [name for name, why in skipped if why == discovery.NOT_IMPORTED]
    every, _ = discovery.discover(folder, build=False, import_python=True)
    assert [e.label for e in entries] == [e.label for e in every] and len(entries) > 40  # 44 today
