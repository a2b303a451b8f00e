"""The user's model: state names plus plain JAX callables.

A :class:`System` describes

    xdot = f0(x) + sum_i f_i(x) u_i + sum_j g_j(x) w_j,      y = h(x) in R^p,

with ``u`` known inputs (free to choose, may jump) and ``w`` unknown inputs (smooth
functions of time). Every callable takes the state vector ``x`` of shape ``(n,)``; a field
returns shape ``(n,)`` and an output returns a scalar (shape ``()``).

With unknown constant parameters ``theta`` (``params=``), every callable takes ``(x, p)``
and the analyses run on the joint vector ``z = [x; theta]`` with ``theta' = 0``: a
parameter is identifiable exactly when its coordinate is observable on ``z``.

A time-varying system (``time="t"``) has callables ``f0(x, t)``, ``h(x, t)``, ... (``(x, p, t)``
with parameters, ``t`` a scalar of shape ``()``); the analyses run on the autonomous System on
``[x; p; t]`` with ``t' = 1`` and ``t`` measured (:meth:`System.autonomous`,
:mod:`uio_jax._model.time`).
"""

import contextlib
import contextvars
import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from .._engine.graph import Graph
from .._engine.graph_trace import translate_or_refuse
from .._errors import ModelError
from .arguments import DEFAULT_BOX as DEFAULT_BOX  # the sampling boxes, imported from here too
from .arguments import DEFAULT_TIME_BOX as DEFAULT_TIME_BOX
from .arguments import (
    as_callables,
    as_domain,
    as_names,
    as_params,
    as_time,
    check_identifiers,
    check_input_names,
)
from .derivation import USER_SYSTEM, Derivation
from .symmetries import as_symmetries, check_symmetry_shapes, lifted_symmetries
from .validation import check_shapes, finite_notes, promoted_functions

#: ``x (n,) -> (n,)``: a vector field (a JAX callable, or a function that builds its own
#: expression, :mod:`uio_jax._engine.graph_trace`)
Field = Callable
#: ``x (n,) -> ()``: an output
Scalar = Callable
_EMPTY = MappingProxyType({})

#: True while a System is built from the functions of an already validated one (the EORC's
#: extended system): the traced checks (shapes, NaN at sampled states) are skipped.
_DERIVED = contextvars.ContextVar("uio_jax_derived_system", default=False)


@contextlib.contextmanager
def derived_system():
    """Build Systems whose functions are those of a validated System, reshaped by us.

    Inside the block the traced checks of :class:`System` (output and field shapes,
    finiteness at sampled states) are skipped: they cost a trace and a compile per
    System, and the parts were checked when the user's System was built.
    """
    token = _DERIVED.set(True)
    try:
        yield
    finally:
        _DERIVED.reset(token)


@dataclass(frozen=True, eq=False)
class System:
    """A control-affine nonlinear system with known and unknown inputs.

    Args:
        states: state names, in the order of the state vector ``x`` (length n).
        outputs: output name -> ``h(x)``, a scalar function of ``x`` (shape ``()``).
        known: known-input name -> field ``f_i(x)`` of shape ``(n,)``.
        unknown: unknown-input name -> field ``g_j(x)`` of shape ``(n,)``.
        drift: optional drift ``f0(x)`` of shape ``(n,)``.
        domain: state name -> ``(lo, hi)``, the box where states are sampled to certify
            ranks. States not listed use ``DEFAULT_BOX`` = (0.5, 1.5), or ``[-pi, pi)``
            when listed in ``angles``.
        angles: names of states that are angles (sampled in ``[-pi, pi)``; innovations
            and errors on them are wrapped by the Monte Carlo filter).
        name: optional name shown in reports.
        params: unknown constant parameters, name -> ``(lo, hi)`` sampling box (or a
            sequence of names: ``DEFAULT_BOX`` each), in the order of the parameter
            vector ``p``. When given, EVERY callable takes
            ``(x, p)`` (``x`` of shape ``(n,)``, ``p`` of shape ``(len(params),)``) and
            returns what it would without parameters. The analyses treat the parameters
            as states with zero derivative (:meth:`joint`), so ``Report.identifiable``
            answers identifiability.
        source: the declarative model this System was built from (model file, sympy),
            kept so that :func:`uio_jax.save_model` can write it back; ``None`` for
            Systems built from Python callables.
        notes: remarks carried into every Report of this System (e.g. how an importer
            rewrote the model).
        time: name of the time variable of a time-varying system (an identifier distinct
            from every state, parameter, input and output name), or ``None`` (default:
            time-invariant). When given, EVERY callable takes a trailing scalar time
            argument: ``fn(x, t)``, or ``fn(x, p, t)`` with params (``t`` of shape ``()``, in
            seconds). ``domain`` may list the time name: the box ``(lo, hi)`` where ``t`` is
            sampled to certify ranks (default ``DEFAULT_TIME_BOX`` = (0.0, 1.0)). The analyses
            run on :meth:`autonomous`: ``t`` becomes a state with ``t' = 1`` that is measured.
        symmetries: name -> ``xi``, a vector field along which the model is claimed
            invariant (a rotation about an axis nobody measures, a scaling of a state
            against a parameter). ``xi`` takes the arguments of the other callables and
            returns shape ``(n + len(params),)`` (states, then parameters; time never
            moves). The analyses verify each claim exactly before using it
            (:mod:`uio_jax._analysis.decisions.symmetry`: ``L_xi h = 0``, ``[xi, f0] = [xi, f_i] = 0``,
            ``[xi, g_j]`` a constant combination of the unknown-input fields); a verified
            one proves the coordinates it moves unobservable and lets the EORC stop once its
            bound is reached. A claim that fails is reported, never used.
        derivation: keyword only, set by the package on the Systems it derives from
            another one (:class:`~uio_jax._model.derivation.Derivation`: the joint and
            autonomous Systems, the jets of smooth inputs, Systems of graph nodes, a renamed
            copy); a user's System leaves the default.

    Raises:
        ModelError: a one-line message naming the problem (wrong length, non-scalar
            output, duplicate or unknown name, non-callable entry, empty or inverted
            domain box, a function that is NaN/inf on the whole domain, no outputs, a time
            name that is not an identifier or is taken by a state, parameter, input or output).

    Example:
        >>> import jax.numpy as jnp, uio_jax as uj
        >>> sys = uj.System(states=("x", "v"), outputs={"x": lambda s: s[0]},
        ...                 known={"a": lambda s: jnp.array([0.0, 1.0])},
        ...                 drift=lambda s: jnp.array([s[1], 0.0]))
    """

    states: tuple[str, ...]
    outputs: Mapping[str, Scalar]
    known: Mapping[str, Field] = field(default_factory=dict)
    unknown: Mapping[str, Field] = field(default_factory=dict)
    drift: Field | None = None
    domain: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    angles: tuple[str, ...] = ()
    name: str = ""
    params: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    source: object = field(default=None, repr=False)
    notes: tuple[str, ...] = ()
    time: str | None = None
    symmetries: Mapping[str, Field] = field(default_factory=dict)
    derivation: Derivation = field(default=USER_SYSTEM, kw_only=True, repr=False)

    def __post_init__(self):
        derivation = self.derivation
        if not isinstance(derivation, Derivation):
            raise ModelError(f"derivation must be a Derivation, got {type(derivation).__name__}")
        origin = derivation.same_functions_as
        states = as_names(self.states, "states")
        if not states:
            raise ModelError("a System needs at least one state")
        object.__setattr__(self, "states", states)
        angles = as_names(self.angles, "angles")
        for a in angles:
            if a not in states:
                raise ModelError(f"angle {a!r} is not a state (states: {', '.join(states)})")
        object.__setattr__(self, "angles", angles)
        for attr in ("outputs", "known", "unknown"):
            object.__setattr__(self, attr, as_callables(getattr(self, attr), attr))
        if not self.outputs:
            raise ModelError("a System needs at least one output")
        both = set(self.known) & set(self.unknown)
        if both:
            raise ModelError(f"input {sorted(both)[0]!r} is declared both known and unknown")
        if self.drift is not None and not callable(self.drift):
            raise ModelError(f"drift must be callable, got {type(self.drift).__name__}")
        if not isinstance(self.name, str):
            raise ModelError(f"name must be a string, got {type(self.name).__name__}")
        params = as_params(self.params, states)
        object.__setattr__(self, "params", params)
        time = as_time(self.time, states, params, self.known, self.unknown, self.outputs)
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "domain", as_domain(self.domain, states, angles, time))
        if not _DERIVED.get():
            check_input_names(self.known, self.unknown, states, params)
            check_identifiers({"state": states, "parameter": tuple(params)})
        notes = (self.notes,) if isinstance(self.notes, str) else tuple(self.notes or ())
        if not all(isinstance(t, str) for t in notes):
            raise ModelError("notes must be strings")
        object.__setattr__(self, "notes", notes)
        object.__setattr__(self, "symmetries", as_symmetries(self.symmetries))
        # the expression graph of the functions and their translations (System.expression)
        object.__setattr__(self, "_graph", derivation.graph if derivation.graph is not None else
                           origin.expression_graph if origin is not None else Graph(len(states)))
        object.__setattr__(self, "_expressions", origin._expressions if origin is not None else {})
        if not _DERIVED.get():
            promote = check_shapes(self)
            for attr, value in promoted_functions(self, promote).items():
                object.__setattr__(self, attr, value)
            check_symmetry_shapes(self)
        if params:
            from .joint import build_joint

            joint = (origin.joint().with_name(self.name) if origin is not None
                     else build_joint(self, lifted_symmetries(self)))  # validated there
            object.__setattr__(self, "_joint", joint)
            object.__setattr__(self, "notes", joint.notes)  # with the notes of its finiteness check
        elif time is not None:
            from .time import build_autonomous

            auto = (origin.autonomous().with_name(self.name) if origin is not None else build_autonomous(
                self, derivation.joint_params, lifted_symmetries(self) or derivation.symmetry_fields))
            object.__setattr__(self, "_autonomous", auto)  # validated there
            object.__setattr__(self, "notes", auto.notes)  # with the notes of its finiteness check
        elif not _DERIVED.get():
            object.__setattr__(self, "notes", finite_notes(self))
        if origin is not None:  # taken over: not kept
            object.__setattr__(self, "derivation", dataclasses.replace(derivation, same_functions_as=None))

    # ------------------------------------------------------------------ accessors
    @property
    def n(self) -> int:
        """Dimension of the state."""
        return len(self.states)

    def fields(self) -> dict[str, Field]:
        """Every vector field by its label: ``f0`` (drift, if any), known, then unknown."""
        drift = {} if self.drift is None else {"f0": self.drift}
        return {**drift, **self.known, **self.unknown}

    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners of the sampling box, each of shape ``(n,)``."""
        lo = np.array([self.domain[s][0] for s in self.states], dtype=np.float64)
        hi = np.array([self.domain[s][1] for s in self.states], dtype=np.float64)
        return lo, hi

    @property
    def time_box(self) -> tuple[float, float] | None:
        """Sampling box ``(lo, hi)`` of the time variable (seconds); ``None`` without ``time``."""
        return None if self.time is None else self.domain[self.time]

    @property
    def time_name(self) -> str | None:
        """Name of the time variable: ``time`` of a time-varying System, the name of the last
        state of the System returned by :meth:`autonomous` (time made a state), else ``None``."""
        return self.time if self.time is not None else self.derivation.time_name

    @property
    def known_coordinates(self) -> int:
        """Number of trailing state coordinates whose values are known (measured exactly).

        1 on the System that :meth:`autonomous` returns for a time-varying System (the time
        coordinate ``t``, with ``t' = 1``); 0 otherwise. The analyses keep the differentials
        of these coordinates in the codistribution and leave them out of the verdicts.
        """
        return self.derivation.known_coordinates

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of the unknown constant parameters (order of ``p``)."""
        return tuple(self.params)

    @property
    def joint_param_names(self) -> tuple[str, ...]:
        """Coordinates of this System's state that are parameters of the user's model.

        Empty for a user's System; set on the System returned by :meth:`joint` (and on its
        :meth:`autonomous`).
        """
        return tuple(self.derivation.joint_params)

    @property
    def known_outputs(self) -> tuple[str, ...]:
        """Names of the outputs that measure this System's known coordinates: the time output
        of :meth:`autonomous`, the jets of the known inputs of
        :func:`uio_jax._model.smooth_inputs.with_input_jets`; empty for a user's System."""
        own = self.derivation.known_outputs
        if own is not None:
            return tuple(own)
        name = self.time_name
        return (name,) if self.known_coordinates and name in self.outputs else ()

    @property
    def expression_graph(self) -> Graph:
        """The expression graph (:class:`~uio_jax._engine.graph.Graph`) of this System's
        functions: the one :meth:`expression` translates them into, or the graph a System
        built of graph nodes is made of (:func:`uio_jax._model.graph_system.graph_system`)."""
        return self._graph

    @property
    def symmetry_fields(self) -> Mapping[str, Field]:
        """The declared symmetries as fields of this System's coordinates, on the System the
        analyses run on (:meth:`autonomous`): name -> ``z (N,) -> (N,)``; empty elsewhere
        (:func:`uio_jax._model.symmetries.lifted_symmetries`)."""
        if self.time is not None:  # the analyses run on the autonomous System
            return _EMPTY
        if self.derivation.symmetry_fields is not None:
            return self.derivation.symmetry_fields
        return self.symmetries if not self.params else _EMPTY

    def with_name(self, name: str) -> "System":
        """This System under another ``name``: the same functions, their translations into the
        graph, its joint and autonomous Systems renamed (nothing is validated or traced
        again); ``self`` when the name is already ``name``."""
        if not isinstance(name, str):
            raise ModelError(f"name must be a string, got {type(name).__name__}")
        if name == self.name:
            return self
        with derived_system():  # the same (validated) functions
            return dataclasses.replace(self, name=name, derivation=dataclasses.replace(
                self.derivation, same_functions_as=self))

    def joint(self) -> "System":
        """The parameter-free System on ``z = [x; p]`` that the analyses run on.

        States are ``states + params``, every field is padded with ``p' = 0`` and every
        callable reads ``x = z[:n]``, ``p = z[n:]``; the parameter boxes become domains.
        Returns ``self`` when there is no parameter. Of a time-varying System, the joint
        System is time-varying too (its callables take ``(z, t)``, ``domain`` keeps the time
        box).
        """
        return getattr(self, "_joint", self)

    def autonomous(self) -> "System":
        """The System without parameters and without explicit time that the analyses run on.

        For a time-varying System (``time`` set), the System on ``z = [x; p; t]``
        (states: ``states``, then ``params``, then the time name; no params left) whose
        callables take ``z`` only:

        * drift ``[f0(x, p, t); 0; 1]`` (``[0; 0; 1]`` when there is no drift);
        * known and unknown fields ``[f_i(x, p, t); 0; 0]``;
        * outputs ``h(x, p, t)`` and one more output named like the time variable,
          ``z[-1]`` (time is known: it is measured);
        * ``domain``: the state boxes, the parameter boxes, then the time box.

        It has ``known_coordinates == 1`` (the time coordinate, last) and ``time_name``,
        ``joint_param_names`` the parameters. For a time-invariant System it is
        :meth:`joint` (``known_coordinates == 0``). Built (and validated: finiteness at
        states, parameters and times drawn in their boxes) with the System.
        """
        return self.joint() if self.time is None else self.joint()._autonomous

    def with_known(self, names) -> "System":
        """A copy where the unknown inputs ``names`` are treated as known inputs."""
        names = tuple(names)
        for nm in names:
            if nm not in self.unknown:
                raise ModelError(f"{nm!r} is not an unknown input of this system")
        known = {**self.known, **{nm: self.unknown[nm] for nm in names}}
        unknown = {k: v for k, v in self.unknown.items() if k not in names}
        with derived_system():  # the same (validated) functions
            return System(self.states, dict(self.outputs), known, unknown, self.drift,
                          dict(self.domain), self.angles, self.name, params=dict(self.params),
                          notes=self.notes, time=self.time, symmetries=dict(self.symmetries))

    def __repr__(self) -> str:
        parts = [f"states={self.states}", f"outputs={tuple(self.outputs)}"]
        if self.known:
            parts.append(f"known={tuple(self.known)}")
        if self.unknown:
            parts.append(f"unknown={tuple(self.unknown)}")
        if self.drift is not None:
            parts.append("drift")
        if self.params:
            parts.append(f"params={tuple(self.params)}")
        if self.symmetries:
            parts.append(f"symmetries={tuple(self.symmetries)}")
        if self.time is not None:
            parts.append(f"time={self.time!r}")
        elif self.known_coordinates:
            parts.append(f"known_coordinates={self.known_coordinates} ({self.time_name!r})")
        label = f"{self.name!r}, " if self.name else ""
        return f"System({label}{', '.join(parts)})"

    # ------------------------------------------------------------------ validation

    def expression(self, fn, shape, what="function"):
        """The expression of one of this System's functions ``x (n,) -> shape`` in its
        expression graph (:mod:`uio_jax._engine.graph`), translated once: an int for a
        scalar, a tuple of ints for a field.

        Raises:
            ModelError: the graph has no rule for a primitive of ``fn`` (the analyses have
                no other evaluator), or ``fn`` does not return ``shape``; ``what`` names
                the function in the message.
            IndexOutOfRange: ``fn`` indexes the state past its end (a constant index).
        """
        table = self._expressions
        key = (id(fn), tuple(shape))
        if key not in table:
            table[key] = (fn, translate_or_refuse(self._graph, fn, shape, what))
        return table[key][1]
