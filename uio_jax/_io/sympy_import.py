"""Systems from sympy expressions: :func:`system_from_sympy` (public as ``uj.system_from_sympy``;
``uj.System.from_sympy`` is the same function, attached by the API layer, ``uio_jax/__init__.py``).

Each expression is printed with sympy's ``str`` and read back by the whitelisted parser of
:mod:`uio_jax._io.expressions`, so the functions accepted here are exactly those of model
files. The declarative spec is kept in ``System.source`` (:func:`uio_jax.save_model` writes it).
sympy is not a dependency of uio_jax; it is imported only when this function is called.
"""

from collections.abc import Mapping

from .._errors import ModelError

_SOURCE = "from_sympy"


def _sympy():
    try:
        import sympy
    except ImportError:
        raise ModelError("system_from_sympy needs sympy: pip install sympy") from None
    return sympy


def system_from_sympy(states, outputs, *, known=None, unknown=None, drift=None, dynamics=None, params=None,
                      constants=None, domain=None, angles=(), name="", notes=(), time=None):
    """Build a System from sympy symbols and expressions.

    Control-affine form ``x' = f0(x, p) + sum_i f_i(x, p) u_i + sum_j g_j(x, p) w_j``::

        x, y, th, v = sympy.symbols("x y th v")
        sys = uj.system_from_sympy([x, y, th], {"x": x, "y": y},
                                   known={"omega": [0, 0, 1]},
                                   unknown={"v": [sympy.cos(th), sympy.sin(th), 0]})

    General form ``x' = f(x, p, u, w)`` (split by :mod:`uio_jax._io.affine`; inputs entering
    non-affinely become states, with a note)::

        sys = uj.system_from_sympy([x, y, th], [x, y],
                                   dynamics=[v*sympy.cos(th), v*sympy.sin(th), om],
                                   known=[om], unknown=[v])

    Args:
        states: state symbols (or names), the order of ``x`` (length n).
        outputs: name -> expression, or a sequence of expressions (named after the state
            when an output is a state symbol, ``y1, y2, ...`` otherwise).
        known, unknown: affine form: input name (or symbol) -> n expressions (a sequence
            in the order of ``states``, or a mapping state -> expression); general form:
            sequences of input symbols.
        drift: affine form: n expressions (sequence or mapping state -> expression).
        dynamics: general form: n expressions (sequence, sympy Matrix, or mapping).
        params: unknown constant parameters: symbol -> ``(lo, hi)`` box, or a sequence
            of symbols (box ``(0.5, 1.5)`` each).
        constants: known constants: symbol -> value.
        domain: symbol -> ``(lo, hi)`` sampling box of a state (or input, general form).
        angles: state symbols that are angles.
        name: name shown in reports.
        notes: remarks copied into every report.
        time: the time symbol (or name) of a time-varying model: expressions may use it,
            ``domain`` may give its box (default ``(0.0, 1.0)``); ``None`` (default): a
            symbol in no role is an unknown name, as in model files.

    Returns:
        A :class:`uio_jax.System`; with params its callables take ``(x, p)``, with time
        ``(x, t)`` or ``(x, p, t)``.

    Raises:
        ModelError: sympy is missing, a name is not a valid identifier, an expression is
            complex or uses a function outside the whitelist, or the model is malformed
            (one line naming the entry).
    """
    sympy = _sympy()
    from .model_file import build_system
    from .model_spec import spec_from_dict

    conv = _Printer(sympy)
    st = [conv.name(s, "states") for s in _seq(states, "states")]
    data = {"states": st}
    if name:
        data["name"] = name
    if notes:
        data["notes"] = [notes] if isinstance(notes, str) else list(notes)
    if angles:
        data["angles"] = [conv.name(a, "angles") for a in _seq(angles, "angles")]
    if time is not None:
        data["time"] = conv.name(time, "time")
    if params is not None:
        if isinstance(params, Mapping):
            data["params"] = {conv.name(k, "params"): list(v) for k, v in params.items()}
        else:
            data["params"] = [conv.name(k, "params") for k in _seq(params, "params")]
    if constants:
        data["constants"] = {conv.name(k, "constants"): conv.number(v, f"constants.{k}")
                             for k, v in _mapping(constants, "constants").items()}
    if domain:
        data["domain"] = {conv.name(k, "domain"): list(v) for k, v in _mapping(domain, "domain").items()}
    data["outputs"] = _output_texts(conv, sympy, outputs, st)
    data.update(_right_hand_side(conv, st, drift, dynamics, known, unknown))
    spec = spec_from_dict(data, _SOURCE)
    return build_system(spec)


def _output_texts(conv, sympy, outputs, st) -> dict:
    """The ``outputs`` table of the spec: name -> text; a sequence of outputs is named after
    the state when an output is a state symbol, ``y1, y2, ...`` otherwise."""
    if isinstance(outputs, Mapping):
        return {conv.name(k, "outputs", identifier=False): conv.text(e, f"outputs.{k}")
                for k, e in outputs.items()}
    outs = {}
    for i, e in enumerate(_seq(outputs, "outputs"), start=1):
        key = str(e.name) if isinstance(e, sympy.Symbol) and e.name in st else f"y{i}"
        while key in outs:
            key += "_"
        outs[key] = conv.text(e, f"outputs[{i - 1}]")
    return outs


def _right_hand_side(conv, st, drift, dynamics, known, unknown) -> dict:
    """The spec's right-hand side: ``dynamics`` and ``inputs`` (general form), or ``drift``,
    ``known`` and ``unknown`` (control-affine form)."""
    data = {}
    if dynamics is not None:
        if drift is not None:
            raise ModelError(f"{_SOURCE}: give either dynamics= (general form) or drift= (control-affine form)")
        data["dynamics"] = conv.rows(dynamics, st, "dynamics")
        data["inputs"] = {"known": [conv.name(v, "known") for v in _seq(known or [], "known")],
                          "unknown": [conv.name(v, "unknown") for v in _seq(unknown or [], "unknown")]}
        return data
    if drift is not None:
        data["drift"] = conv.rows(drift, st, "drift")
    for kind, table in (("known", known), ("unknown", unknown)):
        if table:
            data[kind] = {conv.name(k, kind): conv.rows(f, st, f"{kind}.{k}")
                          for k, f in _mapping(table, kind).items()}
    return data


def _seq(v, what):
    if isinstance(v, (str, bytes)) or isinstance(v, Mapping):
        raise ModelError(f"{_SOURCE}: {what} must be a sequence, got {type(v).__name__}")
    try:
        return list(v)
    except TypeError:
        return [v]


def _mapping(v, what):
    if not isinstance(v, Mapping):
        raise ModelError(f"{_SOURCE}: {what} must be a mapping, got {type(v).__name__}")
    return v


class _Printer:
    """sympy objects -> names and expression texts of the model-file schema."""

    def __init__(self, sympy):
        self.sp = sympy

    def name(self, s, what, identifier=True) -> str:
        sp = self.sp
        if isinstance(s, sp.Symbol):
            s = s.name
        elif isinstance(s, sp.Basic):
            raise ModelError(f"{_SOURCE}: {what} must name symbols, got the expression {s}")
        if not isinstance(s, str):
            raise ModelError(f"{_SOURCE}: {what} must name symbols, got {type(s).__name__}")
        if identifier and not s.isidentifier():
            raise ModelError(f"{_SOURCE}: symbol name {s!r} in {what} is not a valid name "
                             "(letters, digits and _)")
        return s

    def number(self, v, what) -> float:
        sp = self.sp
        try:
            return float(sp.sympify(v) if isinstance(v, sp.Basic) else v)
        except (TypeError, ValueError):
            raise ModelError(f"{_SOURCE}: {what} must be a number, got {v!r}") from None

    def text(self, e, what) -> str:
        sp = self.sp
        if isinstance(e, str):
            return e  # expression text: checked by the whitelisted parser
        if isinstance(e, bool):
            raise ModelError(f"{_SOURCE}: {what} must be an expression, got {e!r}")
        if isinstance(e, (int, float)):
            return repr(float(e)) if isinstance(e, float) else str(e)
        if not isinstance(e, sp.Basic):
            raise ModelError(f"{_SOURCE}: {what} must be a sympy expression, got {type(e).__name__}")
        if e.has(sp.I):
            raise ModelError(f"{_SOURCE}: {what} is complex ({e}); only real expressions are supported")
        names = {s.name for s in e.free_symbols}
        for const, nm in ((sp.E, "E"), (sp.pi, "pi")):
            if nm in names and e.has(const):
                raise ModelError(f"{_SOURCE}: {what} uses both the constant {nm} and a symbol named {nm!r}")
        for s in names:
            if not s.isidentifier():
                raise ModelError(f"{_SOURCE}: symbol name {s!r} in {what} is not a valid name (letters, digits and _)")
        return sp.sstr(e)

    def rows(self, v, states, what) -> dict:
        """n expressions (sequence, Matrix, or mapping state -> expression) -> {state: text}."""
        sp = self.sp
        if isinstance(v, Mapping):
            pairs = [(self.name(k, what), e, f"{what}.{k}") for k, e in v.items()]
        else:
            if isinstance(v, sp.MatrixBase):
                v = list(v)
            items = _seq(v, what)
            if len(items) != len(states):
                raise ModelError(f"{_SOURCE}: {what} has {len(items)} entries for {len(states)} states")
            pairs = [(s, e, f"{what}[{i}]") for i, (s, e) in enumerate(zip(states, items))]
        # zero entries are left out (a missing entry is 0), so that a zero drift is no drift
        return {s: self.text(e, where) for s, e, where in pairs if not _is_zero(e)}


def _is_zero(e) -> bool:
    if isinstance(e, bool):
        return False
    if isinstance(e, (int, float)):
        return e == 0
    return getattr(e, "is_zero", False) is True and getattr(e, "is_number", False) is True
