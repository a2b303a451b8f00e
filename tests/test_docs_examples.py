"""Every example of the README and of ``docs/*.md`` runs as written (issue 47 item 9).

The fenced ``python`` and ``bash`` blocks are read from the files themselves. Python blocks
run in order in one namespace per file (a later block uses the names of an earlier one);
each line of a bash block runs in a shell. The working directory holds what the examples
name: ``systems/`` and ``scripts/`` of this checkout, and the files an example only
supposes (``model.xml`` with species ``S1``, ``S2`` and an inflow ``k_in`` in a compartment
``V``; ``observables.tsv``; a folder ``models/`` of SBML files with ``P`` and ``k_in``).

Not run, each for the reason listed in :data:`NOT_RUN`: installing the package, running this
suite from inside itself, and starting Dask servers on other hosts. The heavy commands (the
whole zoo, the papers' numbers, Monte Carlo trials) are marked slow.
"""

import os
import re
import shlex
import subprocess
import sys

import pytest
from conftest import ROOT

#: Lines of bash blocks not run, and why (matched at the start of the line).
NOT_RUN = {
    "pip install": "installs the package (the suite runs on the installed one)",
    "dask ": "starts cluster servers on other hosts",
}
#: Lines run only with ``-m slow`` (minutes each).
HEAVY = ("uio-jax batch systems/", "python scripts/reproduce_papers.py", "uio-jax montecarlo")

DOCS = ["README.md"] + sorted(os.path.join("docs", f) for f in os.listdir(os.path.join(ROOT, "docs"))
                             if f.endswith(".md"))


def _blocks(name):
    with open(os.path.join(ROOT, name), encoding="utf-8") as fh:
        text = fh.read()
    return re.findall(r"```(python|bash)\n(.*?)```", text, re.S)


def _bash_lines(name):
    out = []
    for lang, body in _blocks(name):
        if lang != "bash":
            continue
        body = body.replace("\\\n", " ")
        for line in body.splitlines():
            line = line.split("  #")[0].split(" # ")[0].strip()
            if line and not line.startswith("#"):
                out.append(line)
    return out


def _skip_reason(line):
    for start, why in NOT_RUN.items():
        if line.startswith(start):
            return why
    if "--scheduler tcp://A:" in line:
        return "needs a Dask scheduler on host A"
    if "python -m pytest" in line:
        return "runs this suite"
    return ""


def _cases():
    for name in DOCS:
        for line in _bash_lines(name):
            why = _skip_reason(line)
            if why:
                continue
            marks = [pytest.mark.slow] if line.startswith(HEAVY) else []
            yield pytest.param(name, line, marks=marks, id=f"{name}:{line[:60]}")


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A directory with what the examples name (module docstring)."""
    pytest.importorskip("libsbml")
    from test_sbml import Builder

    here = tmp_path_factory.mktemp("examples")
    for d in ("systems", "scripts"):
        os.symlink(os.path.join(ROOT, d), here / d)
    (here / "tests" / "data").mkdir(parents=True)  # the model files docs/global.md reads
    os.symlink(os.path.join(ROOT, "tests", "data", "global"), here / "tests" / "data" / "global")
    (Builder().compartment("V", 2.0).species("S1", "V").species("S2", "V")
     .parameter("k_in", 0.5).parameter("k1", 0.3).parameter("k2", 0.2)
     .reaction("inflow", {}, {"S1": 1}, "k_in")
     .reaction("conversion", {"S1": 1}, {"S2": 1}, "k1*S1*V")
     .reaction("decay", {"S2": 1}, {}, "k2*S2*V").write(here / "model.xml"))
    (here / "observables.tsv").write_text("observableId\tobservableFormula\tnoiseFormula\ny\tS1 + S2\t1\n")
    (here / "models").mkdir()
    (Builder().compartment("c", 1).species("S", "c").species("P", "c").parameter("k_in", 0.4).parameter("k", 0.3)
     .reaction("feed", {}, {"S": 1}, "k_in").reaction("make", {"S": 1}, {"P": 1}, "k*S")
     .write(here / "models" / "m1.xml"))
    return here


def test_every_bash_line_is_run_or_has_a_reason():
    """Nothing is left out silently: the lines not run are exactly those with a reason."""
    lines = [line for name in DOCS for line in _bash_lines(name)]
    assert lines and all(_skip_reason(line) or any(c.values[1] == line for c in _cases()) for line in lines)


@pytest.mark.parametrize("name, line", list(_cases()))
def test_bash_example_runs_as_written(workdir, name, line, monkeypatch, capsys):
    """A ``uio-jax`` line runs through the command's own entry point in this process (the
    same argv, without starting Python again); anything else in a shell."""
    if line.startswith("uio-jax ") and not set(line) & set("|&;<>$`"):
        from uio_jax.cli import main

        monkeypatch.chdir(workdir)
        code = main(shlex.split(line)[1:])
        out, err = capsys.readouterr()
        assert code == 0, f"{name}: {line}\n{out[-3000:]}\n{err[-3000:]}"
        return
    env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    proc = subprocess.run(line, shell=True, cwd=workdir, capture_output=True, text=True, env=env, timeout=3000)
    assert proc.returncode == 0, f"{name}: {line}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"


@pytest.mark.parametrize("name", [n for n in DOCS if any(lang == "python" for lang, _ in _blocks(n))])
def test_python_examples_run_as_written(workdir, name, monkeypatch):
    monkeypatch.chdir(workdir)
    namespace = {"__name__": "__example__"}
    for lang, body in _blocks(name):
        if lang == "python":
            exec(compile(body, f"{name} (example)", "exec"), namespace)  # noqa: S102 - the docs' own code
