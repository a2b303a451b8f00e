"""The package's layout: layers as subpackages, imports only one way, the documented API.

The rule (README, "Layout"): ``A <- B`` means B may import A, never the reverse.

    _errors, _progress, _output  (leaves: import nothing of the package)
      <- _engine                the front end (jaxpr -> expression graph), the graph and its evaluators
      <- _model                 System, sampling, experiments
      <- _calculus              Lie derivatives as graph expressions, the node graph
      <- _analysis              rank certificate, recursion driver, one file per algorithm, report
    _model <- _filter           EKF, Monte Carlo, its result and plots (never an analysis); its fast trig,
                                Jacobian sparsity and compilation cache
    _model, _calculus <- _io    model files, expressions, importers, loaders
    everything <- _batch <- cli <- uio_jax (the public names)

Every import counts, at module level and inside functions. No module imports a private
name (``_x``) of another module, and the module graph has no cycle.
"""

import ast
import re
from pathlib import Path

import pytest

import uio_jax as uj

PACKAGE = Path(uj.__file__).parent

#: layer -> the layers it may import (besides itself).
ALLOWED = {
    "leaf": set(),
    "engine": {"leaf"},
    "model": {"leaf", "engine"},
    "calculus": {"leaf", "model", "engine"},
    "analysis": {"leaf", "model", "engine", "calculus"},
    "filter": {"leaf", "model", "engine"},
    "io": {"leaf", "model", "calculus"},
    "batch": {"leaf", "model", "engine", "calculus", "analysis", "filter", "io"},
    "cli": {"leaf", "model", "engine", "calculus", "analysis", "filter", "io", "batch"},
    "api": {"leaf", "model", "engine", "calculus", "analysis", "filter", "io", "batch", "cli"},
}

WINGS = {"_model": "model", "_engine": "engine", "_calculus": "calculus", "_analysis": "analysis",
         "_filter": "filter", "_io": "io", "_batch": "batch", "cli": "cli"}
LEAVES = {"_errors", "_progress", "_output"}


def layer_of(module: str) -> str:
    """Layer of a dotted module name inside the package (``uio_jax._io.loading`` -> io)."""
    parts = module.split(".")
    if len(parts) == 1:
        return "api"
    if parts[1] in LEAVES:
        return "leaf"
    if parts[1] == "__main__":
        return "cli"
    return WINGS[parts[1]]


def modules(root: Path, package: str):
    """``{dotted name: path}`` of every module under ``root``."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).with_suffix("")
        parts = [package, *rel.parts]
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imports(module: str, path: Path, known: set[str]):
    """``(target module, imported name or None, line)`` of every import of the package.

    ``from X import y`` names the module ``X.y`` when that is a module, else ``(X, y)``.
    """
    tree = ast.parse(path.read_text(), str(path))
    is_pkg = path.name == "__init__.py"
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name.split(".")[0] == base[0]:
                    out.append((a.name, None, node.lineno))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                anchor = base[:len(base) - node.level + 1]
                target = ".".join(anchor + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != base[0]:
                continue
            for a in node.names:
                sub = f"{target}.{a.name}"
                if sub in known:
                    out.append((sub, None, node.lineno))
                else:
                    out.append((target, a.name, node.lineno))
    return out


def violations(root: Path, package: str) -> list[str]:
    """Every break of the layout rule in the package at ``root``, one line each."""
    mods = modules(root, package)
    known = set(mods)
    bad, graph = [], {m: set() for m in mods}
    for mod, path in mods.items():
        here = layer_of(mod)
        where = f"{path.relative_to(root.parent)}"
        for target, name, line in imports(mod, path, known):
            if target not in known:
                bad.append(f"{where}:{line} imports {target}, which is not a module of the package")
                continue
            graph[mod].add(target)
            there = layer_of(target)
            if there != here and there not in ALLOWED[here]:
                bad.append(f"{where}:{line}: layer {here} imports {target} (layer {there})")
            if name is not None and name.startswith("_") and not name.startswith("__") \
                    and target != mod:
                bad.append(f"{where}:{line} imports the private name {name} of {target}")
    bad += [f"import cycle: {' -> '.join(c)}" for c in _cycles(graph)]
    return bad


def _cycles(graph):
    """One cycle per strongly connected component of more than one module (or a self-loop)."""
    index, low, stack, on, comps = {}, {}, [], set(), []

    def visit(v):  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w == v:
                continue
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                comps.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return comps


def test_the_package_keeps_the_layout_rule():
    bad = violations(PACKAGE, "uio_jax")
    assert not bad, "\n".join(bad)


def test_every_module_is_in_a_layer():
    for mod in modules(PACKAGE, "uio_jax"):
        assert layer_of(mod) in ALLOWED, mod


def _fake_package(tmp_path, files):
    root = tmp_path / "uio_jax"
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    for d in [root, *[p for p in root.rglob("*") if p.is_dir()]]:
        (d / "__init__.py").touch()
    return root


@pytest.mark.parametrize("files, expected", [
    # the model layer may not import an importer, even inside a function
    ({"_model/system.py": "def f():\n    from .._io.sympy_import import g\n",
      "_io/sympy_import.py": "g = 1\n"}, r"layer model imports uio_jax\._io\.sympy_import"),
    # the filter never runs an analysis
    ({"_filter/result.py": "from .._analysis import analyze\n", "_analysis/analyze.py": ""},
     r"layer filter imports uio_jax\._analysis\.analyze"),
    # the engine knows nothing of systems
    ({"_engine/graph.py": "from .._model.system import S\n", "_model/system.py": "S = 1\n"},
     r"layer engine imports uio_jax\._model\.system"),
    # the engine never imports an analysis (absolute import)
    ({"_engine/taylor.py": "import uio_jax._analysis.rank\n", "_analysis/rank.py": ""},
     r"layer engine imports uio_jax\._analysis\.rank"),
    # a private name of another module
    ({"_engine/flow.py": "from .taylor import _LINEAR\n", "_engine/taylor.py": "_LINEAR = 1\n"},
     r"private name _LINEAR"),
    # a cycle inside one layer
    ({"_engine/a.py": "from . import b\n", "_engine/b.py": "from .a import x\n"},
     r"import cycle: uio_jax\._engine\.a -> uio_jax\._engine\.b"),
])
def test_the_rule_catches_a_forbidden_import(tmp_path, files, expected):
    """The checker itself can fail: each forbidden import, added to a small package."""
    bad = violations(_fake_package(tmp_path, files), "uio_jax")
    assert any(re.search(expected, b) for b in bad), bad


def test_allowed_imports_pass_the_rule(tmp_path):
    root = _fake_package(tmp_path, {
        "_analysis/orc.py": "from .._calculus.lie import d\nfrom .._errors import E\n",
        "_calculus/lie.py": "from .._model.system import S\nd = 1\n",
        "_model/system.py": "from .._engine import taylor\nS = 1\n",
        "_engine/taylor.py": "from .._errors import E\n", "_errors.py": "E = 1\n"})
    assert violations(root, "uio_jax") == []


def _readme_api_names() -> list[str]:
    text = (PACKAGE.parent / "README.md").read_text()
    block = text.split("<!-- public-api -->")[1].split("<!-- /public-api -->")[0]
    return sorted(re.findall(r"`uj\.(\w+)`", block))


def test_exported_names_equal_the_readme_list():
    """``uio_jax.__all__`` is the list the README documents, and every name is importable."""
    public = sorted(n for n in vars(uj) if not n.startswith("_") and n not in ("cli",))
    assert sorted(uj.__all__) == public
    assert _readme_api_names() == public
    for name in uj.__all__:
        assert getattr(uj, name) is not None
