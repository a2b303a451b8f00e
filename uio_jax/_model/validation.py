"""The checks a System passes when it is built: shapes, expressions, finiteness.

:func:`check_shapes` traces every function once (shape, dtype) and translates it into the
expression graph; :func:`finite_notes` evaluates every function at sampled states of the box
(numpy over the graph). :class:`~uio_jax.System` applies what they return; they write nothing
on the System. A function that builds its own expression is only translated (JAX is not
imported for it).
"""

from types import MappingProxyType

import numpy as np

from .._engine.graph import Graph
from .._engine.graph_numpy import evaluate
from .._engine.graph_trace import graph_native, translate_or_refuse
from .._engine.graph_values import IndexOutOfRange
from .._errors import ModelError

#: Number of states drawn when a System is built, to catch fields that are NaN everywhere.
CHECK_SAMPLES = 64
#: A function finite at fewer than this fraction of the ``CHECK_SAMPLES`` states is evaluated
#: at ``MORE_SAMPLES`` more to estimate where it is defined (64 states miss a set covering 5 %
#: of the box with probability 4 %, 4096 states with probability below 1e-90).
SPARSE_FRACTION = 0.125
#: States drawn (one vmapped evaluation) before a function is declared NaN/inf everywhere.
MORE_SAMPLES = 4096


def check_traced_output(what, out, expected, real) -> np.dtype:
    """The traced result ``out`` of a model function (``jax.eval_shape``): an array of shape
    ``expected`` (``()`` or ``(n,)``), not complex; returns its dtype. ``what`` names the
    function in the one-line ModelError, ``real`` what must be real."""
    shape = getattr(out, "shape", None)
    if shape is None:
        raise ModelError(f"{what} must return an array, got {type(out).__name__}")
    if tuple(shape) != expected:
        want = "a scalar ()" if expected == () else f"shape {expected} (one entry per state)"
        raise ModelError(f"{what} returns shape {tuple(shape)}, expected {want}")
    dtype = np.dtype(getattr(out, "dtype", np.float64))
    if np.issubdtype(dtype, np.complexfloating):
        raise ModelError(f"{what} returns a complex value ({dtype}); {real} must be real")
    return dtype


def named_functions(system):
    """``(what, fn, shape)`` of every output and field of ``system`` (``what`` names it in
    messages)."""
    yield from ((f"output {k!r}", fn, ()) for k, fn in system.outputs.items())
    yield from ((f"known field {k!r}", fn, (system.n,)) for k, fn in system.known.items())
    yield from ((f"unknown field {k!r}", fn, (system.n,)) for k, fn in system.unknown.items())
    if system.drift is not None:
        yield ("drift", system.drift, (system.n,))


def check_shapes(system) -> set:
    """Trace every function once: it must run on ``x`` (or ``(x, p)``, ``(x, t)``,
    ``(x, p, t)``), return the right shape and a real dtype; then translate it into the
    expression graph.

    Returns:
        The names (``what``) of the functions whose results are integer or boolean (the
        System wraps them to return floats, :func:`as_float`).

    Raises:
        ModelError: a function fails to trace, returns the wrong shape or a complex value,
            has a primitive the expression graph has no rule for, or indexes outside its
            arguments.
    """
    # functions of (x, p) or (x, t) are translated into one scratch graph of [x; p; t]
    scratch = (Graph(system.n + len(system.params) + (system.time is not None))
               if system.params or system.time is not None else None)
    traced = []
    for what, fn, expected in named_functions(system):
        if graph_native(fn):  # builds its own expression: its translation checks its shape
            _check_index_range(system, what, fn, expected, scratch)
        else:
            traced.append((what, fn, expected))
    return _check_traced(system, traced, scratch) if traced else set()


def _check_traced(system, traced, scratch) -> set:
    """:func:`check_shapes` of the JAX callables ``traced`` (``(what, fn, shape)``): traced
    once each (``jax.eval_shape``), then translated."""
    import jax
    import jax.numpy as jnp

    promote = set()
    args = [jax.ShapeDtypeStruct((system.n,), jnp.float64)]
    on = f"a state vector of length {system.n}"
    hint = "(with params, every function takes (x, p))"
    if system.params:
        args.append(jax.ShapeDtypeStruct((len(system.params),), jnp.float64))
        on = f"(x, p) of lengths ({system.n}, {len(system.params)})"
    if system.time is not None:
        args.append(jax.ShapeDtypeStruct((), jnp.float64))
        sig = "(x, p, t)" if system.params else "(x, t)"
        on = (f"(x, p, {system.time}) of shapes ({system.n},), ({len(system.params)},), ()" if system.params
              else f"(x, {system.time}) of shapes ({system.n},), ()")
        hint = f"(with time {system.time!r}, every function takes {sig})"
    with jax.enable_x64(True):
        for what, fn, expected in traced:
            try:
                out = jax.eval_shape(fn, *args)
            except Exception as exc:  # the user's function fails to trace
                msg = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
                if (system.params or system.time is not None) and isinstance(exc, TypeError) and "argument" in msg:
                    msg += " " + hint
                raise ModelError(
                    f"{what} fails on {on}: {type(exc).__name__}: {msg}"
                ) from None
            dtype = check_traced_output(what, out, expected, "outputs and fields")
            if not np.issubdtype(dtype, np.floating):
                promote.add(what)
            _check_index_range(system, what, fn, expected, scratch)
    return promote


def _check_index_range(system, what, fn, expected, scratch):
    """Translate every function into the expression graph: refuse one with a primitive
    the graph has no rule for, and catch indexing past the state vector (or the
    parameters), which JAX silently clamps (``x[5]`` of 2 states). ``scratch``: the graph
    that functions of ``(x, p)`` or ``(x, t)`` are translated into (one per System)."""
    n, P = system.n, len(system.params)
    try:
        if not system.params and system.time is None:
            system.expression(fn, expected, what)
        else:
            extra = ((P,),) if P else ()
            extra += ((),) if system.time is not None else ()
            translate_or_refuse(scratch, fn, expected, what, extra)
    except IndexOutOfRange as exc:
        where = f"the state vector of length {n}" if not P else f"x (length {n}) or p (length {P})"
        raise ModelError(f"{what} indexes outside {where}: {exc}") from None


def finite_notes(system) -> tuple:
    """Every function must be finite somewhere in the sampling box: the System's notes then.

    It is evaluated at ``CHECK_SAMPLES`` states, then at ``MORE_SAMPLES`` more when finite at
    fewer than ``SPARSE_FRACTION`` of them: finite nowhere is a ModelError, on a small fraction
    of the box a note (the analyses drop the states where it is not).

    Returns:
        ``system.notes`` and one note per function finite on a small fraction of the box.

    Raises:
        ModelError: a function is NaN/inf at every state drawn.
    """
    named = list(named_functions(system))
    finite = _finite_masks(system, named, CHECK_SAMPLES, 12345)
    sparse = [i for i, ok in enumerate(finite) if ok.mean() < SPARSE_FRACTION]
    if not sparse:
        return tuple(system.notes)
    more = _finite_masks(system, [named[i] for i in sparse], MORE_SAMPLES, 12346)
    notes = list(system.notes)
    for i, ok in zip(sparse, more):
        what = named[i][0]
        hits = int(ok.sum()) + int(finite[i].sum())
        total = MORE_SAMPLES + CHECK_SAMPLES
        if hits == 0:
            raise ModelError(
                f"{what} returns NaN/inf at every one of {total} states drawn in the sampling "
                f"box ({CHECK_SAMPLES} at validation, {MORE_SAMPLES} more to look for where "
                "it is defined): check the model and its `domain`"
            )
        notes.append(
            f"{what} is finite on only {_percent(hits / total)} % of the sampling box; the "
            "analysis uses those states: narrow `domain` to where the model is defined"
        )
    return tuple(notes)


def _finite_masks(system, named, samples, seed) -> list[np.ndarray]:
    """For each ``(what, fn, shape)`` of ``named`` (functions of ``x``), the ``(samples,)``
    mask of sampled states where it is finite: their expressions in the System's graph
    evaluated by numpy (nothing is compiled)."""
    from .sampling import sample_states

    xs = sample_states(system, samples, seed=seed)
    exprs = [system.expression(fn, shape, what) for what, fn, shape in named]
    roots = [r for e in exprs for r in ((e,) if isinstance(e, int) else e)]
    values = evaluate(system.expression_graph, roots, xs, gradients=False)
    ends = np.cumsum([1 if isinstance(e, int) else len(e) for e in exprs])
    return [np.isfinite(v).all(axis=1) for v in np.split(values, ends[:-1], axis=1)]


def _percent(fraction: float) -> str:
    """A fraction as a percentage with two significant digits (``0.047`` -> ``"4.7"``)."""
    pct = 100.0 * fraction
    return f"{pct:.2g}" if pct < 10 else f"{pct:.0f}"


def promoted_functions(system, which) -> dict:
    """The functions of ``system`` named in ``which`` (:func:`check_shapes`: integer or
    boolean results) wrapped to return floats (:func:`as_float`): attribute -> its new value
    (``outputs``, ``known``, ``unknown``: read-only mappings; ``drift``); empty when none."""
    out = {}
    if not which:
        return out
    for attr, kind in (("outputs", "output"), ("known", "known field"), ("unknown", "unknown field")):
        table = getattr(system, attr)
        if any(f"{kind} {k!r}" in which for k in table):
            out[attr] = MappingProxyType({k: as_float(fn) if f"{kind} {k!r}" in which else fn
                                          for k, fn in table.items()})
    if "drift" in which:
        out["drift"] = as_float(system.drift)
    return out


def as_float(fn):
    """``fn`` with its integer or boolean result converted to float (float64 under x64)."""

    def f(*args):
        import jax
        import jax.numpy as jnp

        out = fn(*args)
        if all(isinstance(a, np.ndarray) for a in args) and not isinstance(out, jax.Array):
            return np.asarray(out, dtype=np.float64)
        return jnp.asarray(out).astype(jnp.result_type(float))

    f.__name__ = getattr(fn, "__name__", "f")
    return f


__all__ = ["CHECK_SAMPLES", "MORE_SAMPLES", "SPARSE_FRACTION", "as_float", "check_shapes", "check_traced_output",
           "finite_notes", "named_functions", "promoted_functions"]
