"""Read StrikePy / STRIKE-GOLDD model modules without importing (executing) them.

A StrikePy model is a Python file that builds sympy symbols and lists::

    import sympy as sym
    x1, x2 = sym.symbols('x1 x2')      # or x1 = sym.Symbol('x1')
    p1 = sym.Symbol('p1')
    x = [[x1], [x2]]                    # states          (nested or flat lists)
    p = [[p1]]                          # unknown constant parameters
    u = [];  w = []                     # known / unknown inputs (optional)
    h = [x1]                            # outputs
    f = [[-p1*x1 + x2], [x1 - x2]]      # dynamics x' = f(x, p, u, w)
    variables_locales = locals().copy()

The source is parsed with :mod:`ast` and only these statements are interpreted:
imports (the aliases of sympy are recorded, and the functions imported from sympy or math;
other imports ignored), docstrings,
``variables_locales = locals().copy()`` (ignored), and assignments whose value is

* ``sym.Symbol('a')`` / ``sym.symbols('a b, c')`` (or ``Symbol``/``symbols`` imported from
  sympy); keyword arguments such as ``real=True`` are ignored;
* a list (or tuple) literal of such values;
* an arithmetic expression under the whitelist of :mod:`uio_jax._io.expressions`, where
  functions are called on the sympy alias (``sym.exp(x)``, ``sympy.sin(x)``), bare when
  imported from sympy, and ``sym.pi``, ``sym.E``, ``sym.Rational(1, 2)``,
  ``sym.Integer(2)``, ``sym.Float(0.5)`` are accepted. Names bound to expressions
  (auxiliary functions, numeric constants) are substituted where they are used.

Anything else raises a one-line :class:`uio_jax.LoadError` naming the file and line.

Meaning (StrikePy's): ``x`` states, ``p`` unknown constant parameters (sampled in
``DEFAULT_BOX`` = [0.5, 1.5]), ``u`` known inputs, ``w`` unknown inputs, ``f`` the
dynamics (general form, split by :mod:`uio_jax._io.affine`; non-affine inputs are promoted
to states), ``h`` the outputs (named after the state when an output is a single state,
``y1, y2, ...`` otherwise). Symbols used in ``f``/``h`` that are in none of ``x, p, u, w``
are **known constants** for StrikePy; each gets the fixed generic value :func:`generic_value`,
listed in the System's notes.
"""

import ast
import hashlib
import keyword
import os
import re

from .._errors import ExpressionError, LoadError, UioJaxError
from .expressions import Binary, Call, Converter, Name, names_of, substitute, to_text

_MAX_SOURCE = 2_000_000
_ROLES = ("x", "p", "u", "w", "f", "h")
_SYMPY_CONSTANTS = {"pi": Name("pi"), "E": Name("E")}
_BUILTINS = ("abs", "min", "max", "pow")


def generic_value(name: str) -> float:
    """The value given to a StrikePy known constant: ``0.5 + (SHA-256(name) mod 10^4) / 10^4``.

    A generic number in [0.5, 1.5) with four decimals: deterministic, different for
    different names (with high probability), never 0 or 1 (values that could make a
    generic rank drop by accident).
    """
    digest = int(hashlib.sha256(name.encode("utf-8")).hexdigest()[:12], 16)
    v = 0.5 + (digest % 10_000) / 10_000
    return 0.5001 if v in (0.5, 1.0) else v


def is_strikepy_module(path) -> bool:
    """Cheap check that ``path`` looks like a StrikePy model module (read, not parsed).

    True for a ``.py`` file that imports sympy and assigns ``x``, ``f`` and ``h`` at top
    level.
    """
    path = os.fspath(path)
    if not path.endswith(".py") or not os.path.isfile(path):
        return False
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            text = fh.read(_MAX_SOURCE)
    except OSError:
        return False
    if not re.search(r"^\s*(import\s+sympy|from\s+sympy\b)", text, re.M):
        return False
    return all(re.search(rf"^{v}\s*=", text, re.M) for v in ("x", "f", "h"))


def _source(path) -> str:
    """The text of the module at ``path`` (at most ``_MAX_SOURCE`` characters).

    Raises:
        LoadError: missing, unreadable or too large.
    """
    if not os.path.isfile(path):
        raise LoadError(f"StrikePy model not found: {path}")
    try:
        with open(path, encoding="utf-8") as fh:
            text = fh.read(_MAX_SOURCE + 1)
    except (OSError, UnicodeDecodeError) as exc:
        raise LoadError(f"{path}: cannot read: {exc}") from None
    if len(text) > _MAX_SOURCE:
        raise LoadError(f"{path}: larger than {_MAX_SOURCE} characters")
    return text


def read_strikepy(path):
    """Parse a StrikePy model module into a :class:`uio_jax._io.model_spec.ModelSpec` (general form).

    Raises:
        LoadError: missing file, Python syntax error, or a statement / expression outside
            what is interpreted (one line naming the file and line).
        ModelError: the lists are inconsistent (e.g. ``len(f) != len(x)``).
    """
    from .._model.system import DEFAULT_BOX
    from .model_spec import spec_from_dict

    path = os.fspath(path)
    reader = _Reader(path, _source(path))
    env = reader.run()
    missing = [v for v in ("x", "f", "h") if v not in env]
    if missing:
        raise LoadError(f"{path}: a StrikePy model defines x, f and h; missing {', '.join(missing)}")
    lists = {role: _flatten(env.get(role, [])) for role in _ROLES}
    notes = []
    symbols = {}
    for role in ("x", "p", "u", "w"):
        out = []
        for e in lists[role]:
            if not isinstance(e, Name):
                raise LoadError(f"{path}: {role} must list symbols, got the expression {to_text(e)!r}")
            if e.id in out:
                notes.append(f"{role} lists {e.id!r} twice (two Python names bound to the same sympy symbol): "
                             "kept once")
                continue
            if e.id in symbols:
                raise LoadError(f"{path}: symbol {e.id!r} is in both {symbols[e.id]} and {role}")
            symbols[e.id] = role
            out.append(e.id)
        lists[role] = out
    states, params, known, unknown = lists["x"], lists["p"], lists["u"], lists["w"]
    if len(lists["f"]) != len(states):
        raise LoadError(f"{path}: f has {len(lists['f'])} entries for {len(states)} states")
    used = set().union(*(names_of(e) for e in lists["f"] + lists["h"]))
    constants = sorted(v for v in used if v not in symbols and v not in _SYMPY_CONSTANTS)
    rename = _renames(list(symbols) + constants)
    for old, new in rename.items():
        notes.append(f"symbol {old!r} renamed {new!r} (not a valid name in model files)")

    def nm(s):
        return rename.get(s, s)

    def txt(e):
        return to_text(substitute(e, {k: Name(v) for k, v in rename.items()}))

    values = {nm(c): generic_value(nm(c)) for c in constants}
    if values:
        notes.append("StrikePy known constants (symbols in f or h that are in none of x, p, u, w) set to "
                     "generic values derived from their names: "
                     + ", ".join(f"{k} = {v:g}" for k, v in values.items()))
    outputs = {}
    for i, e in enumerate(lists["h"], start=1):
        key = nm(e.id) if isinstance(e, Name) and e.id in states else f"y{i}"
        while key in outputs:
            key += "_"
        outputs[key] = txt(e)
    data = {
        "name": os.path.splitext(os.path.basename(path))[0],
        "description": f"imported from the StrikePy model {os.path.basename(path)}",
        "notes": notes,
        "states": [nm(s) for s in states],
        "params": {nm(q): list(DEFAULT_BOX) for q in params},
        "constants": values,
        "outputs": outputs,
        "inputs": {"known": [nm(v) for v in known], "unknown": [nm(v) for v in unknown]},
        "dynamics": {nm(s): txt(e) for s, e in zip(states, lists["f"])},
    }
    return spec_from_dict(data, path)


def load_strikepy(path):
    """Load a StrikePy / STRIKE-GOLDD model module as a :class:`uio_jax.System` (without importing it).

    See the module doc for what is read and how. The System keeps its spec in
    ``System.source`` (so :func:`uio_jax.save_model` can convert it to TOML/JSON) and
    explains known constants and promoted inputs in ``System.notes``.

    Raises:
        LoadError, ModelError: one line naming the file (and line) and the problem.
    """
    from .model_file import build_system

    spec = read_strikepy(path)
    try:
        return build_system(spec)
    except UioJaxError as exc:
        raise type(exc)(f"{os.fspath(path)}: {exc}") from None


def _renames(names):
    out = {}
    taken = set(names)
    for s in names:
        if s.isidentifier() and not keyword.iskeyword(s):
            continue
        new = re.sub(r"\W", "_", s)
        if not new or new[0].isdigit():
            new = "s_" + new
        while keyword.iskeyword(new) or new in taken:
            new += "_"
        taken.add(new)
        out[s] = new
    return out


def _flatten(value):
    """``[[a], [b]]``, ``[a, b]`` or ``a`` -> ``[a, b]`` / ``[a]`` (expressions only)."""
    if isinstance(value, list):
        return [item for v in value for item in _flatten(v)]
    if isinstance(value, tuple):  # symbols('a b') bound to one name
        return list(value)
    return [value]


def _is_locals_copy(node) -> bool:
    if isinstance(node, ast.Call) and not node.args and isinstance(node.func, ast.Attribute):
        node = node.func.value if node.func.attr == "copy" else node
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "locals"
            and not node.args)


class _Reader:
    """Interpret the allowed statements of a StrikePy module; values are Exprs, lists or tuples."""

    def __init__(self, path, text):
        self.path = path
        self.text = text
        self.env = {}
        self.sympy_aliases = set()
        self.imported = {}  # bare name -> sympy attribute name

    def fail(self, node, message):
        line = getattr(node, "lineno", None)
        at = f" line {line}" if line else ""
        raise LoadError(f"{self.path}{at}: {message}")

    def run(self):
        try:
            tree = ast.parse(self.text, filename=self.path, mode="exec")
        except SyntaxError as exc:
            raise LoadError(f"{self.path} line {exc.lineno}: Python syntax error: {exc.msg}") from None
        except (RecursionError, MemoryError, ValueError) as exc:
            raise LoadError(f"{self.path}: cannot parse: {type(exc).__name__}") from None
        for stmt in tree.body:
            self.statement(stmt)
        return self.env

    # -- statements
    def statement(self, stmt):
        if isinstance(stmt, ast.Import):
            for a in stmt.names:
                if a.name == "sympy":
                    self.sympy_aliases.add(a.asname or "sympy")
            return
        if isinstance(stmt, ast.ImportFrom):
            if stmt.module in ("sympy", "math"):  # math's functions on symbols: their sympy namesakes
                for a in stmt.names:
                    if a.name == "*":
                        self.fail(stmt, "'from sympy import *' is not supported: use 'import sympy as sym'")
                    self.imported[a.asname or a.name] = a.name
            return
        if isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Constant) and isinstance(stmt.value.value, str):
            return  # docstring
        if isinstance(stmt, ast.Pass):
            return
        if isinstance(stmt, ast.Assign):
            if _is_locals_copy(stmt.value):
                return
            if len(stmt.targets) != 1:
                self.fail(stmt, "chained assignments (a = b = ...) are not supported")
            self.assign(stmt.targets[0], stmt.value, stmt)
            return
        kind = type(stmt).__name__
        self.fail(stmt, f"statement {kind} is not supported in a StrikePy model (only imports and "
                        "assignments of symbols, lists and expressions)")

    def assign(self, target, value_node, stmt):
        if isinstance(target, ast.Name):
            self.env[target.id] = self.value(value_node)
            return
        if isinstance(target, (ast.Tuple, ast.List)):
            if any(not isinstance(t, ast.Name) for t in target.elts):
                self.fail(stmt, "only names can be unpacked")
            if isinstance(value_node, (ast.Tuple, ast.List)):
                items = [self.value(v) for v in value_node.elts]
            else:
                v = self.value(value_node)
                items = list(v) if isinstance(v, (tuple, list)) else None
                if items is None:
                    self.fail(stmt, "cannot unpack a single expression into several names")
            if len(items) != len(target.elts):
                self.fail(stmt, f"{len(target.elts)} names but {len(items)} values")
            for t, v in zip(target.elts, items):
                self.env[t.id] = v
            return
        self.fail(stmt, f"assignment to {type(target).__name__} is not supported (only names)")

    # -- values
    def value(self, node):
        if isinstance(node, (ast.List, ast.Tuple)):
            return [self.value(v) for v in node.elts]
        sym = self.symbol_call(node)
        if sym is not None:
            return sym
        return self.expression(node)

    def _sympy_func(self, func):
        """Name of the sympy function a call refers to (``sym.exp`` / imported ``exp``), or None."""
        if isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name) and func.value.id in self.sympy_aliases:
            return func.attr
        if isinstance(func, ast.Name) and func.id in self.imported and func.id not in self.env:
            return self.imported[func.id]
        return None

    def symbol_call(self, node):
        if not isinstance(node, ast.Call):
            return None
        fname = self._sympy_func(node.func)
        if fname not in ("Symbol", "symbols", "var"):
            return None
        if len(node.args) != 1 or not isinstance(node.args[0], ast.Constant) or not isinstance(node.args[0].value, str):
            self.fail(node, f"{fname}() must be given one string of symbol names")
        names = [s for s in re.split(r"[\s,]+", node.args[0].value.strip()) if s]
        if not names:
            self.fail(node, f"{fname}() got no symbol name")
        if any(":" in s for s in names):
            self.fail(node, "symbol ranges ('x0:3') are not supported: list the names")
        if fname == "Symbol":
            if len(names) != 1 or names[0] != node.args[0].value.strip():
                self.fail(node, f"Symbol() takes one name, got {node.args[0].value!r}")
            return Name(names[0])
        trailing_comma = node.args[0].value.strip().endswith(",")
        if len(names) == 1 and not trailing_comma:
            return Name(names[0])
        return tuple(Name(s) for s in names)

    def expression(self, node):
        reader = self

        def on_name(n):
            if n.id.startswith("\0"):
                return _SYMPY_CONSTANTS[n.id[1:]]
            if n.id in reader.env:
                v = reader.env[n.id]
                if isinstance(v, (list, tuple)):
                    reader.fail(n, f"{n.id!r} is a list, used in an expression")
                return v
            if n.id in reader.imported and reader.imported[n.id] in _SYMPY_CONSTANTS:
                return _SYMPY_CONSTANTS[reader.imported[n.id]]
            reader.fail(n, f"name {n.id!r} is not defined (define symbols with sym.Symbol or sym.symbols)")

        def on_call(n, conv):
            fname = reader._sympy_func(n.func)
            bare = isinstance(n.func, ast.Name) and n.func.id in _BUILTINS and n.func.id not in reader.env
            if fname is None and bare:
                fname = n.func.id  # Python's abs/min/max/pow work on sympy expressions
            if fname is None:
                if isinstance(n.func, ast.Attribute):
                    reader.fail(n, f"call of '{ast.unparse(n.func)}' is not allowed (functions must be called "
                                   f"on the sympy module: {', '.join(sorted(reader.sympy_aliases)) or 'not imported'})")
                reader.fail(n, f"call of {ast.unparse(n.func)!r} is not allowed (use sympy's functions, "
                               "e.g. sym.exp)")
            if fname in ("Rational", "Integer", "Float"):
                if n.keywords or not 1 <= len(n.args) <= (2 if fname == "Rational" else 1):
                    what = "one or two numbers" if fname == "Rational" else "one number"
                    reader.fail(n, f"sym.{fname}() takes {what}")
                args = [conv.convert(a) for a in n.args]
                return args[0] if len(args) == 1 else Binary("/", args[0], args[1])
            if fname in ("sqrt",) and len(n.args) == 1 and not n.keywords:
                return Call("sqrt", (conv.convert(n.args[0]),))
            return conv.whitelisted_call(n, fname, n)

        conv = Converter(on_name, on_call, reader.fail, lambda: "")
        # sympy constants as attributes: sym.pi, sym.E
        node = _SympyConstants(self.sympy_aliases).visit(node)
        try:
            return conv.convert(node)
        except ExpressionError as exc:  # pragma: no cover - fail() raises LoadError
            raise LoadError(f"{self.path}: {exc}") from None


class _SympyConstants(ast.NodeTransformer):
    """Rewrite ``sym.pi`` / ``sym.E`` into bare names (the only attributes read as values)."""

    def __init__(self, aliases):
        self.aliases = aliases

    def visit_Attribute(self, node):
        if (isinstance(node.value, ast.Name) and node.value.id in self.aliases
                and node.attr in _SYMPY_CONSTANTS):
            return ast.copy_location(ast.Name(id=f"\0{node.attr}", ctx=ast.Load()), node)
        return self.generic_visit(node)

