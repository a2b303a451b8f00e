"""Known initial conditions: local identifiability at a given initial state, decided exactly.

**The question.** A System ``x' = f0(x, p) + sum_i u_i f_i(x, p) + sum_j w_j g_j(x, p)``,
``y = h(x, p)``, started at ``x(0) = x0`` where some components are known: numbers
(``x1(0) = 0``) or functions of the parameters (``x2(0) = p3``). The unknowns are
``theta = (the unknown components of x0, p)``. The output is analytic in ``t``, so it is
determined by its Taylor coefficients at ``t = 0``, ``y_k = y^(k)(0) / k!``: polynomials (or
rational functions) of ``theta``, of the known components and of the inputs' derivatives at
``t = 0``. ``theta_j`` is *locally identifiable at the given initial state* when it is
determined, near a generic value of ``theta``, by the sequence ``(y_k)``; by the implicit
function theorem that holds when ``e_j`` lies in the row space of the Jacobian

    J_K = d(y_0, .., y_K) / d theta

for some ``K`` (at a generic ``theta``, the known components fixed at their values). The
rank of ``J_K`` never decreases with ``K``, so ``e_j`` in the row space at one ``K`` is a
proof at every later one.

**How it is decided** (one engine: the expression graph, :class:`~uio_jax._analysis.recursions.series.GraphCoefficients`
for the ``y_k``, the :class:`~uio_jax._analysis.decisions.settle.Settler` for every decision). The inputs
are jets ``u_i^(d)`` (the derivatives at ``t = 0``) appended to the state with the chain
``(u^(d))' = u^(d+1)``; ``y^(k)`` is built by symbolic forward mode along that field, at
``t = 0``, in a graph whose coordinates are the unknowns, the unknown inputs' jets and the
known inputs' jets; the known components of ``x0`` are substituted as exact constants or as
the parameter expressions they equal. Each row ``d y_k`` is absorbed into the span by an
exact rank decision modulo ``p = 2^127 - 1`` at random points (independent: certain;
dependent: wrong with probability at most ``D / p`` per point, Schwartz-Zippel, summed into
the error bound under ``1 - prob_threshold``). The known inputs' jets are known coordinates:
their unit covectors seed the span (a generic known input, drawn with the point, so that the
bound covers it); the unknown inputs' jets are unknowns whose columns stay in the Jacobian
(nuisance unknowns: never asked about). ``e_j`` in the span is a dependence decision of
the same kind.

**When it stops.** Every unknown determined; or, with no known component and no unknown
input, an order that adds nothing (the span of ``d L_F^j h`` and of the known jets is then
closed under ``L_F``: each later order lies in it, :mod:`uio_jax._analysis.recursions.series`); or the
order cap. At a *specific* initial state an order adding nothing proves nothing (``x1' = a
x2, x2' = b, y = x1`` from ``x1 = x2 = 0``: ``y_1 = 0`` adds no rank, ``y_2 = a b`` does) and
no a-priori order bound is known (StructuralIdentifiability.jl issue 168, STRIKE-GOLDD issue
7): an unknown not determined at the cap is reported undecided with the order reached,
unless a declared symmetry of the System, verified, tangent to the set of initial states and
moving it, proves it is not (:mod:`uio_jax._analysis.at_t0.initial_proofs`).
"""

import dataclasses
import decimal
import enum
import math
import numbers
import sys
from fractions import Fraction

import numpy as np

from ..._calculus.generators import Node, builder_for
from ..._engine import graph_exact, graph_numpy
from ..._engine.graph import Graph, exact_literal
from ..._engine.graph_elementary import Singular
from ..._engine.graph_trace import FunctionOfSlice
from ..._errors import ModelError, OptionError
from ..recursions.series import GraphCoefficients
from ..results.evidence import Finding

#: The box in which extended-precision points draw an input's derivative at t = 0 (the
#: modular points draw every coordinate uniformly in F_p).
JET_BOX = (-1.0, 1.0)

#: The record's text for a decision made exactly without a float64 vote.
NO_VOTE = "no float64 vote: decided exactly"


class Role(enum.Enum):
    """What a coordinate of the target graph is."""

    STATE = "unknown initial state"  # asked about: observable at t = 0?
    PARAM = "parameter"  # asked about: identifiable?
    UNKNOWN_JET = "unknown input derivative at t = 0"  # a nuisance unknown
    KNOWN_JET = "known input derivative at t = 0"  # known: its unit covector seeds the span


@dataclasses.dataclass(frozen=True)
class InitialValue:
    """The known initial value of one state.

    Attributes:
        state: the state's name.
        value: a :class:`~fractions.Fraction` (a number, read as its decimal), a ``float``
            (a constant known in float64 only, ``sin(pi)``), a parameter name (``str``), or
            a function ``p (len(params),) -> ()`` of the parameters.
        text: how the value reads in reports.
    """

    state: str
    value: object
    text: str


def check_initial(system, initial) -> dict:
    """``{state: InitialValue}`` from ``initial`` (``state -> value``), checked.

    One validation for every way a value arrives (:func:`initial_value`): a number (Python,
    :class:`~fractions.Fraction`, a numpy or JAX scalar), a string holding a number or a
    parameter's name, or a function of the parameter vector ``p`` (JAX-traceable, returning a
    scalar; the expressions of ``--initial`` and of a model file's ``[initial]`` table arrive
    as such functions).

    Raises:
        OptionError: not a mapping, a name that is not a state, a time-varying System, or a
            value refused by :func:`initial_value` (one line each).
    """
    if not hasattr(initial, "items"):
        raise OptionError(f"initial must be a mapping state -> value, got {type(initial).__name__}")
    if system.time is not None:
        raise OptionError("known initial conditions of a time-varying System are not supported")
    out = {}
    for name, value in initial.items():
        if not isinstance(name, str) or name not in system.states:
            what = "a parameter, not a state" if name in system.params else "not a state"
            raise OptionError(f"initial: {name!r} is {what} (states: {', '.join(system.states)})")
        out[name] = initial_value(system, name, value)
    return out


#: Parameter values at which a function-valued initial value must be real somewhere (float64,
#: drawn in the parameters' boxes): one that is not real at any of them is refused.
FUNCTION_SAMPLES = 64


def initial_value(system, name, value) -> InitialValue:
    """The known initial value of state ``name``, checked: a real number or a function of the
    parameters that is real somewhere in their box.

    A known value is not bounded by the state's sampling box (it may lie anywhere the model is
    defined: :func:`check_defined`). Every value becomes one of

    * an exact :class:`~fractions.Fraction`: a number (a float means its shortest decimal, as
      every literal does: ``docs/exactness.md``), or a function whose graph folds to an exact
      constant (``3 * 1``, ``1 / 3``);
    * a ``float``: a constant known in float64 only (a non-rational function of constants,
      ``sin(pi)``): the decisions that use it are not exact, and the report says so;
    * a parameter's name (``str``), or the function itself (it depends on the parameters).

    Raises:
        OptionError: a value that is not a real number (NaN, infinite, complex, ``1/0``,
            ``sqrt(-1)``, an overflow such as ``exp(1000)``), a boolean or another type, a
            string that is neither a number nor a parameter, a function that raises, does not
            translate, or is not real at any parameter value of the box.
    """
    params = tuple(system.params)
    if isinstance(value, str):
        text = value.strip()
        if text in params:
            return InitialValue(name, text, text)
        try:
            number = float(text)
        except ValueError:
            raise OptionError(
                f"initial value of {name}: {value!r} is neither a number nor a parameter "
                f"(parameters: {', '.join(params) or 'none'}); an expression in the parameters is a "
                "function of p in Python, text in a model file's [initial] or --initial") from None
        if not math.isfinite(number):
            raise OptionError(f"initial value of {name} is {text}: not a real number")
        return _constant(name, Fraction(text), text)
    if callable(value):
        return _function_value(system, name, value)
    return _constant(name, _real(name, value), None)


def _real(name, value):
    """A Python number, Fraction, numpy or JAX scalar as an exact Fraction (OptionError if
    it is not a finite real number)."""
    if isinstance(value, Fraction):
        return value
    if hasattr(value, "dtype") and hasattr(value, "shape") and not isinstance(value, numbers.Number):
        arr = np.asarray(value)
        if arr.shape != ():
            raise OptionError(f"initial value of {name} must be a scalar, got an array of shape {arr.shape}")
        value = arr[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Number):
        raise OptionError(f"initial value of {name} must be a number, a parameter name or a function of "
                          f"the parameters, got {type(value).__name__}")
    if isinstance(value, numbers.Complex) and not isinstance(value, numbers.Real):
        raise OptionError(f"initial value of {name} is {value}: not a real number")
    exact = exact_literal(float(value) if isinstance(value, np.floating) else value)
    if exact is None:
        raise OptionError(f"initial value of {name} is {value}: not a real number")
    return exact


def _constant(name, value, text) -> InitialValue:
    """A constant initial value: exact (Fraction) or known in float64 only (float)."""
    if isinstance(value, float) and not math.isfinite(value):
        shown = f"{text} = {value}" if text else f"{value}"
        raise OptionError(f"initial value of {name} is {shown}: not a real number")
    if abs(value) > sys.float_info.max:
        raise OptionError(f"initial value of {name}{f' ({text})' if text else ''} lies outside the float64 range "
                          "(the model is evaluated in float64 too)")
    shown = number_text(value)
    if text is None:
        text = shown
    elif isinstance(value, float) or not _same_number(text, value):
        text = f"{text} = {shown}"
    return InitialValue(name, value, text)


def _same_number(text, value) -> bool:
    try:
        return Fraction(text) == value
    except (ValueError, ZeroDivisionError):
        return False


def number_text(value) -> str:
    """A number as reports show it: an integer exactly, a fraction or a float to 6 digits,
    never a nonzero value printed as 0 (``1e-400``)."""
    if isinstance(value, Fraction):
        if value.denominator == 1:
            return str(value.numerator)
        with decimal.localcontext() as ctx:
            ctx.prec = 40
            return format(decimal.Decimal(value.numerator) / decimal.Decimal(value.denominator), ".6g")
    return f"{value:.6g}"


def _function_value(system, name, fn) -> InitialValue:
    """A function of the parameters, translated into the model's graph once and checked: a
    constant result becomes a number (:func:`_constant`); otherwise it must be real at some
    parameter value of the box (float64)."""
    text = getattr(fn, "text", None) or f"{getattr(fn, '__name__', 'f')}(p)"
    joint = system.autonomous()
    builder = builder_for(joint)
    ns = len(system.states)
    try:
        node = builder.function(f"initial value of {name}", FunctionOfSlice(fn, ns)).expr
    except Exception as exc:  # the user's function raised: one line, not their traceback
        why = str(exc) if isinstance(exc, ModelError) else f"the function raised {type(exc).__name__}: {exc}"
        if not system.params:
            why = f"a function of the parameters, but the System has none ({why})"
        raise OptionError(f"initial value of {name}: {why}") from None
    graph = builder.graph
    if graph.op[node] == "c":
        exact = graph.exact_value(node)
        return _constant(name, exact if exact is not None else graph.value_of(node), text)
    lo, hi = joint.box()
    rng = np.random.default_rng(0x1417)
    zs = lo + rng.random((FUNCTION_SAMPLES, len(lo))) * (hi - lo)
    with np.errstate(all="ignore"):
        values = graph_numpy.evaluate(graph, [node], zs, gradients=False)[:, 0]
    if not np.isfinite(values).any():
        raise OptionError(f"initial value of {name} ({text}) is not a real number at any of {FUNCTION_SAMPLES} "
                          "parameter values drawn in their box")
    return InitialValue(name, fn, text)


def unused_parameters(system) -> tuple:
    """The parameters of ``system`` (a user's System, or the joint System of one) that appear
    in none of its outputs and fields: declared, but no equation uses them."""
    joint = system.autonomous() if system.params else system
    names = joint.joint_param_names
    if not names:
        return ()
    builder = builder_for(joint)
    graph = builder.graph
    roots = [builder.scalar(k, fn).expr for k, fn in joint.outputs.items()]
    roots += [e for k, fn in joint.fields().items() for e in builder.field(k, fn).expr]
    used = {graph.param[k] for k in graph.reachable(roots) if graph.op[k] == "x"}
    first = joint.states.index(names[0])
    return tuple(nm for i, nm in enumerate(names) if first + i not in used)


def unused_note(names) -> str:
    """The note of parameters that no equation uses."""
    many = len(names) > 1
    return (f"parameter{'s' if many else ''} {', '.join(names)} appear{'' if many else 's'} in no equation "
            f"(output or field): declared but unused, {'they are' if many else 'it is'} not identifiable")


class Coordinates:
    """The coordinates of a target graph: one per unknown and per input derivative."""

    def __init__(self):
        self.names, self.roles, self.boxes = [], [], []
        self.index = {}

    def add(self, name, role: Role, box) -> int:
        """The coordinate ``name`` (added once; shared parameters are named once)."""
        if name not in self.index:
            self.index[name] = len(self.names)
            self.names.append(name)
            self.roles.append(role)
            self.boxes.append(tuple(float(v) for v in box))
        return self.index[name]

    def of(self, *roles) -> list[int]:
        """The coordinates with one of ``roles``, in order."""
        return [i for i, r in enumerate(self.roles) if r in roles]

    def box(self):
        """``(lo, hi)`` arrays of the coordinates' boxes."""
        lo, hi = np.array(self.boxes, dtype=float).reshape(-1, 2).T
        return lo, hi


class Experiment:
    """One experiment's output coefficients ``y_k`` as rows of a target graph.

    Args:
        system: the user's System (with ``params``).
        initial: ``{state: InitialValue}`` (:func:`check_initial`).
        coords: the target graph's :class:`Coordinates` (this experiment's are added).
        cap: the highest order (``cap`` jets per input).
        suffix: appended to the names of this experiment's own coordinates (``""`` for one).
        shared: the parameters named without the suffix (shared between experiments).
    """

    def __init__(self, system, initial, coords: Coordinates, cap: int, suffix: str = "", shared=None):
        self.system, self.initial, self.cap, self.suffix = system, initial, cap, suffix
        self.joint = system.autonomous()
        params = tuple(system.params)
        shared = params if shared is None else tuple(shared)
        self.z_index = []  # per coordinate of the joint state: a target coordinate, or None (known)
        for s in system.states:
            self.z_index.append(None if s in initial else
                                coords.add(s + suffix, Role.STATE, system.domain[s]))
        for p in params:
            self.z_index.append(coords.add(p if p in shared else p + suffix, Role.PARAM, system.params[p]))
        self.jet_index = []
        for names, role in ((self.joint.known, Role.KNOWN_JET), (self.joint.unknown, Role.UNKNOWN_JET)):
            for u in names:
                self.jet_index += [coords.add(f"{u}^({d}){suffix}", role, JET_BOX) for d in range(cap)]
        self.seeds = [i for i in self.jet_index if coords.roles[i] is Role.KNOWN_JET]
        self.outputs = tuple(self.joint.outputs)
        self.target = None

    @property
    def closable(self) -> bool:
        """Whether an order that adds nothing to this experiment's own span closes it: no known
        component of the initial state and no unknown input (module docstring)."""
        return not self.initial and not self.joint.unknown

    def attach(self, target: Graph) -> None:
        """Build the coefficients and the map into ``target`` (its coordinates allocated)."""
        self.target = target
        joint, cap = self.joint, self.cap
        builder = builder_for(joint)
        g, nz = builder.graph, joint.n
        inputs = [*joint.known.items(), *joint.unknown.items()]
        g1 = Graph(nz + len(inputs) * cap)
        z1 = g1.coords[:nz]
        outs = g1.import_nodes(g, [builder.scalar(k, fn).expr for k, fn in joint.outputs.items()], z1)
        F = (list(g1.import_nodes(g, list(builder.field("f0", joint.drift).expr), z1))
             if joint.drift is not None else [g1.zero] * nz)
        for i, (label, fn) in enumerate(inputs):
            u0 = g1.x(nz + i * cap)
            field = g1.import_nodes(g, list(builder.field(label, fn).expr), z1)
            F = [g1.add(a, g1.mul(u0, b)) for a, b in zip(F, field)]
        for i in range(len(inputs)):  # the chain (u^(d))' = u^(d+1), the last one's 0
            F += [g1.x(nz + i * cap + d + 1) for d in range(cap - 1)] + [g1.zero]
        self.g1 = g1
        self.coefficients = GraphCoefficients(g1, outs, F, [], np.zeros((0, cap + 1)), cap)
        z_map = [self._value_node(builder, k) if t is None else target.x(t) for k, t in enumerate(self.z_index)]
        self.coord_map = z_map + [target.x(j) for j in self.jet_index]

    def _value_node(self, builder, k):
        """The node of ``target`` that the known initial state ``k`` equals."""
        target, system = self.target, self.system
        v = self.initial[system.states[k]]
        ns = len(system.states)
        if isinstance(v.value, Fraction):
            return target.const(v.value)
        if isinstance(v.value, float):  # known in float64 only: no exact decision uses it
            return target.inexact_const(v.value)
        params = tuple(system.params)
        p_nodes = [target.x(self.z_index[ns + i]) for i in range(len(params))]
        if isinstance(v.value, str):
            return p_nodes[params.index(v.value)]
        fn = v.value
        expr = builder.function(f"initial value of {v.state}", FunctionOfSlice(fn, ns)).expr
        return target.import_nodes(builder.graph, [expr], [target.zero] * ns + p_nodes)[0]

    def order(self, k: int) -> list:
        """The rows ``y_k[h]`` of every output, as Nodes of the target graph."""
        nodes = self.coefficients.order(k)
        exprs = self.target.import_nodes(self.g1, nodes, self.coord_map)
        return [Node(f"y_{k}[{h}]{self.suffix}", "scalar", k, e) for h, e in zip(self.outputs, exprs)]


def check_defined(graph: Graph, rows, seed: int, where: str, box) -> None:
    """Refuse (ModelError, one line) rows that are not defined at the initial state for any
    value of the unknowns: not finite in float64 at every point of the unknowns' ``box``
    (``y = 1/x`` or ``log x`` at ``x(0) = 0`` fold to a constant ``inf``; ``sqrt x`` at 0 has
    an infinite first coefficient), or dividing by zero at every random point of ``F_p``.

    Args:
        graph: the target graph.
        rows: the Nodes of the first orders ``y_0, y_1``.
        seed: seed of the points.
        where: the initial state, as text.
        box: ``(lo, hi)`` of the target coordinates.
    """
    exprs = [r.expr for r in rows]
    lo, hi = (np.asarray(b, dtype=float) for b in box)
    rng = np.random.default_rng([int(seed), 0xDEF1])
    zs = lo + rng.random((16, graph.n)) * (hi - lo)
    with np.errstate(all="ignore"):
        values = graph_numpy.evaluate(graph, exprs, zs, gradients=False)
    for r, row in enumerate(rows):
        if not np.isfinite(values[:, r]).any():
            raise ModelError(f"the model is not defined at the initial state ({where}): {row.label} is not finite "
                             "there for any value of the unknowns tried (a division by zero or a function outside "
                             "its domain)")
    for _ in range(3):
        point = [int(v) for v in rng.integers(1, 2**62, size=graph.n)]
        try:
            graph_exact.ModularEvaluator(graph, [point]).evaluate(exprs)
            return
        except Singular:
            continue
        except ValueError:
            return
    raise ModelError(f"the model is not defined at the initial state ({where}): a division by zero "
                     "there for every value of the unknowns tried")


class Span:
    """The rows kept so far, each decision made by a :class:`~uio_jax._analysis.decisions.settle.Settler`.

    Args:
        settler: the Settler of the target graph.
        seeds: coordinates whose unit covectors start the span (known coordinates).
    """

    def __init__(self, settler, seeds=()):
        self.settler = settler
        coords = settler.graph.coords
        self.kept = [Node(f"e_{i}", "scalar", 0, coords[i]) for i in seeds]
        self.seeds = len(self.kept)
        self.escalations = []  # every decision's record

    @property
    def rank(self) -> int:
        """The rank of the rows kept, the seeds not counted."""
        return len(self.kept) - self.seeds

    def absorb(self, rows) -> list[str]:
        """Keep the rows that raise the rank; returns their labels."""
        added = []
        graph = self.settler.graph
        for row in rows:
            if graph.op[row.expr] == "c":  # a constant: no direction
                continue
            esc = self.settler.settle(self.kept, row, NO_VOTE)
            self.escalations.append(esc)
            if esc.result is Finding.INDEPENDENT:
                self.kept.append(row)
                added.append(row.label)
        return added

    def contains(self, index: int) -> Finding:
        """Whether the unit covector of coordinate ``index`` lies in the span (DEPENDENT), not
        (INDEPENDENT), or could not be decided."""
        unit = Node(f"e_{index}", "scalar", 0, self.settler.graph.coords[index])
        esc = self.settler.settle(self.kept, unit, NO_VOTE)
        self.escalations.append(esc)
        return esc.result


__all__ = ["Role", "InitialValue", "check_initial", "initial_value", "number_text", "unused_parameters",
           "unused_note", "Coordinates", "Experiment", "Span", "check_defined",
           "JET_BOX", "NO_VOTE"]
