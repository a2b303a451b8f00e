"""The analysis wing's floor plan (README, "Layout"; issue 44), as rules that can fail.

* **One chooser.** The route and the method are chosen in exactly one function,
  :func:`uio_jax._analysis.plan.plan` (its predicates ``choose_method`` and
  ``taylor_applicable`` are called nowhere else); the Taylor route's fallback is caught in
  exactly one place, the dispatch of that plan.
* **The arithmetic in one place.** Whether a decision is made modulo p or in extended
  precision is decided by ``Settler.arithmetic`` alone: the rationality predicates of the
  engine (``rationalizable``, the generators' ``independent``, ``generator_keys``) are called
  in ``decisions/settle.py`` only, and ``arithmetic`` is defined once.
* **Results are members, not text.** No ``startswith``/``endswith`` in the analysis wing
  outside the two modules that *write* expression text (the printer of named functions and
  the mixing coefficients of a verified symmetry), and no ``hasattr`` on a report.
* **A Report and the questions asked of it.** ``Report.method``/``route``/``answer`` are
  members; ``str(rep)`` and ``rep.to_dict()`` run no search; the follow-up questions are
  functions of a report whose answers the report keeps.
"""

import ast
import dataclasses
import json
from pathlib import Path

import pytest

import uio_jax as uj

PACKAGE = Path(uj.__file__).parent
WING = PACKAGE / "_analysis"

#: Modules of the wing that build expression text (a sign in front of a term), with the
#: reason: they write text, they never read a result back.
TEXT_WRITERS = {"followups/expression_text.py", "decisions/symmetry.py"}
#: ``hasattr`` on a value that is not a report: an initial state given as a mapping or not, an
#: initial value given as a numpy or JAX scalar or not (input checks of the user's values).
HASATTR_ALLOWED = {("at_t0/initial.py", "initial"), ("at_t0/initial.py", "value")}


def calls(root: Path, names: set[str]) -> list[tuple[str, str, str]]:
    """``(module path, enclosing function, called name)`` of every call of a name in
    ``names`` (``f(...)`` or ``x.f(...)``) in the package at ``root``."""
    out = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text())
        for func in [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.Module))]:
            for node in ast.walk(func):
                if not isinstance(node, ast.Call):
                    continue
                f = node.func
                name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else None
                if name in names:
                    where = func.name if isinstance(func, ast.FunctionDef) else "<module>"
                    out.append((path.relative_to(root).as_posix(), where, name))
    # a call inside a function is also seen from the module: keep the innermost only
    inner = {(p, n) for p, w, n in out if w != "<module>"}
    return sorted({c for c in out if c[1] != "<module>" or (c[0], c[2]) not in inner})


def chooser_violations(root: Path) -> list[str]:
    """Calls of the route's predicates outside ``plan.plan``, catches of ``NotTaken`` outside
    ``analyze.dispatch``."""
    bad = [f"{p}:{w} calls {n}" for p, w, n in calls(root, {"choose_method", "taylor_applicable"})
           if (p, w) not in {("_analysis/plan.py", "plan"), ("_analysis/plan.py", "choose_method")}]
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ExceptHandler) and isinstance(node.type, ast.Name) and node.type.id == "NotTaken":
                rel = path.relative_to(root).as_posix()
                if rel != "_analysis/analyze.py":
                    bad.append(f"{rel} catches NotTaken")
    return bad


def arithmetic_violations(root: Path) -> list[str]:
    """Calls of the rationality predicates outside ``decisions/settle.py`` (the engine, which
    defines them, aside), and more than one chooser ``def arithmetic(self, exprs)`` (a
    certificate's ``arithmetic`` property reads what was used; it chooses nothing)."""
    wing = root / "_analysis"
    bad = [f"_analysis/{p}:{w} calls {n}" for p, w, n in calls(wing, {"rationalizable", "independent",
                                                                       "generator_keys", "exact_capable"})
           if p != "decisions/settle.py"]
    defs = [path.relative_to(wing).as_posix() for path in sorted(wing.rglob("*.py"))
            for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.FunctionDef) and node.name == "arithmetic" and len(node.args.args) > 1]
    if defs != ["decisions/settle.py"]:
        bad.append(f"arithmetic is defined in {defs}")
    return bad


def text_violations(root: Path) -> list[str]:
    """``startswith``/``endswith`` in the analysis wing outside :data:`TEXT_WRITERS`, and
    ``hasattr`` outside :data:`HASATTR_ALLOWED`."""
    wing = root / "_analysis"
    bad = [f"_analysis/{p}:{w} calls {n}" for p, w, n in calls(wing, {"startswith", "endswith"})
           if p not in TEXT_WRITERS]
    for path in sorted(wing.rglob("*.py")):
        rel = path.relative_to(wing).as_posix()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "hasattr":
                target = ast.unparse(node.args[0]) if node.args else ""
                if (rel, target) not in HASATTR_ALLOWED:
                    bad.append(f"_analysis/{rel}:{node.lineno} hasattr({target}, ...)")
    return bad


@pytest.mark.parametrize("checker", [chooser_violations, arithmetic_violations, text_violations])
def test_the_package_keeps_the_floor_plan(checker):
    assert checker(PACKAGE) == []


def _fake(tmp_path, files):
    root = tmp_path / "uio_jax"
    for rel, text in files.items():
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text(text)
    return root


@pytest.mark.parametrize("files, checker, expected", [
    # a second chooser: a recursion that decides the route itself
    ({"_analysis/recursions/orc.py": "def run(s):\n    return taylor_applicable(s)\n"}, chooser_violations,
     "_analysis/recursions/orc.py:run calls taylor_applicable"),
    ({"_analysis/analyze.py": "def _run(s):\n    return choose_method(s)\n"}, chooser_violations,
     "_analysis/analyze.py:_run calls choose_method"),
    ({"_analysis/recursions/x.py": "try:\n    pass\nexcept NotTaken:\n    pass\n"}, chooser_violations,
     "_analysis/recursions/x.py catches NotTaken"),
    # the arithmetic chosen again beside the Settler
    ({"_analysis/decisions/symmetry.py": "def ok(g, r):\n    return graph_independence.rationalizable(g, r)\n"},
     arithmetic_violations, "_analysis/decisions/symmetry.py:ok calls rationalizable"),
    ({"_analysis/decisions/settle.py": "def arithmetic(self, x):\n    pass\n",
      "_analysis/followups/names.py": "def arithmetic(self, x):\n    pass\n"},
     arithmetic_violations, "arithmetic is defined in ['decisions/settle.py', 'followups/names.py']"),
    # a result's text parsed back, a report probed by hasattr
    ({"_analysis/results/report.py": "def exact(r):\n    return r.answer_kind().startswith('exact')\n"},
     text_violations, "_analysis/results/report.py:exact calls startswith"),
    ({"_analysis/followups/questions.py": "def f(rep):\n    return hasattr(rep.space, 'parts')\n"},
     text_violations, "_analysis/followups/questions.py:2 hasattr(rep.space, ...)"),
])
def test_the_floor_plan_checkers_can_fail(tmp_path, files, checker, expected):
    assert expected in checker(_fake(tmp_path, files))


# ------------------------------------------------------------------ the report
@pytest.fixture(scope="module")
def vehicle():
    return uj.analyze(uj.load_system(str(PACKAGE.parent / "systems" / "vehicle_wind.py") + ":no_wind"),
                      samples=256)


def test_the_report_keeps_members_and_the_plan(vehicle):
    assert vehicle.method is uj.Method.ORC and vehicle.method == "orc" and f"{vehicle.method}" == "orc"
    assert vehicle.route is uj.Route.SYMBOLIC and vehicle.answer is uj.Answer.EXACT and vehicle.exact
    plan = vehicle.plan
    assert plan.method is uj.Method.ORC and plan.arithmetic.name == "EXACT" and plan.fallback is None
    assert "no unknown input -> ORC" in plan.why and "modulo p" in plan.why
    d = json.loads(vehicle.to_json())
    assert d["method"] == "orc" and d["route"] == "symbolic" and d["answer"] == "exact"
    assert d["plan"]["route"] == "symbolic" and d["plan"]["arithmetic"] == "exact"


def test_printing_and_serialising_run_no_search(vehicle, monkeypatch):
    """``str(rep)`` and ``rep.to_dict()`` serialise what was computed: the follow-ups appear
    once asked, and asking again returns the kept answer."""
    from uio_jax._analysis.followups import questions

    rep = dataclasses.replace(vehicle, followups=type(vehicle.followups)())
    searched = []
    real = questions.name_functions
    monkeypatch.setattr(questions, "name_functions", lambda *a, **k: searched.append(1) or real(*a, **k))
    assert "observable_functions" not in rep.to_dict() and "observable functions:" not in str(rep)
    assert searched == []
    named = uj.observable_functions(rep)
    assert uj.observable_functions(rep) is named and searched == [1]
    assert rep.to_dict()["observable_functions"] == named.to_dict()
    assert "observable functions:" in str(rep) and rep.named_functions is named  # the alias
    found = uj.find_symmetries(rep)
    assert rep.symmetries is found and rep.to_dict()["found_symmetries"] == found.to_dict()


def test_the_plan_is_public_and_chooses_before_sampling():
    system = uj.load_system(str(PACKAGE.parent / "systems" / "unicycle_polar.py") + ":range_v_unknown")
    plan = uj.plan(system.autonomous())
    assert plan.method is uj.Method.SINGLE_UI and plan.route is uj.Route.SYMBOLIC
    with pytest.raises(uj.OptionError, match="needs every input known"):
        uj.plan(system.autonomous(), "orc")


def test_follow_ups_refuse_what_is_not_a_report():
    with pytest.raises(uj.ModelError, match="needs the Report of uj.analyze"):
        uj.observable_functions("not a report")
