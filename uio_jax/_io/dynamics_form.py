"""Systems from Python callables in the general form: :func:`system_from_dynamics` (public as
``uj.system_from_dynamics``; ``uj.System.from_dynamics`` is the same function, attached by the
API layer, ``uio_jax/__init__.py``).

The model is one right-hand side ``x' = f(x, u, w)`` (``f(x, p, u, w)`` with parameters, a
trailing ``t`` for a time-varying model), split into the control-affine form by the same code
as model files (:func:`uio_jax._io.affine_callable.split_callable`).
"""

import keyword
from collections.abc import Mapping

import numpy as np

from .._errors import ModelError
from .._model.arguments import check_names
from .._model.system import System
from .._model.validation import check_traced_output
from .loading import one_line

_SOURCE = "from_dynamics"


def system_from_dynamics(states, dynamics, outputs, *, known=(), unknown=(), params=None, domain=None,
                         angles=(), name="", notes=(), time=None) -> System:
    """Build a System from ``x' = f(x, u, w)``, ``y = h(x, u, w)`` (JAX callables).

    Example::

        sys = uj.system_from_dynamics(
            states=("px", "py", "th"),
            dynamics=lambda x, u, w: jnp.array([w[0] * jnp.cos(x[2]), w[0] * jnp.sin(x[2]), u[0]]),
            outputs={"px": lambda x, u, w: x[0], "py": lambda x, u, w: x[1]},
            known=("omega",), unknown=("v",))

    Args:
        states: state names, the order of ``x`` (length n).
        dynamics: ``f(x, u, w) -> (n,)`` with ``x (n,)``, ``u (len(known),)`` and
            ``w (len(unknown),)``; with ``params``, ``f(x, p, u, w)`` with ``p (P,)``.
        outputs: output name -> ``h(x, u, w) -> ()`` (``h(x, p, u, w)`` with params).
        known, unknown: names of the known inputs (order of ``u``) and of the unknown
            inputs (order of ``w``).
        params: unknown constant parameters, name -> ``(lo, hi)`` box, or a sequence of
            names (box ``(0.5, 1.5)`` each), the order of ``p``.
        domain: state or input name -> ``(lo, hi)`` sampling box (an input's box is where
            the affinity test samples it, and the box of its state if it is promoted).
        angles: state names that are angles.
        name: name shown in reports.
        notes: remarks copied into every report.
        time: name of the time variable of a time-varying model (``None``: time-invariant).
            Then ``dynamics`` and the outputs take a trailing scalar ``t``: ``f(x, u, w, t)``
            (``f(x, p, u, w, t)`` with params), ``domain`` may give its box (default
            ``(0.0, 1.0)``), and the System's callables take ``(x, t)`` / ``(x, p, t)``
            (see ``System.time``). The affinity test samples ``t`` in its box.

    Returns:
        A :class:`uio_jax.System` in the control-affine form: drift ``f(x, 0, 0)``, fields
        ``d f / d u_i`` and ``d f / d w_j`` at ``u = w = 0``. An input that enters
        non-affinely or appears in an output becomes a state (``v' = d_v``; a known one is
        also an output), an input that appears nowhere is dropped, each with a note in
        ``System.notes``. With params its callables take ``(x, p)``, with time ``(x, t)``
        or ``(x, p, t)``.

    Raises:
        ModelError: one line naming the problem (bad or clashing name, a callable that
            fails or returns the wrong shape or a complex value, dynamics not finite at
            any sampled point).
    """
    from .affine import system_callables
    from .affine_callable import split_callable

    states, known, unknown, pnames, boxes, domain = _arguments(states, known, unknown, params, time, dynamics,
                                                               outputs, domain)
    n, P, nk, nw = len(states), len(pnames), len(known), len(unknown)
    with_p, with_t = bool(pnames), time is not None
    # the split sees the time as one more parameter, last: q = [p; t]
    extra = {}
    if with_t:
        from .._model.system import DEFAULT_TIME_BOX

        extra = {time: tuple(domain.pop(time, DEFAULT_TIME_BOX))}

    def full(fn):  # always (x, q, u, w), q = [p; t]
        if with_t:
            if with_p:
                return lambda x, q, u, w: fn(x, q[:P], u, w, q[P])
            return lambda x, q, u, w: fn(x, u, w, q[0])
        return fn if with_p else (lambda x, p, u, w: fn(x, u, w))

    args, lengths = _signature(with_p, time, n, P, nk, nw)
    dyn = full(dynamics)
    outs = {k: full(h) for k, h in outputs.items()}
    Q = P + len(extra)
    _check("dynamics", dyn, (n,), args, lengths, n, Q, nk, nw)
    for k, h in outs.items():
        _check(f"output {k!r}", h, (), args, lengths, n, Q, nk, nw)
    parts = split_callable(states, dyn, outs, known, unknown, {**boxes, **extra}, domain, tuple(angles))
    wrap = system_callables(with_p, with_t)
    notes = (notes,) if isinstance(notes, str) else tuple(notes or ())
    return parts.to_system(wrap, name=name, params=boxes, notes=notes, time=time,
                           time_box=extra.get(time))


def _arguments(states, known, unknown, params, time, dynamics, outputs, domain):
    """The arguments of :func:`system_from_dynamics`, checked: ``(states, known, unknown,
    parameter names, parameter boxes, domain)``.

    Raises:
        ModelError: a bad or clashing name, a dynamics or output that is not callable, a
            domain entry for something that is neither a state, an input nor the time.
    """
    states = _names(states, "states")
    known = _names(known, "known")
    unknown = _names(unknown, "unknown")
    if isinstance(params, Mapping):
        pnames = _names(tuple(params), "params")
        boxes = dict(params)
    elif params is None:
        pnames, boxes = (), {}
    else:
        pnames = _names(params, "params")
        from .._model.system import DEFAULT_BOX

        boxes = {k: DEFAULT_BOX for k in pnames}
    if time is not None and (not isinstance(time, str) or not time.isidentifier() or keyword.iskeyword(time)):
        raise ModelError(f"{_SOURCE}: time {time!r} is not a valid name of the time variable (letters, digits "
                         "and _, not starting with a digit, not a Python keyword)")
    tname = () if time is None else (time,)
    taken = {}
    for kind, group in (("state", states), ("parameter", pnames), ("known input", known),
                        ("unknown input", unknown), ("time variable", tname)):
        for nm in group:
            if nm in taken:
                raise ModelError(f"{_SOURCE}: {kind} {nm!r} has the name of {_a(taken[nm])}")
            taken[nm] = kind
    if not callable(dynamics):
        raise ModelError(f"{_SOURCE}: dynamics must be callable, got {type(dynamics).__name__}")
    if not isinstance(outputs, Mapping) or not outputs:
        raise ModelError(f"{_SOURCE}: outputs must be a non-empty mapping name -> h(x, u, w)")
    for k, h in outputs.items():
        if not isinstance(k, str) or not k:
            raise ModelError(f"{_SOURCE}: output names must be non-empty strings, got {k!r}")
        if not callable(h):
            raise ModelError(f"{_SOURCE}: output {k!r} is not callable (got {type(h).__name__})")
    domain = dict(domain or {})
    for k in domain:
        if k not in taken or taken[k] == "parameter":
            raise ModelError(f"{_SOURCE}: domain given for {k!r}, which is neither a state nor an input"
                             + (" nor the time" if time is not None else ""))
    return states, known, unknown, pnames, boxes, domain


def _signature(with_p, time, n, P, nk, nw):
    """``("(x, p, u, w, t)", "x (n), p (P), ...")``: the arguments of the user's callables and
    their lengths, as the error messages name them."""
    args = "(x, p, u, w" if with_p else "(x, u, w"
    args += f", {time})" if time is not None else ")"
    lengths = f"x ({n}), p ({P}), u ({nk}), w ({nw})" if with_p else f"x ({n}), u ({nk}), w ({nw})"
    if time is not None:
        lengths += f", {time} (a scalar)"
    return args, lengths


def _a(kind: str) -> str:
    return ("an " if kind[0] in "aeiou" else "a ") + kind


def _names(v, what) -> tuple:
    if isinstance(v, str) or isinstance(v, Mapping):
        raise ModelError(f"{_SOURCE}: {what} must be a sequence of names, got {type(v).__name__} {v!r}")
    try:
        names = tuple(v)
    except TypeError:
        raise ModelError(f"{_SOURCE}: {what} must be a sequence of names, got {type(v).__name__}") from None
    check_names(names, lambda nm: not isinstance(nm, str) or not nm.isidentifier(),
                f"{_SOURCE}: {what} entry " + "{nm!r} is not a valid name (letters, digits and _)",
                f"{_SOURCE}: " + "{nm!r} is listed twice in " + what)
    return names


def _check(what, fn, expected, args, lengths, n, P, nk, nw):
    """Trace ``fn(x, p, u, w)`` once: right shape, real dtype, no indexing past a vector."""
    try:
        fn(np.full(n, 0.75), np.full(P, 0.75), np.full(nk, 0.75), np.full(nw, 0.75))
    except IndexError as exc:
        raise ModelError(f"{_SOURCE}: {what} indexes outside {lengths}: {exc}") from None
    except Exception:  # numpy input not supported: the traced check decides
        pass
    import jax  # the user's JAX callables
    import jax.numpy as jnp

    specs = [jax.ShapeDtypeStruct((k,), jnp.float64) for k in (n, P, nk, nw)]
    with jax.enable_x64(True):
        try:
            out = jax.eval_shape(fn, *specs)
        except Exception as exc:
            raise ModelError(f"{_SOURCE}: {what} fails on {args} of lengths {lengths}: {one_line(exc)}") from None
    check_traced_output(f"{_SOURCE}: {what}", out, expected, "the dynamics and outputs")
