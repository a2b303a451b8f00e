"""Split a general right-hand side ``x' = f(x, p, u, w)`` into the control-affine form.

The analyses need ``x' = f0(x) + sum_i f_i(x) u_i + sum_j g_j(x) w_j``. A model written in
the general form (model files with ``[dynamics]``, StrikePy modules, ``from_sympy`` with
``dynamics=``) is split here:

* drift ``f0(x, p) = f(x, p, 0, 0)``;
* known field ``f_i(x, p) = d f / d u_i (x, p, 0, 0)`` and unknown field
  ``g_j(x, p) = d f / d w_j (x, p, 0, 0)`` (a forward-mode derivative, equal to
  ``f(e_i) - f0`` when ``f`` is affine in the inputs, without its cancellation error).

**Affinity check**: :mod:`uio_jax._io.affinity` (the Hessian in the inputs at random samples;
an input inside ``abs``, ``sign``, ``min`` or ``max`` is promoted without a test).

**Promotion.** An input that enters non-affinely (or that appears in an output) is made a
state, which is exact (the first extension of 004, what STRIKE-GOLDD does):

* known ``u`` -> new state ``u`` with ``u' = d_u``, ``d_u`` a new known input (field
  ``e_u``), and a new output ``u`` (it is known, hence measured);
* unknown ``w`` -> new state ``w`` with ``w' = d_w``, ``d_w`` a new unknown input.

Diagonal terms promote their input; the remaining cross terms (``u*w``) are covered
greedily: the input with the most non-affine partners first, an unknown input before a
known one, then the later declared. Every promotion adds one line to the System's notes.
Inputs that appear in no equation are dropped, with a note.
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from .._model.joint import Coordinate
from .affinity import INPUT_BOX, box, compile_rows, inputs_in_nonsmooth, nonaffine_pattern, promotion_reasons, vanishes
from .expression_functions import to_function
from .expressions import Expr, names_of
from .model_functions import GeneralDrift, InputField, Joined, RowsFunction, UnitField


# ----------------------------------------------------------------------------- split
@dataclass(frozen=True)
class Parts:
    """A control-affine model as functions of ``z = [x; p]`` (shape ``(n + n_params,)``; a
    time-varying model's time is one more coordinate after ``p``, see :func:`system_callables`).

    ``outputs``: name -> scalar function; ``drift`` (or None), ``known``, ``unknown``:
    functions returning shape ``(n,)``. ``states``, ``domain`` and ``angles`` describe
    the (possibly extended) state; ``notes`` say how it was derived. Every function runs
    on JAX arrays (traceable) and, without JAX dispatch, on numpy arrays.
    """

    states: tuple
    outputs: dict
    known: dict
    unknown: dict
    drift: object
    domain: dict
    angles: tuple
    notes: tuple = ()
    promoted: tuple = field(default=())

    def to_system(self, wrap, *, name, params, source=None, notes=(), time=None, time_box=None):
        """The :class:`uio_jax.System` of these parts, every function passed through ``wrap``
        (``fn(z)`` -> the System's callable: ``x`` as is, ``(x, p)`` with params, ``(x, t)``
        or ``(x, p, t)`` with time; see :func:`system_callables`).

        ``name``, ``params`` (name -> box), ``source`` and ``time`` go to the System as given;
        ``time_box`` (None: the default) is added to its domain; its notes are ``notes``
        followed by those of the parts.
        """
        from .._model.system import System

        domain = dict(self.domain)
        if time is not None and time_box is not None:
            domain[time] = tuple(time_box)
        return System(
            self.states,
            {k: wrap(f) for k, f in self.outputs.items()},
            known={k: wrap(f) for k, f in self.known.items()},
            unknown={k: wrap(f) for k, f in self.unknown.items()},
            drift=None if self.drift is None else wrap(self.drift),
            domain=domain, angles=self.angles, name=name, params=params, source=source,
            notes=tuple(notes) + tuple(self.notes), time=time,
        )


def system_callables(with_params: bool, with_time: bool):
    """The ``wrap`` of :meth:`Parts.to_system`: ``fn(z)`` -> the System's callable.

    ``z`` is ``[x; p; t]`` (``p`` only ``with_params``, ``t`` only ``with_time``); the callable
    takes ``x`` (shape ``(n,)``), ``(x, p)``, ``(x, t)`` or ``(x, p, t)`` (``t`` a scalar) and
    returns ``fn`` of their concatenation (:class:`~uio_jax._io.model_functions.Joined`; numpy
    on numpy arguments).
    """
    arity = 1 + bool(with_params) + bool(with_time)
    return (lambda fn: fn) if arity == 1 else (lambda fn: Joined(fn, arity))


def vector_function(exprs: Mapping[str, Expr], rows: Sequence[str], names: Sequence[str], constants):
    """Compile per-row expressions into ``fn(z) -> (len(rows),)``; rows absent from ``exprs`` are 0.

    ``z`` (shape ``(len(names),)``) is read by ``names`` (see
    :func:`uio_jax._io.expressions.to_function`); a numpy ``z`` is evaluated with numpy
    (:class:`~uio_jax._io.model_functions.RowsFunction`).
    """
    return RowsFunction(compile_rows(exprs, rows, names, constants))


def split_general(states, dynamics, outputs, known_inputs, unknown_inputs, params, constants,
                  domain, angles, *, seed: int = 0) -> Parts:
    """Split ``x' = f(x, p, u, w)`` into drift and input fields, promoting non-affine inputs.

    Args:
        states: state names (order of ``x``, length n).
        dynamics: state -> Expr of its derivative (missing states: 0).
        outputs: output name -> Expr (may use states, params, inputs, constants).
        known_inputs, unknown_inputs: input names (``u`` and ``w``).
        params: parameter name -> (lo, hi) box (order of ``p``).
        constants: known constant name -> value.
        domain: state or input name -> (lo, hi) sampling box.
        angles: state names that are angles.
        seed: seed of the affinity samples.

    Returns:
        :class:`Parts` on ``z = [x; promoted inputs; p]``: the drift ``f0 = f(u=0, w=0)``
        (None when it vanishes identically), the fields ``d f / d u_i`` and
        ``d f / d w_j`` at ``u = w = 0``, unit fields for the derivatives of promoted
        inputs, and one note per promotion or dropped input.

    Raises:
        ModelError: the dynamics are not finite at any sampled point.
    """
    states, known_inputs, unknown_inputs = tuple(states), tuple(known_inputs), tuple(unknown_inputs)
    inputs = known_inputs + unknown_inputs
    notes = []
    used = set().union(*(names_of(e) for e in dynamics.values())) if dynamics else set()
    in_outputs = set().union(*(names_of(e) for e in outputs.values())) if outputs else set()
    dropped = [v for v in inputs if v not in used and v not in in_outputs]
    for v in dropped:
        kind = "known" if v in known_inputs else "unknown"
        notes.append(f"{kind} input {v!r} appears in no equation: dropped")
    known_inputs = tuple(v for v in known_inputs if v not in dropped)
    unknown_inputs = tuple(v for v in unknown_inputs if v not in dropped)
    inputs = known_inputs + unknown_inputs

    nonsmooth = inputs_in_nonsmooth(dynamics.values(), set(inputs))
    reasons = promotion_reasons(
        inputs, unknown_inputs, in_outputs, {v: "enters through abs/sign/min/max" for v in nonsmooth},
        lambda: nonaffine_pattern(states, dynamics, inputs, params, constants, domain, angles, seed=seed))
    promoted = tuple(v for v in inputs if v in reasons)
    return _assemble(states, dynamics, outputs, known_inputs, unknown_inputs, promoted, reasons, params,
                     constants, domain, angles, tuple(notes))


def _fresh(name, taken):
    out = name
    while out in taken:
        out += "_"
    taken.add(out)
    return out


def _assemble(states, dynamics, outputs, known_inputs, unknown_inputs, promoted, reasons, params,
              constants, domain, angles, notes):
    pnames = tuple(params)
    taken = set(states) | set(pnames) | set(known_inputs) | set(unknown_inputs) | set(outputs) | set(constants)
    new_states = tuple(states) + promoted
    n = len(new_states)
    znames = new_states + pnames
    rest = tuple(v for v in known_inputs + unknown_inputs if v not in promoted)
    nrest = len(rest)
    fns = compile_rows(dynamics, states, znames + rest, constants)  # promoted inputs read their state
    drift = GeneralDrift(fns, nrest, n)
    return build_parts(states, promoted, known_inputs, unknown_inputs, outputs, reasons, params, domain, angles,
                       notes, taken, field_of=lambda i: InputField(fns, nrest, n, i),
                       output_of=lambda e: to_function(e, znames, constants), unit=lambda j: UnitField(n, j),
                       drift=drift, has_drift=lambda boxes: bool(dynamics) and not vanishes(drift, boxes))


def build_parts(states, promoted, known_inputs, unknown_inputs, outputs, reasons, params, domain, angles, notes,
           taken, *, field_of, output_of, unit, drift, has_drift) -> Parts:
    """The :class:`Parts` on ``z = [x; promoted; p]`` that both routes assemble alike.

    ``known_inputs``/``unknown_inputs``: the inputs kept (not dropped), ``promoted`` those
    of them that become states (after ``states``, in this order). The routes differ only in
    how their functions are made: ``field_of(i)`` is the field of the ``i``-th unpromoted
    input (in the order known then unknown), ``output_of(h)`` the output function of
    ``outputs[name]``, ``unit(j)`` the constant field ``e_j`` (the derivative of promoted
    state ``j``); ``has_drift(boxes)`` (the sampling boxes of ``z``) says whether ``drift``
    is kept. Each promotion (:func:`promotions`, which adds its new names to ``taken``)
    adds its note, its input ``d`` with field ``e_j``, its box (``domain`` or
    :data:`INPUT_BOX`) and, for a known input, an output reading the state.
    """
    from .._model.system import DEFAULT_BOX

    n0 = len(states)
    new_states = tuple(states) + tuple(promoted)
    rest = tuple(v for v in known_inputs + unknown_inputs if v not in promoted)
    known = {v: field_of(rest.index(v)) for v in known_inputs if v not in promoted}
    unknown = {v: field_of(rest.index(v)) for v in unknown_inputs if v not in promoted}
    out_fns = {k: output_of(h) for k, h in outputs.items()}
    new_domain = {k: tuple(b) for k, b in domain.items() if k in states}
    notes = list(notes)
    for j, (v, d, y, note) in enumerate(promotions(promoted, reasons, known_inputs, outputs, taken)):
        new_domain[v] = box(v, domain, (), INPUT_BOX)
        notes.append(note)
        if v in known_inputs:
            known[d] = unit(n0 + j)
            out_fns[y] = Coordinate(n0 + j)  # a known input is measured
        else:
            unknown[d] = unit(n0 + j)
    boxes = [new_domain.get(s) or box(s, domain, angles, DEFAULT_BOX) for s in new_states]
    boxes += [tuple(map(float, params[q])) for q in params]
    return Parts(states=new_states, outputs=out_fns, known=known, unknown=unknown,
                 drift=drift if has_drift(boxes) else None, domain=new_domain, angles=tuple(angles),
                 notes=tuple(notes), promoted=promoted)


def promotions(promoted, reasons, known_inputs, outputs, taken):
    """For each promoted input ``v``: ``(v, d, y, note)``, with ``d`` the new input ``v' = d``,
    ``y`` the new output of a known ``v`` (None for an unknown one) and the System's note.

    ``taken`` (a set of every name in use) receives the new names.
    """
    out = []
    for v in promoted:
        d = _fresh(f"d_{v}", taken)
        if v in known_inputs:
            y = _fresh(v if v not in outputs else f"y_{v}", taken - {v})
            note = (f"known input {v!r} {reasons[v]}: promoted to a state {v!r} with {v}' = {d} "
                    f"({d!r} a new known input) and output {y!r} (a known input is measured)")
        else:
            y = None
            note = (f"unknown input {v!r} {reasons[v]}: promoted to a state {v!r} with {v}' = {d} "
                    f"({d!r} a new unknown input; exact for a smooth {v})")
        out.append((v, d, y, note))
    return out
